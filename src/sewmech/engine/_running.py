"""Compiled kernels of the run in time (:mod:`sewmech.engine.running`): the tables' interpolation,
the motor, the right-hand side of the machine's equation of motion and a Dormand-Prince 5(4)
integrator with events.

The tables (``running.RunTables``) are periodic in the shaft angle phi:

- the reduced inertia J and its derivative J' on a fine grid (``JG``, ``DJG`` exact at the
  nodes, ``D2JG`` the central differences of J'): J is the cubic Hermite interpolant of J and
  J', J' that of J' and its differences (C1 both);
- the non-inertial torque N(phi, w, e) on the coarse grid of the force analysis: ``N0[j, i]``
  at the speeds ``WN[j]`` and e = 0 (``N0W`` its slopes in w: the monotone cubic of Fritsch and
  Carlson, linear beyond the last speed), and the change friction makes with the acceleration,
  ``DT[j, k, i]`` at the speeds ``WM[j]`` and accelerations ``EA[k]`` (0 at e = 0 and at
  w = 0: the smooth signs of friction vanish at rest), linear in w and piecewise linear in e
  (the end pieces continued). In phi the four grid values around a point give a Catmull-Rom
  cubic (C1, no wiggles wider than a cell at a load that starts or stops).

Motor parameters ``MP`` (see ``running._motor_params``): 0 kind (0 table, 1 induction, 2
clutch, 3 servo), 1 belt ratio i, 2 hand wheel J_hw, 3 rotor J_r (kg mm^2), 4 synchronous
speed (rad/s of the motor), 5 breakdown slip, 6 breakdown torque, 7 clutch torque, 8 brake
torque, 9 servo torque limit (N mm), 10 k_p (N mm s), 11 k_i (N mm), 12 the servo's speed
command (rad/s of the motor), 13 its tracking time (s), 14 the brake's smooth speed (rad/s).
A table motor's points are ``TW`` (rad/s) and ``TT`` (N mm).

State y = (phi, w, I, w_m): the shaft's angle and speed, the servo's integral torque (N mm)
and the motor's speed while a clutch slips (else i w). Modes: RUN (motor on, coupled), STOP
(motor off, still belted to the shaft; a servo's command 0), SLIP (a clutch motor's clutch
slipping, the sign of the slip apart), FREE (a clutch motor stopping: declutched, braked).
Units: mm, kg, s, N; torques N mm, inertias kg mm^2 (1 kg mm^2 rad/s^2 = 1e-3 N mm).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import _compiling

_compiling.install()  # a kernel compiled on its first use says so on stderr

RUN, STOP, SLIP, FREE = 0, 1, 2, 3
#: segment ends: the time asked for, phi_end, the shaft at rest while driven (stalled), the
#: speed below w_stop while stopping, the clutch locks, it slips, the buffers are full, the
#: step fell below what floating point resolves
AT_TIME, AT_PHI, STALLED, STOPPED, LOCKED, SLIPS, FULL, TINY_STEP = range(8)

TWO_PI = 2.0 * math.pi

_OPT = dict(cache=True, error_model="numpy", fastmath={"contract"})


@njit(**_OPT, inline="always")
def _hermite(f, h, y0, y1, m0, m1):
    f2 = f * f
    f3 = f2 * f
    return ((2.0 * f3 - 3.0 * f2 + 1.0) * y0 + (f3 - 2.0 * f2 + f) * h * m0
            + (-2.0 * f3 + 3.0 * f2) * y1 + (f3 - f2) * h * m1)


@njit(**_OPT)
def inertia_at(phi, JG, DJG, D2JG):
    """J(phi) and J'(phi) (kg mm^2, kg mm^2/rad) from the fine grid."""
    n = JG.shape[0]
    h = TWO_PI / n
    x = (phi - TWO_PI * math.floor(phi / TWO_PI)) / h
    i = int(math.floor(x))
    f = x - i
    if i >= n:
        i, f = 0, 0.0
    k = i + 1 if i + 1 < n else 0
    J = _hermite(f, h, JG[i], JG[k], DJG[i], DJG[k])
    dJ = _hermite(f, h, DJG[i], DJG[k], D2JG[i], D2JG[k])
    return J, dJ


@njit(**_OPT, inline="always")
def _in_w(WN, Y, DY, i, w):
    """Column i of a table over speeds WN at w: the monotone cubic, constant below the first
    speed, linear beyond the last."""
    n = WN.shape[0]
    if n == 1 or w <= WN[0]:
        return Y[0, i]
    if w >= WN[n - 1]:
        return Y[n - 1, i] + DY[n - 1, i] * (w - WN[n - 1])
    j = 0
    while WN[j + 1] < w:
        j += 1
    h = WN[j + 1] - WN[j]
    return _hermite((w - WN[j]) / h, h, Y[j, i], Y[j + 1, i], DY[j, i], DY[j + 1, i])


@njit(**_OPT, inline="always")
def _phi_cell(phi, n):
    h = TWO_PI / n
    x = (phi - TWO_PI * math.floor(phi / TWO_PI)) / h
    i = int(math.floor(x))
    f = x - i
    if i >= n:
        i, f = 0, 0.0
    return i, f


@njit(**_OPT, inline="always")
def _catmull(f, a, b, c, d):
    """The Catmull-Rom cubic through b (f = 0) and c (f = 1), slopes from the neighbours."""
    return _hermite(f, 1.0, b, c, 0.5 * (c - a), 0.5 * (d - b))


@njit(**_OPT)
def nonlinear_at(phi, w, WN, N0, N0W, WM, EA, DT, out):
    """N(phi, w, e_k) at every acceleration node e_k (``out[k]``, N mm)."""
    n = N0.shape[1]
    i, f = _phi_cell(phi, n)
    v = np.empty(4)
    for q in range(4):
        v[q] = _in_w(WN, N0, N0W, (i - 1 + q) % n, w)
    base = _catmull(f, v[0], v[1], v[2], v[3])
    ne = EA.shape[0]
    nm = WM.shape[0]
    # linear in w between the speeds WM (constant beyond them)
    if nm == 1 or w <= WM[0]:
        j, g = 0, 0.0
    elif w >= WM[nm - 1]:
        j, g = nm - 2, 1.0
    else:
        j = 0
        while WM[j + 1] < w:
            j += 1
        g = (w - WM[j]) / (WM[j + 1] - WM[j])
    for k in range(ne):
        if nm == 1:
            for q in range(4):
                v[q] = DT[0, k, (i - 1 + q) % n]
        else:
            for q in range(4):
                c = (i - 1 + q) % n
                v[q] = (1.0 - g) * DT[j, k, c] + g * DT[j + 1, k, c]
        out[k] = base + _catmull(f, v[0], v[1], v[2], v[3])


@njit(**_OPT)
def solve_acceleration(A, R, EA, NK):
    """e with A e + N(e) = R, N piecewise linear through (EA[k], NK[k]) and continued beyond;
    returns (e, N(e)). A: the inertia, N mm per rad/s^2."""
    ne = EA.shape[0]
    if ne == 1:
        return (R - NK[0]) / A, NK[0]
    k = 0
    while k < ne - 2 and A * EA[k + 1] + NK[k + 1] - R < 0.0:
        k += 1
    s = (NK[k + 1] - NK[k]) / (EA[k + 1] - EA[k])
    e = (R - NK[k] + s * EA[k]) / (A + s)
    return e, NK[k] + s * (e - EA[k])


@njit(**_OPT)
def motor_torque(wm, MP, TW, TT):
    """The torque of a table or induction motor at its speed wm (rad/s), N mm."""
    kind = int(MP[0])
    if kind == 0:
        n = TW.shape[0]
        if wm <= 0.0:
            return TT[0]
        if wm >= TW[n - 1]:
            return TT[n - 1] + (TT[n - 1] - TT[n - 2]) / (TW[n - 1] - TW[n - 2]) * (
                wm - TW[n - 1])
        j = 0
        while TW[j + 1] < wm:
            j += 1
        return TT[j] + (TT[j + 1] - TT[j]) * (wm - TW[j]) / (TW[j + 1] - TW[j])
    s = (MP[4] - wm) / MP[4]
    sb = MP[5]
    return 2.0 * MP[6] * s * sb / (s * s + sb * sb)


@njit(**_OPT)
def rhs(y, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, dy, NK, info):
    """dy/dt of the state y in ``mode``; ``info`` gets (e, the motor's torque, the torque the
    belt puts on the shaft, N(phi, w, e), the motor's speed, the clutch's torque)."""
    phi, w = y[0], y[1]
    ratio, jhw, jr = MP[1], MP[2], MP[3]
    J, dJ = inertia_at(phi, JG, DJG, D2JG)
    J += jhw
    kind = int(MP[0])
    dI = 0.0
    clutch = 0.0
    if mode == SLIP:
        wm = y[3]
        tm = motor_torque(wm, MP, TW, TT)
        clutch = slip_sign * MP[7]
        drive = ratio * clutch
        A = 1e-3 * J
    elif mode == FREE:
        wm = y[3]
        tm = 0.0
        drive = -ratio * MP[8] * w / math.sqrt(w * w + MP[14] * MP[14])
        A = 1e-3 * J
    else:
        wm = ratio * w
        if kind == 3:
            command = MP[12] if mode == RUN else 0.0
            err = command - wm
            u = MP[10] * err + y[2]
            tm = min(max(u, -MP[9]), MP[9])
            dI = MP[11] * err + (tm - u) / MP[13]
        elif mode == RUN:
            tm = motor_torque(wm, MP, TW, TT)
        else:
            tm = 0.0
        drive = ratio * tm
        A = 1e-3 * (J + jr * ratio * ratio)
    nonlinear_at(phi, w, WN, N0, N0W, WM, EA, DT, NK)
    R = drive - 0.5e-3 * dJ * w * w
    e, n_e = solve_acceleration(A, R, EA, NK)
    dy[0] = w
    dy[1] = e
    dy[2] = dI
    if mode == SLIP:
        dy[3] = 1e3 * (tm - clutch) / jr
        belt = drive
    elif mode == FREE:
        dy[3] = 0.0
        belt = drive
    else:
        dy[3] = ratio * e
        belt = drive - 1e-3 * jr * ratio * ratio * e
        clutch = tm - 1e-3 * jr * ratio * e
    info[0] = e
    info[1] = tm
    info[2] = belt
    info[3] = n_e
    info[4] = wm
    info[5] = clutch


# ---- Dormand-Prince 5(4) -----------------------------------------------------------------------

_C = (0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0)
_A2 = (0.2,)
_A3 = (3.0 / 40.0, 9.0 / 40.0)
_A4 = (44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0)
_A5 = (19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0)
_A6 = (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0)
_B = (35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0)
_E = (71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0,
      -1.0 / 40.0)


@njit(**_OPT)
def _step(y, f0, h, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, K,
          ynew, fnew, NK, info, tmp):
    """One Dormand-Prince step of size h from (y, f0); ynew, fnew the 5th-order solution and its
    derivative; returns the error estimate's vector in K[7]."""
    m = y.shape[0]
    for r in range(m):
        K[0, r] = f0[r]
    for s in range(1, 6):
        for r in range(m):
            acc = 0.0
            if s == 1:
                acc = _A2[0] * K[0, r]
            elif s == 2:
                acc = _A3[0] * K[0, r] + _A3[1] * K[1, r]
            elif s == 3:
                acc = _A4[0] * K[0, r] + _A4[1] * K[1, r] + _A4[2] * K[2, r]
            elif s == 4:
                acc = (_A5[0] * K[0, r] + _A5[1] * K[1, r] + _A5[2] * K[2, r]
                       + _A5[3] * K[3, r])
            else:
                acc = (_A6[0] * K[0, r] + _A6[1] * K[1, r] + _A6[2] * K[2, r]
                       + _A6[3] * K[3, r] + _A6[4] * K[4, r])
            tmp[r] = y[r] + h * acc
        rhs(tmp, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT,
            K[s], NK, info)
    for r in range(m):
        ynew[r] = y[r] + h * (_B[0] * K[0, r] + _B[2] * K[2, r] + _B[3] * K[3, r]
                              + _B[4] * K[4, r] + _B[5] * K[5, r])
    rhs(ynew, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, fnew, NK,
        info)
    for r in range(m):
        K[7, r] = h * (_E[0] * K[0, r] + _E[2] * K[2, r] + _E[3] * K[3, r] + _E[4] * K[4, r]
                       + _E[5] * K[5, r] + _E[6] * fnew[r])


@njit(**_OPT)
def _applies(code, mode, kind):
    """Whether the event ``code`` is watched in ``mode``."""
    if code == AT_PHI:
        return True
    if code == STALLED:
        return mode == RUN or mode == SLIP
    if code == STOPPED:
        return mode == STOP or mode == FREE
    if code == LOCKED:
        return mode == SLIP
    return mode == RUN and kind == 2  # SLIPS: a clutch motor's clutch, while it holds


@njit(**_OPT)
def _value(code, y, mode, slip_sign, phi_end, w_stop, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W,
           WM, EA, DT, NK, info, scratch):
    """The event function of ``code`` at y: > 0 once the event has happened."""
    if code == AT_PHI:
        return y[0] - phi_end
    if code == STALLED:
        return -y[1]
    if code == STOPPED:
        return w_stop - y[1]
    if code == LOCKED:
        return -slip_sign * (y[3] - MP[1] * y[1])
    rhs(y, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, scratch, NK,
        info)
    return abs(info[5]) - MP[7]


@njit(**_OPT)
def segment(t0, y0, h0, t_end, phi_end, mode, slip_sign, w_stop, rtol, ATOL, max_dphi, w_floor,
            MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, T, Y, F):
    """Integrate from (t0, y0) in ``mode`` until t_end, an event or full buffers.

    Every accepted step's end is stored (T, Y, F: time, state, derivative; row 0 the start);
    an event's step is taken again to end on the event (located on the step's cubic Hermite
    interpolant, 60 bisections). A step advances phi by at most ``max_dphi`` (rad; at speeds
    below ``w_floor`` as if at w_floor). Returns (rows stored, end code, next step size)."""
    m = y0.shape[0]
    cap = T.shape[0]
    ne = EA.shape[0]
    NK = np.empty(ne)
    info = np.empty(6)
    K = np.empty((8, m))
    scratch = np.empty(m)
    tmp = np.empty(m)
    kind = int(MP[0])
    y = y0.copy()
    f = np.empty(m)
    rhs(y, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, f, NK, info)
    ynew = np.empty(m)
    fnew = np.empty(m)
    ymid = np.empty(m)
    T[0] = t0
    for r in range(m):
        Y[0, r] = y[r]
        F[0, r] = f[r]
    n = 1
    t = t0
    h = h0
    while True:
        if n >= cap:
            return n, FULL, h
        if t >= t_end:
            return n, AT_TIME, h
        hmax = max_dphi / max(abs(y[1]), w_floor)
        h = min(h, hmax, t_end - t)
        if h <= 1e-14 * max(1.0, abs(t)):
            return n, TINY_STEP, h
        _step(y, f, h, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, K,
              ynew, fnew, NK, info, tmp)
        err = 0.0
        for r in range(m):
            sc = ATOL[r] + rtol * max(abs(y[r]), abs(ynew[r]))
            err += (K[7, r] / sc) ** 2
        err = math.sqrt(err / m)
        if not err <= 1.0:  # (a NaN is refused too)
            h *= max(0.2, 0.9 * err ** -0.2) if err == err else 0.2
            continue
        # the events of this step: the earliest, located on the step's cubic Hermite
        # (values and slopes at both ends) by bisection, then the step taken again to end there
        code, first = -1, 2.0
        for c in range(AT_PHI, SLIPS + 1):
            if not _applies(c, mode, kind):
                continue
            if _value(c, ynew, mode, slip_sign, phi_end, w_stop, MP, TW, TT, JG, DJG, D2JG,
                      WN, N0, N0W, WM, EA, DT, NK, info, scratch) <= 0.0:
                continue
            lo, hi = 0.0, 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                for r in range(m):
                    ymid[r] = _hermite(mid, h, y[r], ynew[r], f[r], fnew[r])
                if _value(c, ymid, mode, slip_sign, phi_end, w_stop, MP, TW, TT, JG, DJG,
                          D2JG, WN, N0, N0W, WM, EA, DT, NK, info, scratch) > 0.0:
                    hi = mid
                else:
                    lo = mid
            if hi < first:
                code, first = c, hi
        if code >= 0:
            hh = first * h
            _step(y, f, hh, mode, slip_sign, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA,
                  DT, K, ynew, fnew, NK, info, tmp)
            T[n] = t + hh
            for r in range(m):
                Y[n, r] = ynew[r]
                F[n, r] = fnew[r]
            return n + 1, code, h
        t += h
        for r in range(m):
            y[r] = ynew[r]
            f[r] = fnew[r]
        T[n] = t
        for r in range(m):
            Y[n, r] = y[r]
            F[n, r] = f[r]
        n += 1
        h *= min(5.0, max(0.2, 0.9 * err ** -0.2)) if err > 0.0 else 5.0


@njit(**_OPT)
def evaluate(Ys, modes, signs, MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, OUT):
    """The right-hand side's figures at states Ys (n, 4) in their modes: OUT (n, 6) as
    ``rhs``'s info."""
    ne = EA.shape[0]
    NK = np.empty(ne)
    dy = np.empty(Ys.shape[1])
    info = np.empty(6)
    for k in range(Ys.shape[0]):
        rhs(Ys[k], modes[k], signs[k], MP, TW, TT, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, dy,
            NK, info)
        for q in range(6):
            OUT[k, q] = info[q]


@njit(**_OPT)
def demand(phi, w, e, JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT, OUT):
    """The tables' torque the machine asks at the shaft in states (phi, w, e): J e + J' w^2 / 2
    + N(phi, w, e), N mm (the hand wheel and the motor not included)."""
    ne = EA.shape[0]
    NK = np.empty(ne)
    for k in range(phi.shape[0]):
        J, dJ = inertia_at(phi[k], JG, DJG, D2JG)
        nonlinear_at(phi[k], w[k], WN, N0, N0W, WM, EA, DT, NK)
        if ne == 1:
            n_e = NK[0]
        else:
            j = 0
            while j < ne - 2 and EA[j + 1] < e[k]:
                j += 1
            n_e = NK[j] + (NK[j + 1] - NK[j]) * (e[k] - EA[j]) / (EA[j + 1] - EA[j])
        OUT[k] = 1e-3 * (J * e[k] + 0.5 * dJ * w[k] * w[k]) + n_e

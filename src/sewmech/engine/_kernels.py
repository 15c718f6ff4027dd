"""Compiled kernels: one interpreter that evaluates a whole compiled machine.

A compiled machine (see :mod:`sewmech.machine`) is a short program: an integer table of units in
solve order, each row an opcode followed by indices into the point, link, variable and parameter
slots. :func:`evaluate_program` walks that program for every design and every crank angle and
fills position, velocity and acceleration of every point, angle, angular velocity and angular
acceleration of every link, and value and first and second time derivative of every joint
variable (slider displacements, free contact angles).

All closed-form units follow the basic units of the JB dynamics report (after C. H. Suh): the
rigid-body point, the two-link (RRR) dyad, the slider (RRP) dyad and the rotating guide (RPR).
Velocities and accelerations are analytic: each unit differentiates its closure equation once
and twice and solves the resulting 2x2 linear system. Loop groups (mechanisms that are not a
chain of those units, cams included) are solved by Newton-Raphson on vector loop-closure
equations, the method of the dynamics report's feed-mechanism analysis; velocities and
accelerations come from the same loop Jacobian.

Units: mm, rad, s. Nothing here allocates per angle, prints or writes files.

What the install compiles is kept small (issue 34; benchmarks/HISTORY.md): functions that only
other kernels call are compiled with ``no_cpython_wrapper=True`` (numba otherwise writes and
compiles code that unboxes their every argument from Python, about 0.8 s of the install's
compile), and big helpers are called rather than inlined by numba (``inline="always"`` types
the helper again inside its caller; LLVM still inlines what pays).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import _compiling
from ._blocks import CHUNK, MAX_BLOCK, block_qr

_compiling.install()  # a kernel compiled on its first use says so on stderr

# ---- opcodes (column 0 of the unit table) -----------------------------------------------------
OP_FIXED = 0  # point, x_param, y_param
OP_CRANK = 1  # link, phase_param, ratio_param, setting_param (-1: driven by the shaft)
OP_POINT = 2  # new point, link, origin point, u_param, v_param
OP_RRR = 3  # p1, p2, new point, link1, link2, l1_param, l2_param, branch
OP_RRP = 4  # pin, guide point, guide link, new point, rod link, slider link, l, alpha, e, branch, var
OP_RPR = 5  # pin, pivot, slot link, block link (-1: none), e_param, branch, var
OP_LOOP = 6  # group index

UNIT_COLS = 12

# ---- failure codes ------------------------------------------------------------------------------
FAIL_NONE = 0
FAIL_ASSEMBLY = 1  # the closure equations have no real solution at this angle
FAIL_SINGULAR = 2  # assembled, but at a singular position: velocity is not defined
FAIL_NEWTON = 3  # the loop solver did not converge
FAIL_LOST = 4  # continuation lost because an earlier angle failed
FAIL_PARAM = 5  # a parameter of the design is outside its domain (fail_unit: its index)

# ---- loop-term table columns ---------------------------------------------------------------------
TERM_POINT = 0  # + position of a known point
TERM_VEC = 1  # + L * e^{i (theta + alpha)}
TERM_CAM = 2  # + contact point (or roller centre) on a circular-arc cam profile
TERM_COLS = 12
# column layout: type, row, sign, len_src, len_idx, ang_src, ang_idx, alpha_param, cam,
#                offset_param, len_col, ang_col
SRC_PARAM = 0
SRC_LINK = 0
SRC_VAR = 1

TWO_PI = 2.0 * math.pi
# a discriminant this small relative to the squared lengths is a toggle position, not a failure
_TOGGLE_REL = 1e-12
_PIO2_LO = 6.123233995736765886130e-17  # pi / 2 - float(pi / 2)


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def atan2(y, x):
    """math.atan2 without branches, so that a loop of them vectorises (rad, within 2 ulp of
    libm's atan2; atan2(0, -0.0) gives pi, atan2(0, 0) gives 0).

    t, the smaller of |x|, |y| over the larger, lies in [0, 1]; above 0.66 it is replaced by
    (t - 1) / (t + 1) and pi/4 added, so atan is only needed on |u| <= 0.66, where the rational
    approximation of Cephes' atan (S. L. Moshier, Cephes Math Library, atan.c) is good to an
    ulp. The octant is then restored by selects.
    """
    ax = abs(x)
    ay = abs(y)
    mx = max(ax, ay)
    t = min(ax, ay) / mx if mx > 0.0 else 0.0
    big = t > 0.66
    u = (t - 1.0) / (t + 1.0) if big else t
    z = u * u
    p = ((((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z
           - 7.500855792314704667340e1) * z - 1.228866684490136173410e2) * z
         - 6.485021904942025371773e1)
    q = (((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z
           + 4.328810604912902668951e2) * z + 4.853903996359136964868e2) * z
         + 1.945506571482613964425e2)
    r = u + u * (z * p / q)
    r = 0.25 * math.pi + (r + 0.5 * _PIO2_LO) if big else r
    r = 0.5 * math.pi - r + _PIO2_LO if ay > ax else r
    r = math.pi - r + 2.0 * _PIO2_LO if math.copysign(1.0, x) < 0.0 else r
    return math.copysign(r, y)


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _solve2(m11, m12, m21, m22, b1, b2):
    det = m11 * m22 - m12 * m21
    return (b1 * m22 - m12 * b2) / det, (m11 * b2 - m21 * b1) / det, det


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _gauss_solve(M, b, n):
    """Solve M x = b in place (partial pivoting). Returns (x in b, smallest |pivot| / scale)."""
    scale = 0.0
    for i in range(n):
        for j in range(n):
            if abs(M[i, j]) > scale:
                scale = abs(M[i, j])
    if scale == 0.0:
        return 0.0
    minpiv = np.inf
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if p != k:
            for j in range(n):
                t = M[k, j]
                M[k, j] = M[p, j]
                M[p, j] = t
            t = b[k]
            b[k] = b[p]
            b[p] = t
        piv = M[k, k]
        if abs(piv) < minpiv:
            minpiv = abs(piv)
        if piv == 0.0:
            return 0.0
        inv = 1.0 / piv  # one division per column, not per row
        M[k, k] = inv  # kept for the back substitution
        for i in range(k + 1, n):
            f = M[i, k] * inv
            if f != 0.0:
                for j in range(k + 1, n):
                    M[i, j] -= f * M[k, j]
                b[i] -= f * b[k]
    for k in range(n - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, n):
            acc -= M[k, j] * b[j]
        b[k] = acc * M[k, k]
    return minpiv / scale


# ---- closed-form units ---------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def rigid_point(px, py, vx, vy, ax, ay, c, s, om, ep, u, v):
    """Point at local (u, v) mm on a link with origin (px, py), angle cos c, sin s."""
    rx = c * u - s * v
    ry = s * u + c * v
    return (
        px + rx,
        py + ry,
        vx - om * ry,
        vy + om * rx,
        ax - ep * ry - om * om * rx,
        ay + ep * rx - om * om * ry,
    )


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def rrr_dyad(p1x, p1y, v1x, v1y, a1x, a1y, p2x, p2y, v2x, v2y, a2x, a2y, l1, l2, branch):
    """Two links l1 (from point 1) and l2 (from point 2) meeting at a new joint C.

    Returns (code, cx, cy, vx, vy, ax, ay, omega1, eps1, omega2, eps2, x1, y1, x2, y2): the
    failure code (a float, FAIL_NONE when assembled), C's position, velocity and acceleration,
    the angular velocities and accelerations of the vectors 1->C and 2->C, and those vectors,
    from which the caller takes the link orientation without trigonometry. ``branch`` +1 puts
    C to the left of the directed line 1 -> 2.

    Written without branches (the failure checks are selects and the values of a failed call
    are garbage), so that a loop of calls over independent angles vectorises.
    """
    dx = p2x - p1x
    dy = p2y - p1y
    dd2 = dx * dx + dy * dy
    inv = 1.0 / math.sqrt(dd2)
    ex = dx * inv
    ey = dy * inv
    a = (l1 * l1 - l2 * l2 + dd2) * (0.5 * inv)
    h2 = l1 * l1 - a * a
    bh = branch * math.sqrt(max(h2, 0.0))  # a small negative h2 is a toggle position
    r1x = a * ex - bh * ey
    r1y = a * ey + bh * ex
    cx = p1x + r1x
    cy = p1y + r1y
    r2x = r1x - dx
    r2y = r1y - dy
    # omega1 x r1 - omega2 x r2 = v2 - v1, and the same matrix for the accelerations
    det = r1y * r2x - r2y * r1x
    idet = 1.0 / det
    b1 = v2x - v1x
    b2 = v2y - v1y
    w1 = -(r2x * b1 + r2y * b2) * idet
    w2 = -(r1x * b1 + r1y * b2) * idet
    b1 = a2x - a1x - w2 * w2 * r2x + w1 * w1 * r1x
    b2 = a2y - a1y - w2 * w2 * r2y + w1 * w1 * r1y
    e1 = -(r2x * b1 + r2y * b2) * idet
    e2 = -(r1x * b1 + r1y * b2) * idet
    # the checks are written so that a NaN anywhere fails them
    code = float(FAIL_NONE) if abs(det) > 1e-13 * l1 * l2 else float(FAIL_SINGULAR)
    code = (code if (dd2 > 0.0) & (h2 >= -_TOGGLE_REL * l1 * l1)
            else float(FAIL_ASSEMBLY))
    return (code, cx, cy, v1x - w1 * r1y, v1y + w1 * r1x, a1x - e1 * r1y - w1 * w1 * r1x,
            a1y + e1 * r1x - w1 * w1 * r1y, w1, e1, w2, e2, r1x, r1y, r2x, r2y)


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def rrp_dyad(
    bx, by, bvx, bvy, bax, bay, gx, gy, gvx, gvy, gax, gay, tg, wg, eg, l, alpha, e, branch, out
):
    """Rod of length l from pin B to a slider C on a guide line of a (possibly moving) link.

    The guide passes through point G of the guide link, direction tg + alpha, shifted e to the
    left. s is the slider position along the guide from the foot G + e*n. out[0:6] = C; out[6:8]
    = rod omega, eps; out[8:10] = the rod vector B->C; out[10:12] = cos, sin of the guide
    direction; out[12:15] = s, s_dot, s_ddot. ``branch`` +1 takes the larger s.
    """
    beta = tg + alpha
    ux = math.cos(beta)
    uy = math.sin(beta)
    nx = -uy
    ny = ux
    qx = gx + e * nx
    qy = gy + e * ny
    wx = qx - bx
    wy = qy - by
    wu = wx * ux + wy * uy
    disc = wu * wu - (wx * wx + wy * wy) + l * l
    if not disc >= 0.0:  # (a NaN fails too)
        if disc > -_TOGGLE_REL * l * l:
            disc = 0.0
        else:
            return FAIL_ASSEMBLY
    s = -wu + branch * math.sqrt(disc)
    cx = qx + s * ux
    cy = qy + s * uy
    r1x = cx - bx
    r1y = cy - by
    rhox = cx - gx
    rhoy = cy - gy
    # s_dot u - omega1 x r1 = vB - vG - omega_g x rho
    sd, w1, det = _solve2(ux, r1y, uy, -r1x, bvx - gvx + wg * rhoy, bvy - gvy - wg * rhox)
    if not abs(det) > 1e-13 * l:
        return FAIL_SINGULAR
    rhs_x = bax - w1 * w1 * r1x - gax + eg * rhoy + wg * wg * rhox + 2.0 * wg * sd * uy
    rhs_y = bay - w1 * w1 * r1y - gay - eg * rhox + wg * wg * rhoy - 2.0 * wg * sd * ux
    sdd, e1, det = _solve2(ux, r1y, uy, -r1x, rhs_x, rhs_y)
    out[0] = cx
    out[1] = cy
    out[2] = bvx - w1 * r1y
    out[3] = bvy + w1 * r1x
    out[4] = bax - e1 * r1y - w1 * w1 * r1x
    out[5] = bay + e1 * r1x - w1 * w1 * r1y
    out[6] = w1
    out[7] = e1
    out[8] = r1x
    out[9] = r1y
    out[10] = ux
    out[11] = uy
    out[12] = s
    out[13] = sd
    out[14] = sdd
    return FAIL_NONE


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def rpr_guide(bx, by, bvx, bvy, bax, bay, ax_, ay_, avx, avy, aax, aay, e, branch, out):
    """Rotating guide: a slot link pivoting at A passes through the block pinned at B.

    The slot line lies e to the left of A; the link angle is the slot direction; s is the
    block position along the slot from the foot A + e*n. out[0:3] = link angle, omega, eps;
    out[3:6] = s, s_dot, s_ddot; out[6:8] = cos, sin of the link angle. ``branch`` +1 takes
    s > 0.
    """
    dx = bx - ax_
    dy = by - ay_
    d2 = dx * dx + dy * dy
    s2 = d2 - e * e
    if not s2 >= 0.0:  # (a NaN fails too)
        if s2 > -_TOGGLE_REL * max(d2, 1e-300):
            s2 = 0.0
        else:
            return FAIL_ASSEMBLY
    s = branch * math.sqrt(s2)
    th = atan2(dy, dx) - atan2(e, s)
    ux = math.cos(th)
    uy = math.sin(th)
    # omega x d + s_dot u = vB - vA
    w, sd, det = _solve2(-dy, ux, dx, uy, bvx - avx, bvy - avy)
    if not abs(det) > 1e-13 * math.sqrt(max(d2, 1e-300)):
        return FAIL_SINGULAR
    rx = bax - aax + w * w * dx + 2.0 * w * sd * uy
    ry = bay - aay + w * w * dy - 2.0 * w * sd * ux
    ep, sdd, det = _solve2(-dy, ux, dx, uy, rx, ry)
    out[0] = th
    out[1] = w
    out[2] = ep
    out[3] = s
    out[4] = sd
    out[5] = sdd
    out[6] = ux
    out[7] = uy
    return FAIL_NONE


# ---- loop groups ---------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def arc_of(cam, rho, d, params, cams_i, arcs_i):
    """The arc of cam ``cam`` (an index into arcs_i) whose normal-angle range (cam frame) holds
    the contact normal's angle ``rho`` (rad) for design d; -1 for none. Shared by the loop
    solver and the tangent kernel, so both pick the same arc."""
    for ka in range(cams_i[cam, 2], cams_i[cam, 2] + cams_i[cam, 3]):
        a0 = params[d, arcs_i[ka, 3]]
        x = rho
        while x < a0:
            x += TWO_PI
        while x >= a0 + TWO_PI:
            x -= TWO_PI
        if x < params[d, arcs_i[ka, 4]]:
            return ka
    return -1


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _loop_steps(u, g, k0, nb, grp, unk, terms, cams_i, arcs_i, params, d, march_phi, march_omega,
                march_eps, march_store, tol, max_iter, p, v, a, th, om, ep, lc, ls, s, sd, sdd,
                fu, fc, q_prev, dq1_prev, dq2_prev, phi_prev, n_hist, lost, loop_res, loop_worst,
                q, F, J, dq, Jw, trig):
    """Loop group g (unit u) at the block's steps k0 .. k0 + nb - 1 in order (continuation):
    Newton-Raphson on the loop closures from a second-order Taylor predictor, then the rates
    and accelerations from the same Jacobian.

    Everything of one step happens in this one function, the loop terms evaluated in its own
    body: numba counts references of every array a compiled function receives (an atomic
    increment and decrement per array and call), and a call per term, assembly or Newton step
    made that counting four fifths of the feed's cost. q, F, J, dq, Jw are scratch of at least
    the group's size; trig (at least the group's terms x 4) keeps each term's cos and sin from
    the last Newton assembly for the rates and accelerations, which are taken at the same
    angles. A failed step marks fu, fc and loses the continuation of the group."""
    n = grp[g, 0]
    u0 = grp[g, 1]
    t0 = grp[g, 3]
    t1 = t0 + grp[g, 4]
    for kb in range(nb):
        if fu[kb] >= 0:
            continue
        k = k0 + kb
        if lost[g]:
            fu[kb] = u
            fc[kb] = FAIL_LOST
            continue
        phi = march_phi[k]
        ws = march_omega[k]
        es = march_eps[k]
        if n_hist[g] == 0:
            for j in range(n):
                q[j] = params[d, unk[u0 + j, 3]]
            iters = 4 * max_iter
        else:
            # second-order Taylor predictor from the last solution's exact rates: one or two
            # Newton steps land within the tolerance
            h = phi - phi_prev[g]
            for j in range(n):
                q[j] = q_prev[u0 + j] + h * (dq1_prev[u0 + j] + 0.5 * h * dq2_prev[u0 + j])
            iters = max_iter
        # stage 0: Newton on the positions; 1: the rates; 2: the accelerations. Each stage
        # assembles the loop equations once (level = stage) in the one block of code below.
        stage = 0
        it = 0
        resid = np.inf
        worst = 0
        code = FAIL_NONE
        while True:
            if stage == 0:
                for j in range(n):
                    idx = unk[u0 + j, 1]
                    if unk[u0 + j, 0] == 0:
                        th[kb, idx] = q[j]
                    else:
                        s[kb, idx] = q[j]
            for i in range(n):
                F[i] = 0.0
                for j in range(n):
                    J[i, j] = 0.0
            arc_missing = False
            for t in range(t0, t1):
                row = 2 * terms[t, 1]
                typ = terms[t, 0]
                sign = float(terms[t, 2])
                fx = 0.0
                fy = 0.0
                jlx = 0.0
                jly = 0.0
                jax = 0.0
                jay = 0.0
                if typ == TERM_POINT:
                    i = terms[t, 4]
                    if stage == 0:
                        fx = p[kb, i, 0]
                        fy = p[kb, i, 1]
                    elif stage == 1:
                        fx = v[kb, i, 0]
                        fy = v[kb, i, 1]
                    else:
                        fx = a[kb, i, 0]
                        fy = a[kb, i, 1]
                else:
                    ai = terms[t, 6]
                    if terms[t, 5] == SRC_LINK:
                        psi = th[kb, ai]
                        psid = om[kb, ai]
                        psidd = ep[kb, ai]
                    else:
                        psi = s[kb, ai]
                        psid = sd[kb, ai]
                        psidd = sdd[kb, ai]
                    if terms[t, 7] >= 0:
                        psi += params[d, terms[t, 7]]
                    ang_col = terms[t, 11]
                    tt = t - t0
                    if stage == 0:
                        c = math.cos(psi)
                        sn = math.sin(psi)
                        trig[tt, 0] = c
                        trig[tt, 1] = sn
                    else:  # the same angles as the converged assembly
                        c = trig[tt, 0]
                        sn = trig[tt, 1]
                    if typ == TERM_VEC:
                        li = terms[t, 4]
                        if terms[t, 3] == SRC_PARAM:
                            L = params[d, li]
                            Ld = 0.0
                            Ldd = 0.0
                        else:
                            L = s[kb, li]
                            Ld = sd[kb, li]
                            Ldd = sdd[kb, li]
                        len_col = terms[t, 10]
                        if stage == 0:
                            fx = L * c
                            fy = L * sn
                        elif stage == 1:
                            # d/dt (L e^{i psi}) = Ld e + i L psid e: the known parts
                            if len_col < 0:
                                fx += Ld * c
                                fy += Ld * sn
                            if ang_col < 0:
                                fx += -L * psid * sn
                                fy += L * psid * c
                        else:
                            # (Ldd + i L psidd) e + (2 i Ld psid - L psid^2) e: every rate
                            # is known now
                            fx = 2.0 * (-Ld * psid * sn) - L * psid * psid * c
                            fy = 2.0 * (Ld * psid * c) - L * psid * psid * sn
                            if len_col < 0:
                                fx += Ldd * c
                                fy += Ldd * sn
                            if ang_col < 0:
                                fx += -L * psidd * sn
                                fy += L * psidd * c
                        jlx = sign * c
                        jly = sign * sn
                        jax = -sign * L * sn
                        jay = sign * L * c
                    else:
                        # TERM_CAM: contact point p_c + R(th_c) c_k + (R_k + off) e^{i psi}
                        cam = terms[t, 8]
                        cl = cams_i[cam, 0]
                        cp = cams_i[cam, 1]
                        tc = th[kb, cl]
                        wc = om[kb, cl]
                        ec = ep[kb, cl]
                        arc = arc_of(cam, psi - tc, d, params, cams_i, arcs_i)
                        if arc < 0:
                            arc_missing = True
                            break
                        ccx = params[d, arcs_i[arc, 0]]
                        ccy = params[d, arcs_i[arc, 1]]
                        R = params[d, arcs_i[arc, 2]]
                        if terms[t, 9] >= 0:
                            R += params[d, terms[t, 9]]
                        if stage == 0:
                            cc = math.cos(tc)
                            cs = math.sin(tc)
                            trig[tt, 2] = cc
                            trig[tt, 3] = cs
                        else:
                            cc = trig[tt, 2]
                            cs = trig[tt, 3]
                        rx = cc * ccx - cs * ccy
                        ry = cs * ccx + cc * ccy
                        if stage == 0:
                            fx = p[kb, cp, 0] + rx + R * c
                            fy = p[kb, cp, 1] + ry + R * sn
                        elif stage == 1:
                            fx = v[kb, cp, 0] - wc * ry
                            fy = v[kb, cp, 1] + wc * rx
                            if ang_col < 0:
                                fx += -R * psid * sn
                                fy += R * psid * c
                        else:
                            fx = a[kb, cp, 0] - ec * ry - wc * wc * rx - R * psid * psid * c
                            fy = a[kb, cp, 1] + ec * rx - wc * wc * ry - R * psid * psid * sn
                            if ang_col < 0:
                                fx += -R * psidd * sn
                                fy += R * psidd * c
                        jax = -sign * R * sn
                        jay = sign * R * c
                F[row] += sign * fx
                F[row + 1] += sign * fy
                lcol = terms[t, 10]
                acol = terms[t, 11]
                if lcol >= 0:
                    J[row, lcol] += jlx
                    J[row + 1, lcol] += jly
                if acol >= 0:
                    J[row, acol] += jax
                    J[row + 1, acol] += jay
            if arc_missing:  # the contact left every arc of the cam profile
                resid = np.inf
                code = FAIL_NEWTON
                break
            if stage == 0:
                resid = 0.0
                for i in range(n):
                    if abs(F[i]) > resid or not math.isfinite(F[i]):
                        resid = abs(F[i])
                        worst = i // 2
                if resid <= tol or it >= iters or not math.isfinite(resid):
                    if not (resid <= tol):
                        code = FAIL_NEWTON
                        break
                    for i in range(n):  # converged: the rates next, with this Jacobian
                        for j in range(n):
                            Jw[i, j] = J[i, j]
                    stage = 1
                    continue
                for i in range(n):
                    dq[i] = -F[i]
                    for j in range(n):
                        Jw[i, j] = J[i, j]
                if _gauss_solve(Jw, dq, n) < 1e-14:
                    code = FAIL_SINGULAR
                    break
                # limit angle steps to half a radian so that a poor start cannot jump a branch
                big = 0.0
                for j in range(n):
                    if unk[u0 + j, 2] == 1 and abs(dq[j]) > big:
                        big = abs(dq[j])
                f = 1.0 if big <= 0.5 else 0.5 / big
                for j in range(n):
                    q[j] += f * dq[j]
                it += 1
                continue
            # the rates (stage 1) solve J qd = -(known part of dF/dt), the accelerations
            # (stage 2) J qdd = -(d2F/dt2 without the unknown accelerations)
            for i in range(n):
                dq[i] = -F[i]
            piv = _gauss_solve(Jw, dq, n)
            if stage == 1 and piv < 1e-13:
                code = FAIL_SINGULAR
                break
            for j in range(n):
                idx = unk[u0 + j, 1]
                if unk[u0 + j, 0] == 0:
                    if stage == 1:
                        om[kb, idx] = dq[j]
                    else:
                        ep[kb, idx] = dq[j]
                else:
                    if stage == 1:
                        sd[kb, idx] = dq[j]
                    else:
                        sdd[kb, idx] = dq[j]
            if stage == 2:
                break
            for i in range(n):
                for j in range(n):
                    Jw[i, j] = J[i, j]
            stage = 2
        row_out = march_store[k]
        if row_out >= 0:
            loop_res[d, row_out, g] = resid
            loop_worst[d, row_out, g] = worst
        if code != FAIL_NONE:
            lost[g] = True
            fu[kb] = u
            fc[kb] = code
            continue
        for j in range(n):
            q_prev[u0 + j] = q[j]
            L = unk[u0 + j, 1]
            if unk[u0 + j, 0] == 0:
                r1 = om[kb, L]
                r2 = ep[kb, L]
            else:
                r1 = sd[kb, L]
                r2 = sdd[kb, L]
            # d/dphi = (d/dt) / omega; at rest, or so slowly that omega^2 leaves the range of
            # floats (below 1e-100 rad/s), the predictor takes the last solution as it is
            if abs(ws) > 1e-100:
                dq1_prev[u0 + j] = r1 / ws
                dq2_prev[u0 + j] = (r2 - r1 / ws * es) / (ws * ws)
            else:
                dq1_prev[u0 + j] = 0.0
                dq2_prev[u0 + j] = 0.0
            if unk[u0 + j, 0] == 0:
                lc[kb, L] = math.cos(th[kb, L])
                ls[kb, L] = math.sin(th[kb, L])
        phi_prev[g] = phi
        n_hist[g] += 1


# ---- the interpreter -------------------------------------------------------------------------------


#: march steps evaluated together: every unit runs over the whole block before the next unit,
#: so the CPU overlaps the independent angles of a closed-form unit instead of waiting on one
#: angle's chain of roots and divisions (see BENCHMARKS.md); the block's state stays in cache.
BLOCK = 32
_U = np.uint64  # unsigned lane indices: numba then emits no negative-index wrap-around


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _nan_row(d, row, P, V, A, TH, OM, EP, S, SD, SDD, GP, GV, GA):
    """A failed output row: NaN in every output of design d at row."""
    P[d, row] = np.nan
    V[d, row] = np.nan
    A[d, row] = np.nan
    TH[d, row] = np.nan
    OM[d, row] = np.nan
    EP[d, row] = np.nan
    S[d, row] = np.nan
    SD[d, row] = np.nan
    SDD[d, row] = np.nan
    GP[d, row] = np.nan
    GV[d, row] = np.nan
    GA[d, row] = np.nan


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _eval_designs(d0, d1, units, params, p_lo, p_hi, march_phi, mc, ms, march_store,
                  march_omega, march_eps, grp, unk, terms, cams_i, arcs_i, n_points, n_links,
                  n_vars, tol, max_iter, need_th, pt_sel, lk_sel, var_sel, P, V, A, TH, OM, EP,
                  S, SD, SDD, fail_unit, fail_code, loop_res, loop_worst, ex_tab, ex_uv, GP, GV,
                  GA):
    """Walk the program along the march for designs d0 <= d < d1 (see :func:`evaluate_program`).

    The march is taken in blocks of :data:`BLOCK` steps; within a block every unit is evaluated
    at all of the block's steps before the next unit (the state has one slot per step), so that
    the steps of a closed-form unit, which are independent, run overlapped. Loop units march
    through the block's steps in order (continuation). A step where a unit failed is skipped by
    every later unit, exactly as if the units were walked step by step.

    Link orientation is carried as (cos, sin) next to the angle, so that rigid points and dyads
    need no trigonometry; the angle itself (an atan2) is computed only for links with
    ``need_th`` set (returned, or read as an angle by a later unit). mc, ms are cos and sin of
    the march angles, shared by all designs: a crank at ratio 1 turns them by its phase with
    four products instead of evaluating cos and sin per design and angle.
    """
    n_units = units.shape[0]
    n_groups = grp.shape[0]
    n_unk = unk.shape[0]
    n_march = march_phi.shape[0]
    max_n = 1
    for g in range(n_groups):
        if grp[g, 0] > max_n:
            max_n = grp[g, 0]
    out = np.empty(16)
    G = np.empty(27 * BLOCK)  # the RRR units' lanes: 12 inputs, 15 outputs (pitch BLOCK)
    F = np.empty(max_n)
    J = np.empty((max_n, max_n))
    q = np.empty(max_n)
    dq = np.empty(max_n)
    Jw = np.empty((max_n, max_n))
    max_t = 1
    for g in range(n_groups):
        if grp[g, 4] > max_t:
            max_t = grp[g, 4]
    trig = np.empty((max_t, 4))
    p = np.empty((BLOCK, n_points, 2))
    v = np.empty((BLOCK, n_points, 2))
    a = np.empty((BLOCK, n_points, 2))
    th = np.zeros((BLOCK, n_links))
    om = np.zeros((BLOCK, n_links))
    ep = np.zeros((BLOCK, n_links))
    lc = np.ones((BLOCK, n_links))  # cos theta; link 0 (the frame) keeps theta = 0
    ls = np.zeros((BLOCK, n_links))  # sin theta
    s = np.empty((BLOCK, n_vars))
    sd = np.empty((BLOCK, n_vars))
    sdd = np.empty((BLOCK, n_vars))
    fu = np.empty(BLOCK, dtype=np.int64)  # failed unit of each step of the block (-1: none)
    fc = np.empty(BLOCK, dtype=np.int64)
    q_prev = np.empty(n_unk)
    dq1_prev = np.empty(n_unk)  # d q / d phi at the last solution
    dq2_prev = np.empty(n_unk)  # d2 q / d phi2
    phi_prev = np.empty(n_groups)
    n_hist = np.zeros(n_groups, dtype=np.int64)
    lost = np.zeros(n_groups, dtype=np.bool_)
    pc = np.empty(n_units)  # cos and sin of each crank's phase
    psn = np.empty(n_units)
    moving = np.empty(n_units, dtype=np.int64)  # units that depend on the shaft angle
    n_moving = 0
    for u in range(n_units):
        if units[u, 0] != OP_FIXED:
            moving[n_moving] = u
            n_moving += 1
    n_failed = 0
    n_par = params.shape[1]
    n_slot = min(BLOCK, n_march)  # the block slots a short march uses
    for d in range(d0, d1):
        bad = -1  # the first parameter outside [p_lo, p_hi] (a NaN is outside too)
        for j in range(n_par):
            if not (params[d, j] >= p_lo[j]) & (params[d, j] <= p_hi[j]):
                bad = j
                break
        if bad >= 0:
            for k in range(n_march):
                row = march_store[k]
                if row < 0:
                    continue
                fail_unit[d, row] = bad
                fail_code[d, row] = FAIL_PARAM
                n_failed += 1
                _nan_row(d, row, P, V, A, TH, OM, EP, S, SD, SDD, GP, GV, GA)
            continue
        n_hist[:] = 0
        lost[:] = False
        for u in range(n_units):
            op = units[u, 0]
            if op == OP_FIXED:  # frame points: once per design, no unit overwrites them
                i = units[u, 1]
                x = params[d, units[u, 2]]
                y = params[d, units[u, 3]]
                for kb in range(n_slot):
                    p[kb, i, 0] = x
                    p[kb, i, 1] = y
                    v[kb, i, 0] = 0.0
                    v[kb, i, 1] = 0.0
                    a[kb, i, 0] = 0.0
                    a[kb, i, 1] = 0.0
            elif op == OP_CRANK:
                pc[u] = math.cos(params[d, units[u, 2]])
                psn[u] = math.sin(params[d, units[u, 2]])
        for k0 in range(0, n_march, BLOCK):
            nb = min(BLOCK, n_march - k0)
            # every unit writes its outputs before any later unit reads them, so the state
            # needs no reset between blocks; a failed step is written out as NaN below
            fu[:nb] = -1
            fc[:nb] = FAIL_NONE
            for ui in range(n_moving):
                u = moving[ui]
                op = units[u, 0]
                if op == OP_CRANK:  # cannot fail
                    L = units[u, 1]
                    phase = params[d, units[u, 2]]
                    if units[u, 4] >= 0:
                        t = phase + params[d, units[u, 4]]
                        ct = math.cos(t)
                        st = math.sin(t)
                        for kb in range(nb):
                            om[kb, L] = 0.0
                            ep[kb, L] = 0.0
                            lc[kb, L] = ct
                            ls[kb, L] = st
                            th[kb, L] = t
                    else:
                        ratio = params[d, units[u, 3]]
                        c0 = pc[u]
                        s0 = psn[u]
                        for kb in range(nb):
                            k = k0 + kb
                            t = phase + ratio * march_phi[k]
                            om[kb, L] = ratio * march_omega[k]
                            ep[kb, L] = ratio * march_eps[k]
                            if ratio == 1.0:
                                lc[kb, L] = c0 * mc[k] - s0 * ms[k]
                                ls[kb, L] = s0 * mc[k] + c0 * ms[k]
                            else:
                                lc[kb, L] = math.cos(t)
                                ls[kb, L] = math.sin(t)
                            th[kb, L] = t
                elif op == OP_POINT:  # cannot fail
                    i = units[u, 1]
                    L = units[u, 2]
                    o = units[u, 3]
                    pu = params[d, units[u, 4]]
                    pv = params[d, units[u, 5]]
                    for kb in range(nb):
                        if fu[kb] >= 0:
                            continue
                        r = rigid_point(p[kb, o, 0], p[kb, o, 1], v[kb, o, 0], v[kb, o, 1],
                                        a[kb, o, 0], a[kb, o, 1], lc[kb, L], ls[kb, L],
                                        om[kb, L], ep[kb, L], pu, pv)
                        p[kb, i, 0] = r[0]
                        p[kb, i, 1] = r[1]
                        v[kb, i, 0] = r[2]
                        v[kb, i, 1] = r[3]
                        a[kb, i, 0] = r[4]
                        a[kb, i, 1] = r[5]
                elif op == OP_RRR:
                    i1 = units[u, 1]
                    i2 = units[u, 2]
                    i = units[u, 3]
                    L1 = units[u, 4]
                    L2 = units[u, 5]
                    l1 = params[d, units[u, 6]]
                    l2 = params[d, units[u, 7]]
                    br = float(units[u, 8])
                    il1 = 1.0 / l1
                    il2 = 1.0 / l2
                    th1 = need_th[L1]
                    th2 = need_th[L2]
                    # gather the inputs into lanes, solve every step of the block in one
                    # loop that vectorises, scatter the results of the steps that assembled
                    for kb in range(nb):
                        for c in range(2):
                            G[c * BLOCK + kb] = p[kb, i1, c]
                            G[(2 + c) * BLOCK + kb] = v[kb, i1, c]
                            G[(4 + c) * BLOCK + kb] = a[kb, i1, c]
                            G[(6 + c) * BLOCK + kb] = p[kb, i2, c]
                            G[(8 + c) * BLOCK + kb] = v[kb, i2, c]
                            G[(10 + c) * BLOCK + kb] = a[kb, i2, c]
                    for kb in range(_U(nb)):
                        (G[_U(12 * BLOCK) + kb], G[_U(13 * BLOCK) + kb], G[_U(14 * BLOCK) + kb],
                         G[_U(15 * BLOCK) + kb], G[_U(16 * BLOCK) + kb], G[_U(17 * BLOCK) + kb],
                         G[_U(18 * BLOCK) + kb], G[_U(19 * BLOCK) + kb], G[_U(20 * BLOCK) + kb],
                         G[_U(21 * BLOCK) + kb], G[_U(22 * BLOCK) + kb], G[_U(23 * BLOCK) + kb],
                         G[_U(24 * BLOCK) + kb], G[_U(25 * BLOCK) + kb],
                         G[_U(26 * BLOCK) + kb]) = rrr_dyad(
                            G[kb], G[_U(BLOCK) + kb], G[_U(2 * BLOCK) + kb],
                            G[_U(3 * BLOCK) + kb], G[_U(4 * BLOCK) + kb], G[_U(5 * BLOCK) + kb],
                            G[_U(6 * BLOCK) + kb], G[_U(7 * BLOCK) + kb], G[_U(8 * BLOCK) + kb],
                            G[_U(9 * BLOCK) + kb], G[_U(10 * BLOCK) + kb],
                            G[_U(11 * BLOCK) + kb], l1, l2, br)
                    for kb in range(nb):
                        if fu[kb] >= 0:
                            continue
                        code = G[12 * BLOCK + kb]
                        if code != FAIL_NONE:
                            fu[kb] = u
                            fc[kb] = int(code)
                            continue
                        for c in range(2):
                            p[kb, i, c] = G[(13 + c) * BLOCK + kb]
                            v[kb, i, c] = G[(15 + c) * BLOCK + kb]
                            a[kb, i, c] = G[(17 + c) * BLOCK + kb]
                        om[kb, L1] = G[19 * BLOCK + kb]
                        ep[kb, L1] = G[20 * BLOCK + kb]
                        om[kb, L2] = G[21 * BLOCK + kb]
                        ep[kb, L2] = G[22 * BLOCK + kb]
                        lc[kb, L1] = G[23 * BLOCK + kb] * il1
                        ls[kb, L1] = G[24 * BLOCK + kb] * il1
                        lc[kb, L2] = G[25 * BLOCK + kb] * il2
                        ls[kb, L2] = G[26 * BLOCK + kb] * il2
                    # the angles in loops of their own, which vectorise (a failed step's
                    # angle is never read)
                    if th1:
                        for kb in range(nb):
                            th[kb, L1] = atan2(ls[kb, L1], lc[kb, L1])
                    if th2:
                        for kb in range(nb):
                            th[kb, L2] = atan2(ls[kb, L2], lc[kb, L2])
                elif op == OP_RRP:
                    b = units[u, 1]
                    gp = units[u, 2]
                    gl = units[u, 3]
                    i = units[u, 4]
                    L1 = units[u, 5]
                    Ls = units[u, 6]
                    l = params[d, units[u, 7]]
                    alpha = params[d, units[u, 8]]
                    e = params[d, units[u, 9]]
                    br = float(units[u, 10])
                    var = units[u, 11]
                    il = 1.0 / l
                    th1 = need_th[L1]
                    for kb in range(nb):
                        if fu[kb] >= 0:
                            continue
                        code = rrp_dyad(p[kb, b, 0], p[kb, b, 1], v[kb, b, 0], v[kb, b, 1],
                                        a[kb, b, 0], a[kb, b, 1], p[kb, gp, 0], p[kb, gp, 1],
                                        v[kb, gp, 0], v[kb, gp, 1], a[kb, gp, 0], a[kb, gp, 1],
                                        th[kb, gl], om[kb, gl], ep[kb, gl], l, alpha, e, br, out)
                        if code != FAIL_NONE:
                            fu[kb] = u
                            fc[kb] = code
                            continue
                        for c in range(2):
                            p[kb, i, c] = out[c]
                            v[kb, i, c] = out[2 + c]
                            a[kb, i, c] = out[4 + c]
                        om[kb, L1] = out[6]
                        ep[kb, L1] = out[7]
                        lc[kb, L1] = out[8] * il
                        ls[kb, L1] = out[9] * il
                        th[kb, Ls] = th[kb, gl] + alpha
                        om[kb, Ls] = om[kb, gl]
                        ep[kb, Ls] = ep[kb, gl]
                        lc[kb, Ls] = out[10]
                        ls[kb, Ls] = out[11]
                        s[kb, var] = out[12]
                        sd[kb, var] = out[13]
                        sdd[kb, var] = out[14]
                    if th1:
                        for kb in range(nb):
                            th[kb, L1] = atan2(ls[kb, L1], lc[kb, L1])
                elif op == OP_RPR:
                    b = units[u, 1]
                    pv_ = units[u, 2]
                    L = units[u, 3]
                    Lb = units[u, 4]
                    e = params[d, units[u, 5]]
                    br = float(units[u, 6])
                    var = units[u, 7]
                    for kb in range(nb):
                        if fu[kb] >= 0:
                            continue
                        code = rpr_guide(p[kb, b, 0], p[kb, b, 1], v[kb, b, 0], v[kb, b, 1],
                                         a[kb, b, 0], a[kb, b, 1], p[kb, pv_, 0], p[kb, pv_, 1],
                                         v[kb, pv_, 0], v[kb, pv_, 1], a[kb, pv_, 0],
                                         a[kb, pv_, 1], e, br, out)
                        if code != FAIL_NONE:
                            fu[kb] = u
                            fc[kb] = code
                            continue
                        th[kb, L] = out[0]
                        om[kb, L] = out[1]
                        ep[kb, L] = out[2]
                        lc[kb, L] = out[6]
                        ls[kb, L] = out[7]
                        if Lb >= 0:
                            th[kb, Lb] = out[0]
                            om[kb, Lb] = out[1]
                            ep[kb, Lb] = out[2]
                            lc[kb, Lb] = out[6]
                            ls[kb, Lb] = out[7]
                        s[kb, var] = out[3]
                        sd[kb, var] = out[4]
                        sdd[kb, var] = out[5]
                elif op == OP_LOOP:  # continuation: the block's steps in order
                    _loop_steps(u, units[u, 1], k0, nb, grp, unk, terms, cams_i, arcs_i, params,
                                d, march_phi, march_omega, march_eps, march_store, tol,
                                max_iter, p, v, a, th, om, ep, lc, ls, s, sd, sdd, fu, fc,
                                q_prev, dq1_prev, dq2_prev, phi_prev, n_hist, lost, loop_res,
                                loop_worst, q, F, J, dq, Jw, trig)
            for kb in range(nb):
                row = march_store[k0 + kb]
                if row < 0:
                    continue
                fail_unit[d, row] = fu[kb]
                fail_code[d, row] = fc[kb]
                if fc[kb] != FAIL_NONE:
                    n_failed += 1
                    _nan_row(d, row, P, V, A, TH, OM, EP, S, SD, SDD, GP, GV, GA)
                    continue
                for j in range(ex_tab.shape[0]):  # extra points: e.g. the centres of mass
                    L = ex_tab[j, 0]
                    o = ex_tab[j, 1]
                    if o < 0:
                        ox = oy = ovx = ovy = oax = oay = 0.0
                    else:
                        ox = p[kb, o, 0]
                        oy = p[kb, o, 1]
                        ovx = v[kb, o, 0]
                        ovy = v[kb, o, 1]
                        oax = a[kb, o, 0]
                        oay = a[kb, o, 1]
                    r = rigid_point(ox, oy, ovx, ovy, oax, oay, lc[kb, L], ls[kb, L], om[kb, L],
                                    ep[kb, L], ex_uv[j, 0], ex_uv[j, 1])
                    GP[d, row, j, 0] = r[0]
                    GP[d, row, j, 1] = r[1]
                    GV[d, row, j, 0] = r[2]
                    GV[d, row, j, 1] = r[3]
                    GA[d, row, j, 0] = r[4]
                    GA[d, row, j, 1] = r[5]
                for j in range(pt_sel.shape[0]):
                    i = pt_sel[j]
                    for c in range(2):
                        P[d, row, j, c] = p[kb, i, c]
                        V[d, row, j, c] = v[kb, i, c]
                        A[d, row, j, c] = a[kb, i, c]
                for j in range(lk_sel.shape[0]):
                    i = lk_sel[j]
                    TH[d, row, j] = th[kb, i]
                    OM[d, row, j] = om[kb, i]
                    EP[d, row, j] = ep[kb, i]
                for j in range(var_sel.shape[0]):
                    i = var_sel[j]
                    S[d, row, j] = s[kb, i]
                    SD[d, row, j] = sd[kb, i]
                    SDD[d, row, j] = sdd[kb, i]
    return n_failed


_DOC = """Evaluate the program for every design (axis 0 of params) along the march of shaft angles.

    A design with a parameter outside [p_lo, p_hi] (a NaN is outside too) is not evaluated:
    its every row fails with FAIL_PARAM and fail_unit holds the parameter's index.
    mc, ms are cos and sin of the march angles (computed once by the caller, see
    :class:`sewmech.kinematics.KinematicsPlan`). march_store[k] is the output row for march step
    k, or -1 for an intermediate continuation step. need_th[link] says whether that link's angle is returned or read by a later unit.
    Designs d0 <= d < d1 are evaluated.
    Output arrays are (n_design, n_out, n_selected, ...) for the selected points, links and
    variables (pt_sel, lk_sel, var_sel); fail_unit is -1 where all units assembled, and a failed
    row is NaN throughout. Extra points (ex_tab rows: link, origin point or -1 for the frame
    origin; ex_uv: their (u, v) mm in the link frame, e.g. centres of mass) are written to GP, GV,
    GA (n_design, n_out, n_extra, 2). Returns the number of failed rows. {which}
    """


# A one-line wrapper: numba compiles _eval_designs alone and then again inside this kernel's
# module (about 4 s more of the install's compile), and the twice-optimised code is measurably
# faster on big batches (the four-bar's 1000 designs x 360 angles 5-7 % slower as one function,
# issue 34), so the wrapper stays.
@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def evaluate_program(d0, d1, units, params, p_lo, p_hi, march_phi, mc, ms, march_store,
                     march_omega, march_eps, grp, unk, terms, cams_i, arcs_i, n_points, n_links,
                     n_vars, tol, max_iter, need_th, pt_sel, lk_sel, var_sel, P, V, A, TH, OM,
                     EP, S, SD, SDD, fail_unit, fail_code, loop_res, loop_worst, ex_tab, ex_uv,
                     GP, GV, GA):
    return _eval_designs(d0, d1, units, params, p_lo, p_hi, march_phi, mc, ms, march_store,
                         march_omega, march_eps, grp, unk, terms, cams_i, arcs_i, n_points,
                         n_links, n_vars, tol, max_iter, need_th, pt_sel, lk_sel, var_sel, P, V,
                         A, TH, OM, EP, S, SD, SDD, fail_unit, fail_code, loop_res, loop_worst,
                         ex_tab, ex_uv, GP, GV, GA)


evaluate_program.__doc__ = _DOC.format(
    which="It releases the GIL: big batches run as chunks of designs on threads"
    " (:func:`sewmech.engine._threads.run_chunks`), which write disjoint rows.")


# ---- inverse dynamics: the Newton-Euler system of every position -------------------------------
PAIR_REVOLUTE = 0
PAIR_PRISMATIC = 1
PAIR_CAM = 2
PAIR_SLOT = 3
PAIR_DRIVER = 4
PAIR_COLS = 11
# pair table columns: kind, link a, link b, point, line link, line var, line param, first
#                     unknown column, cam sign (+1/-1), first row in cam_rows, number of rows
# pair_angle: the fixed angle added to the line direction (rad)


@njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _cam_point(t0, nt, cam_rows, terms, params, d, k, P, TH, Q, sign):
    """Contact point of a cam pair at design d, position k: minus the sum of its loop's other
    terms (mm)."""
    sx = 0.0
    sy = 0.0
    for r in range(t0, t0 + nt):
        t = cam_rows[r]
        sg = float(terms[t, 2])
        if terms[t, 0] == TERM_POINT:
            sx += sg * P[d, k, terms[t, 4], 0]
            sy += sg * P[d, k, terms[t, 4], 1]
            continue
        L = params[d, terms[t, 4]] if terms[t, 3] == SRC_PARAM else Q[d, k, terms[t, 4]]
        a = TH[d, k, terms[t, 6]] if terms[t, 5] == SRC_LINK else Q[d, k, terms[t, 6]]
        if terms[t, 7] >= 0:
            a += params[d, terms[t, 7]]
        sx += sg * L * math.cos(a)
        sy += sg * L * math.sin(a)
    return -sign * sx, -sign * sy


@njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _pair_geometry(i, pairs, pair_angle, cam_rows, terms, params, d, k, P, TH, Q):
    """Where pair i's force acts (x, y mm) and the direction of its single force (cos, sin) at
    design d, position k: the line's left normal (prismatic, slot) or the cam's outward normal.
    Revolute pairs: the pin and (1, 0). (Full arrays and indices, not per-position views: a
    view costs reference counting in the inner loop.)"""
    kind = pairs[i, 0]
    if kind == PAIR_CAM:
        xx, xy = _cam_point(pairs[i, 9], pairs[i, 10], cam_rows, terms, params, d, k, P, TH, Q,
                            float(pairs[i, 8]))
    else:
        xx = P[d, k, pairs[i, 3], 0]
        xy = P[d, k, pairs[i, 3], 1]
    if kind == PAIR_REVOLUTE:
        return xx, xy, 1.0, 0.0
    a = TH[d, k, pairs[i, 4]] if pairs[i, 4] >= 0 else Q[d, k, pairs[i, 5]]
    a += pair_angle[i]
    if pairs[i, 6] >= 0:
        a += params[d, pairs[i, 6]]
    if kind != PAIR_CAM:
        a += 0.5 * math.pi
    return xx, xy, math.cos(a), math.sin(a)


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def pair_geometry(pairs, pair_angle, cam_rows, terms, params, P, TH, Q, X, N):
    """Force points X (D, n_phi, n_pairs, 2) and force directions N of every pair (drivers
    left untouched) at every design and position; the same geometry :func:`force_solve` uses."""
    for d in range(X.shape[0]):
        for k in range(X.shape[1]):
            for i in range(pairs.shape[0]):
                if pairs[i, 0] == PAIR_DRIVER:
                    continue
                X[d, k, i, 0], X[d, k, i, 1], N[d, k, i, 0], N[d, k, i, 1] = _pair_geometry(
                    i, pairs, pair_angle, cam_rows, terms, params, d, k, P, TH, Q)


#: a block whose smallest |R_jj| relative to its largest entry is this small is singular
PIVOT_MIN = 1e-12

#: positions solved together by the force kernel: every loop over positions is innermost and
#: free of branches, so that the compiler vectorises it (four positions per AVX2 instruction).
#: The pitch of the block solvers' flat scratch (:mod:`sewmech._blocks`).
FORCE_CHUNK = CHUNK




_FORCE_DOC = """Right-hand sides and pair forces of every design and position.

    The motion comes from the kinematics kernel: P (D, n_phi, n_pt, 2) of the points, EP,
    TH (D, n_phi, n_links) of the links, Q (D, n_phi, n_var), GP, GA (D, n_phi, n_links, 2) of
    the centres of mass. mass (kg), inertia (kg mm^2 about the centre of mass) per link;
    gravity (m/s^2, along -y). XB (D, n_phi, n_eq): the applied forces on every moving link
    (process loads, springs, dampers, friction), as equation rows: the sum of their x and y
    components (N) and of their moments about the link's centre of mass (N mm), row 3 (link -
    1) + 0, 1, 2. The equations (row 3 (link
    - 1) + x, y, moment about the centre of mass; one column per unknown) are solved block by
    block in the block upper-triangular order of blk_ptr, rperm (rows) and cperm (unknowns);
    block b's entries sit row-major at blk_off[b] of the n_slots entry slots, its coupling
    entries (cpl_row within the block, cpl_col) after all blocks, and pslot says in which slot
    each matrix entry of each pair goes (see :func:`sewmech.dynamics.force_structure`). Fills
    X (D, n_phi, n_eq) and MINPIV (D,
    n_phi), the smallest |R_jj| of the blocks' QR factors relative to each block's largest
    entry (0: singular). Blocks of up to max_written unknowns (at most
    :data:`sewmech._blocks.MAX_BLOCK`) go to the written solvers of :mod:`sewmech._blocks`,
    larger ones to a generic loop; 0 sends every block to the generic loop (a test compares
    the two). Returns the number of positions whose MINPIV is not above PIVOT_MIN.

    Friction in the pairs (:mod:`sewmech.engine.friction`; none when fr_int has no rows or
    max_steps is 0): fr_int rows (kind, first link, second link, column of its first unknown in
    X), fr_f rows (mu, pin radius mm, viscous N mm s or N s/mm, smoothing speed mm/s) and
    fr_pair (each one's index among the pairs) of the frictional pairs; OM (D, n_phi, n_links)
    the links' angular velocities, GV (D, n_phi, >= n_links, 2) the velocities of the points
    GP; feasible (D, n_phi) the assembled positions. After the frictionless solve, each design
    on its own runs a fixed-point iteration of its pair forces with the friction of the last
    step added to the loads of XB (:func:`_friction`, :func:`_friction_motion`; XB itself is
    left as given), accelerated by Anderson's method of depth ``depth``
    (:func:`_anderson`), until no assembled position changes by more than ``tol`` of the
    design's largest force, at most max_steps steps; the steps hold a design's unknowns with
    its positions side by side (n_eq, n_phi), so that their loops over the positions
    vectorise, and write X[d] once, when they end. The matrix does not depend on the
    friction: every step solves with the QR factors of the first solve, kept per position
    (Fa; the written solvers' factors, see :mod:`sewmech.engine._blocks`). CW (D, n_phi, n_eq) or empty: a part
    added to X after every solve (the counterweights', linear and frictionless). Fills FF, FP
    (D, n_phi, n_fr) (see :func:`_friction`) and SETTLE (D, 2): the change left relative to the
    design's largest force and the position where it is largest, the position -1 when the
    design settled. A design with an assembled position whose pivot is ~zero is not iterated.
    {which}
    """


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _force_scratch(n_slots, n_fac, n_chunks, n_eq):
    c = FORCE_CHUNK
    return (np.zeros(n_chunks * n_slots * c), np.zeros(n_chunks * n_fac * c), np.zeros(n_eq * c),
            np.zeros(n_eq * c), np.empty(c), np.empty(c), np.empty(c), np.empty(c),
            np.empty(c), np.empty(n_eq, dtype=np.int64), np.empty(n_eq, dtype=np.int64))


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def force_solve(d0, d1, pairs, pair_angle, cam_rows, terms, params, P, EP, Q, TH, GP, GA,
                mass, inertia, gravity, XB, blk_ptr, blk_off, rperm, cperm, cpl_ptr, cpl_row,
                cpl_col, pslot, n_slots, X, MINPIV, fr_int, fr_f, fr_pair, OM, GV, feasible,
                CW, FF, FP, SETTLE, max_steps, tol, depth, max_written):
    n_phi = X.shape[1]
    n_eq = X.shape[2]
    n_links = mass.shape[0]
    n_blocks = blk_ptr.shape[0] - 1
    n_blk_slots = blk_off[n_blocks]
    n_written = min(max_written, MAX_BLOCK)
    n_chunks = (n_phi + FORCE_CHUNK - 1) // FORCE_CHUNK
    # each block's factors (see _blocks): N (N + 2) entries from foffs[block] of a chunk's n_fac
    foffs = np.empty(n_blocks + 1, dtype=np.int64)
    foffs[0] = 0
    for blk in range(n_blocks):
        nb = blk_ptr[blk + 1] - blk_ptr[blk]
        foffs[blk + 1] = foffs[blk] + nb * (nb + 2)
    n_fac = foffs[n_blocks]
    W, Fa, B, XV, t1, t2, t3, t4, worst, rpos, cpos = _force_scratch(n_slots, n_fac, n_chunks,
                                                                     n_eq)
    n_low = 0
    # One design at a time, positions in chunks of FORCE_CHUNK, all in this one function: numba
    # compiles a called function twice (alone, and again inside its caller), which cost 6 s of
    # the install's compile for a per-design function. W (n_slots * chunk per chunk of
    # positions, flat: slot s of position kk of chunk c at (c * n_slots + s) * chunk + kk)
    # holds the blocks' entries (row-major within a block) and then the coupling entries, Fa
    # (n_fac * chunk per chunk, the same way) the blocks' QR factors; B the right-hand sides
    # and XV the unknowns (n_eq * chunk, flat), both in block order (row rperm[p] and unknown
    # cperm[p] at p); t1..t4, worst scratch (chunk); rpos, cpos (n_eq) the inverse
    # permutations.
    for p in range(n_eq):
        rpos[rperm[p]] = p
        cpos[cperm[p]] = p
    Wf = W
    Ff = Fa
    Bf = B
    XVf = XV
    W = Wf.reshape((Wf.shape[0] // FORCE_CHUNK, FORCE_CHUNK))
    Fa = Ff.reshape((Ff.shape[0] // FORCE_CHUNK, FORCE_CHUNK))
    B = Bf.reshape((Bf.shape[0] // FORCE_CHUNK, FORCE_CHUNK))
    XV = XVf.reshape((XVf.shape[0] // FORCE_CHUNK, FORCE_CHUNK))
    # flat views with unsigned offsets for the loops over positions (no wrap-around checks)
    Pf = P.reshape(P.size)
    Xf = X.reshape(X.size)
    GPf = GP.reshape(GP.size)
    GAf = GA.reshape(GA.size)
    EPf = EP.reshape(EP.size)
    XBf = XB.reshape(XB.size)
    n_pt = P.shape[2]
    n_g = GP.shape[2]
    sp = _U(2 * n_pt)  # P's step from one position to the next
    sg_ = _U(2 * n_g)  # GP's and GA's
    sl = _U(EP.shape[2])  # EP's
    CH = _U(FORCE_CHUNK)
    # friction (see the doc): each position's factors are kept, so that a step of the
    # fixed-point iteration costs a solve with them, the friction forces and Anderson's update
    n_fr = fr_int.shape[0]
    friction = n_fr > 0 and max_steps > 0
    with_cw = CW.shape[0] == X.shape[0] and CW.shape[1] == n_phi and CW.shape[2] == n_eq
    nf = n_fr if friction else 0
    frpos = np.full(pairs.shape[0], -1, dtype=np.int64)
    for i in range(nf):
        frpos[fr_pair[i]] = i
    GEO = np.zeros((nf, 4, n_phi))  # force point and direction of the frictional pairs
    FC = np.zeros((nf, 7, n_phi))  # what their friction takes from the motion (_friction)
    # the iteration's state with the positions side by side (n_eq, n_phi), unknowns in X's
    # order: x_k (XT), g(x_k) (GT), minus the right-hand sides without (XB0T) and with friction
    # (XBT: the applied forces, friction included, less the inertia forces and weights)
    ring = depth + 1
    nph = n_phi if friction else 0
    XT = np.zeros((n_eq, nph))
    GT = np.zeros((n_eq, nph))
    XB0T = np.zeros((n_eq, nph))
    XBT = np.zeros((n_eq, nph))
    HF = np.zeros((ring, n_eq, nph))
    HG = np.zeros((ring, n_eq, nph))
    done = np.zeros(n_phi, dtype=np.bool_)
    T = np.zeros((14, nph))
    MODE = np.zeros(nph, dtype=np.int64)
    A = np.zeros((depth, depth + 1))
    for d in range(d0, d1):
        step = -1  # -1: factor and solve; then the friction steps with the kept factors
        n_bad = 0  # assembled positions with a zero pivot: no friction iteration
        if friction:
            SETTLE[d, 0] = 0.0
            SETTLE[d, 1] = -1.0
        settled = False
        while True:
            if step >= 0:  # the friction of the last step's forces as applied forces
                # (settled: of the settled forces, the answer's). The friction functions are
                # called, not inlined by numba: numba types an inlined function again inside
                # its caller, at 2 s more of the install's compile, while LLVM inlines or
                # calls them at no measurable cost to the kernel (issue 34)
                _friction(fr_int, FC, XT, XB0T, XBT, FF, FP, d, settled)
                if settled:
                    for k in range(n_phi):
                        for e in range(n_eq):
                            X[d, k, e] = XT[e, k]
                    break
            for ci in range(n_chunks):
                k0 = ci * FORCE_CHUNK
                nk = min(FORCE_CHUNK, n_phi - k0)
                wb = ci * n_slots  # this chunk's rows of W and Fa
                fb = ci * n_fac
                if step < 0:
                    # W starts zeroed and every chunk writes the same entries, which the written
                    # solvers only read: only the blocks of the generic loop, which works in
                    # place, are re-zeroed
                    for blk in range(n_blocks):
                        if blk_ptr[blk + 1] - blk_ptr[blk] > n_written:
                            W[wb + blk_off[blk]:wb + blk_off[blk + 1], :] = 0.0
                # right-hand side per moving link: m a_G - m g - sum F ; I alpha - sum (X - G)
                # x F, the applied forces and their moments about the centre of mass given in XB
                for li in range(1, n_links):
                    rx = rpos[3 * (li - 1)]
                    ry = rpos[3 * (li - 1) + 1]
                    rm = rpos[3 * (li - 1) + 2]
                    m = 1e-3 * mass[li]
                    mg = gravity * mass[li]
                    ii = 1e-3 * inertia[li]
                    ga = _U(((d * n_phi + k0) * n_g + li) * 2)
                    el = _U((d * n_phi + k0) * EP.shape[2] + li)
                    xb = _U((d * n_phi + k0) * n_eq + 3 * (li - 1))
                    bx, by, bm = _U(rx) * CH, _U(ry) * CH, _U(rm) * CH
                    for kk in range(_U(nk) if step < 0 else _U(0)):
                        ix = xb + kk * _U(n_eq)
                        Bf[bx + kk] = m * GAf[ga + kk * sg_] - XBf[ix]
                        Bf[by + kk] = m * GAf[ga + kk * sg_ + _U(1)] + mg - XBf[ix + _U(1)]
                        Bf[bm + kk] = ii * EPf[el + kk * sl] - XBf[ix + _U(2)]
                for r in range(n_eq if step >= 0 else 0):  # the friction steps' (XBT: minus
                    br = _U(rpos[r]) * CH  # the right-hand sides, positions side by side)
                    for kk in range(nk):
                        Bf[br + kk] = -XBT[r, k0 + kk]
                # the matrix entries of every pair (pslot: where each of its entries goes in W)
                for i in range(pairs.shape[0] if step < 0 else 0):
                    kind = pairs[i, 0]
                    if kind == PAIR_DRIVER:
                        s = wb + pslot[i, 0]
                        for kk in range(nk):
                            W[s, kk] = 1.0
                        continue
                    fi = frpos[i]
                    for side in range(2):
                        link = pairs[i, 2] if side == 0 else pairs[i, 1]
                        if link == 0:
                            continue
                        sg = 1.0 if side == 0 else -1.0
                        if kind == PAIR_REVOLUTE:  # the forces along x and y at the pin
                            bp = _U(((d * n_phi + k0) * n_pt + pairs[i, 3]) * 2)
                            bg = _U(((d * n_phi + k0) * n_g + link) * 2)
                            sx = _U(wb + pslot[i, 3 * side]) * CH
                            smx = _U(wb + pslot[i, 3 * side + 2]) * CH
                            sy = _U(wb + pslot[i, 6 + 3 * side + 1]) * CH
                            smy = _U(wb + pslot[i, 6 + 3 * side + 2]) * CH
                            for kk in range(_U(nk)):
                                ip = bp + kk * sp
                                ig = bg + kk * sg_
                                Wf[sx + kk] = sg
                                Wf[smx + kk] = -sg * (Pf[ip + _U(1)] - GPf[ig + _U(1)])
                                Wf[sy + kk] = sg
                                Wf[smy + kk] = sg * (Pf[ip] - GPf[ig])
                        else:  # one force along the contact normal
                            sx = wb + pslot[i, 3 * side]
                            sy = wb + pslot[i, 3 * side + 1]
                            sm = wb + pslot[i, 3 * side + 2]
                            for kk in range(nk):
                                k = k0 + kk
                                xx, xy, fx, fy = _pair_geometry(i, pairs, pair_angle, cam_rows,
                                                                terms, params, d, k, P, TH, Q)
                                dx = xx - GP[d, k, link, 0]
                                dy = xy - GP[d, k, link, 1]
                                W[sx, kk] = sg * fx
                                W[sy, kk] = sg * fy
                                W[sm, kk] = sg * (dx * fy - dy * fx)
                                if fi >= 0:  # friction's force point and direction
                                    GEO[fi, 0, k] = xx
                                    GEO[fi, 1, k] = xy
                                    GEO[fi, 2, k] = fx
                                    GEO[fi, 3, k] = fy
                        if kind == PAIR_PRISMATIC:  # the guide's couple
                            s = wb + pslot[i, 12 + side]
                            for kk in range(nk):
                                W[s, kk] = sg
                # block upper-triangular form: the last block first, each with the unknowns of
                # the later blocks known (coupling terms to the right-hand side); every block by
                # Householder QR, which is stable without pivoting and so runs the same
                # instructions at every position
                for kk in range(nk):
                    worst[kk] = np.inf
                for blk in range(n_blocks - 1, -1, -1):
                    r0 = blk_ptr[blk]
                    nb = blk_ptr[blk + 1] - r0
                    off = wb + blk_off[blk]
                    fo = fb + foffs[blk]
                    for c in range(cpl_ptr[blk], cpl_ptr[blk + 1]):  # known unknowns to the right
                        ri = _U(r0 + cpl_row[c]) * CH
                        col = _U(cpos[cpl_col[c]]) * CH
                        s = _U(wb + n_blk_slots + c) * CH
                        for kk in range(_U(nk)):
                            Bf[ri + kk] -= Wf[s + kk] * XVf[col + kk]
                    if step < 0 and nb <= n_written and block_qr(nb, Wf, off, Ff, fo, Bf, XVf,
                                                                 r0, nk, worst):
                        continue
                    if step >= 0:  # the kept reflectors on the right-hand side
                        for j in range(nb):
                            sv = fo + nb * nb + j  # v0
                            for kk in range(nk):
                                t4[kk] = Fa[sv, kk] * B[r0 + j, kk]
                            for i in range(j + 1, nb):
                                sv = fo + i * nb + j
                                for kk in range(nk):
                                    t4[kk] += Fa[sv, kk] * B[r0 + i, kk]
                            st = fo + nb * nb + nb + j
                            for kk in range(nk):
                                t4[kk] *= Fa[st, kk]
                            sv = fo + nb * nb + j
                            for kk in range(nk):
                                B[r0 + j, kk] -= t4[kk] * Fa[sv, kk]
                            for i in range(j + 1, nb):
                                sv = fo + i * nb + j
                                for kk in range(nk):
                                    B[r0 + i, kk] -= t4[kk] * Fa[sv, kk]
                    else:
                        for kk in range(nk):  # scale: the block's largest entry
                            t3[kk] = 0.0
                        for e in range(nb * nb):
                            for kk in range(nk):
                                t3[kk] = max(t3[kk], abs(W[off + e, kk]))
                        for j in range(nb):
                            sj = off + j * nb + j
                            for kk in range(nk):
                                t1[kk] = 0.0
                            for i in range(j, nb):
                                s = off + i * nb + j
                                for kk in range(nk):
                                    t1[kk] += W[s, kk] * W[s, kk]
                            for kk in range(nk):
                                ajj = W[sj, kk]
                                alpha = -math.copysign(math.sqrt(t1[kk]), ajj)
                                v0 = ajj - alpha
                                vn2 = t1[kk] - ajj * ajj + v0 * v0
                                t2[kk] = 2.0 / vn2 if vn2 > 0.0 else 0.0
                                W[sj, kk] = v0  # the reflector's vector replaces column j ...
                                t1[kk] = alpha  # ... and R_jj waits in t1
                                worst[kk] = min(worst[kk],
                                                abs(alpha) / t3[kk] if t3[kk] > 0.0 else 0.0)
                                Fa[fo + nb * nb + j, kk] = v0  # kept for the friction steps
                                Fa[fo + nb * nb + nb + j, kk] = t2[kk]
                            for c in range(j + 1, nb + 1):  # the later columns, then the rhs
                                for kk in range(nk):
                                    t4[kk] = 0.0
                                for i in range(j, nb):
                                    sv = off + i * nb + j
                                    if c < nb:
                                        sc = off + i * nb + c
                                        for kk in range(nk):
                                            t4[kk] += W[sv, kk] * W[sc, kk]
                                    else:
                                        ri = r0 + i
                                        for kk in range(nk):
                                            t4[kk] += W[sv, kk] * B[ri, kk]
                                for kk in range(nk):
                                    t4[kk] *= t2[kk]
                                for i in range(j, nb):
                                    sv = off + i * nb + j
                                    if c < nb:
                                        sc = off + i * nb + c
                                        for kk in range(nk):
                                            W[sc, kk] -= t4[kk] * W[sv, kk]
                                    else:
                                        ri = r0 + i
                                        for kk in range(nk):
                                            B[ri, kk] -= t4[kk] * W[sv, kk]
                            for kk in range(nk):
                                W[sj, kk] = t1[kk]  # R_jj on the diagonal
                        for e in range(nb * nb):  # the factors, kept as the written solvers do
                            for kk in range(nk):
                                Fa[fo + e, kk] = W[off + e, kk]
                    R = Fa if step >= 0 else W  # back substitution with R
                    oR = fo if step >= 0 else off
                    for j in range(nb - 1, -1, -1):
                        rj = r0 + j
                        for kk in range(nk):
                            t4[kk] = B[rj, kk]
                        for c in range(j + 1, nb):
                            s = oR + j * nb + c
                            cc = r0 + c
                            for kk in range(nk):
                                t4[kk] -= R[s, kk] * XV[cc, kk]
                        cj = r0 + j
                        sj = oR + j * nb + j
                        for kk in range(nk):
                            XV[cj, kk] = t4[kk] / R[sj, kk]
                if step < 0:
                    for kk in range(nk):
                        MINPIV[d, k0 + kk] = worst[kk]
                        if not worst[kk] > PIVOT_MIN:  # NaN (did not assemble) included
                            n_low += 1
                            if feasible[d, k0 + kk]:
                                n_bad += 1
                if step >= 0:  # g(x_k), positions side by side
                    for e in range(n_eq):
                        ce = cperm[e]
                        for kk in range(nk):
                            GT[ce, k0 + kk] = XV[e, kk]
                    continue
                bx = _U((d * n_phi + k0) * n_eq)
                for e in range(n_eq):
                    xo = bx + _U(cperm[e])
                    xi = _U(e) * CH
                    for kk in range(_U(nk)):
                        Xf[xo + kk * _U(n_eq)] = XVf[xi + kk]
            if not friction or n_bad > 0:  # (a singular design is reported, not iterated)
                break
            if step < 0:
                for k in range(n_phi):
                    done[k] = False
                    for e in range(n_eq):  # (the counterweights' part: linear, frictionless)
                        XT[e, k] = X[d, k, e] + CW[d, k, e] if with_cw else X[d, k, e]
                for li in range(1, n_links):  # the applied forces less the inertia forces and
                    r = 3 * (li - 1)  # weight: minus the right-hand sides without friction
                    m = 1e-3 * mass[li]
                    mg = gravity * mass[li]
                    ii = 1e-3 * inertia[li]
                    for k in range(n_phi):
                        XB0T[r, k] = XB[d, k, r] - m * GA[d, k, li, 0]
                        XB0T[r + 1, k] = XB[d, k, r + 1] - (m * GA[d, k, li, 1] + mg)
                        XB0T[r + 2, k] = XB[d, k, r + 2] - ii * EP[d, k, li]
                _friction_motion(fr_int, fr_f, GEO, OM, GP, GV, FC, d)
            else:
                if with_cw:
                    for k in range(n_phi):
                        for e in range(n_eq):
                            GT[e, k] += CW[d, k, e]
                # (the step as np.int64: typed as a literal -1 first, it would compile twice)
                change, kw = _anderson(GT, XT, HF, HG, np.int64(step), feasible, done, tol, T,
                                       MODE, A, d)
                if change <= tol:  # every position settled (each keeps its own answer)
                    settled = True
                    continue
                if step + 1 >= max_steps:
                    SETTLE[d, 0] = change
                    SETTLE[d, 1] = kw
                    for k in range(n_phi):
                        for e in range(n_eq):
                            X[d, k, e] = XT[e, k]
                    break
            step += 1
    return n_low


force_solve.__doc__ = _FORCE_DOC.format(
    which="Designs d0 <= d < d1; it releases the GIL, so big batches run as chunks on threads.")


# ---- friction -----------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _friction_motion(fr_int, fr_f, GEO, OM, GP, GV, FC, d):
    """What the friction of every frictional pair of design d takes from the motion (it does not
    change over the friction iteration), FC (n_fr, 7, n_phi): revolute pairs mu r s(r w),
    viscous w, w; prismatic, cam and slot pairs mu s(v), viscous v, v, the contact's tangent t
    (x, y) and the moments of t at the force point about the centres of mass of the second and
    the first link. w: the relative angular velocity (second link less first), v = t . (relative
    velocity of the force point on the second link and on the first), s(x) = x / sqrt(x^2 +
    smooth^2). GEO (n_fr, 4, n_phi): each pair's force point and force direction (revolute:
    unused); fr_int, fr_f, OM, GP, GV: see :func:`force_solve`."""
    n_phi = FC.shape[2]
    for i in range(fr_int.shape[0]):
        kind = fr_int[i, 0]
        la = fr_int[i, 1]
        lb = fr_int[i, 2]
        mu = fr_f[i, 0]
        rad = fr_f[i, 1]
        visc = fr_f[i, 2]
        sm = fr_f[i, 3]
        for k in range(n_phi):
            if kind == PAIR_REVOLUTE:
                w = OM[d, k, lb] - OM[d, k, la]
                v = rad * w
                FC[i, 0, k] = mu * rad * (v / math.sqrt(v * v + sm * sm))
                FC[i, 1, k] = visc * w
                FC[i, 2, k] = w
                continue
            px = GEO[i, 0, k]
            py = GEO[i, 1, k]
            tx = GEO[i, 3, k]  # the tangent: the normal turned -90 deg
            ty = -GEO[i, 2, k]
            # velocity of the force point as a point of each link
            vbx = GV[d, k, lb, 0] - OM[d, k, lb] * (py - GP[d, k, lb, 1])
            vby = GV[d, k, lb, 1] + OM[d, k, lb] * (px - GP[d, k, lb, 0])
            vax = GV[d, k, la, 0] - OM[d, k, la] * (py - GP[d, k, la, 1])
            vay = GV[d, k, la, 1] + OM[d, k, la] * (px - GP[d, k, la, 0])
            v = tx * (vbx - vax) + ty * (vby - vay)
            FC[i, 0, k] = mu * (v / math.sqrt(v * v + sm * sm))
            FC[i, 1, k] = visc * v
            FC[i, 2, k] = v
            FC[i, 3, k] = tx
            FC[i, 4, k] = ty
            FC[i, 5, k] = (px - GP[d, k, lb, 0]) * ty - (py - GP[d, k, lb, 1]) * tx
            FC[i, 6, k] = (px - GP[d, k, la, 0]) * ty - (py - GP[d, k, la, 1]) * tx


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _friction(fr_int, FC, XT, XB0T, XBT, FF, FP, d, final):
    """The friction of every frictional pair of design d from its pair forces XT (n_eq, n_phi:
    unknown by position, the positions side by side), as generalized forces XBT = XB0T +
    friction (the same layout; see :func:`force_solve`'s friction arguments), with what it
    takes from the motion in FC (:func:`_friction_motion`).

    Revolute pairs: a moment -(mu r |F| s(r w) + viscous w) on the second link, the opposite on
    the first; prismatic, cam and slot pairs: a force -(mu |N| s(v) + viscous v) along the
    contact's tangent on the second link at the force point, the opposite on the first.
    ``final``: also fill FF[d] (n_phi, n_fr) with that moment (N mm) or force (N) on the second
    link and FP[d] with the power it takes out of the machine (N mm/s, >= 0)."""
    n_phi = XT.shape[1]
    for r in range(XBT.shape[0]):
        for k in range(n_phi):
            XBT[r, k] = XB0T[r, k]
    for i in range(fr_int.shape[0]):
        kind = fr_int[i, 0]
        la = fr_int[i, 1]
        lb = fr_int[i, 2]
        c = fr_int[i, 3]
        rb = 3 * (lb - 1)
        ra = 3 * (la - 1)
        if kind == PAIR_REVOLUTE:
            for k in range(n_phi):
                fx = XT[c, k]
                fy = XT[c + 1, k]
                m = -(FC[i, 0, k] * math.sqrt(fx * fx + fy * fy) + FC[i, 1, k])
                if lb > 0:
                    XBT[rb + 2, k] += m
                if la > 0:
                    XBT[ra + 2, k] -= m
            for k in range(n_phi if final else 0):
                fx = XT[c, k]
                fy = XT[c + 1, k]
                m = -(FC[i, 0, k] * math.sqrt(fx * fx + fy * fy) + FC[i, 1, k])
                FF[d, k, i] = m
                FP[d, k, i] = -m * FC[i, 2, k]
            continue
        for k in range(n_phi):
            f = -(FC[i, 0, k] * abs(XT[c, k]) + FC[i, 1, k])
            if lb > 0:
                XBT[rb, k] += f * FC[i, 3, k]
                XBT[rb + 1, k] += f * FC[i, 4, k]
                XBT[rb + 2, k] += f * FC[i, 5, k]
            if la > 0:
                XBT[ra, k] -= f * FC[i, 3, k]
                XBT[ra + 1, k] -= f * FC[i, 4, k]
                XBT[ra + 2, k] -= f * FC[i, 6, k]
        for k in range(n_phi if final else 0):
            f = -(FC[i, 0, k] * abs(XT[c, k]) + FC[i, 1, k])
            FF[d, k, i] = f
            FP[d, k, i] = -f * FC[i, 2, k]


@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)
def _anderson(GT, XT, HF, HG, k, feasible, done, tol, T, MODE, A, d):
    """One step of Anderson acceleration (type II, depth HF.shape[0] - 1, at most 3) of the fixed
    point x = g(x) at every position of design d on its own, the positions side by side (the
    loops over them vectorise): XT (n, n_phi) is x_k on entry and x_{k+1} on return, GT (n,
    n_phi) holds g(x_k). HF, HG (depth + 1, n, n_phi): the residuals f = g(x) - x and the images
    g(x) of the last steps (a ring, step k in slot k % (depth + 1)). x_{k+1} = g_k - sum_j
    gamma_j (g_{k-j} - g_{k-j-1}), gamma the least-squares combination of the residuals'
    differences that best cancels f_k (normal equations of at most depth unknowns per position,
    solved by Gaussian elimination, damped by 1e-12 of their trace). A position whose |f_k| is
    at most ``tol`` of the design's largest |g| is done (``done`` (n_phi,) bool, kept across the
    steps): XT takes that g_k and later steps leave it. T (14, n_phi), MODE (n_phi,), A (depth,
    depth + 1) scratch.
    Returns max |f_k| relative to the design's largest |g| over its assembled positions not yet
    done (0 when all are) and the position where it is (-1: none)."""
    depth = HF.shape[0] - 1
    ring = depth + 1
    slot = k % ring
    n, n_phi = GT.shape
    mk = min(k, depth)
    s0, s1, s2, s3 = slot, (k - 1) % ring, (k - 2) % ring, (k - 3) % ring  # steps k, k - 1, ...
    # per position: |f_k| (T[9]) and |g| (T[10]) largest over the unknowns; the ring's slots
    # (every position's, the done ones' unread)
    for kk in range(n_phi):
        T[9, kk] = 0.0
        T[10, kk] = 0.0
    for e in range(n):
        for kk in range(n_phi):
            g = GT[e, kk]
            f = g - XT[e, kk]
            HF[slot, e, kk] = f
            HG[slot, e, kk] = g
            T[9, kk] = max(T[9, kk], abs(f))
            T[10, kk] = max(T[10, kk], abs(g))
    scale = 1.0
    for kk in range(n_phi):
        if feasible[d, kk]:
            scale = max(scale, T[10, kk])
    worst = 0.0
    kw = -1
    n_acc = 0
    for kk in range(n_phi):  # MODE: 0 keeps XT (done), 1 takes g_k, 2 Anderson's combination
        if done[kk]:  # settled before: its forces stay as they were
            MODE[kk] = 0
            continue
        MODE[kk] = 1
        if not feasible[d, kk]:
            continue
        res = T[9, kk]
        if res / scale <= tol:  # settled now: it takes g_k, the forces of this solve
            done[kk] = True
            continue
        if not res / scale <= worst:
            worst = res / scale
            kw = kk
        if mk > 0:
            MODE[kk] = 2
            n_acc += 1
    # normal equations [A | b] of min |f_k - sum_j gamma_j (f_{k-j} - f_{k-j-1})| at every
    # position (depth <= 3, unused sums 0), each sum in the unknowns' order: T[0..8] = a00, a01,
    # a02, a11, a12, a22, b0, b1, b2
    for j in range(9 if n_acc > 0 else 0):
        for kk in range(n_phi):
            T[j, kk] = 0.0
    for e in range(n if n_acc > 0 else 0):
        for kk in range(n_phi):
            fk = HF[s0, e, kk]
            q0 = HF[s0, e, kk] - HF[s1, e, kk]
            q1 = HF[s1, e, kk] - HF[s2, e, kk] if mk > 1 else 0.0
            q2 = HF[s2, e, kk] - HF[s3, e, kk] if mk > 2 else 0.0
            T[0, kk] += q0 * q0
            T[1, kk] += q0 * q1
            T[2, kk] += q0 * q2
            T[3, kk] += q1 * q1
            T[4, kk] += q1 * q2
            T[5, kk] += q2 * q2
            T[6, kk] += q0 * fk
            T[7, kk] += q1 * fk
            T[8, kk] += q2 * fk
    for kk in range(n_phi if n_acc > 0 else 0):  # gamma in T[11..13] (elimination, symmetric
        if MODE[kk] != 2:  # positive definite)
            continue
        A[0, 0] = T[0, kk]
        if mk > 1:
            A[0, 1] = A[1, 0] = T[1, kk]
            A[1, 1] = T[3, kk]
        if mk > 2:
            A[0, 2] = A[2, 0] = T[2, kk]
            A[1, 2] = A[2, 1] = T[4, kk]
            A[2, 2] = T[5, kk]
        for i in range(mk):
            A[i, mk] = T[6 + i, kk]
        tr = 0.0
        for i in range(mk):
            tr += A[i, i]
        ok = tr > 0.0
        for i in range(mk):
            A[i, i] += 1e-12 * tr
        for c in range(mk if ok else 0):
            p = A[c, c]
            if not p > 0.0:
                ok = False
                break
            for r in range(c + 1, mk):
                q = A[r, c] / p
                for j in range(c, mk + 1):
                    A[r, j] -= q * A[c, j]
        if not ok:
            MODE[kk] = 1
            continue
        for c in range(mk - 1, -1, -1):
            t = A[c, mk]
            for j in range(c + 1, mk):
                t -= A[c, j] * T[11 + j, kk]
            T[11 + c, kk] = t / A[c, c]
    for e in range(n):
        for kk in range(n_phi):
            g = GT[e, kk]
            v = g - T[11, kk] * (HG[s0, e, kk] - HG[s1, e, kk])
            if mk > 1:
                v -= T[12, kk] * (HG[s1, e, kk] - HG[s2, e, kk])
            if mk > 2:
                v -= T[13, kk] * (HG[s2, e, kk] - HG[s3, e, kk])
            m = MODE[kk]
            XT[e, kk] = XT[e, kk] if m == 0 else (v if m == 2 else g)
    return worst, kw

"""Exact design sensitivities of positions: d(point position, link angle, joint variable) /
d(every parameter), at every shaft angle, from the solved mechanism.

Each unit of the compiled program is differentiated where it is solved, in solve order
(forward mode, every parameter direction at once): a closed-form unit's closure equations give
its outputs' tangents from its inputs' tangents and its own parameters' (for a dyad,
(C - B1) . (dC - dB1) = l1 dl1 and (C - B2) . (dC - dB2) = l2 dl2: a 2 x 2 system per angle); a
loop unit's closure F(q, known, p) = 0 gives J_q dq = -(dF/dknown dknown + dF/dp dp), with the
same terms (points, vectors of parameter or variable length, circular-arc cam contacts) as the
kernel's loop solver. The positions come from the kinematics kernel; this module adds the
tangents, vectorised over designs and angles, in numpy.

With ``rates=True`` the velocities, angular velocities and joint rates follow the same way: each
unit's velocity relation (for a dyad (C - B_k) . (v_C - v_k) = 0; for a loop J q_dot = -b)
differentiated with the position tangents known; then the accelerations from the acceleration
relations (for a dyad (C - B_k) . (a_C - a_k) + |v_C - v_k|^2 = 0) with both known.

Derivatives are in internal units: mm, rad, mm/s, rad/s per unit of the parameter (mm, rad, 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ._kernels import (OP_CRANK, OP_FIXED, OP_LOOP, OP_POINT, OP_RPR, OP_RRP, OP_RRR, SRC_LINK,
                       SRC_PARAM, TERM_POINT, TERM_VEC)
from .errors import AnalysisError, name_index
from .kinematics import kinematics
from .machine import Machine
from .results import KinematicsResult


#: the most memory the tangents of one call may take, bytes
MAX_BYTES = 2 * 2**30


@dataclass(frozen=True)
class Sensitivities:
    """Tangents of the positions with respect to every parameter.

    kin : the kinematics the tangents belong to; dp : (batch, n_phi, n_points, 2, n_params)
    d(point position)/d(parameter), mm per parameter unit; dtheta : (batch, n_phi, n_links,
    n_params) rad per unit; dq : (batch, n_phi, n_variables, n_params) per unit (mm or rad);
    dv, domega, dqd, da, depsilon, dqdd : the same for the velocities (mm/s), angular
    velocities (rad/s), joint rates and their accelerations, or None without ``rates``.
    """

    kin: KinematicsResult
    dp: np.ndarray
    dtheta: np.ndarray
    dq: np.ndarray
    dv: np.ndarray | None = None
    domega: np.ndarray | None = None
    dqd: np.ndarray | None = None
    da: np.ndarray | None = None
    depsilon: np.ndarray | None = None
    dqdd: np.ndarray | None = None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.kin.machine.parameter_names

    def channel(self, name: str) -> tuple[np.ndarray, np.ndarray, str]:
        """A channel (``p_POINT_x``/``_y``, ``theta_LINK``, ``q_VAR``; with ``rates``:
        ``v_POINT_x``/``_y``, ``omega_LINK``, ``qd_VAR``): its values (batch + (n_phi,)), its
        derivatives (batch + (n_phi, n_params)) and its unit."""
        r = self.kin
        kind, _, rest = name.partition("_")
        if kind in ("v", "omega", "qd", "a", "epsilon", "qdd") and self.dv is None:
            raise KeyError(f"'{name}' is a rate: ask sensitivities(..., rates=True)")
        if kind in ("p", "v", "a"):
            pt, _, comp = rest.rpartition("_")
            if comp not in ("x", "y"):
                raise KeyError(f"channel '{name}': a point channel ends in _x or _y")
            i = name_index(r.point_names, pt, "point")
            c = "xy".index(comp)
            if kind == "p":
                return r.p[..., i, c], self.dp[..., i, c, :], "mm"
            if kind == "v":
                return r.v[..., i, c], self.dv[..., i, c, :], "mm/s"
            return r.a[..., i, c], self.da[..., i, c, :], "mm/s^2"
        if kind in ("theta", "omega", "epsilon"):
            i = name_index(r.link_names, rest, "link")
            value, d, unit = {"theta": (r.theta, self.dtheta, "rad"),
                              "omega": (r.omega, self.domega, "rad/s"),
                              "epsilon": (r.epsilon, self.depsilon, "rad/s^2")}[kind]
            return value[..., i], d[..., i, :], unit
        if kind in ("q", "qd", "qdd"):
            i = name_index(r.variable_names, rest, "joint variable")
            base = r.variable_units[i]
            value, d, unit = {"q": (r.q, self.dq, base), "qd": (r.q_dot, self.dqd, f"{base}/s"),
                              "qdd": (r.q_ddot, self.dqdd, f"{base}/s^2")}[kind]
            return value[..., i], d[..., i, :], unit
        raise KeyError(f"'{name}' is not a channel: p_POINT_x, p_POINT_y, theta_LINK, q_VAR,"
                       " their rates v_, omega_, qd_ and accelerations a_, epsilon_, qdd_")


def _rot90(x: np.ndarray) -> np.ndarray:
    """(x, y) -> (-y, x) on the coordinate axis -2 (vectors with a trailing parameter axis) or
    -1."""
    return np.stack([-x[..., 1], x[..., 0]], axis=-1)


def sensitivities(machine: Machine, phi: ArrayLike, *, params: ArrayLike | None = None,
                  inputs=None, rates: bool = False,
                  outputs: list[str] | None = None) -> Sensitivities:
    """Exact derivatives of every point position, link angle and joint variable with respect
    to every parameter (``machine.parameter_names``), at shaft angles ``phi`` (rad), for the
    designs ``params`` (default: the file's) and setting ``inputs`` (rad, as for
    :func:`sewmech.kinematics`). With ``rates`` the velocities, angular velocities, joint
    rates and the accelerations are differentiated too (at the file's speed). A position where
    the mechanism cannot be assembled raises (the derivatives are not defined there).

    ``outputs`` (channel names as :meth:`Sensitivities.channel` takes them, e.g.
    ``["p_needle.point_y"]``; None: every channel): only the units these depend on are solved
    and differentiated, and the result holds the points, links and variables of those units
    (a gradient of one channel then costs a few of its own kinematics evaluations)."""
    designs = int(np.prod(np.shape(params)[:-1])) if params is not None else 1
    for v in (inputs or {}).values():
        designs = max(designs, int(np.size(v)))
    _check_size(machine, designs * int(np.size(phi)) * (3 if rates else 1))
    prog, pt_sel, lk_sel, var_sel = _outputs_of(machine, outputs)
    r = kinematics(machine, phi, params=params, inputs=inputs,
                   **({} if outputs is None else {
                       "points": [machine.point_names[i] for i in pt_sel],
                       "links": [machine.link_names[i] for i in lk_sel],
                       "variables": [machine.variable_names[i] for i in var_sel]}))
    if not r.all_feasible:
        raise AnalysisError(f"machine '{machine.name}'", "cannot be assembled at some of the"
                            " angles: the sensitivities are not defined there",
                            "Choose angles where it assembles (sewmech check)")
    batch = r.p.shape[:-2]  # (batch..., n_phi)
    n = int(np.prod(batch)) if batch else 1
    full = _Full(n, machine, pt_sel, lk_sel, var_sel)
    P = full.points(r.p)
    TH = full.links(r.theta)
    Q = full.variables(r.q)
    # the parameters of each position (designs broadcast over the angles)
    par = np.broadcast_to(_design_params(machine, r, params, inputs)[..., None, :],
                          batch + (len(machine.parameter_names),)).reshape(n, -1)
    npar = par.shape[1]
    dP = np.zeros((n, len(machine.point_names), 2, npar))
    dTH = np.zeros((n, len(machine.link_names), npar))
    dQ = np.zeros((n, len(machine.variable_names), npar))
    eye = np.eye(npar)
    for row in prog:
        op = row[0]
        if op == OP_FIXED:
            i, jx, jy = row[1], row[2], row[3]
            dP[:, i, 0, :] = eye[jx]
            dP[:, i, 1, :] = eye[jy]
        elif op == OP_CRANK:
            L, jph, jra, jset = row[1], row[2], row[3], row[4]
            if jset >= 0:
                dTH[:, L, :] = eye[jph] + eye[jset]
            else:  # theta = phase + ratio * (the march's angle, which may differ from phi
                # by whole turns): d theta / d ratio = (theta - phase) / ratio
                turned = (TH[:, L] - par[:, jph]) / par[:, jra]
                dTH[:, L, :] = eye[jph][None, :] + turned[:, None] * eye[jra][None, :]
        elif op == OP_POINT:
            i, L, o, ju, jv = row[1], row[2], row[3], row[4], row[5]
            c, s = np.cos(TH[:, L]), np.sin(TH[:, L])
            rel = P[:, i] - P[:, o]
            # dP = dO + R (du, dv) + J (P - O) dtheta
            dP[:, i, 0, :] = (dP[:, o, 0, :] + c[:, None] * eye[ju] - s[:, None] * eye[jv]
                              - rel[:, 1, None] * dTH[:, L, :])
            dP[:, i, 1, :] = (dP[:, o, 1, :] + s[:, None] * eye[ju] + c[:, None] * eye[jv]
                              + rel[:, 0, None] * dTH[:, L, :])
        elif op == OP_RRR:
            _rrr(row, P, dP, dTH, par, eye)
        elif op == OP_RRP:
            _rrp(row, P, TH, Q, dP, dTH, dQ, par, eye)
        elif op == OP_RPR:
            _rpr(row, P, TH, Q, dP, dTH, dQ, par, eye)
        elif op == OP_LOOP:
            _loop(machine, row[1], 0, _State(P, TH, Q, dP, dTH, dQ), par, eye)
    shape = batch
    rate_tangents = {}
    if rates:
        V = full.points(r.v)
        OM = full.links(r.omega)
        QD = full.variables(r.q_dot)
        dV, dOM, dQD = _rates(machine, V, OM, QD, P, TH, Q, dP, dTH, dQ, par, eye, prog)
        A = full.points(r.a)
        EP = full.links(r.epsilon)
        QDD = full.variables(r.q_ddot)
        dA, dEP, dQDD = _accels(machine, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM,
                                dQD, par, eye, prog)
        rate_tangents = {"dv": full.back(dV, pt_sel, shape),
                         "domega": full.back(dOM, lk_sel, shape),
                         "dqd": full.back(dQD, var_sel, shape),
                         "da": full.back(dA, pt_sel, shape),
                         "depsilon": full.back(dEP, lk_sel, shape),
                         "dqdd": full.back(dQDD, var_sel, shape)}
    return Sensitivities(r, full.back(dP, pt_sel, shape), full.back(dTH, lk_sel, shape),
                         full.back(dQ, var_sel, shape), **rate_tangents)


def _outputs_of(machine: Machine, outputs) -> tuple:
    """The program rows the channels ``outputs`` depend on (None: all) and the points, links
    and variables those rows write (indices): what the tangents need solved."""
    if outputs is None:
        return (machine.program, np.arange(len(machine.point_names)),
                np.arange(len(machine.link_names)), np.arange(len(machine.variable_names)))
    pts, lks, vrs = [], [], []
    for name in ([outputs] if isinstance(outputs, str) else outputs):
        kind, _, rest = str(name).partition("_")
        if kind in ("p", "v", "a"):
            pt, _, comp = rest.rpartition("_")
            if comp not in ("x", "y"):
                raise KeyError(f"channel '{name}': a point channel ends in _x or _y")
            pts.append(name_index(machine.point_names, pt, "point"))
        elif kind in ("theta", "omega", "epsilon"):
            lks.append(name_index(machine.link_names, rest, "link"))
        elif kind in ("q", "qd", "qdd"):
            vrs.append(name_index(machine.variable_names, rest, "joint variable"))
        else:  # (KeyError, as Sensitivities.channel raises for a name it does not know)
            raise KeyError(f"'{name}' is not a channel: p_POINT_x, p_POINT_y, theta_LINK,"
                           " q_VAR, their rates v_, omega_, qd_ and accelerations a_,"
                           " epsilon_, qdd_")
    rows = machine.rows_for(pts, lks, vrs)
    written: set = set()
    for k in rows:
        written |= machine._row_io[k][1]
    sel = [np.array(sorted(i for t, i in written if t == tag), dtype=np.int64)
           for tag in ("p", "l", "v")]
    return (machine.program[rows], *sel)


class _Full:
    """Scatters the selected outputs of a kinematics result into arrays over every point,
    link and variable of the machine (indices as the program's; unsolved ones NaN), and
    gathers the tangents back."""

    def __init__(self, n, machine, pt_sel, lk_sel, var_sel):
        self.n, self.m = n, machine
        self.sel = (pt_sel, lk_sel, var_sel)

    def _scatter(self, a, count, sel, tail):
        a = np.asarray(a).reshape((self.n, len(sel)) + tail)
        if len(sel) == count:  # every one: the arrays as they are
            return a
        out = np.full((self.n, count) + tail, np.nan)
        out[:, sel] = a
        return out

    def points(self, a):
        return self._scatter(a, len(self.m.point_names), self.sel[0], (2,))

    def links(self, a):
        out = self._scatter(a, len(self.m.link_names), self.sel[1], ())
        if 0 not in self.sel[1]:  # the frame (link 0) reads as still, as in a whole result
            out[:, 0] = 0.0
        return out

    def variables(self, a):
        return self._scatter(a, len(self.m.variable_names), self.sel[2], ())

    @staticmethod
    def back(d, sel, shape):
        d = d if len(sel) == d.shape[1] else d[:, sel]
        return d.reshape(shape + d.shape[1:])


def _check_size(machine: Machine, n: int) -> None:
    """Refuse a call whose tangents would not fit in :data:`MAX_BYTES`."""
    need = n * (2 * len(machine.point_names) + len(machine.link_names)
                + len(machine.variable_names)) * len(machine.parameter_names) * 8
    if need > MAX_BYTES:
        raise AnalysisError(f"machine '{machine.name}'", f"the derivatives of {n} positions"
                            f" (designs x angles) by {len(machine.parameter_names)} parameters"
                            f" take {need / 2**30:.1f} GiB", "Ask for fewer designs or angles"
                            f" at a time (at most {MAX_BYTES / 2**30:g} GiB)")


def _design_params(machine: Machine, r: KinematicsResult, params, inputs) -> np.ndarray:
    """The parameter vectors the kinematics used: batch + (n_params,)."""
    return machine.parameters(base=params, inputs=inputs) if params is not None or inputs \
        else np.asarray(machine.defaults)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for a (n, 2) and b (n, 2, k): (n, k)."""
    return a[:, 0, None] * b[:, 1, :] - a[:, 1, None] * b[:, 0, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a . b for a (n, 2) and b (n, 2, k): (n, k)."""
    return a[:, 0, None] * b[:, 0, :] + a[:, 1, None] * b[:, 1, :]


def _rrr(row, P, dP, dTH, par, eye) -> None:
    i1, i2, i, L1, L2, j1, j2 = row[1], row[2], row[3], row[4], row[5], row[6], row[7]
    r1 = P[:, i] - P[:, i1]
    r2 = P[:, i] - P[:, i2]
    l1, l2 = par[:, j1], par[:, j2]
    # r_k . dC = l_k dl_k + r_k . dP_k: a 2 x 2 system [r1; r2] dC = rhs per angle
    rhs1 = l1[:, None] * eye[j1][None, :] + _dot(r1, dP[:, i1])
    rhs2 = l2[:, None] * eye[j2][None, :] + _dot(r2, dP[:, i2])
    det = r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]
    dCx = (rhs1 * r2[:, 1, None] - rhs2 * r1[:, 1, None]) / det[:, None]
    dCy = (r1[:, 0, None] * rhs2 - r2[:, 0, None] * rhs1) / det[:, None]
    dP[:, i, 0, :] = dCx
    dP[:, i, 1, :] = dCy
    dC = dP[:, i]
    dTH[:, L1, :] = _cross(r1, dC - dP[:, i1]) / (l1 * l1)[:, None]
    dTH[:, L2, :] = _cross(r2, dC - dP[:, i2]) / (l2 * l2)[:, None]


def _rrp(row, P, TH, Q, dP, dTH, dQ, par, eye) -> None:
    b, gp, gl, i, L1, Ls, jl, ja, je, _, var = row[1:12]
    beta = TH[:, Ls]
    u = np.stack([np.cos(beta), np.sin(beta)], axis=-1)
    nrm = _rot90(u)
    s = Q[:, var]
    e = par[:, je]
    l = par[:, jl]
    dbeta = dTH[:, gl, :] + eye[ja][None, :]
    # dQ_foot = dG + de n - e u dbeta; dC = dQ_foot + ds u + s n dbeta
    known = (dP[:, gp] + nrm[:, :, None] * eye[je][None, None, :]
             - (e[:, None, None] * u[:, :, None]) * dbeta[:, None, :]
             + (s[:, None, None] * nrm[:, :, None]) * dbeta[:, None, :])
    r1 = P[:, i] - P[:, b]
    # r1 . (dC - dB) = l dl
    ds = (l[:, None] * eye[jl][None, :] - _dot(r1, known - dP[:, b])) / _dot(r1, u[:, :, None])
    dC = known + u[:, :, None] * ds[:, None, :]
    dP[:, i] = dC
    dQ[:, var, :] = ds
    dTH[:, L1, :] = _cross(r1, dC - dP[:, b]) / (l * l)[:, None]
    dTH[:, Ls, :] = dbeta


def _rpr(row, P, TH, Q, dP, dTH, dQ, par, eye) -> None:
    b, pv, L, Lb, je, _, var = row[1:8]
    th = TH[:, L]
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    nrm = _rot90(u)
    s = Q[:, var]
    e = par[:, je]
    # B - A = e n + s u: dB - dA = u (ds - e dtheta) + n (de + s dtheta)
    dd = dP[:, b] - dP[:, pv]
    dth = (_dot(nrm, dd) - eye[je][None, :]) / s[:, None]
    ds = _dot(u, dd) + e[:, None] * dth
    dTH[:, L, :] = dth
    if Lb >= 0:
        dTH[:, Lb, :] = dth
    dQ[:, var, :] = ds


def _rows(x):
    """A tangent (positions, n_params) as (positions, 1, n_params) to multiply a vector; a
    constant 0 stays 0."""
    return x[:, None, :] if np.ndim(x) == 2 else x


def _active_arc(machine: Machine, par: np.ndarray, cl, a0: int, na: int, rho: np.ndarray
                ) -> np.ndarray:
    """Index (into machine.arcs) of the arc whose normal-angle range holds ``rho`` (per
    position), as the kernel picks it."""
    two_pi = 2.0 * np.pi
    out = np.full(rho.shape, -1, dtype=np.int64)
    for k in range(a0, a0 + na):
        lo = par[:, machine.arcs[k, 3]]
        hi = par[:, machine.arcs[k, 4]]
        r = lo + np.mod(rho - lo, two_pi)
        hit = (out < 0) & (r < hi)
        out[hit] = k
    if np.any(out < 0):
        raise AnalysisError(f"machine '{machine.name}'", "a cam contact lies on no arc of its"
                            " profile", "Check the cam's arcs (sewmech check)")
    return out


# ---- the rates' derivatives ----------------------------------------------------------------------


def _rates(machine: Machine, V, OM, QD, P, TH, Q, dP, dTH, dQ, par, eye, prog):
    """Derivatives of the velocities (mm/s), angular velocities (rad/s) and joint rates by every
    parameter, from the velocity relations of each unit differentiated in solve order (the
    position tangents ``dP``, ``dTH``, ``dQ`` known): returns dV, dOM, dQD."""
    dV = np.zeros_like(dP)
    dOM = np.zeros_like(dTH)
    dQD = np.zeros_like(dQ)
    for row in prog:
        op = row[0]
        if op == OP_CRANK:
            L, jra, jset = row[1], row[3], row[4]
            if jset < 0:  # omega = ratio * omega_shaft
                dOM[:, L, :] = (OM[:, L] / par[:, jra])[:, None] * eye[jra][None, :]
        elif op == OP_POINT:
            i, L, o = row[1], row[2], row[3]
            rel = P[:, i] - P[:, o]
            drel = dP[:, i] - dP[:, o]
            # v = vO + omega J (P - O)
            dV[:, i] = (dV[:, o] + _rot90v(rel)[:, :, None] * dOM[:, L, None, :]
                        + OM[:, L, None, None] * _rot90t(drel))
        elif op == OP_RRR:
            i1, i2, i, L1, L2, j1, j2 = row[1], row[2], row[3], row[4], row[5], row[6], row[7]
            r1, r2 = P[:, i] - P[:, i1], P[:, i] - P[:, i2]
            dr1, dr2 = dP[:, i] - dP[:, i1], dP[:, i] - dP[:, i2]
            w1, w2 = V[:, i] - V[:, i1], V[:, i] - V[:, i2]
            # r_k . (vC - v_k) = 0: r_k . dvC = r_k . dv_k - dr_k . (vC - v_k)
            rhs1 = _dot(r1, dV[:, i1]) - _dot(w1, dr1)
            rhs2 = _dot(r2, dV[:, i2]) - _dot(w2, dr2)
            det = r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]
            dV[:, i, 0, :] = (rhs1 * r2[:, 1, None] - rhs2 * r1[:, 1, None]) / det[:, None]
            dV[:, i, 1, :] = (r1[:, 0, None] * rhs2 - r2[:, 0, None] * rhs1) / det[:, None]
            for L, r, dr, w, k, j in ((L1, r1, dr1, w1, i1, j1), (L2, r2, dr2, w2, i2, j2)):
                ll = par[:, j]
                dOM[:, L, :] = ((_cross_tv(dr, w) + _cross(r, dV[:, i] - dV[:, k])) / (ll * ll)[:, None]
                                - (2.0 * OM[:, L] / ll)[:, None] * eye[j][None, :])
        elif op == OP_RRP:
            _rrp_rates(row, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, par, eye)
        elif op == OP_RPR:
            _rpr_rates(row, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, par, eye)
        elif op == OP_LOOP:
            _loop(machine, row[1], 1, _State(P, TH, Q, dP, dTH, dQ, V, OM, QD, dV, dOM, dQD),
                  par, eye)
    return dV, dOM, dQD


def _rot90v(x):
    """(x, y) -> (-y, x) for (n, 2)."""
    return np.stack([-x[:, 1], x[:, 0]], axis=1)


def _rot90t(x):
    """(x, y) -> (-y, x) for tangents (n, 2, k)."""
    return np.stack([-x[:, 1, :], x[:, 0, :]], axis=1)


def _cross_tv(a, b):
    """a x b for tangents a (n, 2, k) and vectors b (n, 2): (n, k)."""
    return a[:, 0, :] * b[:, 1, None] - a[:, 1, :] * b[:, 0, None]


def _rrp_rates(row, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, par, eye) -> None:
    b, gp, gl, i, L1, Ls, jl, _, je, _, var = row[1:12]
    beta = TH[:, Ls]
    u = np.stack([np.cos(beta), np.sin(beta)], axis=-1)
    nrm = _rot90v(u)
    s, sd = Q[:, var], QD[:, var]
    e, l = par[:, je], par[:, jl]
    wg = OM[:, gl]
    dbeta = dTH[:, Ls]
    du = nrm[:, :, None] * dbeta[:, None, :]
    dn = -u[:, :, None] * dbeta[:, None, :]
    r1 = P[:, i] - P[:, b]
    dr1 = dP[:, i] - dP[:, b]
    # vC = W + vB + sd u with W = vG - e wg u + s wg n - vB, sd = -r1 . W / (r1 . u)
    W = V[:, gp] - (e * wg)[:, None] * u + (s * wg)[:, None] * nrm - V[:, b]
    # dW = dvG - u (de wg + e dwg) - e wg du + n (ds wg + s dwg) + s wg dn - dvB
    de_wg = wg[:, None] * eye[je][None, :] + e[:, None] * dOM[:, gl, :]
    ds_wg = wg[:, None] * dQ[:, var, :] + s[:, None] * dOM[:, gl, :]
    dW = (dV[:, gp] - u[:, :, None] * de_wg[:, None, :] - (e * wg)[:, None, None] * du
          + nrm[:, :, None] * ds_wg[:, None, :] + (s * wg)[:, None, None] * dn - dV[:, b])
    ru = np.sum(r1 * u, axis=1)
    rW = np.sum(r1 * W, axis=1)
    dsd = (-(_dot(W, dr1) + _dot(r1, dW)) / ru[:, None]
           + (rW / ru ** 2)[:, None] * (_dot(u, dr1) + _dot(r1, du)))
    dV[:, i] = dW + dV[:, b] + u[:, :, None] * dsd[:, None, :] + sd[:, None, None] * du
    dQD[:, var, :] = dsd
    dOM[:, Ls, :] = dOM[:, gl, :]
    vrel = V[:, i] - V[:, b]
    dOM[:, L1, :] = ((_cross_tv(dr1, vrel) + _cross(r1, dV[:, i] - dV[:, b])) / (l * l)[:, None]
                     - (2.0 * OM[:, L1] / l)[:, None] * eye[jl][None, :])


def _rpr_rates(row, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, par, eye) -> None:
    b, pv, L, Lb, je, _, var = row[1:8]
    th = TH[:, L]
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    nrm = _rot90v(u)
    s, e, w = Q[:, var], par[:, je], OM[:, L]
    dth = dTH[:, L]
    du = nrm[:, :, None] * dth[:, None, :]
    dn = -u[:, :, None] * dth[:, None, :]
    dv = V[:, b] - V[:, pv]
    ddv = dV[:, b] - dV[:, pv]
    # vB - vA = (sd - e w) u + s w n: w = n . dv / s, sd = u . dv + e w
    dw = (_dot(dv, dn) + _dot(nrm, ddv)) / s[:, None] - (w / s)[:, None] * dQ[:, var, :]
    dsd = _dot(dv, du) + _dot(u, ddv) + w[:, None] * eye[je][None, :] + e[:, None] * dw
    dOM[:, L, :] = dw
    if Lb >= 0:
        dOM[:, Lb, :] = dw
    dQD[:, var, :] = dsd





# ---- the accelerations' derivatives --------------------------------------------------------------


def _accels(machine: Machine, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, par,
            eye, prog):
    """Derivatives of the accelerations (mm/s^2), angular accelerations (rad/s^2) and joint
    accelerations by every parameter: each unit's acceleration relation differentiated with the
    position and rate tangents known. Returns dA, dEP, dQDD."""
    dA = np.zeros_like(dP)
    dEP = np.zeros_like(dTH)
    dQDD = np.zeros_like(dQ)
    for row in prog:
        op = row[0]
        if op == OP_CRANK:
            L, jra, jset = row[1], row[3], row[4]
            if jset < 0:  # epsilon = ratio * epsilon_shaft
                dEP[:, L, :] = (EP[:, L] / par[:, jra])[:, None] * eye[jra][None, :]
        elif op == OP_POINT:
            i, L, o = row[1], row[2], row[3]
            rel = P[:, i] - P[:, o]
            drel = dP[:, i] - dP[:, o]
            w, e = OM[:, L], EP[:, L]
            # a = aO + eps J rel - w^2 rel
            dA[:, i] = (dA[:, o] + _rot90v(rel)[:, :, None] * dEP[:, L, None, :]
                        + e[:, None, None] * _rot90t(drel)
                        - (2.0 * w)[:, None, None] * rel[:, :, None] * dOM[:, L, None, :]
                        - (w * w)[:, None, None] * drel)
        elif op == OP_RRR:
            i1, i2, i, L1, L2, j1, j2 = row[1], row[2], row[3], row[4], row[5], row[6], row[7]
            r1, r2 = P[:, i] - P[:, i1], P[:, i] - P[:, i2]
            dr1, dr2 = dP[:, i] - dP[:, i1], dP[:, i] - dP[:, i2]
            w1, w2 = V[:, i] - V[:, i1], V[:, i] - V[:, i2]
            dw1, dw2 = dV[:, i] - dV[:, i1], dV[:, i] - dV[:, i2]
            b1, b2 = A[:, i] - A[:, i1], A[:, i] - A[:, i2]
            # r_k . (aC - a_k) + |w_k|^2 = 0
            rhs1 = _dot(r1, dA[:, i1]) - _dot(b1, dr1) - 2.0 * _dot(w1, dw1)
            rhs2 = _dot(r2, dA[:, i2]) - _dot(b2, dr2) - 2.0 * _dot(w2, dw2)
            det = r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]
            dA[:, i, 0, :] = (rhs1 * r2[:, 1, None] - rhs2 * r1[:, 1, None]) / det[:, None]
            dA[:, i, 1, :] = (r1[:, 0, None] * rhs2 - r2[:, 0, None] * rhs1) / det[:, None]
            for L, r, dr, bk, k, j in ((L1, r1, dr1, b1, i1, j1), (L2, r2, dr2, b2, i2, j2)):
                ll = par[:, j]
                dEP[:, L, :] = ((_cross_tv(dr, bk) + _cross(r, dA[:, i] - dA[:, k]))
                                / (ll * ll)[:, None]
                                - (2.0 * EP[:, L] / ll)[:, None] * eye[j][None, :])
        elif op == OP_RRP:
            _rrp_accels(row, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, dA,
                        dEP, dQDD, par, eye)
        elif op == OP_RPR:
            _rpr_accels(row, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, dA,
                        dEP, dQDD, par, eye)
        elif op == OP_LOOP:
            _loop(machine, row[1], 2, _State(P, TH, Q, dP, dTH, dQ, V, OM, QD, dV, dOM, dQD,
                                             A, EP, QDD, dA, dEP, dQDD), par, eye)
    return dA, dEP, dQDD


def _rrp_accels(row, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, dA, dEP, dQDD,
                par, eye) -> None:
    b, gp, gl, i, L1, Ls, jl, _, je, _, var = row[1:12]
    beta = TH[:, Ls]
    u = np.stack([np.cos(beta), np.sin(beta)], axis=-1)
    nrm = _rot90v(u)
    s, sd, sdd = Q[:, var], QD[:, var], QDD[:, var]
    e, l = par[:, je], par[:, jl]
    wg, eg = OM[:, gl], EP[:, gl]
    dbeta = dTH[:, Ls]
    du = nrm[:, :, None] * dbeta[:, None, :]
    dn = -u[:, :, None] * dbeta[:, None, :]
    ds, dsd = dQ[:, var, :], dQD[:, var, :]
    dwg, deg_ = dOM[:, gl, :], dEP[:, gl, :]
    de = eye[je][None, :]

    # aC = K + aB + sdd u with K = aG - e (eg u + wg^2 n) + 2 sd wg n + s (eg n - wg^2 u) - aB
    K = (A[:, gp] - e[:, None] * (eg[:, None] * u + (wg * wg)[:, None] * nrm)
         + (2.0 * sd * wg)[:, None] * nrm + s[:, None] * (eg[:, None] * nrm
                                                           - (wg * wg)[:, None] * u) - A[:, b])
    dK = (dA[:, gp]
          - (eg[:, None] * u + (wg * wg)[:, None] * nrm)[:, :, None] * de[:, None, :]
          - e[:, None, None] * (u[:, :, None] * deg_[:, None, :] + eg[:, None, None] * du
                                + (2.0 * wg)[:, None, None] * nrm[:, :, None] * dwg[:, None, :]
                                + (wg * wg)[:, None, None] * dn)
          + 2.0 * (nrm[:, :, None] * (dsd * wg[:, None] + sd[:, None] * dwg)[:, None, :]
                   + (sd * wg)[:, None, None] * dn)
          + (eg[:, None] * nrm - (wg * wg)[:, None] * u)[:, :, None] * ds[:, None, :]
          + s[:, None, None] * (nrm[:, :, None] * deg_[:, None, :] + eg[:, None, None] * dn
                                - (2.0 * wg)[:, None, None] * u[:, :, None] * dwg[:, None, :]
                                - (wg * wg)[:, None, None] * du)
          - dA[:, b])
    r1 = P[:, i] - P[:, b]
    dr1 = dP[:, i] - dP[:, b]
    w = V[:, i] - V[:, b]
    dw = dV[:, i] - dV[:, b]
    ru = np.sum(r1 * u, axis=1)
    num = np.sum(r1 * K, axis=1) + np.sum(w * w, axis=1)
    dsdd = (-(_dot(K, dr1) + _dot(r1, dK) + 2.0 * _dot(w, dw)) / ru[:, None]
            + (num / ru ** 2)[:, None] * (_dot(u, dr1) + _dot(r1, du)))
    dA[:, i] = dK + dA[:, b] + u[:, :, None] * dsdd[:, None, :] + sdd[:, None, None] * du
    dQDD[:, var, :] = dsdd
    dEP[:, Ls, :] = deg_
    arel = A[:, i] - A[:, b]
    dEP[:, L1, :] = ((_cross_tv(dr1, arel) + _cross(r1, dA[:, i] - dA[:, b])) / (l * l)[:, None]
                     - (2.0 * EP[:, L1] / l)[:, None] * eye[jl][None, :])


def _rpr_accels(row, A, EP, QDD, V, OM, QD, P, TH, Q, dP, dTH, dQ, dV, dOM, dQD, dA, dEP, dQDD,
                par, eye) -> None:
    b, pv, L, Lb, je, _, var = row[1:8]
    th = TH[:, L]
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    nrm = _rot90v(u)
    s, sd = Q[:, var], QD[:, var]
    e, w, ep = par[:, je], OM[:, L], EP[:, L]
    dth = dTH[:, L]
    du = nrm[:, :, None] * dth[:, None, :]
    dn = -u[:, :, None] * dth[:, None, :]
    da = A[:, b] - A[:, pv]
    dda = dA[:, b] - dA[:, pv]
    ds, dsd, dw = dQ[:, var, :], dQD[:, var, :], dOM[:, L, :]
    de = eye[je][None, :]
    # aB - aA = (sdd - e eps - s w^2) u + (2 sd w - e w^2 + s eps) n
    dep = ((_dot(da, dn) + _dot(nrm, dda) - 2.0 * (dsd * w[:, None] + sd[:, None] * dw)
            + de * (w * w)[:, None] + (2.0 * e * w)[:, None] * dw) / s[:, None]
           - (ep / s)[:, None] * ds)
    dsdd = (_dot(da, du) + _dot(u, dda) + de * ep[:, None] + e[:, None] * dep
            + ds * (w * w)[:, None] + (2.0 * s * w)[:, None] * dw)
    dEP[:, L, :] = dep
    if Lb >= 0:
        dEP[:, Lb, :] = dep
    dQDD[:, var, :] = dsdd


# ---- loop units: one closure, three levels -------------------------------------------------------


@dataclass
class _State:
    """The solved state (positions; rates; accelerations) and their tangents so far, shared by
    the loop levels (a level reads those up to its own and writes its own)."""

    P: np.ndarray
    TH: np.ndarray
    Q: np.ndarray
    dP: np.ndarray
    dTH: np.ndarray
    dQ: np.ndarray
    V: np.ndarray | None = None
    OM: np.ndarray | None = None
    QD: np.ndarray | None = None
    dV: np.ndarray | None = None
    dOM: np.ndarray | None = None
    dQD: np.ndarray | None = None
    A: np.ndarray | None = None
    EP: np.ndarray | None = None
    QDD: np.ndarray | None = None
    dA: np.ndarray | None = None
    dEP: np.ndarray | None = None
    dQDD: np.ndarray | None = None


def _loop(machine: Machine, g: int, level: int, st: _State, par, eye) -> None:
    """A loop's closure sum_t sign T_t = 0 differentiated by the parameters at ``level`` (0: the
    positions, 1: the rates, 2: the accelerations): J d(q, q_dot or q_ddot) = -(every part
    already known), J the position Jacobian at every level (the unknowns enter each level's
    closure linearly with the same coefficients)."""
    grp, unk, terms = machine.groups, machine.unknowns, machine.terms
    nq, u0, _, t0, nt = grp[g]
    n, npar = st.P.shape[0], eye.shape[0]
    rows = np.arange(n)
    J = np.zeros((n, nq, nq))
    rhs = np.zeros((n, nq, npar))
    dpoint = (st.dP, st.dV, st.dA)[level]
    for t in range(t0, t0 + nt):
        typ, lrow, sign, len_src, len_idx, ang_src, ang_idx, jalpha, cam, joff, lc, ac = terms[t]
        row = 2 * lrow
        if typ == TERM_POINT:
            rhs[:, row:row + 2, :] -= sign * dpoint[:, len_idx]
            continue
        link = ang_src == SRC_LINK
        # the term's angle psi and its rates, values and tangents; the unknown's own tangent at
        # this level is 0 here (it is J's column)
        ang = [(st.TH, st.OM, st.EP), (st.Q, st.QD, st.QDD)][0 if link else 1]
        dang = [(st.dTH, st.dOM, st.dEP), (st.dQ, st.dQD, st.dQDD)][0 if link else 1]
        psi = ang[0][:, ang_idx] + (par[:, jalpha] if jalpha >= 0 else 0.0)
        rate = [np.zeros(n) if a is None else a[:, ang_idx] for a in ang[1:]]
        dalpha = eye[jalpha][None, :] if jalpha >= 0 else 0.0
        dpsi = []
        for k in range(3):
            own = 0.0 if k > level or (k == level and ac >= 0) else dang[k][:, ang_idx]
            dpsi.append(own + dalpha if k == 0 else own)
        e = np.stack([np.cos(psi), np.sin(psi)], axis=-1)
        E, IE = e[:, :, None], _rot90v(e)[:, :, None]
        if typ == TERM_VEC:
            if len_src == SRC_PARAM:
                Ls = [par[:, len_idx], np.zeros(n), np.zeros(n)]
                dLs = [eye[len_idx][None, :], 0.0, 0.0]
            else:
                vals = (st.Q, st.QD, st.QDD)
                tans = (st.dQ, st.dQD, st.dQDD)
                Ls = [np.zeros(n) if vals[k] is None else vals[k][:, len_idx] for k in range(3)]
                dLs = [0.0 if (k == level and lc >= 0) or tans[k] is None
                       else tans[k][:, len_idx] for k in range(3)]
            if lc >= 0:
                J[:, row:row + 2, lc] += sign * e
            if ac >= 0:
                J[:, row:row + 2, ac] += sign * Ls[0][:, None] * _rot90v(e)
            known = _vec_known(level, E, IE, Ls, dLs, rate, dpsi)
        else:
            cl, cp, a0, na = machine.cams[cam]
            tc = st.TH[:, cl]
            k = _active_arc(machine, par, cl, a0, na, psi - tc)
            jcx, jcy, jR = (machine.arcs[k, c] for c in range(3))
            cx, cy = par[rows, jcx], par[rows, jcy]
            R = par[rows, jR] + (par[:, joff] if joff >= 0 else 0.0)
            cc, cs = np.cos(tc), np.sin(tc)
            rc = np.stack([cc * cx - cs * cy, cs * cx + cc * cy], axis=-1)
            dcx, dcy = eye[jcx], eye[jcy]
            dR = eye[jR] + (eye[joff] if joff >= 0 else 0.0)
            rot_dc = np.stack([cc[:, None] * dcx - cs[:, None] * dcy,
                               cs[:, None] * dcx + cc[:, None] * dcy], axis=1)
            drc = _rot90v(rc)[:, :, None] * st.dTH[:, cl, None, :] + rot_dc
            if ac >= 0:
                J[:, row:row + 2, ac] += sign * R[:, None] * _rot90v(e)
            known = _cam_known(level, st, cl, cp, rc, drc, R, dR, E, IE, rate, dpsi)
        rhs[:, row:row + 2, :] -= sign * known
    sol = np.linalg.inv(J) @ rhs  # (n, nq, npar): one small inverse per position
    out = [(st.dTH, st.dQ), (st.dOM, st.dQD), (st.dEP, st.dQDD)][level]
    for j in range(nq):
        kind, idx = unk[u0 + j, 0], unk[u0 + j, 1]
        out[0 if kind == 0 else 1][:, idx, :] = sol[:, j, :]


def _vec_known(level, E, IE, Ls, dLs, rate, dpsi):
    """The known part of d(T), d(T_dot) or d(T_ddot) of a term T = L e^{i psi}: T_dot =
    L_dot e + L psi_dot ie, T_ddot = L_ddot e + 2 L_dot psi_dot ie + L psi_ddot ie - L psi_dot^2
    e (the unknown's part, its column of J, is 0 in ``dLs``/``dpsi``)."""
    L, Ld, Ldd = (x[:, None, None] for x in Ls)
    dL, dLd, dLdd = (_rows(x) for x in dLs)
    w, a = (x[:, None, None] for x in rate)
    p0, p1, p2 = (_rows(x) for x in dpsi)
    if level == 0:
        return E * dL + L * IE * p0
    if level == 1:
        return E * dLd + Ld * IE * p0 + w * IE * dL + L * IE * p1 - L * w * E * p0
    return (E * dLdd + Ldd * IE * p0 + 2.0 * IE * (dLd * w + Ld * p1) - 2.0 * Ld * w * E * p0
            + IE * (dL * a + L * p2) - L * a * E * p0 - E * (dL * w * w + 2.0 * L * w * p1)
            - L * w * w * IE * p0)


def _cam_known(level, st, cl, cp, rc, drc, R, dR, E, IE, rate, dpsi):
    """The known part of d(T), d(T_dot) or d(T_ddot) of a cam contact T = p_cp + R(theta_c) c
    + R e^{i psi}: T_dot = v_cp + w_c J rc + R psi_dot ie, T_ddot = a_cp + eps_c J rc - w_c^2 rc
    + R (psi_ddot ie - psi_dot^2 e)."""
    Rr, dRr = R[:, None, None], dR[:, None, :]
    w, a = (x[:, None, None] for x in rate)
    p0, p1, p2 = (_rows(x) for x in dpsi)
    Jrc = _rot90v(rc)[:, :, None]
    if level == 0:
        return st.dP[:, cp] + drc + E * dRr + Rr * IE * p0
    wc = st.OM[:, cl][:, None, None]
    if level == 1:
        return (st.dV[:, cp] + Jrc * st.dOM[:, cl, None, :] + wc * _rot90t(drc)
                + w * IE * dRr + Rr * IE * p1 - Rr * w * E * p0)
    ec = st.EP[:, cl][:, None, None]
    return (st.dA[:, cp] + Jrc * st.dEP[:, cl, None, :] + ec * _rot90t(drc)
            - 2.0 * wc * rc[:, :, None] * st.dOM[:, cl, None, :] - wc * wc * drc
            + (a * IE - w * w * E) * dRr
            + Rr * (IE * p2 - a * E * p0 - 2.0 * w * E * p1 - w * w * IE * p0))

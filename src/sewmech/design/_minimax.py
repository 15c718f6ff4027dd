"""Minimising the peaks of the balancing quantities over a turn (the solvers behind
:func:`sewmech.design.balancing.balance`).

A problem is a weighted sum of parts, each ``(kind, quantity keys, weight)``: the peak of a
vector's length over the turn (``"vector"``: the shaking force, the bearing reactions), of a
scalar's magnitude (``"abs"``: the shaking moment), a scalar's range max - min (``"range"``: the
driving torque) or a vector's RMS (``"rms"``). The quantities come from a balancing basis
(:class:`sewmech.design.balancing.BalanceBasis`): linear in the counterweights' static-moment
components where the S terms vanish, smooth in each counterweight's (S, beta) where they do not.

- :func:`_cutting_planes`: Kelley's method, a linear programme (HiGHS) per step over the cuts
  so far; its value bounds the optimum from below, the exact value at its answer from above.
- :func:`_polar_slsqp`: SLSQP on the epigraph form in polar coordinates, exact gradients,
  several starts, near-active constraints exchanged in.
- :func:`_minimise` chooses between them by the strength of the S terms (:func:`_s_terms`).

Every function takes the basis as ``B`` and reads only its arrays and
:meth:`~sewmech.design.balancing.BalanceBasis.quantities` (so this module does not import the
one that calls it). Units: static moments kg mm; forces N; moments and torques N m in the
programmes (N mm in the basis).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..engine.errors import AnalysisError


def _linear(B, key: str, xy0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quantity ``key`` as c + L @ z, its first-order expansion at static moments ``xy0``
    (n, 2) in z = (x_1, y_1, ..., x_n, y_n): exact where the S terms vanish, and along the ray
    through xy0 (S is homogeneous of degree 1). Moments and torques in N m. Returns
    (c (n_phi, k), L (n_phi, k, 2n))."""
    r = B.resp[key]  # (n, 4, n_phi[, 2])
    base = B.base[key]
    shape = base.shape if base.ndim == 2 else base.shape + (1,)
    unit = 1e-3 if key in ("M", "T") else 1.0
    n = len(B.counterweights)
    L = np.zeros(shape + (2 * n,))
    for i in range(n):
        x, y = xy0[i]
        s = math.hypot(x, y)
        E = (r[i, 0] / B.radius[i] + B.radius[i] * r[i, 3]).reshape(shape)
        ux, uy = (x / s, y / s) if s > 0 else (0.0, 0.0)  # the gradient of S at xy0
        L[..., 2 * i] = r[i, 1].reshape(shape) + ux * E
        L[..., 2 * i + 1] = r[i, 2].reshape(shape) + uy * E
    return unit * base.reshape(shape), unit * L


def _s_terms(B, keys: Sequence[str]) -> float:
    """How strong the S terms of the quantities ``keys`` are against their linear terms (the
    largest ratio of their peaks; 0 when they vanish to round-off): where they do not vanish
    the problems are not linear in the static moments' components."""
    out = 0.0
    for key in keys:
        r = B.resp[key]
        # what counts as nothing: round-off of the quantity itself per kg mm of static moment
        # (the shaking moment about the shaft's axis does not see a counterweight on the shaft)
        floor = 1e-12 * max(float(np.abs(B.base[key]).max()), float(np.abs(r[:, 1:3]).max()))
        for i in range(len(B.counterweights)):
            lin = max(float(np.abs(r[i, 1:3]).max()), floor, 1e-300)
            E = float(np.abs(r[i, 0] / B.radius[i] + B.radius[i] * r[i, 3]).max())
            if E > max(1e-9 * lin, floor):
                out = max(out, E / lin)
    return out


def _minimise(B, parts, xy0: np.ndarray, what: str
              ) -> tuple[np.ndarray, str, str]:
    """Minimise sum_i w_i f_i (see :func:`_cutting_planes`) from ``xy0``: exactly by cutting
    planes where the quantities have no S terms, else by SLSQP in polar coordinates."""
    if _objective(B.quantities, parts, B.start.reshape(-1)) <= 1e-12:
        return B.start.copy(), "optimal", f"{what}: 0 with the counterweights as they are"
    strength = _s_terms(B, [k for _, keys, _ in parts for k in keys])
    if strength == 0.0:  # convex: cutting planes, certified by their lower bound
        info: dict = {}
        xy, status, message = _cutting_planes(B, parts, xy0, what, max_iter=30, info=info)
        if status == "optimal":
            return xy, status, message
        # Kelley's tail is slow where a peak is flat: SLSQP finishes from its best answer (a
        # local optimum of a convex problem is the optimum), the bound says how close it is
        xy, status, message = _polar_slsqp(B, parts, [xy], what, exchange=True)
        gap = _objective(B.quantities, parts, xy.reshape(-1)) - info["lower"]
        return xy, status, (f"{what}: cutting planes ({info['iterations']} linear programmes)"
                            f" then SLSQP; within {gap:.2g} of the programmes' lower bound")
    if strength < 0.05:  # nearly linear (weights against inertia forces): the expansion's
        near, _, _ = _cutting_planes(B, parts, xy0, what, max_iter=3, at=xy0)  # optimum
        return _polar_slsqp(B, parts, [near], what, exchange=True)  # starts the exact one
    return _polar_slsqp(B, parts, [xy0, B.start], what, turns=True)


def _polar(B, key: str, sb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quantity ``key`` (N, or N m for moments and torques) at static moments and angles
    ``sb`` = (S_1, beta_1, ..., S_n, beta_n) and its derivatives by them: (n_phi, k) and
    (n_phi, k, 2n)."""
    r = B.resp[key]
    base = B.base[key]
    shape = base.shape if base.ndim == 2 else base.shape + (1,)
    unit = 1e-3 if key in ("M", "T") else 1.0
    n = len(B.counterweights)
    Q = base.reshape(shape).copy()
    D = np.zeros(shape + (2 * n,))
    for i in range(n):
        S, b = sb[2 * i], sb[2 * i + 1]
        c, s = math.cos(b), math.sin(b)
        R0, R1, R2, R3 = (r[i, j].reshape(shape) for j in range(4))
        dS = R0 / B.radius[i] + c * R1 + s * R2 + B.radius[i] * R3
        Q += S * dS
        D[..., 2 * i] = dS
        D[..., 2 * i + 1] = S * (c * R2 - s * R1)
    return unit * Q, unit * D


def _polar_slsqp(B, parts, firsts: Sequence[np.ndarray], what: str,
                 turns: bool = False, exchange: bool = False) -> tuple[np.ndarray, str, str]:
    """Minimise sum_i w_i f_i where S terms make the quantities nonlinear in the static
    moments' components: each quantity is smooth in (S, beta) per counterweight, so SLSQP
    solves the epigraph form (a bound t_i on each peak, t_i^2 >= |Q|^2 at every angle for a
    vector, t_i >= +-Q for a scalar) with exact gradients, 0 <= S <= max_static_moment. The
    problem is not convex: it starts from each of ``firsts`` (n, 2) and, with ``turns``, from
    the first turned by 90, 180 and 270 degrees, each counterweight in turn, and keeps the best
    local optimum. With ``exchange`` (for a start near the answer) SLSQP sees only the
    constraints near their bounds, within a box of four times the starts' static moments, and
    an answer that breaks another constraint adds it (:func:`_minimise`)."""
    from scipy.optimize import minimize

    n = len(B.counterweights)
    nz = 2 * n
    slots, nv = [], nz
    for kind, _, _ in parts:
        k = {"range": 2, "rms": 0}.get(kind, 1)
        slots.append(list(range(nv, nv + k)))
        nv += k

    memo = {}

    def split(v):  # the objective, constraints and Jacobian at one point share it
        key = v[:nz].tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = {k: _polar(B, k, v[:nz]) for _, keys, _ in parts for k in keys}
        return memo[key]

    def objective(v):  # in units of its value at the first start
        f, g = 0.0, np.zeros(nv)
        q = split(v)
        for (kind, keys, w), sl in zip(parts, slots):
            if kind == "rms":
                Q, D = q[keys[0]]
                val = math.sqrt(float(np.mean(np.sum(Q * Q, axis=-1))))
                f += w * val
                if val > 0:
                    g[:nz] += w * np.einsum("pk,pkz->z", Q, D) / (len(Q) * val)
            else:
                f += w * v[sl[0]]
                g[sl[0]] += w
                if kind == "range":
                    f -= w * v[sl[1]]
                    g[sl[1]] -= w
        return f / unit_f[0], g / unit_f[0]

    # the constraints in units of each peak at the first start: SLSQP's steps and tolerances
    # then mean the same for a force of 50 N and a moment of 0.5 N m
    unit = np.ones(len(parts))
    unit_f = [1.0]

    def cons_all(v):
        q = split(v)
        out = []
        for (kind, keys, _), sl, un in zip(parts, slots, unit):
            for k in keys:
                Q = q[k][0] / un
                if kind == "vector":
                    out.append((v[sl[0]] / un) ** 2 - np.sum(Q * Q, axis=-1))
                elif kind == "abs":
                    out += [v[sl[0]] / un - Q[:, 0], v[sl[0]] / un + Q[:, 0]]
                elif kind == "range":
                    out += [v[sl[0]] / un - Q[:, 0], Q[:, 0] - v[sl[1]] / un]
        return np.concatenate(out) if out else np.zeros(0)

    def cons_jac_all(v):
        q = split(v)
        rows = []
        for (kind, keys, _), sl, un in zip(parts, slots, unit):
            for k in keys:
                Q, D = q[k]
                if kind == "vector":
                    J = np.zeros((len(Q), nv))
                    J[:, :nz] = -2.0 * np.einsum("pk,pkz->pz", Q, D) / un ** 2
                    J[:, sl[0]] = 2.0 * v[sl[0]] / un ** 2
                    rows.append(J)
                elif kind in ("abs", "range"):
                    for sgn, col in ((-1.0, sl[0]), (1.0, sl[-1])):
                        J = np.zeros((len(Q), nv))
                        J[:, :nz] = sgn * D[:, 0] / un
                        J[:, col] = (-sgn if kind == "range" else 1.0) / un
                        rows.append(J)
        return np.vstack(rows) if rows else np.zeros((0, nv))

    # SLSQP's subproblem grows with the constraints (one per angle and bound); with exchange it
    # sees those near their bound (the peaks' neighbourhoods), and an answer that breaks
    # another adds it and goes on from there (the answer holds every constraint)
    keep = [np.zeros(0, dtype=bool)]

    def cons(v):
        return cons_all(v)[keep[0]]

    def cons_jac(v):
        return cons_jac_all(v)[keep[0]]

    def polar(xy):
        return np.column_stack([np.hypot(xy[:, 0], xy[:, 1]),
                                np.arctan2(xy[:, 1], xy[:, 0])]).reshape(-1)

    # a scale of static moments: the starts' or the natural one
    scale = max(max(float(np.abs(f).max()) for f in firsts), _natural(B))
    # (S_1, beta_1, ...) of each start; a static moment of 0 turned is no new start, so the
    # turned ones get at least a tenth of the largest
    starts = [polar(np.asarray(f, dtype=float)) for f in firsts]
    for i in range(n if turns else 0):
        for turn in (0.5, 1.0, 1.5):
            p = starts[0].copy()
            p[2 * i] = max(p[2 * i], 0.1 * scale)
            p[2 * i + 1] += turn * math.pi
            starts.append(p)
    box = 4.0 * scale if exchange else np.inf
    bounds = [b for i in range(n) for b in ((0.0, min(B.s_max[i], box) if
                                             math.isfinite(min(B.s_max[i], box)) else None),
                                            (None, None))]
    bounds += [(None, None)] * (nv - nz)
    results, tried = [], 0
    for p in starts:
        p = p.copy()
        p[0:nz:2] = np.minimum(p[0:nz:2], B.s_max)
        v0 = np.concatenate([p, np.zeros(nv - nz)])
        q = split(v0)
        for (kind, keys, _), sl in zip(parts, slots):  # start each bound where it holds
            if kind == "vector":
                v0[sl[0]] = max(float(np.hypot(q[k][0][:, 0], q[k][0][:, 1]).max())
                                for k in keys)
            elif kind == "abs":
                v0[sl[0]] = float(np.abs(q[keys[0]][0]).max())
            elif kind == "range":
                v0[sl[0]], v0[sl[1]] = float(q[keys[0]][0].max()), float(q[keys[0]][0].min())
        if not tried:
            for j, ((kind, _, _), sl) in enumerate(zip(parts, slots)):
                if kind != "rms":
                    unit[j] = max(abs(v0[sl[0]]), abs(v0[sl[-1]]), 1e-9)
            unit_f[0] = max(objective(v0)[0], 1e-12)
        keep[0] = cons_all(v0) <= (0.5 if exchange else np.inf)
        for _ in range(20):
            res = minimize(objective, v0, jac=True, method="SLSQP", bounds=bounds,
                           constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}]
                           if nv > nz else [], options={"maxiter": 500, "ftol": 1e-12})
            full = cons_all(res.x)
            broken = full < -1e-10
            if not broken[~keep[0]].any():
                break
            keep[0] = keep[0] | broken | (full <= 0.5)
            v0 = res.x
        tried += 1
        sb = res.x[:nz]
        if exchange and np.any((sb[0::2] >= box * (1 - 1e-9)) & (B.s_max > box)):
            return _polar_slsqp(B, parts, firsts, what, turns)  # the box binds: without it
        xy = np.column_stack([sb[0::2] * np.cos(sb[1::2]), sb[0::2] * np.sin(sb[1::2])])
        results.append((_objective(B.quantities, parts, xy.reshape(-1)), bool(res.success), xy))
    best = min(results, key=lambda r: r[0])
    # optimal when a start that converged reached the best value (others may stop a hair
    # lower with "positive directional derivative": the line search found no more descent)
    tol = 1e-9 * max(abs(best[0]), 1e-12)
    ok = [r for r in results if r[1]]
    status = "optimal" if any(r[0] <= best[0] + tol for r in ok) else "not converged"
    how = (f"{what}: SLSQP on the exact basis in polar coordinates (the S terms make it"
           f" nonlinear), best local optimum of {tried} starts ({len(ok)} converged)")
    return best[2], status, how


def _worst(excess: np.ndarray, eps: float, most: int = 8) -> np.ndarray:
    """Where a periodic curve ``excess`` over the turn is above ``eps``: its local maxima there,
    at most ``most`` of them, the largest first (cuts at the peaks of what a programme
    underestimates keep it small, and the neighbours follow if they must)."""
    over = excess > eps
    if not over.any():
        return np.zeros(0, dtype=np.int64)
    peak = over & (excess >= np.roll(excess, 1)) & (excess >= np.roll(excess, -1))
    idx = np.nonzero(peak)[0]
    if idx.size == 0:
        idx = np.nonzero(over)[0]
    return idx[np.argsort(excess[idx])[::-1][:most]]


def _natural(B) -> float:
    """A scale of static moments, kg mm: the one whose inertia force at the basis' speed is the
    machine's peak shaking force as the file has it (F = S w^2 with S in kg mm, F in N:
    S = 1e3 F / w^2)."""
    w = 2.0 * math.pi * B.rpm / 60.0
    F = B.quantities(B.start)["F"]
    peak = float(np.hypot(F[:, 0], F[:, 1]).max())
    return max(1e3 * peak / w ** 2, 1e-6)


#: HiGHS's feasibility tolerances, tighter than its defaults (1e-7): the programmes' values are
#: the lower bounds that certify an answer to 1e-9 of the criterion
_HIGHS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}


def _within_limits(B, xy: np.ndarray) -> np.ndarray:
    """Static moments ``xy`` (batch + (n, 2)) with each one beyond its limit scaled back onto
    it."""
    s = np.hypot(xy[..., 0], xy[..., 1])
    f = np.where(s > B.s_max, B.s_max / np.maximum(s, 1e-300), 1.0)
    return xy * f[..., None]


def _cutting_planes(B, parts, xy0: np.ndarray, what: str,
                    tol: float = 1e-9, max_iter: int = 300, at: np.ndarray | None = None,
                    info: dict | None = None) -> tuple[np.ndarray, str, str]:
    """Minimise sum_i w_i f_i(z) by cutting planes (Kelley's method): each f_i is a peak over
    the turn of a vector's length (``"vector"``), of a scalar's magnitude (``"abs"``), a range
    max - min (``"range"``) or an RMS (``"rms"``), each convex in the static moments'
    components z where the S terms vanish. Every step is a linear programme (HiGHS) over the
    cuts so far; its value is a lower bound and the exact objective at its answer an upper
    bound, and the method stops when they meet (to ``tol``). Cuts: for a vector, its direction
    at the angles where the programme underestimates it; for an RMS, its tangent plane; for a
    limited counterweight, the direction of a static moment beyond the limit. Only for
    quantities without S terms (:func:`_s_terms`); :func:`_polar_slsqp` solves the others.

    With ``at`` (n, 2) it minimises the first-order expansion at ``at`` instead (for weak S
    terms, see :func:`_minimise`). ``info``, if given, receives the last lower bound
    (``"lower"``) and the number of programmes (``"iterations"``).

    parts: (kind, quantity keys, weight) each. Returns (xy, status, message)."""
    from scipy.optimize import linprog

    lin = {k: _linear(B, k, xy0 if at is None else at) for _, keys, _ in parts for k in keys}
    qf = B.quantities if at is None else _expansion(lin)  # exact without S terms
    n = len(B.counterweights)
    nz = 2 * n
    slots, nv = [], nz
    for kind, _, _ in parts:
        slots.append(list(range(nv, nv + (2 if kind == "range" else 1))))
        nv += len(slots[-1])
    cost = np.zeros(nv)
    for (kind, _, w), sl in zip(parts, slots):
        cost[sl[0]] = w
        if kind == "range":
            cost[sl[1]] = -w
    ring = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    cuts = {}  # vector key -> (angle indices, directions): the vector's at the start
    q0 = qf(xy0)
    for kind, keys, _ in parts:
        if kind == "vector":
            for k in keys:
                # the angles near the peak to begin with: the programme stays small, and an
                # angle it underestimates later gets its cut then
                mag = np.maximum(np.hypot(q0[k][:, 0], q0[k][:, 1]), 1e-300)
                near = np.nonzero(mag >= 0.5 * mag.max())[0]
                cuts[k] = (near, q0[k][near] / mag[near, None])
    tangents: list[tuple[np.ndarray, float, np.ndarray]] = []  # rms: (z_j, f_j, gradient)
    limited = [i for i in range(n) if math.isfinite(B.s_max[i])]
    limit_dirs = {i: ring.copy() for i in limited}
    # a box that keeps the first programmes bounded; an answer on it widens it
    box = 4.0 * max(float(np.abs(xy0).max()), float(np.abs(B.start).max()), _natural(B))
    z = _within_limits(B, xy0).reshape(-1)
    exact = _objective(qf, parts, z)
    best = (exact, z.copy())
    # a scalar's rows (its magnitude's, its range's two sides): the angles near its extremes to
    # begin with; one the programme breaks later is added then
    rows_at = {}
    for kind, keys, _ in parts:
        if kind in ("abs", "range"):
            c, L = lin[keys[0]]
            val = c[:, 0] + L[:, 0] @ z
            if kind == "abs":
                m = float(np.abs(val).max())
                up, down = val >= 0.5 * m, -val >= 0.5 * m
            else:
                half = 0.5 * float(np.ptp(val))
                up, down = val >= val.max() - half, val <= val.min() + half
            up[np.argmax(val)] = down[np.argmin(val)] = True
            rows_at[keys[0], 1.0], rows_at[keys[0], -1.0] = np.nonzero(up)[0], \
                np.nonzero(down)[0]
    # the gap that counts as closed: relative, with a floor for a criterion already ~0
    floor = 1e-12 * max(_objective(qf, parts, B.start.reshape(-1)), exact, 1e-3)
    lower = -np.inf
    status, it = "not converged", 0
    for it in range(1, max_iter + 1):
        if any(kind == "rms" for kind, _, _ in parts):
            f, g = _rms_and_gradient(lin["F"], z)
            tangents.append((z.copy(), f, g))
        rows, rhs = [], []
        for (kind, keys, _), sl in zip(parts, slots):
            for k in keys:
                c, L = lin[k]
                if kind == "vector":
                    P, D = cuts[k]
                    A = np.zeros((len(P), nv))
                    A[:, :nz] = np.einsum("mk,mkz->mz", D, L[P])
                    A[:, sl[0]] = -1.0
                    rows.append(A)
                    rhs.append(-np.einsum("mk,mk->m", D, c[P]))
                elif kind == "abs":  # t >= +-(c + L z)
                    for sgn in (1.0, -1.0):
                        P = rows_at[k, sgn]
                        A = np.zeros((len(P), nv))
                        A[:, :nz], A[:, sl[0]] = sgn * L[P, 0], -1.0
                        rows.append(A)
                        rhs.append(-sgn * c[P, 0])
                elif kind == "range":  # t_max >= c + L z >= t_min
                    P = rows_at[k, 1.0]
                    A = np.zeros((len(P), nv))
                    A[:, :nz], A[:, sl[0]] = L[P, 0], -1.0
                    rows.append(A)
                    rhs.append(-c[P, 0])
                    P = rows_at[k, -1.0]
                    A = np.zeros((len(P), nv))
                    A[:, :nz], A[:, sl[1]] = -L[P, 0], 1.0
                    rows.append(A)
                    rhs.append(c[P, 0])
                else:  # rms: tau >= f_j + g_j (z - z_j)
                    for zj, fj, gj in tangents:
                        A = np.zeros((1, nv))
                        A[0, :nz], A[0, sl[0]] = gj, -1.0
                        rows.append(A)
                        rhs.append(np.array([gj @ zj - fj]))
        for i in limited:
            A = np.zeros((len(limit_dirs[i]), nv))
            A[:, 2 * i:2 * i + 2] = limit_dirs[i]
            rows.append(A)
            rhs.append(np.full(len(limit_dirs[i]), B.s_max[i]))
        bounds = [(-box, box)] * nz + [(None, None)] * (nv - nz)
        A_ub, b_ub = np.vstack(rows), np.concatenate(rhs)
        lp = linprog(cost, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method="highs",
                     options=_HIGHS)
        if lp.status != 0:
            raise AnalysisError(f"balancing '{B.machine.name}'", f"a linear programme failed:"
                                f" {lp.message}", "Report this machine file as a bug")
        z_new = lp.x
        # the box is widened only where it binds (a direction the criterion does not see,
        # such as two counterweights that act alike, leaves the answer on it at no cost)
        pull = np.abs(lp.lower.marginals[:nz]) + np.abs(lp.upper.marginals[:nz])
        on_box = np.any((np.abs(z_new[:nz]) >= box * (1 - 1e-9))
                        & (pull > 1e-12 * np.abs(cost).max()))
        lower = lp.fun
        # the upper bound: the answer drawn back inside the limits (the cuts only approximate
        # their circles)
        z_in = _within_limits(B, z_new[:nz].reshape(n, 2)).reshape(-1)
        value = _objective(qf, parts, z_in)
        if value < best[0]:
            best = (value, z_in)
        gap = value - lower
        if on_box:
            box *= 4.0
        elif gap <= max(tol * abs(value), floor):
            status = "optimal"
            break
        # new cuts and rows where the programme underestimates
        xy_new = z_new[:nz].reshape(n, 2)
        q = qf(xy_new)
        for (kind, keys, _), sl in zip(parts, slots):
            if kind in ("abs", "range"):
                c, L = lin[keys[0]]
                val = c[:, 0] + L[:, 0] @ z_new[:nz]
                top, bottom = z_new[sl[0]], (-z_new[sl[0]] if kind == "abs" else z_new[sl[1]])
                eps = 1e-12 * max(abs(top), abs(bottom), 1e-300)
                for sgn, bad in ((1.0, val > top + eps), (-1.0, val < bottom - eps)):
                    if bad.any():
                        rows_at[keys[0], sgn] = np.union1d(rows_at[keys[0], sgn],
                                                           np.nonzero(bad)[0])
            if kind != "vector":
                continue
            t = z_new[sl[0]]
            for k in keys:
                mag = np.hypot(q[k][:, 0], q[k][:, 1])
                bad = _worst(mag - t, 1e-12 * max(t, 1e-300))
                if bad.size:
                    P, D = cuts[k]
                    cuts[k] = (np.concatenate([P, bad]),
                               np.vstack([D, q[k][bad] / mag[bad, None]]))
        for i in limited:
            x, y = xy_new[i]
            s = math.hypot(x, y)
            if s > B.s_max[i] * (1 + 1e-12):
                limit_dirs[i] = np.vstack([limit_dirs[i], [x / s, y / s]])
        z = z_new[:nz]
    if status == "optimal":  # of the optimal designs, the one with the least static moments
        best = _least_moments(B, qf, parts, A_ub, b_ub, bounds, cost, best, tol, floor)
    xy = best[1].reshape(n, 2)
    message = (f"{what}: cutting planes, {it} linear programmes (HiGHS), lower bound met"
               if status == "optimal" else
               f"{what}: cutting planes did not converge in {max_iter} linear programmes"
               f" (best found; gap {best[0] - lower:.3g})")
    if info is not None:
        info["lower"], info["iterations"] = lower, it
    return xy, status, message


def _least_moments(B, qf, parts, A_ub, b_ub, bounds, cost, best, tol, floor):
    """Among the designs of the last programme whose objective is at most the best found, the
    one of least sum |x| + |y| (where the criterion does not fix every component, e.g. two
    counterweights that act alike, it would otherwise pick any); kept if the exact objective
    there is still the best (to ``tol``). Returns (value, z)."""
    from scipy.optimize import linprog

    nv, nz = len(cost), len(best[1])
    c = np.concatenate([np.zeros(nv), np.ones(nz)])
    eye = np.eye(nz, nv)
    A = np.block([[A_ub, np.zeros((len(A_ub), nz))],
                  [cost[None, :], np.zeros((1, nz))],
                  [eye, -np.eye(nz)], [-eye, -np.eye(nz)]])
    b = np.concatenate([b_ub, [best[0]], np.zeros(2 * nz)])
    lp = linprog(c, A_ub=A, b_ub=b, bounds=list(bounds) + [(0.0, None)] * nz, method="highs",
                 options=_HIGHS)
    if lp.status != 0:
        return best
    z = _within_limits(B, lp.x[:nz].reshape(-1, 2)).reshape(-1)
    value = _objective(qf, parts, z)
    if value <= best[0] + max(tol * abs(best[0]), floor) and \
            np.abs(z).sum() < np.abs(best[1]).sum():
        return value, z
    return best


def _rms_and_gradient(lin, z: np.ndarray) -> tuple[float, np.ndarray]:
    """RMS of a vector quantity over the turn and its gradient, from its expansion (c, L)."""
    c, L = lin
    q = c + np.einsum("pkz,z->pk", L, z)
    f = math.sqrt(float(np.mean(np.sum(q * q, axis=-1))))
    g = np.einsum("pk,pkz->z", q, L) / (len(q) * f) if f > 0 else np.zeros(len(z))
    return f, g


def _expansion(lin: dict):
    """The quantities as :meth:`BalanceBasis.quantities` gives them, from their first-order
    expansions (:func:`_linear`, key -> (c, L))."""
    def quantities(xy):
        z = np.asarray(xy, dtype=float).reshape(-1)
        out = {}
        for k, (c, L) in lin.items():
            unit = 1e-3 if k in ("M", "T") else 1.0
            q = (c + L @ z) / unit
            out[k] = q if k not in ("M", "T") else q[:, 0]
        return out
    return quantities


def _objective(qf, parts, z: np.ndarray) -> float:
    """sum_i w_i f_i at z (N, N m), with quantities ``qf`` (:meth:`BalanceBasis.quantities` or
    an :func:`_expansion`)."""
    q = qf(np.asarray(z).reshape(-1, 2))
    total = 0.0
    for kind, keys, w in parts:
        if kind == "vector":
            f = max(float(np.hypot(q[k][:, 0], q[k][:, 1]).max()) for k in keys)
        elif kind == "abs":
            f = 1e-3 * float(np.abs(q[keys[0]]).max())
        elif kind == "range":
            f = 1e-3 * float(np.ptp(q[keys[0]]))
        else:
            f = math.sqrt(float(np.mean(np.sum(q[keys[0]] ** 2, axis=-1))))
        total += w * f
    return total

"""Compiled design tangents: every solved quantity's derivatives by its support's parameters.

:func:`tangents` walks a compiled program (the rows of :mod:`sewmech.engine._kernels`) once per
position (design x shaft angle), after the kinematics kernel has solved it, and differentiates
each unit's closure in solve order (forward mode, every parameter direction at once). Tangents
are compact (:mod:`sewmech.engine._supports`): per position one flat row, each quantity's
derivatives by the parameters of its support only, so a unit costs a few small loops over its
output's support instead of array operations over every parameter.

- a rigid point: dP = dO + R(theta) (du, dv) + J (P - O) dtheta;
- an RRR dyad: (C - B_k) . (dC - dB_k) = l_k dl_k, a 2 x 2 system per position;
- an RRP dyad: r . (dC - dB) = l dl with C = G + e n + s u on the guide;
- an RPR guide: B - A = e n + s u;
- a loop group: J_q dq = -(dF/dknown dknown + dF/dp dp), with the terms of the kernel's loop
  solver (points, vectors of parameter or variable length, circular-arc cam contacts); J_q is
  factored once per position and solved for every support column.

With ``level`` 1 the velocities, angular velocities and joint rates are differentiated too (each
unit's velocity relation with the position tangents known), with 2 also the accelerations; the
loop Jacobian's factors serve all three levels.

Units: tangents in mm, rad (and per s, per s^2) per unit of the parameter (mm, rad, 1).
Nothing here allocates per position.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernels import (OP_CRANK, OP_FIXED, OP_LOOP, OP_POINT, OP_RPR, OP_RRP, OP_RRR, SRC_LINK,
                       SRC_PARAM, TERM_POINT, TERM_VEC, TWO_PI)

_OPTS = dict(cache=True, error_model="numpy", fastmath={"contract"})


@njit(inline="always", **_OPTS)
def _acc(dst, do, src, so, maps, mo, mq, c):
    """dst[do + maps[mo + k]] += c src[so + k] for k < mq: an input's tangent (its support)
    added into an output's (a larger support)."""
    for k in range(mq):
        dst[do + maps[mo + k]] += c * src[so + k]


@njit(inline="always", **_OPTS)
def _zero(dst, do, m):
    for k in range(m):
        dst[do + k] = 0.0


@njit(inline="always", **_OPTS)
def _lu(M, perm, n):
    """LU factors of M[:n, :n] in place (partial pivoting, the row order in perm); the
    diagonal holds the pivots' reciprocals. Returns the smallest |pivot|."""
    smallest = np.inf
    for i in range(n):
        perm[i] = i
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
            t2 = perm[k]
            perm[k] = perm[p]
            perm[p] = t2
        piv = M[k, k]
        smallest = min(smallest, abs(piv))
        inv = 1.0 / piv
        M[k, k] = inv
        for i in range(k + 1, n):
            f = M[i, k] * inv
            M[i, k] = f
            for j in range(k + 1, n):
                M[i, j] -= f * M[k, j]
    return smallest


@njit(inline="always", **_OPTS)
def _lu_solve(M, perm, n, B, X, m, stride):
    """X = M^-1 B from :func:`_lu`'s factors, B and X (n, m) flat with row ``stride`` (B is
    left unchanged)."""
    for i in range(n):
        bi = perm[i] * stride
        xi = i * stride
        for k in range(m):
            X[xi + k] = B[bi + k]
    for i in range(n):
        xi = i * stride
        for j in range(i):
            f = M[i, j]
            if f != 0.0:
                xj = j * stride
                for k in range(m):
                    X[xi + k] -= f * X[xj + k]
    for i in range(n - 1, -1, -1):
        xi = i * stride
        for j in range(i + 1, n):
            f = M[i, j]
            if f != 0.0:
                xj = j * stride
                for k in range(m):
                    X[xi + k] -= f * X[xj + k]
        d = M[i, i]
        for k in range(m):
            X[xi + k] *= d


@njit(inline="always", **_OPTS)
def _copy(dst, do, src, so, m, c):
    """dst[do + k] = c src[so + k] for k < m."""
    for k in range(m):
        dst[do + k] = c * src[so + k]


@njit(inline="always", **_OPTS)
def _diff(dst, do, src, so, m, maps, mo, sub, mq):
    """dst[do:do + m] = src[so:so + m] - (src[sub:sub + mq] mapped): a difference of an
    output's tangent and an input's."""
    for k in range(m):
        dst[do + k] = src[so + k]
    for k in range(mq):
        dst[do + maps[mo + k]] -= src[sub + k]


@njit(nogil=True, **_OPTS)
def tangents(p0, p1, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps, max_m,
             max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol, lcol, vcol, PS,
             THS, QS, T):
    """The position tangents of positions p0 .. p1 - 1 (arguments as :func:`_walk`'s, level
    0): compiled apart from :func:`tangents_rates`, the level a constant, so that none of the
    rates' code is in its loops."""
    return _walk(p0, p1, 0, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps,
                 max_m, max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol,
                 lcol, vcol, PS, THS, QS, T)


@njit(nogil=True, **_OPTS)
def tangents_rates(p0, p1, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps,
                   max_m, max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol,
                   lcol, vcol, PS, THS, QS, T):
    """The tangents of the positions, velocities and accelerations (level 2) of positions
    p0 .. p1 - 1 (arguments as :func:`_walk`'s)."""
    return _walk(p0, p1, 2, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps,
                 max_m, max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol,
                 lcol, vcol, PS, THS, QS, T)


@njit(inline="always", **_OPTS)  # (numba inlines functions of at most 30 arguments)
def _walk(p0, p1, level, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps, max_m,
          max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol, lcol, vcol, PS,
          THS, QS, T):
    """The tangents of positions p0 .. p1 - 1.

    units : the program rows solved (solve order); params (n_design, n_params), position k
    belonging to design k // n_phi; qoff, qm, row_out, rin, ppos, tin, maps, max_m : the layout
    (:class:`sewmech.engine._supports.TangentLayout`); max_n, max_t : the largest loop group's
    unknowns and terms; groups .. arcs : the machine's loop tables; pcol, lcol, vcol : each
    point's, link's and variable's column in PS, THS, QS (links: -1 for the frame, angle 0);
    PS (levels, n, n_points, 2), THS (levels, n, n_links), QS (levels, n, n_variables): the
    solved positions (level 0), velocities (1) and accelerations (2), mm, rad, s. Fills T
    (levels, n, width) with the tangents of levels 0 .. ``level``. Returns 1 where a cam contact
    lies on no arc of its profile (the tangents are then incomplete), else 0.
    """
    # scratch and tangents as flat arrays with offsets (no views per position or unit)
    M1 = max_m
    S = np.empty(16 * max_m)
    Jm = np.empty((max_n, max_n))
    perm = np.empty(max_n, dtype=np.int64)
    Rh = np.empty(max_n * max_m)
    X = np.empty(max_n * max_m)
    TR = np.empty((max(max_t, 1), 5))
    n_rows = units.shape[0]
    width = T.shape[2]
    LS = T.shape[1] * width  # one level's stride in t
    t = T.reshape(-1)
    for pos in range(p0, p1):
        d = pos // n_phi
        tb = pos * width
        for r in range(n_rows):
            op = units[r, 0]
            m = row_out[r, 1]
            if op == OP_FIXED:
                off = tb + qoff[units[r, 1]]
                _zero(t, off, 2 * m)
                t[off + ppos[r, units[r, 2]]] = 1.0
                t[off + m + ppos[r, units[r, 3]]] = 1.0
                for lev in range(1, level + 1):
                    _zero(t, off + lev * LS, 2 * m)
            elif op == OP_CRANK:
                L = units[r, 1]
                jph = units[r, 2]
                jra = units[r, 3]
                jset = units[r, 4]
                off = tb + qoff[n_pt + L]
                for lev in range(level + 1):
                    _zero(t, off + lev * LS, m)
                t[off + ppos[r, jph]] += 1.0
                if jset >= 0:
                    t[off + ppos[r, jset]] += 1.0
                else:  # theta = phase + ratio * (the march's angle, whole turns included);
                    # omega = ratio omega_shaft, epsilon = ratio epsilon_shaft
                    kr = ppos[r, jra]
                    ratio = params[d, jra]
                    t[off + kr] += (THS[0, pos, lcol[L]] - params[d, jph]) / ratio
                    for lev in range(1, level + 1):
                        t[off + lev * LS + kr] = THS[lev, pos, lcol[L]] / ratio
            elif op == OP_POINT:
                _point(r, pos, d, m, level, units, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol,
                       PS, THS, t, tb, LS, S, M1)
            elif op == OP_RRR:
                _rrr(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol,
                     lcol, PS, THS, t, tb, LS, S, M1)
            elif op == OP_RRP:
                _rrp(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l,
                     pcol, lcol, vcol, PS, THS, QS, t, tb, LS, S, M1)
            elif op == OP_RPR:
                _rpr(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l,
                     pcol, lcol, vcol, PS, THS, QS, t, tb, LS, S, M1)
            elif op == OP_LOOP:
                bad = _loop(units[r, 1], ppos[r], pos, d, m, level, params, qoff, qm, tin, maps,
                            groups, unknowns, terms, cams, arcs, n_pt, n_l, lcol, vcol, THS, QS,
                            t, tb, LS, Jm, perm, Rh, X, TR)
                if bad:
                    return 1
    return 0


@njit(inline="always", **_OPTS)
def _point(r, pos, d, m, level, units, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol, PS, THS, t,
           tb, LS, S, M1):
    """A rigid point P = O + R(theta) (u, v): dP = dO + R (du, dv) + J (P - O) dtheta; its
    velocity v = vO + omega J (P - O) and acceleration a = aO + eps J (P - O) - omega^2 (P - O)
    differentiated."""
    i = units[r, 1]
    L = units[r, 2]
    o = units[r, 3]
    ju = units[r, 4]
    jv = units[r, 5]
    lc = lcol[L]
    th = THS[0, pos, lc] if lc >= 0 else 0.0
    c = math.cos(th)
    s = math.sin(th)
    relx = PS[0, pos, pcol[i], 0] - PS[0, pos, pcol[o], 0]
    rely = PS[0, pos, pcol[i], 1] - PS[0, pos, pcol[o], 1]
    off = tb + qoff[i]
    oo = tb + qoff[o]
    ol = tb + qoff[n_pt + L]
    mo = qm[o]
    ml = qm[n_pt + L]
    r0 = rin[r, 0]
    r1 = rin[r, 1]
    _zero(t, off, 2 * m)
    _acc(t, off, t, oo, maps, r0, mo, 1.0)
    _acc(t, off + m, t, oo + mo, maps, r0, mo, 1.0)
    _acc(t, off, t, ol, maps, r1, ml, -rely)
    _acc(t, off + m, t, ol, maps, r1, ml, relx)
    if ju >= 0:
        t[off + ppos[r, ju]] += c
        t[off + m + ppos[r, ju]] += s
    if jv >= 0:
        t[off + ppos[r, jv]] -= s
        t[off + m + ppos[r, jv]] += c
    if level == 0:
        return
    # drel = dP - dO (scratch x at 0, y at M1)
    _diff(S, 0, t, off, m, maps, r0, oo, mo)
    _diff(S, M1, t, off + m, m, maps, r0, oo + mo, mo)
    w = THS[1, pos, lc] if lc >= 0 else 0.0
    o1 = off + LS
    _zero(t, o1, 2 * m)
    _acc(t, o1, t, oo + LS, maps, r0, mo, 1.0)
    _acc(t, o1 + m, t, oo + LS + mo, maps, r0, mo, 1.0)
    _acc(t, o1, t, ol + LS, maps, r1, ml, -rely)
    _acc(t, o1 + m, t, ol + LS, maps, r1, ml, relx)
    for k in range(m):
        t[o1 + k] -= w * S[M1 + k]
        t[o1 + m + k] += w * S[k]
    if level == 1:
        return
    ep = THS[2, pos, lc] if lc >= 0 else 0.0
    o2 = off + 2 * LS
    _zero(t, o2, 2 * m)
    _acc(t, o2, t, oo + 2 * LS, maps, r0, mo, 1.0)
    _acc(t, o2 + m, t, oo + 2 * LS + mo, maps, r0, mo, 1.0)
    _acc(t, o2, t, ol + 2 * LS, maps, r1, ml, -rely)
    _acc(t, o2 + m, t, ol + 2 * LS, maps, r1, ml, relx)
    _acc(t, o2, t, ol + LS, maps, r1, ml, -2.0 * w * relx)
    _acc(t, o2 + m, t, ol + LS, maps, r1, ml, -2.0 * w * rely)
    w2 = w * w
    for k in range(m):
        t[o2 + k] -= ep * S[M1 + k] + w2 * S[k]
        t[o2 + m + k] += ep * S[k] - w2 * S[M1 + k]


@njit(inline="always", **_OPTS)
def _rrr(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol, PS,
         THS, t, tb, LS, S, M1):
    """An RRR dyad: r_k . (dC - dP_k) = l_k dl_k (k = 1, 2) solved for dC, and the links'
    dtheta_k = r_k x (dC - dP_k) / l_k^2; at the rates r_k . (vC - v_k) = 0 and at the
    accelerations r_k . (aC - a_k) + |vC - v_k|^2 = 0 differentiated the same way."""
    i1 = units[r, 1]
    i2 = units[r, 2]
    i = units[r, 3]
    j1 = units[r, 6]
    j2 = units[r, 7]
    c1 = pcol[i1]
    c2 = pcol[i2]
    cc = pcol[i]
    r1x = PS[0, pos, cc, 0] - PS[0, pos, c1, 0]
    r1y = PS[0, pos, cc, 1] - PS[0, pos, c1, 1]
    r2x = PS[0, pos, cc, 0] - PS[0, pos, c2, 0]
    r2y = PS[0, pos, cc, 1] - PS[0, pos, c2, 1]
    l1 = params[d, j1]
    l2 = params[d, j2]
    idet = 1.0 / (r1x * r2y - r1y * r2x)
    w1 = 1.0 / (l1 * l1)
    w2 = 1.0 / (l2 * l2)
    m1 = qm[i1]
    m2 = qm[i2]
    q1 = tb + qoff[i1]
    q2 = tb + qoff[i2]
    ma = rin[r, 0]
    mb = rin[r, 1]
    oc = tb + qoff[i]
    la = n_pt + units[r, 4]
    lb = n_pt + units[r, 5]
    oa = tb + qoff[la]
    ob = tb + qoff[lb]
    ka = ppos[r, j1]
    kb = ppos[r, j2]
    # scratch: rhs1 0, rhs2 M1, dr1 (x 2 M1, y 3 M1), dr2 (4, 5 M1), dw1 (6, 7), dw2 (8, 9)
    for lev in range(level + 1):
        sh = lev * LS
        _zero(S, 0, m)
        _zero(S, M1, m)
        _acc(S, 0, t, q1 + sh, maps, ma, m1, r1x)
        _acc(S, 0, t, q1 + sh + m1, maps, ma, m1, r1y)
        _acc(S, M1, t, q2 + sh, maps, mb, m2, r2x)
        _acc(S, M1, t, q2 + sh + m2, maps, mb, m2, r2y)
        g1x = 0.0
        g1y = 0.0
        g2x = 0.0
        g2y = 0.0
        if lev == 0:
            S[ka] += l1
            S[M1 + kb] += l2
        else:
            # -(g_k . dr_k), g_k = vC - v_k (rates) or aC - a_k (accelerations)
            g1x = PS[lev, pos, cc, 0] - PS[lev, pos, c1, 0]
            g1y = PS[lev, pos, cc, 1] - PS[lev, pos, c1, 1]
            g2x = PS[lev, pos, cc, 0] - PS[lev, pos, c2, 0]
            g2y = PS[lev, pos, cc, 1] - PS[lev, pos, c2, 1]
            for k in range(m):
                S[k] -= g1x * S[2 * M1 + k] + g1y * S[3 * M1 + k]
                S[M1 + k] -= g2x * S[4 * M1 + k] + g2y * S[5 * M1 + k]
            if lev == 2:  # - 2 (vC - v_k) . (dvC - dv_k)
                v1x = PS[1, pos, cc, 0] - PS[1, pos, c1, 0]
                v1y = PS[1, pos, cc, 1] - PS[1, pos, c1, 1]
                v2x = PS[1, pos, cc, 0] - PS[1, pos, c2, 0]
                v2y = PS[1, pos, cc, 1] - PS[1, pos, c2, 1]
                for k in range(m):
                    S[k] -= 2.0 * (v1x * S[6 * M1 + k] + v1y * S[7 * M1 + k])
                    S[M1 + k] -= 2.0 * (v2x * S[8 * M1 + k] + v2y * S[9 * M1 + k])
        for k in range(m):
            dcx = (S[k] * r2y - S[M1 + k] * r1y) * idet
            dcy = (r1x * S[M1 + k] - r2x * S[k]) * idet
            t[oc + sh + k] = dcx
            t[oc + sh + m + k] = dcy
            t[oa + sh + k] = (r1x * dcy - r1y * dcx) * w1
            t[ob + sh + k] = (r2x * dcy - r2y * dcx) * w2
        _acc(t, oa + sh, t, q1 + sh + m1, maps, ma, m1, -r1x * w1)
        _acc(t, oa + sh, t, q1 + sh, maps, ma, m1, r1y * w1)
        _acc(t, ob + sh, t, q2 + sh + m2, maps, mb, m2, -r2x * w2)
        _acc(t, ob + sh, t, q2 + sh, maps, mb, m2, r2y * w2)
        if lev == 0:
            if level == 0:
                return
            _diff(S, 2 * M1, t, oc, m, maps, ma, q1, m1)
            _diff(S, 3 * M1, t, oc + m, m, maps, ma, q1 + m1, m1)
            _diff(S, 4 * M1, t, oc, m, maps, mb, q2, m2)
            _diff(S, 5 * M1, t, oc + m, m, maps, mb, q2 + m2, m2)
        else:
            # + dr_k x g_k / l_k^2 - 2 (omega_k or eps_k) / l_k dl_k
            for k in range(m):
                t[oa + sh + k] += (S[2 * M1 + k] * g1y - S[3 * M1 + k] * g1x) * w1
                t[ob + sh + k] += (S[4 * M1 + k] * g2y - S[5 * M1 + k] * g2x) * w2
            t[oa + sh + ka] -= 2.0 * THS[lev, pos, lcol[la - n_pt]] / l1
            t[ob + sh + kb] -= 2.0 * THS[lev, pos, lcol[lb - n_pt]] / l2
            if lev == 1 and level == 2:
                _diff(S, 6 * M1, t, oc + LS, m, maps, ma, q1 + LS, m1)
                _diff(S, 7 * M1, t, oc + LS + m, m, maps, ma, q1 + LS + m1, m1)
                _diff(S, 8 * M1, t, oc + LS, m, maps, mb, q2 + LS, m2)
                _diff(S, 9 * M1, t, oc + LS + m, m, maps, mb, q2 + LS + m2, m2)


@njit(inline="always", **_OPTS)
def _rrp(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol, lcol,
         vcol, PS, THS, QS, t, tb, LS, S, M1):
    """An RRP dyad: the slider C = G + e n + s u on the guide (G a point of the guide link,
    u = (cos beta, sin beta), beta = the guide's angle + alpha, n = J u) and the rod
    r1 . (dC - dB) = l dl, r1 = C - B; then its velocity and acceleration relations
    differentiated (as the numpy reference of the rates wrote them)."""
    b = units[r, 1]
    gp = units[r, 2]
    gl = units[r, 3]
    i = units[r, 4]
    L1 = units[r, 5]
    Ls = units[r, 6]
    jl = units[r, 7]
    ja = units[r, 8]
    je = units[r, 9]
    var = units[r, 11]
    beta = THS[0, pos, lcol[Ls]]
    ux = math.cos(beta)
    uy = math.sin(beta)
    nx = -uy
    ny = ux
    vc = vcol[var]
    s = QS[0, pos, vc]
    e = params[d, je]
    ll = params[d, jl]
    qg = n_pt + gl
    og = tb + qoff[qg]
    mgl = qm[qg]
    rg = rin[r, 1]
    # dbeta = dtheta_guide + dalpha (scratch at 0), known (x at M1, y at 2 M1), ds (3 M1)
    _zero(S, 0, m)
    _acc(S, 0, t, og, maps, rg, mgl, 1.0)
    if ja >= 0:
        S[ppos[r, ja]] += 1.0
    # known = dG + n de - e u dbeta + s n dbeta (the foot's and the slider offset's motion)
    kx = M1
    ky = 2 * M1
    mg = qm[gp]
    ogp = tb + qoff[gp]
    rp = rin[r, 0]
    _zero(S, kx, m)
    _zero(S, ky, m)
    _acc(S, kx, t, ogp, maps, rp, mg, 1.0)
    _acc(S, ky, t, ogp + mg, maps, rp, mg, 1.0)
    kj = ppos[r, je]
    S[kx + kj] += nx
    S[ky + kj] += ny
    for k in range(m):
        S[kx + k] += (s * nx - e * ux) * S[k]
        S[ky + k] += (s * ny - e * uy) * S[k]
    cb = pcol[b]
    ci = pcol[i]
    r1x = PS[0, pos, ci, 0] - PS[0, pos, cb, 0]
    r1y = PS[0, pos, ci, 1] - PS[0, pos, cb, 1]
    # r1 . (dC - dB) = l dl with dC = known + u ds
    ds = 3 * M1
    _zero(S, ds, m)
    mb = qm[b]
    ob = tb + qoff[b]
    rb = rin[r, 2]
    _acc(S, ds, t, ob, maps, rb, mb, r1x)
    _acc(S, ds, t, ob + mb, maps, rb, mb, r1y)
    S[ds + ppos[r, jl]] += ll
    ru = r1x * ux + r1y * uy
    iru = 1.0 / ru
    oc = tb + qoff[i]
    ov = tb + qoff[n_pt + n_l + var]
    o1 = tb + qoff[n_pt + L1]
    os_ = tb + qoff[n_pt + Ls]
    w = 1.0 / (ll * ll)
    kl = ppos[r, jl]
    for k in range(m):
        dsk = (S[ds + k] - r1x * S[kx + k] - r1y * S[ky + k]) * iru
        dcx = S[kx + k] + ux * dsk
        dcy = S[ky + k] + uy * dsk
        t[oc + k] = dcx
        t[oc + m + k] = dcy
        t[ov + k] = dsk
        t[o1 + k] = (r1x * dcy - r1y * dcx) * w
        t[os_ + k] = S[k]
    _acc(t, o1, t, ob + mb, maps, rb, mb, -r1x * w)
    _acc(t, o1, t, ob, maps, rb, mb, r1y * w)
    if level == 0:
        return
    # the rates. Scratch: dr1 (x 4 M1, y 5 M1), dWb = dW + dvB (6, 7), dsd (8)
    _diff(S, 4 * M1, t, oc, m, maps, rb, ob, mb)
    _diff(S, 5 * M1, t, oc + m, m, maps, rb, ob + mb, mb)
    rn = r1x * nx + r1y * ny
    wg = THS[1, pos, lcol[gl]] if lcol[gl] >= 0 else 0.0
    sd = QS[1, pos, vc]
    Wx = PS[1, pos, pcol[gp], 0] - e * wg * ux + s * wg * nx - PS[1, pos, cb, 0]
    Wy = PS[1, pos, pcol[gp], 1] - e * wg * uy + s * wg * ny - PS[1, pos, cb, 1]
    rW = r1x * Wx + r1y * Wy
    # dW + dvB = dvG - u (wg de + e dwg) - e wg du + n (wg ds + s dwg) + s wg dn,
    # du = n dbeta, dn = -u dbeta
    for c in range(2):
        oW = (6 + c) * M1
        uc = ux if c == 0 else uy
        nc = nx if c == 0 else ny
        _zero(S, oW, m)
        _acc(S, oW, t, ogp + LS + c * mg, maps, rp, mg, 1.0)
        _acc(S, oW, t, og + LS, maps, rg, mgl, -e * uc + s * nc)
        S[oW + kj] -= uc * wg
        cdb = -e * wg * nc - s * wg * uc
        for k in range(m):
            S[oW + k] += wg * nc * t[ov + k] + cdb * S[k]
    # dsd = -(W . dr1 + r1 . dW) / ru + (rW / ru^2) (u . dr1 + r1 . du)
    dsd = 8 * M1
    _zero(S, dsd, m)
    _acc(S, dsd, t, ob + LS, maps, rb, mb, r1x * iru)
    _acc(S, dsd, t, ob + LS + mb, maps, rb, mb, r1y * iru)
    f = rW * iru
    for k in range(m):
        S[dsd + k] += (-(Wx * S[4 * M1 + k] + Wy * S[5 * M1 + k] + r1x * S[6 * M1 + k]
                         + r1y * S[7 * M1 + k])
                       + f * (ux * S[4 * M1 + k] + uy * S[5 * M1 + k] + rn * S[k])) * iru
    vrx = PS[1, pos, ci, 0] - PS[1, pos, cb, 0]
    vry = PS[1, pos, ci, 1] - PS[1, pos, cb, 1]
    om1 = THS[1, pos, lcol[L1]]
    for k in range(m):
        dvx = S[6 * M1 + k] + ux * S[dsd + k] + sd * nx * S[k]
        dvy = S[7 * M1 + k] + uy * S[dsd + k] + sd * ny * S[k]
        t[oc + LS + k] = dvx
        t[oc + LS + m + k] = dvy
        t[ov + LS + k] = S[dsd + k]
        # domega_rod = (dr1 x vrel + r1 x (dvC - dvB)) / l^2 - 2 omega / l dl
        t[o1 + LS + k] = (S[4 * M1 + k] * vry - S[5 * M1 + k] * vrx + r1x * dvy
                          - r1y * dvx) * w
    _acc(t, o1 + LS, t, ob + LS + mb, maps, rb, mb, -r1x * w)
    _acc(t, o1 + LS, t, ob + LS, maps, rb, mb, r1y * w)
    t[o1 + LS + kl] -= 2.0 * om1 / ll
    _zero(t, os_ + LS, m)
    _acc(t, os_ + LS, t, og + LS, maps, rg, mgl, 1.0)
    if level == 1:
        return
    # the accelerations: aC = K + aB + sdd u, K = aG - e (eg u + wg^2 n) + 2 sd wg n
    # + s (eg n - wg^2 u) - aB. Scratch: dKb = dK + daB (x 6 M1, y 7 M1), dsdd 8, dw (9, 10)
    eg = THS[2, pos, lcol[gl]] if lcol[gl] >= 0 else 0.0
    sdd = QS[2, pos, vc]
    wg2 = wg * wg
    Kx = (PS[2, pos, pcol[gp], 0] - e * (eg * ux + wg2 * nx) + 2.0 * sd * wg * nx
          + s * (eg * nx - wg2 * ux) - PS[2, pos, cb, 0])
    Ky = (PS[2, pos, pcol[gp], 1] - e * (eg * uy + wg2 * ny) + 2.0 * sd * wg * ny
          + s * (eg * ny - wg2 * uy) - PS[2, pos, cb, 1])
    for c in range(2):
        oK = (6 + c) * M1
        uc = ux if c == 0 else uy
        nc = nx if c == 0 else ny
        _zero(S, oK, m)
        _acc(S, oK, t, ogp + 2 * LS + c * mg, maps, rp, mg, 1.0)
        _acc(S, oK, t, og + 2 * LS, maps, rg, mgl, -e * uc + s * nc)  # deg
        _acc(S, oK, t, og + LS, maps, rg, mgl,  # dwg
             -2.0 * e * wg * nc + 2.0 * sd * nc - 2.0 * s * wg * uc)
        S[oK + kj] -= eg * uc + wg2 * nc
        c_dsd = 2.0 * wg * nc
        c_ds = eg * nc - wg2 * uc
        c_db = (-e * eg * nc + e * wg2 * uc - 2.0 * sd * wg * uc - s * eg * uc
                - s * wg2 * nc)
        for k in range(m):
            S[oK + k] += c_dsd * t[ov + LS + k] + c_ds * t[ov + k] + c_db * S[k]
    wx = vrx
    wy = vry
    _diff(S, 9 * M1, t, oc + LS, m, maps, rb, ob + LS, mb)
    _diff(S, 10 * M1, t, oc + LS + m, m, maps, rb, ob + LS + mb, mb)
    num = r1x * Kx + r1y * Ky + wx * wx + wy * wy
    dsdd = 8 * M1
    _zero(S, dsdd, m)
    _acc(S, dsdd, t, ob + 2 * LS, maps, rb, mb, r1x * iru)
    _acc(S, dsdd, t, ob + 2 * LS + mb, maps, rb, mb, r1y * iru)
    f = num * iru
    for k in range(m):
        S[dsdd + k] += (-(Kx * S[4 * M1 + k] + Ky * S[5 * M1 + k] + r1x * S[6 * M1 + k]
                          + r1y * S[7 * M1 + k]
                          + 2.0 * (wx * S[9 * M1 + k] + wy * S[10 * M1 + k]))
                        + f * (ux * S[4 * M1 + k] + uy * S[5 * M1 + k] + rn * S[k])) * iru
    arx = PS[2, pos, ci, 0] - PS[2, pos, cb, 0]
    ary = PS[2, pos, ci, 1] - PS[2, pos, cb, 1]
    ep1 = THS[2, pos, lcol[L1]]
    for k in range(m):
        dax = S[6 * M1 + k] + ux * S[dsdd + k] + sdd * nx * S[k]
        day = S[7 * M1 + k] + uy * S[dsdd + k] + sdd * ny * S[k]
        t[oc + 2 * LS + k] = dax
        t[oc + 2 * LS + m + k] = day
        t[ov + 2 * LS + k] = S[dsdd + k]
        t[o1 + 2 * LS + k] = (S[4 * M1 + k] * ary - S[5 * M1 + k] * arx + r1x * day
                              - r1y * dax) * w
    _acc(t, o1 + 2 * LS, t, ob + 2 * LS + mb, maps, rb, mb, -r1x * w)
    _acc(t, o1 + 2 * LS, t, ob + 2 * LS, maps, rb, mb, r1y * w)
    t[o1 + 2 * LS + kl] -= 2.0 * ep1 / ll
    _zero(t, os_ + 2 * LS, m)
    _acc(t, os_ + 2 * LS, t, og + 2 * LS, maps, rg, mgl, 1.0)


@njit(inline="always", **_OPTS)
def _rpr(r, pos, d, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol, lcol,
         vcol, PS, THS, QS, t, tb, LS, S, M1):
    """An RPR guide: B - A = e n + s u (u along the slot link, n = J u), so dB - dA =
    u (ds - e dtheta) + n (de + s dtheta); its velocity and acceleration relations
    differentiated."""
    b = units[r, 1]
    pv = units[r, 2]
    L = units[r, 3]
    Lb = units[r, 4]
    je = units[r, 5]
    var = units[r, 7]
    th = THS[0, pos, lcol[L]]
    ux = math.cos(th)
    uy = math.sin(th)
    nx = -uy
    ny = ux
    vc = vcol[var]
    s = QS[0, pos, vc]
    e = params[d, je]
    kj = ppos[r, je]
    mb = qm[b]
    mp = qm[pv]
    ob = tb + qoff[b]
    opv = tb + qoff[pv]
    ol = tb + qoff[n_pt + L]
    ov = tb + qoff[n_pt + n_l + var]
    olb = tb + qoff[n_pt + Lb] if Lb >= 0 else -1
    r0 = rin[r, 0]
    r1 = rin[r, 1]
    for lev in range(level + 1):
        sh = lev * LS
        # dd = d(B - A) at this level (x at 0, y at M1)
        _zero(S, 0, m)
        _zero(S, M1, m)
        _acc(S, 0, t, ob + sh, maps, r0, mb, 1.0)
        _acc(S, M1, t, ob + sh + mb, maps, r0, mb, 1.0)
        _acc(S, 0, t, opv + sh, maps, r1, mp, -1.0)
        _acc(S, M1, t, opv + sh + mp, maps, r1, mp, -1.0)
        if lev == 0:
            for k in range(m):
                t[ol + k] = (nx * S[k] + ny * S[M1 + k]) / s
            t[ol + kj] -= 1.0 / s  # dtheta = (n . dd - de) / s
            for k in range(m):  # ds = u . dd + e dtheta
                t[ov + k] = ux * S[k] + uy * S[M1 + k] + e * t[ol + k]
        elif lev == 1:
            w = THS[1, pos, lcol[L]]
            dvx = PS[1, pos, pcol[b], 0] - PS[1, pos, pcol[pv], 0]
            dvy = PS[1, pos, pcol[b], 1] - PS[1, pos, pcol[pv], 1]
            dvu = dvx * ux + dvy * uy
            dvn = dvx * nx + dvy * ny
            # dw = (dv . dn + n . ddv) / s - (w / s) ds; dsd = dv . du + u . ddv + w de + e dw
            for k in range(m):
                dw = (-dvu * t[ol + k] + nx * S[k] + ny * S[M1 + k] - w * t[ov + k]) / s
                t[ol + LS + k] = dw
                t[ov + LS + k] = dvn * t[ol + k] + ux * S[k] + uy * S[M1 + k] + e * dw
            t[ov + LS + kj] += w
        else:
            w = THS[1, pos, lcol[L]]
            ep = THS[2, pos, lcol[L]]
            sd = QS[1, pos, vc]
            dax = PS[2, pos, pcol[b], 0] - PS[2, pos, pcol[pv], 0]
            day = PS[2, pos, pcol[b], 1] - PS[2, pos, pcol[pv], 1]
            dau = dax * ux + day * uy
            dan = dax * nx + day * ny
            for k in range(m):
                dth = t[ol + k]
                dwk = t[ol + LS + k]
                dep = ((-dau * dth + nx * S[k] + ny * S[M1 + k]
                        - 2.0 * (t[ov + LS + k] * w + sd * dwk) + 2.0 * e * w * dwk) / s
                       - ep / s * t[ov + k])
                t[ol + sh + k] = dep
                t[ov + sh + k] = (dan * dth + ux * S[k] + uy * S[M1 + k] + e * dep
                                  + w * w * t[ov + k] + 2.0 * s * w * dwk)
            t[ol + sh + kj] += w * w / s
            t[ov + sh + kj] += ep + e * w * w / s
        if Lb >= 0:
            _copy(t, olb + sh, t, ol + sh, m, 1.0)


@njit(inline="always", **_OPTS)
def _arc_of(cam, rho, d, params, cams, arcs):
    """The arc (index into arcs) whose normal-angle range holds rho, as the kernel picks it;
    -1 for none."""
    for ka in range(cams[cam, 2], cams[cam, 2] + cams[cam, 3]):
        a0 = params[d, arcs[ka, 3]]
        x = rho
        while x < a0:
            x += TWO_PI
        while x >= a0 + TWO_PI:
            x -= TWO_PI
        if x < params[d, arcs[ka, 4]]:
            return ka
    return -1


@njit(inline="always", **_OPTS)
def _src(Rh, rx, ry, vx, vy, t, so, maps, mo, mq, own, m):
    """A term's source tangent t[so:] times the vector (vx, vy) added to the right-hand sides
    (rows at rx, ry): through the map of the input (mo, mq), or, for the group's own unknown
    (``own``), as it is."""
    if own:
        for k in range(m):
            x = t[so + k]
            Rh[rx + k] += vx * x
            Rh[ry + k] += vy * x
    else:
        for k in range(mq):
            j = maps[mo + k]
            x = t[so + k]
            Rh[rx + j] += vx * x
            Rh[ry + j] += vy * x


@njit(inline="always", **_OPTS)  # (numba inlines functions of at most 30 arguments)
def _loop(g, pp, pos, d, m, level, params, qoff, qm, tin, maps, groups, unknowns, terms, cams,
          arcs, n_pt, n_l, lcol, vcol, THS, QS, t, tb, LS, Jm, perm, Rh, X, TR):
    """A loop group: J d(q, q_dot or q_ddot) = -(the known part of each term's tangent),
    sum over terms of sign * T_t = 0, one factorisation of J for every level (the unknowns enter
    each level's closure linearly with the same coefficients). pp: each parameter's place in
    the group's support. Returns True where a cam contact lies on no arc."""
    M1 = Rh.shape[0] // Jm.shape[0]  # Rh's row stride
    nq = groups[g, 0]
    u0 = groups[g, 1]
    t0 = groups[g, 3]
    t1 = t0 + groups[g, 4]
    for a in range(nq):
        for b in range(nq):
            Jm[a, b] = 0.0
    for lev in range(level + 1):
        sh = lev * LS
        for a in range(nq):
            for k in range(m):
                Rh[a * M1 + k] = 0.0
        for tt in range(t0, t1):
            typ = terms[tt, 0]
            row = 2 * terms[tt, 1]
            rx = row * M1  # the term's two equations' right-hand sides in Rh
            ry = rx + M1
            sg = -float(terms[tt, 2])  # (moved to the right-hand side)
            if typ == TERM_POINT:
                q = terms[tt, 4]
                mq = qm[q]
                o = tb + qoff[q] + sh
                _acc(Rh, rx, t, o, maps, tin[tt, 0], mq, sg)
                _acc(Rh, ry, t, o + mq, maps, tin[tt, 0], mq, sg)
                continue
            ai = terms[tt, 6]
            ja = terms[tt, 7]
            lc = terms[tt, 10]
            ac = terms[tt, 11]
            k0 = tt - t0
            if terms[tt, 5] == SRC_LINK:
                qa = n_pt + ai
                col = lcol[ai]
                psi = THS[0, pos, col] if col >= 0 else 0.0
                wa = THS[1, pos, col] if col >= 0 and level >= 1 else 0.0
                aa = THS[2, pos, col] if col >= 0 and level >= 2 else 0.0
            else:
                qa = n_pt + n_l + ai
                psi = QS[0, pos, vcol[ai]]
                wa = QS[1, pos, vcol[ai]] if level >= 1 else 0.0
                aa = QS[2, pos, vcol[ai]] if level >= 2 else 0.0
            if lev == 0:
                if ja >= 0:
                    psi += params[d, ja]
                TR[k0, 0] = math.cos(psi)
                TR[k0, 1] = math.sin(psi)
            c = TR[k0, 0]
            sn = TR[k0, 1]
            oa = tb + qoff[qa]
            # the length: a parameter (L, its place kl) or a variable (L, Ld, Ldd, its tangents)
            kl = -1
            ql = -1
            Ld = 0.0
            Ldd = 0.0
            if typ == TERM_VEC:
                li = terms[tt, 4]
                if terms[tt, 3] == SRC_PARAM:
                    L = params[d, li]
                    kl = pp[li]
                else:
                    ql = n_pt + n_l + li
                    L = QS[0, pos, vcol[li]]
                    if level >= 1:
                        Ld = QS[1, pos, vcol[li]]
                    if level >= 2:
                        Ldd = QS[2, pos, vcol[li]]
                if lev == 0:
                    if lc >= 0:
                        Jm[row, lc] += -sg * c
                        Jm[row + 1, lc] += -sg * sn
                    if ac >= 0:
                        Jm[row, ac] -= -sg * L * sn
                        Jm[row + 1, ac] += -sg * L * c
            else:  # TERM_CAM: p_cp + R(theta_c) c_k + (R_k + off) e^{i psi}
                cam = terms[tt, 8]
                cl = cams[cam, 0]
                cp = cams[cam, 1]
                col = lcol[cl]
                tc = THS[0, pos, col] if col >= 0 else 0.0
                if lev == 0:
                    ka = _arc_of(cam, psi - tc, d, params, cams, arcs)
                    if ka < 0:
                        return True
                    TR[k0, 2] = ka
                    TR[k0, 3] = math.cos(tc)
                    TR[k0, 4] = math.sin(tc)
                ka = int(TR[k0, 2])
                cc = TR[k0, 3]
                cs = TR[k0, 4]
                ccx = params[d, arcs[ka, 0]]
                ccy = params[d, arcs[ka, 1]]
                L = params[d, arcs[ka, 2]]
                jo = terms[tt, 9]
                if jo >= 0:
                    L += params[d, jo]
                if lev == 0 and ac >= 0:
                    Jm[row, ac] -= -sg * L * sn
                    Jm[row + 1, ac] += -sg * L * c
                rcx = cc * ccx - cs * ccy
                rcy = cs * ccx + cc * ccy
                wc = THS[1, pos, col] if col >= 0 and level >= 1 else 0.0
                ec = THS[2, pos, col] if col >= 0 and level >= 2 else 0.0
                # the cam's body: the pivot's tangent, its angle's, the arc centre's
                mq = qm[cp]
                o = tb + qoff[cp] + sh
                _acc(Rh, rx, t, o, maps, tin[tt, 0], mq, sg)
                _acc(Rh, ry, t, o + mq, maps, tin[tt, 0], mq, sg)
                qc = n_pt + cl
                oc = tb + qoff[qc]
                mc = qm[qc]
                rc = tin[tt, 3]
                kx = pp[arcs[ka, 0]]
                ky = pp[arcs[ka, 1]]
                if lev == 0:
                    _src(Rh, rx, ry, -sg * rcy, sg * rcx, t, oc, maps, rc, mc, False, m)
                    vxx, vxy, vyx, vyy = cc, cs, -cs, cc
                elif lev == 1:
                    _src(Rh, rx, ry, -sg * wc * rcx, -sg * wc * rcy, t, oc, maps, rc, mc,
                         False, m)
                    _src(Rh, rx, ry, -sg * rcy, sg * rcx, t, oc + LS, maps, rc, mc, False, m)
                    vxx, vxy, vyx, vyy = -wc * cs, wc * cc, -wc * cc, -wc * cs
                else:
                    w2 = wc * wc
                    _src(Rh, rx, ry, sg * (-ec * rcx + w2 * rcy), sg * (-ec * rcy - w2 * rcx),
                         t, oc, maps, rc, mc, False, m)
                    _src(Rh, rx, ry, -2.0 * sg * wc * rcx, -2.0 * sg * wc * rcy, t, oc + LS,
                         maps, rc, mc, False, m)
                    _src(Rh, rx, ry, -sg * rcy, sg * rcx, t, oc + 2 * LS, maps, rc, mc, False,
                         m)
                    vxx = -ec * cs - w2 * cc
                    vxy = ec * cc - w2 * cs
                    vyx = -ec * cc + w2 * cs
                    vyy = -ec * cs - w2 * cc
                Rh[rx + kx] += sg * vxx
                Rh[ry + kx] += sg * vxy
                Rh[rx + ky] += sg * vyx
                Rh[ry + ky] += sg * vyy
                # the radius: a parameter (and the offset's)
                kl = pp[arcs[ka, 2]]
            # E / IE coefficients (ce, ci) of the length's tangents dL_k and the angle's p_k
            # (p_0 with the alpha parameter's); see the module docstring of the numpy
            # reference: level 0: dL0 (1, 0), p0 (0, L); level 1: dL1 (1, 0), p0 (-L w, Ld),
            # dL0 (0, w), p1 (0, L); level 2: dL2 (1, 0), p0 (-2 Ld w - L a, Ldd - L w^2),
            # dL1 (0, 2 w), p1 (-2 L w, 2 Ld), dL0 (-w^2, a), p2 (0, L)
            w = wa
            a = aa
            for kk in range(lev + 1):  # kk: the level of the tangent
                if kk == lev:
                    ceL, ciL, ceP, ciP = 1.0, 0.0, 0.0, L
                elif lev == 1:  # kk == 0
                    ceL, ciL, ceP, ciP = 0.0, w, -L * w, Ld
                elif kk == 1:  # lev == 2
                    ceL, ciL, ceP, ciP = 0.0, 2.0 * w, -2.0 * L * w, 2.0 * Ld
                else:  # lev == 2, kk == 0
                    ceL, ciL = -w * w, a
                    ceP, ciP = -2.0 * Ld * w - L * a, Ldd - L * w * w
                vLx = sg * (ceL * c - ciL * sn)
                vLy = sg * (ceL * sn + ciL * c)
                vPx = sg * (ceP * c - ciP * sn)
                vPy = sg * (ceP * sn + ciP * c)
                ks = kk * LS
                # the length's tangent at level kk (a parameter's only at level 0)
                if kl >= 0:
                    if kk == 0:
                        Rh[rx + kl] += vLx
                        Rh[ry + kl] += vLy
                        if typ != TERM_VEC:
                            jo = terms[tt, 9]
                            if jo >= 0:
                                Rh[rx + pp[jo]] += vLx
                                Rh[ry + pp[jo]] += vLy
                elif ql >= 0 and not (kk == lev and lc >= 0):
                    _src(Rh, rx, ry, vLx, vLy, t, tb + qoff[ql] + ks, maps, tin[tt, 1],
                         qm[ql], lc >= 0, m)
                # the angle's tangent at level kk
                if not (kk == lev and ac >= 0):
                    _src(Rh, rx, ry, vPx, vPy, t, oa + ks, maps, tin[tt, 2], qm[qa], ac >= 0,
                         m)
                if kk == 0 and ja >= 0:
                    Rh[rx + pp[ja]] += vPx
                    Rh[ry + pp[ja]] += vPy
        if lev == 0:
            _lu(Jm, perm, nq)
        _lu_solve(Jm, perm, nq, Rh, X, m, M1)
        for j in range(nq):
            idx = unknowns[u0 + j, 1]
            q = n_pt + idx if unknowns[u0 + j, 0] == 0 else n_pt + n_l + idx
            _copy(t, tb + qoff[q] + sh, X, j * M1, m, 1.0)
    return False

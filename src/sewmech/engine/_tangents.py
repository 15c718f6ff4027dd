"""Compiled design tangents: every solved quantity's derivatives by its support's parameters.

:func:`tangents` walks a compiled program (the rows of :mod:`sewmech.engine._kernels`) after the
kinematics kernel has solved it, and differentiates each unit's closure in solve order (forward
mode, every parameter direction at once). Tangents are compact (:mod:`sewmech.engine._supports`):
each quantity's derivatives by the parameters of its support only, so a unit costs a few small
loops over its output's support instead of array operations over every parameter. Positions
(designs x shaft angles) go through in blocks of :data:`LANES`: every unit computes its
coefficients per lane, then each support loop's body is one short vector operation over the
lanes (the tangents are stored (levels, block, width, LANES)).

- a rigid point: dP = dO + R(theta) (du, dv) + J (P - O) dtheta;
- an RRR dyad: (C - B_k) . (dC - dB_k) = l_k dl_k, a 2 x 2 system per position;
- an RRP dyad: r . (dC - dB) = l dl with C = G + e n + s u on the guide;
- an RPR guide: B - A = e n + s u;
- a loop group: J_q dq = -(dF/dknown dknown + dF/dp dp), with the terms of the kernel's loop
  solver (points, vectors of parameter or variable length, circular-arc cam contacts); J_q is
  factored once per position and solved for every support column.

:func:`tangents` at level 2 differentiates the velocities, angular velocities and joint rates too
(each unit's velocity relation with the position tangents known) and the accelerations; the
loop Jacobian's factors serve all three levels.

Units: tangents in mm, rad (and per s, per s^2) per unit of the parameter (mm, rad, 1).
Nothing here allocates per position.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import _compiling
from ._kernels import (
    OP_CRANK,
    OP_FIXED,
    OP_LOOP,
    OP_POINT,
    OP_RPR,
    OP_RRP,
    OP_RRR,
    SRC_LINK,
    SRC_PARAM,
    TERM_POINT,
    TERM_VEC,
    arc_of,
)

_compiling.install()  # a kernel compiled on its first use says so on stderr

_OPTS = dict(cache=True, error_model="numpy", fastmath={"contract"})

#: positions per block: a support loop's body is one operation on this many lanes (two AVX2
#: vectors)
LANES = 8
_B = LANES
#: blocks a unit goes through per call
_CHUNK = 8
#: coefficient slots per unit (of LANES each)
_SLOTS = 64
#: support-sized scratch rows per unit (of max_m x LANES each)
_ROWS = 12


# ---- lane helpers: "rows" count LANES values each ---------------------------------------------


@njit(inline="always", **_OPTS)
def _zero(t, row, m):
    for i in range(row * _B, (row + m) * _B):
        t[i] = 0.0


@njit(inline="always", **_OPTS)
def _acc(dst, drow, src, srow, maps, mo, mq, C, cs):
    """dst[drow + maps[mo + k]] += C[cs] * src[srow + k] (lane by lane) for k < mq: an input's
    tangent (its support) added into an output's (a larger support)."""
    for k in range(mq):
        a = (drow + maps[mo + k]) * _B
        b = (srow + k) * _B
        for j in range(_B):
            dst[a + j] += C[cs + j] * src[b + j]


@njit(inline="always", **_OPTS)
def _accs(dst, drow, src, srow, maps, mo, mq, c):
    """:func:`_acc` with one coefficient ``c`` for every lane."""
    for k in range(mq):
        a = (drow + maps[mo + k]) * _B
        b = (srow + k) * _B
        for j in range(_B):
            dst[a + j] += c * src[b + j]


@njit(inline="always", **_OPTS)
def _own(dst, row, C, cs):
    """dst[row] += C[cs] (lane by lane): a parameter's own part."""
    a = row * _B
    for j in range(_B):
        dst[a + j] += C[cs + j]


@njit(inline="always", **_OPTS)
def _addc(dst, row, c):
    a = row * _B
    for j in range(_B):
        dst[a + j] += c


@njit(inline="always", **_OPTS)
def _copy(dst, drow, src, srow, m):
    a = drow * _B
    b = srow * _B
    for i in range(m * _B):
        dst[a + i] = src[b + i]


@njit(inline="always", **_OPTS)
def _diff(dst, drow, src, srow, m, maps, mo, sub, mq):
    """dst[drow:drow + m] = src[srow:srow + m] - (src[sub:sub + mq] mapped): an output's
    tangent less an input's."""
    _copy(dst, drow, src, srow, m)
    for k in range(mq):
        a = (drow + maps[mo + k]) * _B
        b = (sub + k) * _B
        for j in range(_B):
            dst[a + j] -= src[b + j]


@njit(inline="always", **_OPTS)
def _lu(M, perm, lane, n):
    """LU factors of lane ``lane``'s M[lane, :n, :n] in place (partial pivoting, the row order
    in perm[lane]); the diagonal holds the pivots' reciprocals."""
    for i in range(n):
        perm[lane, i] = i
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[lane, i, k]) > abs(M[lane, p, k]):
                p = i
        if p != k:
            for j in range(n):
                x = M[lane, k, j]
                M[lane, k, j] = M[lane, p, j]
                M[lane, p, j] = x
            q = perm[lane, k]
            perm[lane, k] = perm[lane, p]
            perm[lane, p] = q
        inv = 1.0 / M[lane, k, k]
        M[lane, k, k] = inv
        for i in range(k + 1, n):
            f = M[lane, i, k] * inv
            M[lane, i, k] = f
            for j in range(k + 1, n):
                M[lane, i, j] -= f * M[lane, k, j]


@njit(inline="always", **_OPTS)
def _lu_solve(M, perm, n, Bm, X, m, stride, C):
    """X = M^-1 Bm lane by lane from :func:`_lu`'s factors; Bm and X hold (n rows of
    ``stride``) x m x LANES; C (a LANES slot) is scratch."""
    for i in range(n):
        for k in range(m):
            a = (i * stride + k) * _B
            for j in range(_B):
                X[a + j] = Bm[(perm[j, i] * stride + k) * _B + j]
    for i in range(n):
        for h in range(i):
            for j in range(_B):
                C[j] = M[j, i, h]
            for k in range(m):
                a = (i * stride + k) * _B
                b = (h * stride + k) * _B
                for j in range(_B):
                    X[a + j] -= C[j] * X[b + j]
    for i in range(n - 1, -1, -1):
        for h in range(i + 1, n):
            for j in range(_B):
                C[j] = M[j, i, h]
            for k in range(m):
                a = (i * stride + k) * _B
                b = (h * stride + k) * _B
                for j in range(_B):
                    X[a + j] -= C[j] * X[b + j]
        for j in range(_B):
            C[j] = M[j, i, i]
        for k in range(m):
            a = (i * stride + k) * _B
            for j in range(_B):
                X[a + j] *= C[j]


# ---- the kernels ----------------------------------------------------------------------------------


@njit(nogil=True, **_OPTS)
def tangents(b0, b1, level, units, params, n_phi, qoff, qm, row_out, rin, ppos, tin, maps, max_m,
             max_n, max_t, groups, unknowns, terms, cams, arcs, n_pt, n_l, pcol, lcol, vcol, PS,
             THS, QS, T):
    """The tangents of the blocks of positions b0 .. b1 - 1 (position k of the n in PS is lane
    k % LANES of block k // LANES; the last block's spare lanes repeat position n - 1) up to
    ``level`` (0: positions; 2: velocities and accelerations too).

    One kernel for every level, the level an argument: a kernel per level (the level a
    compile-time constant) compiled every unit's code twice, 35 s of CPU, for no measurable
    speed (bench_sensitivity).

    units : the program rows solved (solve order); params (n_design, n_params), position k
    belonging to design k // n_phi; qoff, qm, row_out, rin, ppos, tin, maps, max_m : the layout
    (:class:`sewmech.engine._supports.TangentLayout`); max_n, max_t : the largest loop group's
    unknowns and terms; groups .. arcs : the machine's loop tables; pcol, lcol, vcol : each
    point's, link's and variable's column in PS, THS, QS (links: -1 for the frame, angle 0);
    PS (levels, n, n_points, 2), THS (levels, n, n_links), QS (levels, n, n_variables): the
    solved positions (level 0), velocities (1) and accelerations (2), mm, rad, s. Fills T
    (levels, blocks, width, LANES) with the tangents of levels 0 .. ``level``. Returns 1
    where a cam contact lies on no arc of its profile (the tangents are then incomplete),
    else 0.
    """
    M1 = max_m
    n = PS.shape[1]
    C = np.empty(_SLOTS * _B)
    S = np.empty(_ROWS * max_m * _B)
    Jm = np.empty((_B, max_n, max_n))
    perm = np.empty((_B, max_n), dtype=np.int64)
    Rh = np.empty(max_n * max_m * _B)
    X = np.empty(max_n * max_m * _B)
    TR = np.empty((max(max_t, 1), 5, _B))
    # each block's lanes' positions and designs (the last block's spare lanes repeat the last
    # position)
    lanes = np.empty((T.shape[1], 2, _B), dtype=np.int64)
    for blk in range(b0, b1):
        for j in range(_B):
            p = min(blk * _B + j, n - 1)
            lanes[blk, 0, j] = p
            lanes[blk, 1, j] = p // n_phi
    n_rows = units.shape[0]
    width = T.shape[2]
    LS = T.shape[1] * width  # one level's stride, rows
    t = T.reshape(-1)
    # a unit at a time over a chunk of blocks (a call per block and unit would cost numba's
    # reference counts of a score of arrays each: more than the tangents of a short chain)
    for c0 in range(b0, b1, _CHUNK):
        c1 = min(c0 + _CHUNK, b1)
        for r in range(n_rows):
            op = units[r, 0]
            m = row_out[r, 1]
            if op == OP_FIXED or op == OP_CRANK:
                for blk in range(c0, c1):
                    _source(r, m, blk, width, n, n_phi, level, units, params, qoff, ppos,
                            n_pt, lcol, THS, t, LS, lanes)
            elif op == OP_POINT:
                _point(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol,
                       PS, THS, t, c0, c1, width, n_phi, LS, S, M1, C, lanes)
            elif op == OP_RRR:
                _rrr(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol,
                     PS, THS, t, c0, c1, width, n_phi, LS, S, M1, C, lanes)
            elif op == OP_RRP:
                _rrp(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol,
                     lcol, vcol, PS, THS, QS, t, c0, c1, width, n_phi, LS, S, M1, C, lanes)
            elif op == OP_RPR:
                _rpr(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol,
                     lcol, vcol, PS, THS, QS, t, c0, c1, width, n_phi, LS, S, M1, C, lanes)
            elif op == OP_LOOP:
                bad = _loop(units[r, 1], ppos[r], m, level, params, qoff, qm, tin, maps, groups,
                            unknowns, terms, cams, arcs, n_pt, n_l, lcol, vcol, THS, QS, t, c0,
                            c1, width, n_phi, LS, Jm, perm, Rh, X, TR, C, lanes)
                if bad:
                    return 1
    return 0


@njit(inline="always", **_OPTS)
def _source(r, m, blk, width, n, n_phi, level, units, params, qoff, ppos, n_pt, lcol, THS, t,
            LS, lanes):
    """A fixed point (dP = the parameters' unit vectors) or a crank (theta = phase + the
    setting, or phase + ratio * the shaft's angle) at block ``blk``."""
    tb = blk * width
    if units[r, 0] == OP_FIXED:
        off = tb + qoff[units[r, 1]]
        for lev in range(level + 1):
            _zero(t, off + lev * LS, 2 * m)
        _addc(t, off + ppos[r, units[r, 2]], 1.0)
        _addc(t, off + m + ppos[r, units[r, 3]], 1.0)
        return
    L = units[r, 1]
    jph = units[r, 2]
    jra = units[r, 3]
    jset = units[r, 4]
    off = tb + qoff[n_pt + L]
    for lev in range(level + 1):
        _zero(t, off + lev * LS, m)
    _addc(t, off + ppos[r, jph], 1.0)
    if jset >= 0:
        _addc(t, off + ppos[r, jset], 1.0)
    else:  # theta = phase + ratio * (the march's angle, whole turns included);
        # omega = ratio omega_shaft, epsilon = ratio epsilon_shaft
        kr = ppos[r, jra]
        col = lcol[L]
        for j in range(_B):
            ratio = params[lanes[blk, 1, j], jra]
            t[(off + kr) * _B + j] += (THS[0, lanes[blk, 0, j], col] - params[lanes[blk, 1, j], jph]) / ratio
            for lev in range(1, level + 1):
                t[(off + lev * LS + kr) * _B + j] = THS[lev, lanes[blk, 0, j], col] / ratio


@njit(**_OPTS)
def _point(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol, PS, THS, t,
           blk0, blk1, width, n_phi, LS, S, M1, C, lanes):
    """A rigid point P = O + R(theta) (u, v): dP = dO + R (du, dv) + J (P - O) dtheta; its
    velocity v = vO + omega J (P - O) and acceleration a = aO + eps J (P - O) - omega^2 (P - O)
    differentiated."""
    for blk in range(blk0, blk1):
        tb = blk * width
        i = units[r, 1]
        L = units[r, 2]
        o = units[r, 3]
        ju = units[r, 4]
        jv = units[r, 5]
        lc = lcol[L]
        ci = pcol[i]
        co = pcol[o]
        # slots: 0 cos, 1 sin, 2 -sin, 3 relx, 4 rely, 5 -rely; rates: 6 omega, 7 eps, 8 omega^2,
        # 9 -2 omega relx, 10 -2 omega rely
        for j in range(_B):
            p = lanes[blk, 0, j]
            relx = PS[0, p, ci, 0] - PS[0, p, co, 0]
            rely = PS[0, p, ci, 1] - PS[0, p, co, 1]
            C[3 * _B + j] = relx
            C[4 * _B + j] = rely
            C[5 * _B + j] = -rely
        if ju >= 0 or jv >= 0:  # cos and sin of the link's angle, for the point's own (u, v)
            for j in range(_B):
                # P - O = R(theta) (u, v) gives them without trigonometry, unless u = v = 0
                u = params[lanes[blk, 1, j], ju] if ju >= 0 else 0.0
                v = params[lanes[blk, 1, j], jv] if jv >= 0 else 0.0
                uv2 = u * u + v * v
                relx = C[3 * _B + j]
                rely = C[4 * _B + j]
                if uv2 > 0.0:
                    c = (relx * u + rely * v) / uv2
                    s = (rely * u - relx * v) / uv2
                else:
                    th = THS[0, lanes[blk, 0, j], lc] if lc >= 0 else 0.0
                    c = math.cos(th)
                    s = math.sin(th)
                C[j] = c
                C[_B + j] = s
                C[2 * _B + j] = -s
        off = tb + qoff[i]
        oo = tb + qoff[o]
        ol = tb + qoff[n_pt + L]
        mo = qm[o]
        ml = qm[n_pt + L]
        r0 = rin[r, 0]
        r1 = rin[r, 1]
        _zero(t, off, 2 * m)
        _accs(t, off, t, oo, maps, r0, mo, 1.0)
        _accs(t, off + m, t, oo + mo, maps, r0, mo, 1.0)
        _acc(t, off, t, ol, maps, r1, ml, C, 5 * _B)
        _acc(t, off + m, t, ol, maps, r1, ml, C, 3 * _B)
        if ju >= 0:
            _own(t, off + ppos[r, ju], C, 0)
            _own(t, off + m + ppos[r, ju], C, _B)
        if jv >= 0:
            _own(t, off + ppos[r, jv], C, 2 * _B)
            _own(t, off + m + ppos[r, jv], C, 0)
        if level == 0:
            continue
        for j in range(_B):
            p = lanes[blk, 0, j]
            w = THS[1, p, lc] if lc >= 0 else 0.0
            C[6 * _B + j] = w
            C[7 * _B + j] = THS[2, p, lc] if lc >= 0 else 0.0
            C[8 * _B + j] = w * w
            C[9 * _B + j] = -2.0 * w * C[3 * _B + j]
            C[10 * _B + j] = -2.0 * w * C[4 * _B + j]
        # drel = dP - dO (scratch: x row 0, y row M1)
        _diff(S, 0, t, off, m, maps, r0, oo, mo)
        _diff(S, M1, t, off + m, m, maps, r0, oo + mo, mo)
        o1 = off + LS
        _zero(t, o1, 2 * m)
        _accs(t, o1, t, oo + LS, maps, r0, mo, 1.0)
        _accs(t, o1 + m, t, oo + LS + mo, maps, r0, mo, 1.0)
        _acc(t, o1, t, ol + LS, maps, r1, ml, C, 5 * _B)
        _acc(t, o1 + m, t, ol + LS, maps, r1, ml, C, 3 * _B)
        for k in range(m):
            ax = (o1 + k) * _B
            ay = (o1 + m + k) * _B
            sx = k * _B
            sy = (M1 + k) * _B
            for j in range(_B):
                w = C[6 * _B + j]
                t[ax + j] -= w * S[sy + j]
                t[ay + j] += w * S[sx + j]
        if level == 1:
            continue
        o2 = off + 2 * LS
        _zero(t, o2, 2 * m)
        _accs(t, o2, t, oo + 2 * LS, maps, r0, mo, 1.0)
        _accs(t, o2 + m, t, oo + 2 * LS + mo, maps, r0, mo, 1.0)
        _acc(t, o2, t, ol + 2 * LS, maps, r1, ml, C, 5 * _B)
        _acc(t, o2 + m, t, ol + 2 * LS, maps, r1, ml, C, 3 * _B)
        _acc(t, o2, t, ol + LS, maps, r1, ml, C, 9 * _B)
        _acc(t, o2 + m, t, ol + LS, maps, r1, ml, C, 10 * _B)
        for k in range(m):
            ax = (o2 + k) * _B
            ay = (o2 + m + k) * _B
            sx = k * _B
            sy = (M1 + k) * _B
            for j in range(_B):
                ep = C[7 * _B + j]
                w2 = C[8 * _B + j]
                t[ax + j] -= ep * S[sy + j] + w2 * S[sx + j]
                t[ay + j] += ep * S[sx + j] - w2 * S[sy + j]


@njit(**_OPTS)
def _rrr(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, pcol, lcol, PS, THS, t,
         blk0, blk1, width, n_phi, LS, S, M1, C, lanes):
    """An RRR dyad: r_k . (dC - dP_k) = l_k dl_k (k = 1, 2) solved for dC, and the links'
    dtheta_k = r_k x (dC - dP_k) / l_k^2; at the rates r_k . (vC - v_k) = 0 and at the
    accelerations r_k . (aC - a_k) + |vC - v_k|^2 = 0 differentiated the same way."""
    for blk in range(blk0, blk1):
        tb = blk * width
        i1 = units[r, 1]
        i2 = units[r, 2]
        i = units[r, 3]
        j1 = units[r, 6]
        j2 = units[r, 7]
        c1 = pcol[i1]
        c2 = pcol[i2]
        cc = pcol[i]
        la = units[r, 4]
        lb = units[r, 5]
        # slots: 0 r1x, 1 r1y, 2 r2x, 3 r2y, 4 1/det, 5 1/l1^2, 6 1/l2^2, 7 l1, 8 l2,
        # 9 -r1x/l1^2, 10 r1y/l1^2, 11 -r2x/l2^2, 12 r2y/l2^2; per level: 13-16 g1x, g1y, g2x, g2y,
        # 17-20 v1x, v1y, v2x, v2y, 21 -2 x_a / l1, 22 -2 x_b / l2
        for j in range(_B):
            p = lanes[blk, 0, j]
            r1x = PS[0, p, cc, 0] - PS[0, p, c1, 0]
            r1y = PS[0, p, cc, 1] - PS[0, p, c1, 1]
            r2x = PS[0, p, cc, 0] - PS[0, p, c2, 0]
            r2y = PS[0, p, cc, 1] - PS[0, p, c2, 1]
            l1 = params[lanes[blk, 1, j], j1]
            l2 = params[lanes[blk, 1, j], j2]
            C[j] = r1x
            C[_B + j] = r1y
            C[2 * _B + j] = r2x
            C[3 * _B + j] = r2y
            C[4 * _B + j] = 1.0 / (r1x * r2y - r1y * r2x)
            w1 = 1.0 / (l1 * l1)
            w2 = 1.0 / (l2 * l2)
            C[5 * _B + j] = w1
            C[6 * _B + j] = w2
            C[7 * _B + j] = l1
            C[8 * _B + j] = l2
            C[9 * _B + j] = -r1x * w1
            C[10 * _B + j] = r1y * w1
            C[11 * _B + j] = -r2x * w2
            C[12 * _B + j] = r2y * w2
        m1 = qm[i1]
        m2 = qm[i2]
        q1 = tb + qoff[i1]
        q2 = tb + qoff[i2]
        ma = rin[r, 0]
        mb = rin[r, 1]
        oc = tb + qoff[i]
        oa = tb + qoff[n_pt + la]
        ob = tb + qoff[n_pt + lb]
        ka = ppos[r, j1]
        kb = ppos[r, j2]
        # scratch rows: rhs1 0, rhs2 M1, dr1 (x 2 M1, y 3 M1), dr2 (4, 5 M1), dw1 (6, 7), dw2 (8, 9)
        for lev in range(level + 1):
            sh = lev * LS
            _zero(S, 0, m)
            _zero(S, M1, m)
            _acc(S, 0, t, q1 + sh, maps, ma, m1, C, 0)
            _acc(S, 0, t, q1 + sh + m1, maps, ma, m1, C, _B)
            _acc(S, M1, t, q2 + sh, maps, mb, m2, C, 2 * _B)
            _acc(S, M1, t, q2 + sh + m2, maps, mb, m2, C, 3 * _B)
            if lev == 0:
                _own(S, ka, C, 7 * _B)
                _own(S, M1 + kb, C, 8 * _B)
            else:
                # -(g_k . dr_k), g_k = vC - v_k (rates) or aC - a_k (accelerations)
                for j in range(_B):
                    p = lanes[blk, 0, j]
                    C[13 * _B + j] = PS[lev, p, cc, 0] - PS[lev, p, c1, 0]
                    C[14 * _B + j] = PS[lev, p, cc, 1] - PS[lev, p, c1, 1]
                    C[15 * _B + j] = PS[lev, p, cc, 0] - PS[lev, p, c2, 0]
                    C[16 * _B + j] = PS[lev, p, cc, 1] - PS[lev, p, c2, 1]
                    C[17 * _B + j] = PS[1, p, cc, 0] - PS[1, p, c1, 0]
                    C[18 * _B + j] = PS[1, p, cc, 1] - PS[1, p, c1, 1]
                    C[19 * _B + j] = PS[1, p, cc, 0] - PS[1, p, c2, 0]
                    C[20 * _B + j] = PS[1, p, cc, 1] - PS[1, p, c2, 1]
                    C[21 * _B + j] = -2.0 * THS[lev, p, lcol[la]] / C[7 * _B + j]
                    C[22 * _B + j] = -2.0 * THS[lev, p, lcol[lb]] / C[8 * _B + j]
                for k in range(m):
                    a1 = k * _B
                    a2 = (M1 + k) * _B
                    for j in range(_B):
                        S[a1 + j] -= (C[13 * _B + j] * S[(2 * M1 + k) * _B + j]
                                      + C[14 * _B + j] * S[(3 * M1 + k) * _B + j])
                        S[a2 + j] -= (C[15 * _B + j] * S[(4 * M1 + k) * _B + j]
                                      + C[16 * _B + j] * S[(5 * M1 + k) * _B + j])
                if lev == 2:  # - 2 (vC - v_k) . (dvC - dv_k)
                    for k in range(m):
                        a1 = k * _B
                        a2 = (M1 + k) * _B
                        for j in range(_B):
                            S[a1 + j] -= 2.0 * (C[17 * _B + j] * S[(6 * M1 + k) * _B + j]
                                                + C[18 * _B + j] * S[(7 * M1 + k) * _B + j])
                            S[a2 + j] -= 2.0 * (C[19 * _B + j] * S[(8 * M1 + k) * _B + j]
                                                + C[20 * _B + j] * S[(9 * M1 + k) * _B + j])
            for k in range(m):
                s1 = k * _B
                s2 = (M1 + k) * _B
                ax = (oc + sh + k) * _B
                ay = (oc + sh + m + k) * _B
                aa = (oa + sh + k) * _B
                ab = (ob + sh + k) * _B
                for j in range(_B):
                    r1x = C[j]
                    r1y = C[_B + j]
                    r2x = C[2 * _B + j]
                    r2y = C[3 * _B + j]
                    idet = C[4 * _B + j]
                    dcx = (S[s1 + j] * r2y - S[s2 + j] * r1y) * idet
                    dcy = (r1x * S[s2 + j] - r2x * S[s1 + j]) * idet
                    t[ax + j] = dcx
                    t[ay + j] = dcy
                    t[aa + j] = (r1x * dcy - r1y * dcx) * C[5 * _B + j]
                    t[ab + j] = (r2x * dcy - r2y * dcx) * C[6 * _B + j]
            _acc(t, oa + sh, t, q1 + sh + m1, maps, ma, m1, C, 9 * _B)
            _acc(t, oa + sh, t, q1 + sh, maps, ma, m1, C, 10 * _B)
            _acc(t, ob + sh, t, q2 + sh + m2, maps, mb, m2, C, 11 * _B)
            _acc(t, ob + sh, t, q2 + sh, maps, mb, m2, C, 12 * _B)
            if lev == 0:
                if level == 0:
                    continue
                _diff(S, 2 * M1, t, oc, m, maps, ma, q1, m1)
                _diff(S, 3 * M1, t, oc + m, m, maps, ma, q1 + m1, m1)
                _diff(S, 4 * M1, t, oc, m, maps, mb, q2, m2)
                _diff(S, 5 * M1, t, oc + m, m, maps, mb, q2 + m2, m2)
            else:
                # + dr_k x g_k / l_k^2 - 2 (omega_k or eps_k) / l_k dl_k
                for k in range(m):
                    aa = (oa + sh + k) * _B
                    ab = (ob + sh + k) * _B
                    for j in range(_B):
                        t[aa + j] += (S[(2 * M1 + k) * _B + j] * C[14 * _B + j]
                                      - S[(3 * M1 + k) * _B + j] * C[13 * _B + j]) * C[5 * _B + j]
                        t[ab + j] += (S[(4 * M1 + k) * _B + j] * C[16 * _B + j]
                                      - S[(5 * M1 + k) * _B + j] * C[15 * _B + j]) * C[6 * _B + j]
                _own(t, oa + sh + ka, C, 21 * _B)
                _own(t, ob + sh + kb, C, 22 * _B)
                if lev == 1 and level == 2:
                    _diff(S, 6 * M1, t, oc + LS, m, maps, ma, q1 + LS, m1)
                    _diff(S, 7 * M1, t, oc + LS + m, m, maps, ma, q1 + LS + m1, m1)
                    _diff(S, 8 * M1, t, oc + LS, m, maps, mb, q2 + LS, m2)
                    _diff(S, 9 * M1, t, oc + LS + m, m, maps, mb, q2 + LS + m2, m2)


@njit(inline="always", **_OPTS)
def _along(s, e, gx, gy, angle):
    """The unit vector u of a slider's line from the offset (gx, gy) = s u + e n = (s + i e) u
    of its point (n = J u), without trigonometry unless s = e = 0 (then from the line's
    ``angle``, rad)."""
    se2 = s * s + e * e
    if se2 > 0.0:
        return (s * gx + e * gy) / se2, (s * gy - e * gx) / se2
    return math.cos(angle), math.sin(angle)


@njit(**_OPTS)
def _rrp(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol, lcol, vcol, PS,
         THS, QS, t, blk0, blk1, width, n_phi, LS, S, M1, C, lanes):
    """An RRP dyad: the slider C = G + e n + s u on the guide (G a point of the guide link,
    u = (cos beta, sin beta), beta = the guide's angle + alpha, n = J u) and the rod
    r1 . (dC - dB) = l dl, r1 = C - B; then its velocity and acceleration relations
    differentiated."""
    for blk in range(blk0, blk1):
        tb = blk * width
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
        vc = vcol[var]
        cb = pcol[b]
        ci = pcol[i]
        cg = pcol[gp]
        lg = lcol[gl]
        # slots: 0 ux, 1 uy, 2 nx, 3 ny, 4 s, 5 e, 6 l, 7 1 / (r1 . u), 8 1 / l^2, 9 r1x, 10 r1y,
        # 11 s nx - e ux, 12 s ny - e uy, 13 -r1x / l^2, 14 r1y / l^2
        for j in range(_B):
            p = lanes[blk, 0, j]
            s = QS[0, p, vc]
            e = params[lanes[blk, 1, j], je]
            # C - G = s u + e n = (s + i e) u
            ux, uy = _along(s, e, PS[0, p, ci, 0] - PS[0, p, cg, 0],
                            PS[0, p, ci, 1] - PS[0, p, cg, 1], THS[0, p, lcol[Ls]])
            ll = params[lanes[blk, 1, j], jl]
            r1x = PS[0, p, ci, 0] - PS[0, p, cb, 0]
            r1y = PS[0, p, ci, 1] - PS[0, p, cb, 1]
            w = 1.0 / (ll * ll)
            C[j] = ux
            C[_B + j] = uy
            C[2 * _B + j] = -uy
            C[3 * _B + j] = ux
            C[4 * _B + j] = s
            C[5 * _B + j] = e
            C[6 * _B + j] = ll
            C[7 * _B + j] = 1.0 / (r1x * ux + r1y * uy)
            C[8 * _B + j] = w
            C[9 * _B + j] = r1x
            C[10 * _B + j] = r1y
            C[11 * _B + j] = -s * uy - e * ux
            C[12 * _B + j] = s * ux - e * uy
            C[13 * _B + j] = -r1x * w
            C[14 * _B + j] = r1y * w
        qg = n_pt + gl
        og = tb + qoff[qg]
        mgl = qm[qg]
        rg = rin[r, 1]
        # scratch rows: dbeta = dtheta_guide + dalpha (0), known (x M1, y 2 M1), ds (3 M1)
        _zero(S, 0, m)
        _accs(S, 0, t, og, maps, rg, mgl, 1.0)
        if ja >= 0:
            _addc(S, ppos[r, ja], 1.0)
        # known = dG + n de - e u dbeta + s n dbeta (the foot's and the slider offset's motion)
        kx = M1
        ky = 2 * M1
        mg = qm[gp]
        ogp = tb + qoff[gp]
        rp = rin[r, 0]
        _zero(S, kx, m)
        _zero(S, ky, m)
        _accs(S, kx, t, ogp, maps, rp, mg, 1.0)
        _accs(S, ky, t, ogp + mg, maps, rp, mg, 1.0)
        kj = ppos[r, je]
        _own(S, kx + kj, C, 2 * _B)
        _own(S, ky + kj, C, 3 * _B)
        for k in range(m):
            a0 = k * _B
            ax = (kx + k) * _B
            ay = (ky + k) * _B
            for j in range(_B):
                S[ax + j] += C[11 * _B + j] * S[a0 + j]
                S[ay + j] += C[12 * _B + j] * S[a0 + j]
        # r1 . (dC - dB) = l dl with dC = known + u ds
        ds = 3 * M1
        _zero(S, ds, m)
        mb = qm[b]
        ob = tb + qoff[b]
        rb = rin[r, 2]
        _acc(S, ds, t, ob, maps, rb, mb, C, 9 * _B)
        _acc(S, ds, t, ob + mb, maps, rb, mb, C, 10 * _B)
        kl = ppos[r, jl]
        _own(S, ds + kl, C, 6 * _B)
        oc = tb + qoff[i]
        ov = tb + qoff[n_pt + n_l + var]
        o1 = tb + qoff[n_pt + L1]
        os_ = tb + qoff[n_pt + Ls]
        for k in range(m):
            a0 = k * _B
            ax = (kx + k) * _B
            ay = (ky + k) * _B
            ad = (ds + k) * _B
            for j in range(_B):
                r1x = C[9 * _B + j]
                r1y = C[10 * _B + j]
                dsk = (S[ad + j] - r1x * S[ax + j] - r1y * S[ay + j]) * C[7 * _B + j]
                dcx = S[ax + j] + C[j] * dsk
                dcy = S[ay + j] + C[_B + j] * dsk
                t[(oc + k) * _B + j] = dcx
                t[(oc + m + k) * _B + j] = dcy
                t[(ov + k) * _B + j] = dsk
                t[(o1 + k) * _B + j] = (r1x * dcy - r1y * dcx) * C[8 * _B + j]
                t[(os_ + k) * _B + j] = S[a0 + j]
        _acc(t, o1, t, ob + mb, maps, rb, mb, C, 13 * _B)
        _acc(t, o1, t, ob, maps, rb, mb, C, 14 * _B)
        if level == 0:
            continue
        # the rates: slots 15 r1 . n, 16 wg, 17 sd, 18 Wx, 19 Wy, 20 (r1 . W) / (r1 . u),
        # 21 vrx, 22 vry, 23 -2 omega_rod / l; for x, y: 24/25 -e u + s n (of dwg), 26/27 -u wg
        # (of de), 28/29 wg n (of ds), 30/31 -e wg n - s wg u (of dbeta); 32/33 r1 / (r1 . u)
        for j in range(_B):
            p = lanes[blk, 0, j]
            ux = C[j]
            uy = C[_B + j]
            nx = C[2 * _B + j]
            ny = C[3 * _B + j]
            s = C[4 * _B + j]
            e = C[5 * _B + j]
            r1x = C[9 * _B + j]
            r1y = C[10 * _B + j]
            iru = C[7 * _B + j]
            wg = THS[1, p, lg] if lg >= 0 else 0.0
            Wx = PS[1, p, cg, 0] - e * wg * ux + s * wg * nx - PS[1, p, cb, 0]
            Wy = PS[1, p, cg, 1] - e * wg * uy + s * wg * ny - PS[1, p, cb, 1]
            C[15 * _B + j] = r1x * nx + r1y * ny
            C[16 * _B + j] = wg
            C[17 * _B + j] = QS[1, p, vc]
            C[18 * _B + j] = Wx
            C[19 * _B + j] = Wy
            C[20 * _B + j] = (r1x * Wx + r1y * Wy) * iru
            C[21 * _B + j] = PS[1, p, ci, 0] - PS[1, p, cb, 0]
            C[22 * _B + j] = PS[1, p, ci, 1] - PS[1, p, cb, 1]
            C[23 * _B + j] = -2.0 * THS[1, p, lcol[L1]] / C[6 * _B + j]
            C[24 * _B + j] = -e * ux + s * nx
            C[25 * _B + j] = -e * uy + s * ny
            C[26 * _B + j] = -ux * wg
            C[27 * _B + j] = -uy * wg
            C[28 * _B + j] = wg * nx
            C[29 * _B + j] = wg * ny
            C[30 * _B + j] = -e * wg * nx - s * wg * ux
            C[31 * _B + j] = -e * wg * ny - s * wg * uy
            C[32 * _B + j] = r1x * iru
            C[33 * _B + j] = r1y * iru
        # scratch rows: dr1 (x 4 M1, y 5 M1), dWb = dW + dvB (6, 7), dsd (8)
        _diff(S, 4 * M1, t, oc, m, maps, rb, ob, mb)
        _diff(S, 5 * M1, t, oc + m, m, maps, rb, ob + mb, mb)
        # dW + dvB = dvG - u (wg de + e dwg) - e wg du + n (wg ds + s dwg) + s wg dn,
        # du = n dbeta, dn = -u dbeta
        for c in range(2):
            oW = (6 + c) * M1
            _zero(S, oW, m)
            _accs(S, oW, t, ogp + LS + c * mg, maps, rp, mg, 1.0)
            _acc(S, oW, t, og + LS, maps, rg, mgl, C, (24 + c) * _B)
            _own(S, oW + kj, C, (26 + c) * _B)
            for k in range(m):
                aw = (oW + k) * _B
                av = (ov + k) * _B
                a0 = k * _B
                for j in range(_B):
                    S[aw + j] += C[(28 + c) * _B + j] * t[av + j] + C[(30 + c) * _B + j] * S[a0 + j]
        # dsd = -(W . dr1 + r1 . dW) / ru + (rW / ru^2) (u . dr1 + r1 . du)
        dsd = 8 * M1
        _zero(S, dsd, m)
        _acc(S, dsd, t, ob + LS, maps, rb, mb, C, 32 * _B)
        _acc(S, dsd, t, ob + LS + mb, maps, rb, mb, C, 33 * _B)
        for k in range(m):
            a0 = k * _B
            a4 = (4 * M1 + k) * _B
            a5 = (5 * M1 + k) * _B
            a6 = (6 * M1 + k) * _B
            a7 = (7 * M1 + k) * _B
            ad = (dsd + k) * _B
            for j in range(_B):
                S[ad + j] += (-(C[18 * _B + j] * S[a4 + j] + C[19 * _B + j] * S[a5 + j]
                                + C[9 * _B + j] * S[a6 + j] + C[10 * _B + j] * S[a7 + j])
                              + C[20 * _B + j] * (C[j] * S[a4 + j] + C[_B + j] * S[a5 + j]
                                                  + C[15 * _B + j] * S[a0 + j])) * C[7 * _B + j]
        for k in range(m):
            a0 = k * _B
            a4 = (4 * M1 + k) * _B
            a5 = (5 * M1 + k) * _B
            a6 = (6 * M1 + k) * _B
            a7 = (7 * M1 + k) * _B
            ad = (dsd + k) * _B
            for j in range(_B):
                sd = C[17 * _B + j]
                dvx = S[a6 + j] + C[j] * S[ad + j] + sd * C[2 * _B + j] * S[a0 + j]
                dvy = S[a7 + j] + C[_B + j] * S[ad + j] + sd * C[3 * _B + j] * S[a0 + j]
                t[(oc + LS + k) * _B + j] = dvx
                t[(oc + LS + m + k) * _B + j] = dvy
                t[(ov + LS + k) * _B + j] = S[ad + j]
                # domega_rod = (dr1 x vrel + r1 x (dvC - dvB)) / l^2 - 2 omega / l dl
                t[(o1 + LS + k) * _B + j] = (S[a4 + j] * C[22 * _B + j] - S[a5 + j] * C[21 * _B + j]
                                             + C[9 * _B + j] * dvy - C[10 * _B + j] * dvx
                                             ) * C[8 * _B + j]
        _acc(t, o1 + LS, t, ob + LS + mb, maps, rb, mb, C, 13 * _B)
        _acc(t, o1 + LS, t, ob + LS, maps, rb, mb, C, 14 * _B)
        _own(t, o1 + LS + kl, C, 23 * _B)
        _zero(t, os_ + LS, m)
        _accs(t, os_ + LS, t, og + LS, maps, rg, mgl, 1.0)
        if level == 1:
            continue
        # the accelerations: aC = K + aB + sdd u, K = aG - e (eg u + wg^2 n) + 2 sd wg n
        # + s (eg n - wg^2 u) - aB. Slots: 34 Kx, 35 Ky, 36 (r1 . K + |w|^2) / ru, 37 arx, 38 ary,
        # 39 -2 eps_rod / l, 50 sdd; for x, y: 40/41 of dwg, 42/43 of de, 44/45 of dsd,
        # 46/47 of ds, 48/49 of dbeta (the coefficient of deg is 24/25's)
        for j in range(_B):
            p = lanes[blk, 0, j]
            ux = C[j]
            uy = C[_B + j]
            nx = C[2 * _B + j]
            ny = C[3 * _B + j]
            s = C[4 * _B + j]
            e = C[5 * _B + j]
            wg = C[16 * _B + j]
            sd = C[17 * _B + j]
            wg2 = wg * wg
            eg = THS[2, p, lg] if lg >= 0 else 0.0
            Kx = (PS[2, p, cg, 0] - e * (eg * ux + wg2 * nx) + 2.0 * sd * wg * nx
                  + s * (eg * nx - wg2 * ux) - PS[2, p, cb, 0])
            Ky = (PS[2, p, cg, 1] - e * (eg * uy + wg2 * ny) + 2.0 * sd * wg * ny
                  + s * (eg * ny - wg2 * uy) - PS[2, p, cb, 1])
            wx = C[21 * _B + j]
            wy = C[22 * _B + j]
            C[34 * _B + j] = Kx
            C[35 * _B + j] = Ky
            C[36 * _B + j] = ((C[9 * _B + j] * Kx + C[10 * _B + j] * Ky + wx * wx + wy * wy)
                              * C[7 * _B + j])
            C[37 * _B + j] = PS[2, p, ci, 0] - PS[2, p, cb, 0]
            C[38 * _B + j] = PS[2, p, ci, 1] - PS[2, p, cb, 1]
            C[39 * _B + j] = -2.0 * THS[2, p, lcol[L1]] / C[6 * _B + j]
            C[50 * _B + j] = QS[2, p, vc]
            for c in range(2):
                uc = ux if c == 0 else uy
                nc = nx if c == 0 else ny
                C[(40 + c) * _B + j] = -2.0 * e * wg * nc + 2.0 * sd * nc - 2.0 * s * wg * uc
                C[(42 + c) * _B + j] = -(eg * uc + wg2 * nc)
                C[(44 + c) * _B + j] = 2.0 * wg * nc
                C[(46 + c) * _B + j] = eg * nc - wg2 * uc
                C[(48 + c) * _B + j] = (-e * eg * nc + e * wg2 * uc - 2.0 * sd * wg * uc
                                        - s * eg * uc - s * wg2 * nc)
        # scratch rows: dKb = dK + daB (x 6 M1, y 7 M1), dsdd 8, dw (9, 10)
        for c in range(2):
            oK = (6 + c) * M1
            _zero(S, oK, m)
            _accs(S, oK, t, ogp + 2 * LS + c * mg, maps, rp, mg, 1.0)
            _acc(S, oK, t, og + 2 * LS, maps, rg, mgl, C, (24 + c) * _B)  # deg
            _acc(S, oK, t, og + LS, maps, rg, mgl, C, (40 + c) * _B)  # dwg
            _own(S, oK + kj, C, (42 + c) * _B)
            for k in range(m):
                aK = (oK + k) * _B
                a1 = (ov + LS + k) * _B
                a2 = (ov + k) * _B
                a0 = k * _B
                for j in range(_B):
                    S[aK + j] += (C[(44 + c) * _B + j] * t[a1 + j] + C[(46 + c) * _B + j] * t[a2 + j]
                                  + C[(48 + c) * _B + j] * S[a0 + j])
        _diff(S, 9 * M1, t, oc + LS, m, maps, rb, ob + LS, mb)
        _diff(S, 10 * M1, t, oc + LS + m, m, maps, rb, ob + LS + mb, mb)
        dsdd = 8 * M1
        _zero(S, dsdd, m)
        _acc(S, dsdd, t, ob + 2 * LS, maps, rb, mb, C, 32 * _B)
        _acc(S, dsdd, t, ob + 2 * LS + mb, maps, rb, mb, C, 33 * _B)
        for k in range(m):
            a0 = k * _B
            a4 = (4 * M1 + k) * _B
            a5 = (5 * M1 + k) * _B
            a6 = (6 * M1 + k) * _B
            a7 = (7 * M1 + k) * _B
            a9 = (9 * M1 + k) * _B
            a10 = (10 * M1 + k) * _B
            ad = (dsdd + k) * _B
            for j in range(_B):
                S[ad + j] += (-(C[34 * _B + j] * S[a4 + j] + C[35 * _B + j] * S[a5 + j]
                                + C[9 * _B + j] * S[a6 + j] + C[10 * _B + j] * S[a7 + j]
                                + 2.0 * (C[21 * _B + j] * S[a9 + j] + C[22 * _B + j] * S[a10 + j]))
                              + C[36 * _B + j] * (C[j] * S[a4 + j] + C[_B + j] * S[a5 + j]
                                                  + C[15 * _B + j] * S[a0 + j])) * C[7 * _B + j]
        for k in range(m):
            a0 = k * _B
            a4 = (4 * M1 + k) * _B
            a5 = (5 * M1 + k) * _B
            a6 = (6 * M1 + k) * _B
            a7 = (7 * M1 + k) * _B
            ad = (dsdd + k) * _B
            for j in range(_B):
                sdd = C[50 * _B + j]
                dax = S[a6 + j] + C[j] * S[ad + j] + sdd * C[2 * _B + j] * S[a0 + j]
                day = S[a7 + j] + C[_B + j] * S[ad + j] + sdd * C[3 * _B + j] * S[a0 + j]
                t[(oc + 2 * LS + k) * _B + j] = dax
                t[(oc + 2 * LS + m + k) * _B + j] = day
                t[(ov + 2 * LS + k) * _B + j] = S[ad + j]
                t[(o1 + 2 * LS + k) * _B + j] = (S[a4 + j] * C[38 * _B + j]
                                                 - S[a5 + j] * C[37 * _B + j]
                                                 + C[9 * _B + j] * day - C[10 * _B + j] * dax
                                                 ) * C[8 * _B + j]
        _acc(t, o1 + 2 * LS, t, ob + 2 * LS + mb, maps, rb, mb, C, 13 * _B)
        _acc(t, o1 + 2 * LS, t, ob + 2 * LS, maps, rb, mb, C, 14 * _B)
        _own(t, o1 + 2 * LS + kl, C, 39 * _B)
        _zero(t, os_ + 2 * LS, m)
        _accs(t, os_ + 2 * LS, t, og + 2 * LS, maps, rg, mgl, 1.0)


@njit(**_OPTS)
def _rpr(r, m, level, units, params, qoff, qm, rin, ppos, maps, n_pt, n_l, pcol, lcol, vcol, PS,
         THS, QS, t, blk0, blk1, width, n_phi, LS, S, M1, C, lanes):
    """An RPR guide: B - A = e n + s u (u along the slot link, n = J u), so dB - dA =
    u (ds - e dtheta) + n (de + s dtheta); its velocity and acceleration relations
    differentiated."""
    for blk in range(blk0, blk1):
        tb = blk * width
        b = units[r, 1]
        pv = units[r, 2]
        L = units[r, 3]
        Lb = units[r, 4]
        je = units[r, 5]
        var = units[r, 7]
        vc = vcol[var]
        lc = lcol[L]
        cb = pcol[b]
        cp = pcol[pv]
        # slots: 0 ux, 1 uy, 2 nx, 3 ny, 4 s, 5 e, 6 -1 / s; rates: 7 omega, 8 (vB - vA) . u,
        # 9 (vB - vA) . n; accelerations: 10 eps, 11 sd, 12 (aB - aA) . u, 13 (aB - aA) . n,
        # 14 omega^2 / s, 15 eps + e omega^2 / s
        for j in range(_B):
            p = lanes[blk, 0, j]
            s = QS[0, p, vc]
            e = params[lanes[blk, 1, j], je]
            # B - A = s u + e n = (s + i e) u
            ux, uy = _along(s, e, PS[0, p, cb, 0] - PS[0, p, cp, 0],
                            PS[0, p, cb, 1] - PS[0, p, cp, 1], THS[0, p, lc])
            C[j] = ux
            C[_B + j] = uy
            C[2 * _B + j] = -uy
            C[3 * _B + j] = ux
            C[4 * _B + j] = s
            C[5 * _B + j] = e
            C[6 * _B + j] = -1.0 / s
            if level >= 1:
                w = THS[1, p, lc]
                dvx = PS[1, p, cb, 0] - PS[1, p, cp, 0]
                dvy = PS[1, p, cb, 1] - PS[1, p, cp, 1]
                C[7 * _B + j] = w
                C[8 * _B + j] = dvx * ux + dvy * uy
                C[9 * _B + j] = -dvx * uy + dvy * ux
            if level >= 2:
                ep = THS[2, p, lc]
                dax = PS[2, p, cb, 0] - PS[2, p, cp, 0]
                day = PS[2, p, cb, 1] - PS[2, p, cp, 1]
                C[10 * _B + j] = ep
                C[11 * _B + j] = QS[1, p, vc]
                C[12 * _B + j] = dax * ux + day * uy
                C[13 * _B + j] = -dax * uy + day * ux
                C[14 * _B + j] = w * w / s
                C[15 * _B + j] = ep + e * w * w / s
        kj = ppos[r, je]
        mb = qm[b]
        mp = qm[pv]
        ob = tb + qoff[b]
        opv = tb + qoff[pv]
        ol = tb + qoff[n_pt + L]
        ov = tb + qoff[n_pt + n_l + var]
        r0 = rin[r, 0]
        r1 = rin[r, 1]
        for lev in range(level + 1):
            sh = lev * LS
            # dd = d(B - A) at this level (x row 0, y row M1)
            _zero(S, 0, m)
            _zero(S, M1, m)
            _accs(S, 0, t, ob + sh, maps, r0, mb, 1.0)
            _accs(S, M1, t, ob + sh + mb, maps, r0, mb, 1.0)
            _accs(S, 0, t, opv + sh, maps, r1, mp, -1.0)
            _accs(S, M1, t, opv + sh + mp, maps, r1, mp, -1.0)
            if lev == 0:
                for k in range(m):
                    a = (ol + k) * _B
                    for j in range(_B):
                        t[a + j] = ((C[2 * _B + j] * S[k * _B + j] + C[3 * _B + j]
                                     * S[(M1 + k) * _B + j]) / C[4 * _B + j])
                _own(t, ol + kj, C, 6 * _B)  # dtheta = (n . dd - de) / s
                for k in range(m):  # ds = u . dd + e dtheta
                    a = (ov + k) * _B
                    for j in range(_B):
                        t[a + j] = (C[j] * S[k * _B + j] + C[_B + j] * S[(M1 + k) * _B + j]
                                    + C[5 * _B + j] * t[(ol + k) * _B + j])
            elif lev == 1:
                # dw = (dv . dn + n . ddv) / s - (w / s) ds; dsd = dv . du + u . ddv + w de + e dw
                for k in range(m):
                    for j in range(_B):
                        sx = S[k * _B + j]
                        sy = S[(M1 + k) * _B + j]
                        dth = t[(ol + k) * _B + j]
                        dw = ((-C[8 * _B + j] * dth + C[2 * _B + j] * sx + C[3 * _B + j] * sy
                               - C[7 * _B + j] * t[(ov + k) * _B + j]) / C[4 * _B + j])
                        t[(ol + LS + k) * _B + j] = dw
                        t[(ov + LS + k) * _B + j] = (C[9 * _B + j] * dth + C[j] * sx
                                                     + C[_B + j] * sy + C[5 * _B + j] * dw)
                _own(t, ov + LS + kj, C, 7 * _B)
            else:
                for k in range(m):
                    for j in range(_B):
                        sx = S[k * _B + j]
                        sy = S[(M1 + k) * _B + j]
                        dth = t[(ol + k) * _B + j]
                        dwk = t[(ol + LS + k) * _B + j]
                        ds = t[(ov + k) * _B + j]
                        w = C[7 * _B + j]
                        s = C[4 * _B + j]
                        e = C[5 * _B + j]
                        dep = ((-C[12 * _B + j] * dth + C[2 * _B + j] * sx + C[3 * _B + j] * sy
                                - 2.0 * (t[(ov + LS + k) * _B + j] * w + C[11 * _B + j] * dwk)
                                + 2.0 * e * w * dwk) / s - C[10 * _B + j] / s * ds)
                        t[(ol + sh + k) * _B + j] = dep
                        t[(ov + sh + k) * _B + j] = (C[13 * _B + j] * dth + C[j] * sx
                                                     + C[_B + j] * sy + e * dep + w * w * ds
                                                     + 2.0 * s * w * dwk)
                _own(t, ol + sh + kj, C, 14 * _B)
                _own(t, ov + sh + kj, C, 15 * _B)
            if Lb >= 0:
                _copy(t, tb + qoff[n_pt + Lb] + sh, t, ol + sh, m)


@njit(inline="always", **_OPTS)
def _src(Rh, rx, ry, C, cx, cy, t, so, maps, mo, mq, own, m):
    """A term's source tangent t[so:] times the lanes' vectors (C[cx], C[cy]) added to the
    right-hand sides (rows rx, ry): through the map of the input (mo, mq), or, for the
    group's own unknown (``own``), as it is."""
    if own:
        for k in range(m):
            a = (so + k) * _B
            bx = (rx + k) * _B
            by = (ry + k) * _B
            for j in range(_B):
                x = t[a + j]
                Rh[bx + j] += C[cx + j] * x
                Rh[by + j] += C[cy + j] * x
    else:
        for k in range(mq):
            h = maps[mo + k]
            a = (so + k) * _B
            bx = (rx + h) * _B
            by = (ry + h) * _B
            for j in range(_B):
                x = t[a + j]
                Rh[bx + j] += C[cx + j] * x
                Rh[by + j] += C[cy + j] * x


@njit(**_OPTS)
def _loop(g, pp, m, level, params, qoff, qm, tin, maps, groups, unknowns, terms, cams, arcs,
          n_pt, n_l, lcol, vcol, THS, QS, t, blk0, blk1, width, n_phi, LS, Jm, perm, Rh, X, TR, C, lanes):
    """A loop group: J d(q, q_dot or q_ddot) = -(the known part of each term's tangent),
    sum over terms of sign * T_t = 0, one factorisation of J per lane for every level (the
    unknowns enter each level's closure linearly with the same coefficients). pp: each
    parameter's place in the group's support. Returns True where a cam contact lies on no
    arc."""
    for blk in range(blk0, blk1):
        tb = blk * width
        M1 = Rh.shape[0] // (Jm.shape[1] * _B)  # Rh's row stride, rows
        nq = groups[g, 0]
        u0 = groups[g, 1]
        t0 = groups[g, 3]
        t1 = t0 + groups[g, 4]
        for j in range(_B):
            for a in range(nq):
                for h in range(nq):
                    Jm[j, a, h] = 0.0
        # slots: 0 cos psi, 1 sin psi, 2 L, 3 L', 4 L'', 5 psi', 6 psi'', 7/8 the length's vector,
        # 9/10 the angle's, 11-16 the cam body's vectors of d theta_c, d omega_c, d eps_c,
        # 17/18 the cam's centre rc, 19 omega_c, 20 eps_c, 21/22 cos, sin theta_c
        for lev in range(level + 1):
            sh = lev * LS
            _zero(Rh, 0, nq * M1)
            for tt in range(t0, t1):
                typ = terms[tt, 0]
                row = 2 * terms[tt, 1]
                rx = row * M1  # the term's two equations' right-hand sides in Rh, rows
                ry = rx + M1
                sg = -float(terms[tt, 2])  # (moved to the right-hand side)
                if typ == TERM_POINT:
                    q = terms[tt, 4]
                    mq = qm[q]
                    o = tb + qoff[q] + sh
                    _accs(Rh, rx, t, o, maps, tin[tt, 0], mq, sg)
                    _accs(Rh, ry, t, o + mq, maps, tin[tt, 0], mq, sg)
                    continue
                ai = terms[tt, 6]
                ja = terms[tt, 7]
                lc = terms[tt, 10]
                ac = terms[tt, 11]
                k0 = tt - t0
                is_link = terms[tt, 5] == SRC_LINK
                qa = n_pt + ai if is_link else n_pt + n_l + ai
                col = lcol[ai] if is_link else vcol[ai]
                li = terms[tt, 4]
                par_len = typ == TERM_VEC and terms[tt, 3] == SRC_PARAM
                ql = -1 if typ != TERM_VEC or par_len else n_pt + n_l + li
                cam = terms[tt, 8]
                jo = terms[tt, 9]
                cl = cams[cam, 0] if typ != TERM_VEC else 0
                ccol = lcol[cl] if typ != TERM_VEC else -1
                for j in range(_B):
                    p = lanes[blk, 0, j]
                    d = lanes[blk, 1, j]
                    if is_link:
                        psi = THS[0, p, col] if col >= 0 else 0.0
                        wa = THS[1, p, col] if col >= 0 and level >= 1 else 0.0
                        aa = THS[2, p, col] if col >= 0 and level >= 2 else 0.0
                    else:
                        psi = QS[0, p, col]
                        wa = QS[1, p, col] if level >= 1 else 0.0
                        aa = QS[2, p, col] if level >= 2 else 0.0
                    C[5 * _B + j] = wa
                    C[6 * _B + j] = aa
                    if lev == 0:
                        if ja >= 0:
                            psi += params[d, ja]
                        TR[k0, 0, j] = math.cos(psi)
                        TR[k0, 1, j] = math.sin(psi)
                    c = TR[k0, 0, j]
                    sn = TR[k0, 1, j]
                    C[j] = c
                    C[_B + j] = sn
                    Ld = 0.0
                    Ldd = 0.0
                    if typ == TERM_VEC:
                        if par_len:
                            L = params[d, li]
                        else:
                            L = QS[0, p, vcol[li]]
                            if level >= 1:
                                Ld = QS[1, p, vcol[li]]
                            if level >= 2:
                                Ldd = QS[2, p, vcol[li]]
                    else:  # TERM_CAM: p_cp + R(theta_c) c_k + (R_k + off) e^{i psi}
                        tc = THS[0, p, ccol] if ccol >= 0 else 0.0
                        if lev == 0:
                            ka = arc_of(cam, psi - tc, d, params, cams, arcs)
                            if ka < 0:
                                return True
                            TR[k0, 2, j] = ka
                            TR[k0, 3, j] = math.cos(tc)
                            TR[k0, 4, j] = math.sin(tc)
                        ka = int(TR[k0, 2, j])
                        cc = TR[k0, 3, j]
                        cs = TR[k0, 4, j]
                        ccx = params[d, arcs[ka, 0]]
                        ccy = params[d, arcs[ka, 1]]
                        L = params[d, arcs[ka, 2]]
                        if jo >= 0:
                            L += params[d, jo]
                        rcx = cc * ccx - cs * ccy
                        rcy = cs * ccx + cc * ccy
                        wc = THS[1, p, ccol] if ccol >= 0 and level >= 1 else 0.0
                        ec = THS[2, p, ccol] if ccol >= 0 and level >= 2 else 0.0
                        # the arc centre's parameters: lane by lane (each lane may be on its own
                        # arc)
                        kx = pp[arcs[ka, 0]]
                        ky = pp[arcs[ka, 1]]
                        if lev == 0:
                            vxx, vxy, vyx, vyy = cc, cs, -cs, cc
                            C[11 * _B + j] = -rcy
                            C[12 * _B + j] = rcx
                        elif lev == 1:
                            vxx, vxy, vyx, vyy = -wc * cs, wc * cc, -wc * cc, -wc * cs
                            C[11 * _B + j] = -wc * rcx
                            C[12 * _B + j] = -wc * rcy
                            C[13 * _B + j] = -rcy
                            C[14 * _B + j] = rcx
                        else:
                            w2 = wc * wc
                            vxx = -ec * cs - w2 * cc
                            vxy = ec * cc - w2 * cs
                            vyx = -ec * cc + w2 * cs
                            vyy = -ec * cs - w2 * cc
                            C[11 * _B + j] = -ec * rcx + w2 * rcy
                            C[12 * _B + j] = -ec * rcy - w2 * rcx
                            C[13 * _B + j] = -2.0 * wc * rcx
                            C[14 * _B + j] = -2.0 * wc * rcy
                            C[15 * _B + j] = -rcy
                            C[16 * _B + j] = rcx
                        for h in range(11, 17):
                            C[h * _B + j] *= sg
                        Rh[(rx + kx) * _B + j] += sg * vxx
                        Rh[(ry + kx) * _B + j] += sg * vxy
                        Rh[(rx + ky) * _B + j] += sg * vyx
                        Rh[(ry + ky) * _B + j] += sg * vyy
                    C[2 * _B + j] = L
                    C[3 * _B + j] = Ld
                    C[4 * _B + j] = Ldd
                    if lev == 0:
                        if lc >= 0:
                            Jm[j, row, lc] += -sg * c
                            Jm[j, row + 1, lc] += -sg * sn
                        if ac >= 0:
                            Jm[j, row, ac] -= -sg * L * sn
                            Jm[j, row + 1, ac] += -sg * L * c
                if typ != TERM_VEC:
                    # the cam's body: the pivot's tangent, its angle's
                    cp = cams[cam, 1]
                    mq = qm[cp]
                    o = tb + qoff[cp] + sh
                    _accs(Rh, rx, t, o, maps, tin[tt, 0], mq, sg)
                    _accs(Rh, ry, t, o + mq, maps, tin[tt, 0], mq, sg)
                    qc = n_pt + cl
                    oc = tb + qoff[qc]
                    mc = qm[qc]
                    rc = tin[tt, 3]
                    for kk in range(lev + 1):
                        _src(Rh, rx, ry, C, (11 + 2 * kk) * _B, (12 + 2 * kk) * _B, t, oc + kk * LS,
                             maps, rc, mc, False, m)
                # E / IE coefficients (ce, ci) of the length's tangents dL_kk and the angle's
                # p_kk (p_0 with the alpha parameter's): level 0: dL0 (1, 0), p0 (0, L); level 1:
                # dL1 (1, 0), p0 (-L w, L'), dL0 (0, w), p1 (0, L); level 2: dL2 (1, 0),
                # p0 (-2 L' w - L a, L'' - L w^2), dL1 (0, 2 w), p1 (-2 L w, 2 L'), dL0 (-w^2, a),
                # p2 (0, L); w, a the angle's rate and acceleration
                oa = tb + qoff[qa]
                for kk in range(lev + 1):  # kk: the level of the tangent
                    for j in range(_B):
                        c = C[j]
                        sn = C[_B + j]
                        L = C[2 * _B + j]
                        Ld = C[3 * _B + j]
                        w = C[5 * _B + j]
                        if kk == lev:
                            ceL, ciL, ceP, ciP = 1.0, 0.0, 0.0, L
                        elif lev == 1:  # kk == 0
                            ceL, ciL, ceP, ciP = 0.0, w, -L * w, Ld
                        elif kk == 1:  # lev == 2
                            ceL, ciL, ceP, ciP = 0.0, 2.0 * w, -2.0 * L * w, 2.0 * Ld
                        else:  # lev == 2, kk == 0
                            a = C[6 * _B + j]
                            ceL, ciL = -w * w, a
                            ceP, ciP = -2.0 * Ld * w - L * a, C[4 * _B + j] - L * w * w
                        vLx = sg * (ceL * c - ciL * sn)
                        vLy = sg * (ceL * sn + ciL * c)
                        C[7 * _B + j] = vLx
                        C[8 * _B + j] = vLy
                        C[9 * _B + j] = sg * (ceP * c - ciP * sn)
                        C[10 * _B + j] = sg * (ceP * sn + ciP * c)
                        if kk == 0 and ql < 0:  # a parameter length (the cam's radius: per lane)
                            kl = pp[li] if typ == TERM_VEC else pp[arcs[int(TR[k0, 2, j]), 2]]
                            Rh[(rx + kl) * _B + j] += vLx
                            Rh[(ry + kl) * _B + j] += vLy
                            if typ != TERM_VEC and jo >= 0:
                                Rh[(rx + pp[jo]) * _B + j] += vLx
                                Rh[(ry + pp[jo]) * _B + j] += vLy
                    ks = kk * LS
                    if ql >= 0 and not (kk == lev and lc >= 0):
                        _src(Rh, rx, ry, C, 7 * _B, 8 * _B, t, tb + qoff[ql] + ks, maps, tin[tt, 1],
                             qm[ql], lc >= 0, m)
                    # the angle's tangent at level kk
                    if not (kk == lev and ac >= 0):
                        _src(Rh, rx, ry, C, 9 * _B, 10 * _B, t, oa + ks, maps, tin[tt, 2], qm[qa],
                             ac >= 0, m)
                    if kk == 0 and ja >= 0:
                        _own(Rh, rx + pp[ja], C, 9 * _B)
                        _own(Rh, ry + pp[ja], C, 10 * _B)
            if lev == 0:
                for j in range(_B):
                    _lu(Jm, perm, j, nq)
            _lu_solve(Jm, perm, nq, Rh, X, m, M1, C)
            for h in range(nq):
                idx = unknowns[u0 + h, 1]
                q = n_pt + idx if unknowns[u0 + h, 0] == 0 else n_pt + n_l + idx
                _copy(t, tb + qoff[q] + sh, X, h * M1, m)
    return False

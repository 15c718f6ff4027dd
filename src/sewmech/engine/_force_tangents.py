"""Compiled derivatives of the force analysis by the design: the kernel of
:mod:`sewmech.engine.dynamic_sensitivity`.

At every position the pair unknowns X solve G(X, s) = A(s) X - B(s) + XB(X, s) = 0 (the force
kernel's equations, :func:`sewmech.engine._kernels.force_solve`). A parameter p moves the state s
along its kinematic tangent ds/dp (the compact tangents of :mod:`sewmech.engine._tangents`:
each quantity's derivatives by its support's parameters only), and

    J dX/dp = -(dG/ds) ds/dp,   J = dG/dX = A + d(friction)/dX.

:func:`force_tangents` evaluates the right-hand side term by term (a pair, a link's inertia,
a counterweight, a load, a spring, a frictional pair), each for the parameters that move what
that term reads (its support, computed once per machine by the caller): a median JB1-3
parameter moves four points and two links, so a position costs a few hundred small term
evaluations instead of one whole residual per parameter. The pairs' moment arms, the inertia
forces, the centres of mass, the springs and the friction (its smoothed sign v / sqrt(v^2 +
s^2) has a closed-form slope) are differentiated by hand; the counterweights (given by static
moment, angle and radius) and the process loads (smoothed signs, bisectors) by the complex step
in the same scalar code (the state plus i h times its tangent, h = 1e-30: exact to rounding, no
difference taken). Each position's tangents are first spread from the compact layout into a
dense scratch (quantity, component, parameter column), so that the terms read them in column
order. J has the pattern of A (friction at a pair acts on the rows its own force acts on), so it
is solved block by block in the force structure's block upper-triangular order
(:func:`sewmech.engine.dynamics.force_structure`), every parameter's right-hand side at once,
with partial pivoting in each small block.

The same pass gives the derivatives of the shaking force and moment and of the upper shaft's
bearing reactions (the sums of :func:`sewmech.engine.dynamics.shaft_bearings`, differentiated:
the shaft pairs' forces with their friction, the loads on the shaft, its parts' dH/dt and m a),
and G at the solution itself (the equations here against the force kernel's answer).

Units: N, N mm per unit of each parameter; mm, rad, s inside.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

from . import _compiling
from ._kernels import (
    PAIR_CAM,
    PAIR_DRIVER,
    PAIR_PRISMATIC,
    PAIR_REVOLUTE,
    SRC_LINK,
    SRC_PARAM,
    TERM_POINT,
    _pair_geometry,
)
from ._tangents import LANES

_compiling.install()  # a kernel compiled on its first use says so on stderr

_OPTS = dict(cache=True, error_model="numpy", fastmath={"contract"})

#: the complex step (the state moves by i H along a tangent)
H = 1e-30

# load laws (column 2 of the load table)
LAW_RESISTIVE = 0
LAW_CONSTANT = 1
LAW_ELASTIC = 2


@njit(inline="always", **_OPTS)
def _d(DT, level, q, comp, j):
    """The tangent of quantity q (component comp of a point) at level 0, 1, 2 (position, rate,
    acceleration) by active parameter j, at the position being worked on (0 outside the
    quantity's support)."""
    return DT[level, q, comp, j]


@njit(inline="always", **_OPTS)
def _z(value, tangent):
    return complex(value, H * tangent)


@njit(inline="always", **_OPTS)
def _zsqrt(x):
    return cmath.sqrt(x)


@njit(nogil=True, **_OPTS)
def force_tangents(d0, d1, P, V, A, TH, OM, EP, Q, prm, GP, GV, GA, X, travel, dtravel, on,
                   T0, T1, T2, qm, ent_q, ent_off, ent_j, vs, as_,
                   pairs, pair_angle, cam_rows, terms, mass, inertia, com_u, com_v, origins,
                   gravity, cw_int, ld_int, ld_f, tw_ptr, tw_pts, sp_int, sp_f, ts_int, ts_f,
                   fr_int, fr_f, fr_pair, n_pt,
                   lk_ptr, lk_p, geo_ptr, geo_p, pr_ptr, pr_p, cw_ptr, cw_p, ld_ptr, ld_p,
                   sp_ptr, sp_p, ts_ptr, ts_p, fr_ptr, fr_p, jpos,
                   blk_ptr, rperm, cperm, cpl_ptr, cpl_row, cpl_col,
                   bp_int, bp_f, bl_int, bl_z, bm_int, bm_f, bc_int, bc_z, z_front, z_rear,
                   act, dX, dSF, dSM, dBf, dBr, G0):
    """The derivatives of the force analysis of designs d0 <= d < d1 by the active parameters
    (compact columns: parameter p is column jpos[p]); see the module doc.

    State (D, n_phi, ...): P, V, A the points, TH, OM, EP the links, Q the joint variables,
    prm (D, n_params), GP, GV, GA (D, n_phi, n_links, 2) the centres of mass, X the solved
    unknowns, travel and dtravel (D, n_phi, n_loads[, n_act]) the elastic loads' travel and
    its derivative, on (D, n_phi, n_loads) where each load acts. T0, T1, T2: the compact
    tangents of positions, rates and accelerations (at the file's speed: the rates are scaled
    by vs, the accelerations by as_; points: x then y, qm[q] entries each); ent_q, ent_off,
    ent_j: every support entry an active parameter has, its quantity, its offset in T's rows
    and the parameter's column. Each position's entries are spread into a dense scratch
    (quantity, component, column) first: the terms then read their tangents in column order.
    The machine's tables as the force kernel and :mod:`sewmech.engine.dynamic_sensitivity`
    lay them out; the CSR lists (*_ptr, *_p) give the parameters each term's support holds.

    The upper shaft's bearings (:func:`sewmech.engine.dynamics.shaft_bearings`, the same
    sums differentiated): bp_int rows (column, pair, frictional pair or -1, 1 if revolute)
    and bp_f (sign, plane z mm) of the pairs it sums, bl_int, bl_z the loads on the shaft's
    links, bm_int, bm_f (J_xz, J_yz about the axis point, mass kg) its links with mass, bc_int,
    bc_z its counterweights, z_front, z_rear the bearings' planes (dBf of size 0: no shaft).

    Fills dX (D, n_phi, n_eq, n_params) dX/dp at the active parameters' columns act (its
    other columns are left as they are: 0); dSF (.., 2, n_act), dSM the shaking force and
    moment's; dBf, dBr (.., 2, n_act) the front and rear bearing reactions'; G0 (D, n_phi,
    n_eq) the equations at the solution. Every output is overwritten where it has a value.
    It releases the GIL: a batch runs as chunks of designs on threads.
    (Names are never reused with another type here: numba types a name once per function.)"""
    n_phi = X.shape[1]
    n_eq = X.shape[2]
    n_links = mass.shape[0]
    n_pairs = pairs.shape[0]
    n_act = act.shape[0]
    Yk = np.zeros((n_eq, n_act))  # this position's dX/dp, active columns
    n_fr = fr_int.shape[0]
    ql = n_pt  # the first link quantity
    q_var = n_pt + n_links  # the first joint variable
    # per position scratch: tangents of the centres of mass and of the pairs' geometry, the
    # right-hand sides and the equations' matrix
    tGP = np.zeros((n_links, 2, n_act))
    tGV = np.zeros((n_links, 2, n_act))
    tGA = np.zeros((n_links, 2, n_act))
    tGEO = np.zeros((n_pairs, 4, n_act))
    geo = np.zeros((n_pairs, 4))
    R = np.zeros((n_eq, n_act))
    J = np.zeros((n_eq, n_eq))
    M = np.zeros((n_eq, n_eq))
    piv = np.zeros(n_eq, dtype=np.int64)
    B = np.zeros((n_eq, n_act))
    frpos = np.full(n_pairs, -1, dtype=np.int64)
    for f in range(n_fr):
        frpos[fr_pair[f]] = f
    dfdx = np.zeros((n_fr, 2))  # d(friction)/d(its pair's unknowns)
    tFF = np.zeros((n_fr, n_act))  # d(friction)/dp at fixed unknowns
    ffv = np.zeros(n_fr)  # the sliding pairs' friction forces
    n_ld = ld_int.shape[0]
    n_cw = cw_int.shape[0]
    tLF = np.zeros((n_ld, 2, n_act))  # d(load force)/dp
    tCWm = np.zeros((n_cw, n_act))  # d(counterweight mass), d(its acceleration)/dp
    tCWa = np.zeros((n_cw, 2, n_act))
    cwm = np.zeros(n_cw)
    cwa = np.zeros((n_cw, 2))
    shaft = dBf.shape[0] > 0
    BA = np.zeros((8, n_act))  # the bearings' sums' derivatives
    g = np.zeros(n_eq)
    n_q = qm.shape[0]
    DT = np.zeros((3, n_q, 2, n_act))  # this position's tangents (entries outside the
    # supports are never written: they stay 0)
    camL = np.zeros(cam_rows.shape[0])  # each cam loop term's length, cos and sin
    camC = np.zeros(cam_rows.shape[0])
    camS = np.zeros(cam_rows.shape[0])
    for d in range(d0, d1):
        for k in range(n_phi):
            n = d * n_phi + k
            nb = n // LANES
            lane = n % LANES
            for e in range(ent_q.shape[0]):
                qe = ent_q[e]
                j = ent_j[e]
                oe = ent_off[e]
                DT[0, qe, 0, j] = T0[nb, oe, lane]
                if qe >= q_var:  # a joint variable: only its value is read
                    continue
                DT[1, qe, 0, j] = vs * T1[nb, oe, lane]
                DT[2, qe, 0, j] = as_ * T2[nb, oe, lane]
                if qe < n_pt:
                    oe += qm[qe]
                    DT[0, qe, 1, j] = T0[nb, oe, lane]
                    DT[1, qe, 1, j] = vs * T1[nb, oe, lane]
                    DT[2, qe, 1, j] = as_ * T2[nb, oe, lane]
            R[:, :] = 0.0
            J[:, :] = 0.0
            g[:] = 0.0
            for j in range(n_act):
                dSF[d, k, 0, j] = 0.0
                dSF[d, k, 1, j] = 0.0
                dSM[d, k, j] = 0.0
            # ---- the centres of mass: GP = O + R(th) (u, v) and its rates ----------------------
            for li in range(1, n_links):
                o = origins[li]
                if o < 0:
                    continue
                cth = math.cos(TH[d, k, li])
                sth = math.sin(TH[d, k, li])
                u = com_u[li]
                v = com_v[li]
                rx = cth * u - sth * v
                ry = sth * u + cth * v
                om = OM[d, k, li]
                ep = EP[d, k, li]
                gpx = GP[d, k, li, 0]
                gpy = GP[d, k, li, 1]
                gax = GA[d, k, li, 0]
                gay = GA[d, k, li, 1]
                for e in range(lk_ptr[li], lk_ptr[li + 1]):
                    p = lk_p[e]
                    j = jpos[p]
                    dth = _d(DT, 0, ql + li, 0, j)
                    dom = _d(DT, 1, ql + li, 0, j)
                    dep = _d(DT, 2, ql + li, 0, j)
                    drx = -ry * dth
                    dry = rx * dth
                    dgpx = _d(DT, 0, o, 0, j) + drx
                    dgpy = _d(DT, 0, o, 1, j) + dry
                    tGP[li, 0, j] = dgpx
                    tGP[li, 1, j] = dgpy
                    tGV[li, 0, j] = _d(DT, 1, o, 0, j) - dom * ry - om * dry
                    tGV[li, 1, j] = _d(DT, 1, o, 1, j) + dom * rx + om * drx
                    dgax = (_d(DT, 2, o, 0, j) - dep * ry - ep * dry
                            - 2.0 * om * dom * rx - om * om * drx)
                    dgay = (_d(DT, 2, o, 1, j) + dep * rx + ep * drx
                            - 2.0 * om * dom * ry - om * om * dry)
                    tGA[li, 0, j] = dgax
                    tGA[li, 1, j] = dgay
                    # inertia force and weight: G -= m a_G, I eps (R = -dG/dp)
                    r = 3 * (li - 1)
                    m = 1e-3 * mass[li]
                    R[r, j] += m * dgax
                    R[r + 1, j] += m * dgay
                    R[r + 2, j] += 1e-3 * inertia[li] * dep
                    # shaking force -sum m a_G and moment -sum (I eps + r_G x m a_G)
                    dSF[d, k, 0, j] -= m * dgax
                    dSF[d, k, 1, j] -= m * dgay
                    dSM[d, k, j] -= (1e-3 * inertia[li] * dep
                                     + m * (dgpx * gay + gpx * dgay - dgpy * gax - gpy * dgax))
                r = 3 * (li - 1)
                g[r] -= 1e-3 * mass[li] * gax
                g[r + 1] -= 1e-3 * mass[li] * gay + gravity * mass[li]
                g[r + 2] -= 1e-3 * inertia[li] * ep
            # ---- the pairs: geometry, their part of G and of J ---------------------------------
            for i in range(n_pairs):
                kind = pairs[i, 0]
                la = pairs[i, 1]
                lb = pairs[i, 2]
                col = pairs[i, 7]
                if kind == PAIR_DRIVER:
                    J[3 * (lb - 1) + 2, col] += 1.0
                    g[3 * (lb - 1) + 2] += X[d, k, col]
                    continue
                xx, xy, fx, fy = _pair_geometry(i, pairs, pair_angle, cam_rows, terms, prm, d, k,
                                                P, TH, Q)
                geo[i, 0] = xx
                geo[i, 1] = xy
                geo[i, 2] = fx
                geo[i, 3] = fy
                if kind == PAIR_CAM:  # each loop term's length and angle, once
                    for r in range(pairs[i, 9], pairs[i, 9] + pairs[i, 10]):
                        t = cam_rows[r]
                        if terms[t, 0] == TERM_POINT:
                            continue
                        camL[r] = prm[d, terms[t, 4]] if terms[t, 3] == SRC_PARAM else \
                            Q[d, k, terms[t, 4]]
                        ang = TH[d, k, terms[t, 6]] if terms[t, 5] == SRC_LINK else \
                            Q[d, k, terms[t, 6]]
                        if terms[t, 7] >= 0:
                            ang += prm[d, terms[t, 7]]
                        camC[r] = math.cos(ang)
                        camS[r] = math.sin(ang)
                for e in range(geo_ptr[i], geo_ptr[i + 1]):
                    p = geo_p[e]
                    j = jpos[p]
                    if kind == PAIR_CAM:  # minus the sum of the loop's other terms
                        sx = 0.0
                        sy = 0.0
                        for r in range(pairs[i, 9], pairs[i, 9] + pairs[i, 10]):
                            t = cam_rows[r]
                            sg = float(terms[t, 2])
                            if terms[t, 0] == TERM_POINT:
                                sx += sg * _d(DT, 0, terms[t, 4], 0, j)
                                sy += sg * _d(DT, 0, terms[t, 4], 1, j)
                                continue
                            if terms[t, 3] == SRC_PARAM:
                                dL = 1.0 if terms[t, 4] == p else 0.0
                            else:
                                dL = _d(DT, 0, ql + n_links + terms[t, 4], 0, j)
                            if terms[t, 5] == SRC_LINK:
                                da = _d(DT, 0, ql + terms[t, 6], 0, j)
                            else:
                                da = _d(DT, 0, ql + n_links + terms[t, 6], 0, j)
                            if terms[t, 7] == p:
                                da += 1.0
                            L = camL[r]
                            sx += sg * (dL * camC[r] - L * camS[r] * da)
                            sy += sg * (dL * camS[r] + L * camC[r] * da)
                        sign = float(pairs[i, 8])
                        dxx = -sign * sx
                        dxy = -sign * sy
                    else:
                        dxx = _d(DT, 0, pairs[i, 3], 0, j)
                        dxy = _d(DT, 0, pairs[i, 3], 1, j)
                    tGEO[i, 0, j] = dxx
                    tGEO[i, 1, j] = dxy
                    if kind != PAIR_REVOLUTE:
                        if pairs[i, 4] >= 0:
                            da = _d(DT, 0, ql + pairs[i, 4], 0, j)
                        else:
                            da = _d(DT, 0, ql + n_links + pairs[i, 5], 0, j)
                        if pairs[i, 6] == p:
                            da += 1.0
                        tGEO[i, 2, j] = -fy * da
                        tGEO[i, 3, j] = fx * da
                for side in range(2):
                    link = lb if side == 0 else la
                    if link == 0:
                        continue
                    sg = 1.0 if side == 0 else -1.0
                    r = 3 * (link - 1)
                    dx = xx - GP[d, k, link, 0]
                    dy = xy - GP[d, k, link, 1]
                    if kind == PAIR_REVOLUTE:
                        Fx = X[d, k, col]
                        Fy = X[d, k, col + 1]
                        J[r, col] += sg
                        J[r + 1, col + 1] += sg
                        J[r + 2, col] += -sg * dy
                        J[r + 2, col + 1] += sg * dx
                        g[r] += sg * Fx
                        g[r + 1] += sg * Fy
                        g[r + 2] += sg * (dx * Fy - dy * Fx)
                        for e in range(pr_ptr[i], pr_ptr[i + 1]):
                            j = jpos[pr_p[e]]
                            ddx = tGEO[i, 0, j] - tGP[link, 0, j]
                            ddy = tGEO[i, 1, j] - tGP[link, 1, j]
                            R[r + 2, j] -= sg * (ddx * Fy - ddy * Fx)
                        continue
                    N = X[d, k, col]
                    J[r, col] += sg * fx
                    J[r + 1, col] += sg * fy
                    J[r + 2, col] += sg * (dx * fy - dy * fx)
                    g[r] += sg * fx * N
                    g[r + 1] += sg * fy * N
                    g[r + 2] += sg * (dx * fy - dy * fx) * N
                    if kind == PAIR_PRISMATIC:
                        J[r + 2, col + 1] += sg
                        g[r + 2] += sg * X[d, k, col + 1]
                    for e in range(pr_ptr[i], pr_ptr[i + 1]):
                        j = jpos[pr_p[e]]
                        ddx = tGEO[i, 0, j] - tGP[link, 0, j]
                        ddy = tGEO[i, 1, j] - tGP[link, 1, j]
                        dfx = tGEO[i, 2, j]
                        dfy = tGEO[i, 3, j]
                        R[r, j] -= sg * dfx * N
                        R[r + 1, j] -= sg * dfy * N
                        R[r + 2, j] -= sg * N * (ddx * fy + dx * dfy - ddy * fx - dy * dfx)
            # ---- counterweights (point masses; by static moment, angle, radius or by mass, u,
            # v): complex step ---------------------------------------------------------------------
            for ci in range(cw_int.shape[0]):
                li = cw_int[ci, 0]
                o = cw_int[ci, 1]
                for e in range(cw_ptr[ci] - 1, cw_ptr[ci + 1]):
                    p = -1 if e < cw_ptr[ci] else cw_p[e]  # -1: the values themselves
                    j = jpos[p] if p >= 0 else 0
                    z0 = _z(prm[d, cw_int[ci, 3]], 1.0 if cw_int[ci, 3] == p else 0.0)
                    z1 = _z(prm[d, cw_int[ci, 4]], 1.0 if cw_int[ci, 4] == p else 0.0)
                    z2 = _z(prm[d, cw_int[ci, 5]], 1.0 if cw_int[ci, 5] == p else 0.0)
                    if cw_int[ci, 2]:
                        cm = z0 / z2
                        cu = z2 * cmath.cos(z1)
                        cv = z2 * cmath.sin(z1)
                    else:
                        cm = z0
                        cu = z1
                        cv = z2
                    tg = 1.0 if p >= 0 else 0.0
                    zth = _z(TH[d, k, li], tg * _d(DT, 0, ql + li, 0, j))
                    zom = _z(OM[d, k, li], tg * _d(DT, 1, ql + li, 0, j))
                    zep = _z(EP[d, k, li], tg * _d(DT, 2, ql + li, 0, j))
                    px = _z(P[d, k, o, 0], tg * _d(DT, 0, o, 0, j))
                    py = _z(P[d, k, o, 1], tg * _d(DT, 0, o, 1, j))
                    zax = _z(A[d, k, o, 0], tg * _d(DT, 2, o, 0, j))
                    zay = _z(A[d, k, o, 1], tg * _d(DT, 2, o, 1, j))
                    gx = _z(GP[d, k, li, 0], tGP[li, 0, j] if p >= 0 else 0.0)
                    gy = _z(GP[d, k, li, 1], tGP[li, 1, j] if p >= 0 else 0.0)
                    zc = cmath.cos(zth)
                    zs = cmath.sin(zth)
                    zrx = zc * cu - zs * cv
                    zry = zs * cu + zc * cv
                    qx = px + zrx
                    qy = py + zry
                    qax = zax - zep * zry - zom * zom * zrx
                    qay = zay + zep * zrx - zom * zom * zry
                    cfx = 1e-3 * cm * qax
                    cfy = 1e-3 * cm * qay + gravity * cm
                    gm = (qx - gx) * cfy - (qy - gy) * cfx
                    r = 3 * (li - 1)
                    if p < 0:
                        g[r] -= cfx.real
                        g[r + 1] -= cfy.real
                        g[r + 2] -= gm.real
                        cwm[ci] = cm.real
                        cwa[ci, 0] = qax.real
                        cwa[ci, 1] = qay.real
                        continue
                    R[r, j] += cfx.imag / H
                    R[r + 1, j] += cfy.imag / H
                    R[r + 2, j] += gm.imag / H
                    dSF[d, k, 0, j] -= (1e-3 * cm * qax).imag / H
                    dSF[d, k, 1, j] -= (1e-3 * cm * qay).imag / H
                    dSM[d, k, j] -= (1e-3 * cm * (qx * qay - qy * qax)).imag / H
                    tCWm[ci, j] = cm.imag / H
                    tCWa[ci, 0, j] = qax.imag / H
                    tCWa[ci, 1, j] = qay.imag / H
            # ---- process loads (where they act as solved): complex step ----------------------
            for lj in range(ld_int.shape[0]):
                if on[d, k, lj] == 0.0:
                    for e in range(ld_ptr[lj], ld_ptr[lj + 1]):
                        j = jpos[ld_p[e]]
                        tLF[lj, 0, j] = 0.0
                        tLF[lj, 1, j] = 0.0
                    continue
                li = ld_int[lj, 0]
                pi = ld_int[lj, 1]
                law = ld_int[lj, 2]
                fixed = ld_int[lj, 3] == 1
                F0 = ld_f[lj, 0]
                sm = ld_f[lj, 1]
                ux = ld_f[lj, 3]
                uy = ld_f[lj, 4]
                w = on[d, k, lj]
                for e in range(ld_ptr[lj] - 1, ld_ptr[lj + 1]):
                    p = -1 if e < ld_ptr[lj] else ld_p[e]
                    j = jpos[p] if p >= 0 else 0
                    tg = 1.0 if p >= 0 else 0.0
                    px = _z(P[d, k, pi, 0], tg * _d(DT, 0, pi, 0, j))
                    py = _z(P[d, k, pi, 1], tg * _d(DT, 0, pi, 1, j))
                    if law == LAW_RESISTIVE:
                        vx = _z(V[d, k, pi, 0], tg * _d(DT, 1, pi, 0, j))
                        vy = _z(V[d, k, pi, 1], tg * _d(DT, 1, pi, 1, j))
                        if fixed:
                            x = vx * ux + vy * uy
                            zf = -F0 * x / _zsqrt(x * x + sm * sm)
                            zFx = zf * ux
                            zFy = zf * uy
                        else:
                            q = _zsqrt(vx * vx + vy * vy + sm * sm)
                            zFx = -F0 * vx / q
                            zFy = -F0 * vy / q
                    else:
                        if fixed:
                            zx = _z(ux, 0.0)
                            zy = _z(uy, 0.0)
                        else:  # the bisector of the unit vectors toward the given points
                            zx = _z(0.0, 0.0)
                            zy = _z(0.0, 0.0)
                            for tq in range(tw_ptr[lj], tw_ptr[lj + 1]):
                                qi = tw_pts[tq]
                                ex = _z(P[d, k, qi, 0], tg * _d(DT, 0, qi, 0, j)) - px
                                ey = _z(P[d, k, qi, 1], tg * _d(DT, 0, qi, 1, j)) - py
                                q = _zsqrt(ex * ex + ey * ey)
                                zx += ex / q
                                zy += ey / q
                            q = _zsqrt(zx * zx + zy * zy)
                            zx = zx / q
                            zy = zy / q
                        zf = _z(F0, 0.0)
                        if law == LAW_ELASTIC:
                            zf += ld_f[lj, 2] * _z(travel[d, k, lj],
                                                  dtravel[d, k, lj, j] if p >= 0 else 0.0)
                        zFx = zf * zx
                        zFy = zf * zy
                    zFx = zFx * w
                    zFy = zFy * w
                    if p >= 0:
                        tLF[lj, 0, j] = zFx.imag / H
                        tLF[lj, 1, j] = zFy.imag / H
                    if li == 0:
                        continue
                    gx = _z(GP[d, k, li, 0], tGP[li, 0, j] if p >= 0 else 0.0)
                    gy = _z(GP[d, k, li, 1], tGP[li, 1, j] if p >= 0 else 0.0)
                    gm = (px - gx) * zFy - (py - gy) * zFx
                    r = 3 * (li - 1)
                    if p < 0:
                        g[r] += zFx.real
                        g[r + 1] += zFy.real
                        g[r + 2] += gm.real
                    else:
                        R[r, j] -= zFx.imag / H
                        R[r + 1, j] -= zFy.imag / H
                        R[r + 2, j] -= gm.imag / H
            # ---- springs and dampers between two points: T = k (L - L0) + c dL/dt along the
            # unit vector u from end a to end b, +T u on a's link and -T u on b's --------------
            for si in range(sp_int.shape[0]):
                la = sp_int[si, 0]
                pa = sp_int[si, 1]
                lb = sp_int[si, 2]
                pb = sp_int[si, 3]
                s_k = sp_f[si, 0]
                s_c = sp_f[si, 2]
                s_ex = P[d, k, pb, 0] - P[d, k, pa, 0]
                s_ey = P[d, k, pb, 1] - P[d, k, pa, 1]
                s_L = math.sqrt(s_ex * s_ex + s_ey * s_ey)
                s_ux = s_ex / s_L
                s_uy = s_ey / s_L
                s_vx = V[d, k, pb, 0] - V[d, k, pa, 0]
                s_vy = V[d, k, pb, 1] - V[d, k, pa, 1]
                s_Ld = s_ux * s_vx + s_uy * s_vy
                s_T = s_k * (s_L - sp_f[si, 1]) + s_c * s_Ld
                s_Fx = s_T * s_ux
                s_Fy = s_T * s_uy
                for side in range(2):
                    link = la if side == 0 else lb
                    if link == 0:
                        continue
                    sg = 1.0 if side == 0 else -1.0
                    s_pt = pa if side == 0 else pb
                    r = 3 * (link - 1)
                    g[r] += sg * s_Fx
                    g[r + 1] += sg * s_Fy
                    g[r + 2] += sg * ((P[d, k, s_pt, 0] - GP[d, k, link, 0]) * s_Fy
                                      - (P[d, k, s_pt, 1] - GP[d, k, link, 1]) * s_Fx)
                for e in range(sp_ptr[si], sp_ptr[si + 1]):
                    j = jpos[sp_p[e]]
                    s_dex = _d(DT, 0, pb, 0, j) - _d(DT, 0, pa, 0, j)
                    s_dey = _d(DT, 0, pb, 1, j) - _d(DT, 0, pa, 1, j)
                    s_dL = s_ux * s_dex + s_uy * s_dey
                    s_dux = (s_dex - s_ux * s_dL) / s_L
                    s_duy = (s_dey - s_uy * s_dL) / s_L
                    s_dvx = _d(DT, 1, pb, 0, j) - _d(DT, 1, pa, 0, j)
                    s_dvy = _d(DT, 1, pb, 1, j) - _d(DT, 1, pa, 1, j)
                    s_dLd = s_dux * s_vx + s_duy * s_vy + s_ux * s_dvx + s_uy * s_dvy
                    s_dT = s_k * s_dL + s_c * s_dLd
                    s_dFx = s_dT * s_ux + s_T * s_dux
                    s_dFy = s_dT * s_uy + s_T * s_duy
                    for side in range(2):
                        link = la if side == 0 else lb
                        if link == 0:
                            continue
                        sg = 1.0 if side == 0 else -1.0
                        s_pt = pa if side == 0 else pb
                        s_rx = P[d, k, s_pt, 0] - GP[d, k, link, 0]
                        s_ry = P[d, k, s_pt, 1] - GP[d, k, link, 1]
                        s_drx = _d(DT, 0, s_pt, 0, j) - tGP[link, 0, j]
                        s_dry = _d(DT, 0, s_pt, 1, j) - tGP[link, 1, j]
                        r = 3 * (link - 1)
                        R[r, j] -= sg * s_dFx
                        R[r + 1, j] -= sg * s_dFy
                        R[r + 2, j] -= sg * (s_drx * s_Fy + s_rx * s_dFy - s_dry * s_Fx
                                             - s_ry * s_dFx)
            # ---- torsion springs at pairs: linear in the angles and rates --------------------
            for si in range(ts_int.shape[0]):
                la = ts_int[si, 0]
                lb = ts_int[si, 1]
                rel = TH[d, k, lb] - TH[d, k, la]
                turns = math.floor((rel - ts_f[si, 1] + math.pi) / (2.0 * math.pi))
                dd = rel - ts_f[si, 1] - 2.0 * math.pi * turns
                w = OM[d, k, lb] - OM[d, k, la]
                Mt = -(ts_f[si, 0] * dd + ts_f[si, 2] * w)
                if lb > 0:
                    g[3 * (lb - 1) + 2] += Mt
                if la > 0:
                    g[3 * (la - 1) + 2] -= Mt
                for e in range(ts_ptr[si], ts_ptr[si + 1]):
                    p = ts_p[e]
                    j = jpos[p]
                    drel = (_d(DT, 0, ql + lb, 0, j)
                            - _d(DT, 0, ql + la, 0, j))
                    dw = (_d(DT, 1, ql + lb, 0, j)
                          - _d(DT, 1, ql + la, 0, j))
                    dM = -(ts_f[si, 0] * drel + ts_f[si, 2] * dw)
                    if lb > 0:
                        R[3 * (lb - 1) + 2, j] -= dM
                    if la > 0:
                        R[3 * (la - 1) + 2, j] += dM
            # ---- friction at fixed unknowns, differentiated by hand (it is smooth: the sign
            # of the sliding speed v is v / sqrt(v^2 + s^2)); its derivative by the unknowns ------
            for f in range(n_fr):
                kind = fr_int[f, 0]
                la = fr_int[f, 1]
                lb = fr_int[f, 2]
                c0 = fr_int[f, 3]
                mu = fr_f[f, 0]
                rad = fr_f[f, 1]
                visc = fr_f[f, 2]
                sm = fr_f[f, 3]
                oma = OM[d, k, la] if la > 0 else 0.0
                omb = OM[d, k, lb] if lb > 0 else 0.0
                if kind == PAIR_REVOLUTE:
                    fx = X[d, k, c0]
                    fy = X[d, k, c0 + 1]
                    fa = math.sqrt(fx * fx + fy * fy)
                    w = omb - oma
                    v = rad * w
                    qv = math.sqrt(v * v + sm * sm)
                    sv = v / qv
                    fm = -(mu * rad * fa * sv + visc * w)
                    kw = -(mu * rad * fa * rad * sm * sm / (qv * qv * qv) + visc)  # dm/dw
                    dfdx[f, 0] = -mu * rad * sv * (fx / fa if fa > 0.0 else 0.0)
                    dfdx[f, 1] = -mu * rad * sv * (fy / fa if fa > 0.0 else 0.0)
                    for side in range(2):
                        link = lb if side == 0 else la
                        if link == 0:
                            continue
                        sg = 1.0 if side == 0 else -1.0
                        g[3 * (link - 1) + 2] += sg * fm
                        J[3 * (link - 1) + 2, c0] += sg * dfdx[f, 0]
                        J[3 * (link - 1) + 2, c0 + 1] += sg * dfdx[f, 1]
                    for j in range(n_act):
                        tFF[f, j] = 0.0
                    for e in range(fr_ptr[f], fr_ptr[f + 1]):
                        p = fr_p[e]
                        j = jpos[p]
                        dw = (_d(DT, 1, ql + lb, 0, j)
                              - _d(DT, 1, ql + la, 0, j))
                        dm = kw * dw
                        tFF[f, j] = dm
                        if lb > 0:
                            R[3 * (lb - 1) + 2, j] -= dm
                        if la > 0:
                            R[3 * (la - 1) + 2, j] += dm
                    continue
                i = fr_pair[f]
                N = X[d, k, c0]
                px = geo[i, 0]
                py = geo[i, 1]
                tx = geo[i, 3]  # the tangent: the normal turned -90 deg
                ty = -geo[i, 2]
                rbx = rby = vbx = vby = 0.0
                rax = ray = vax = vay = 0.0
                if lb > 0:
                    rbx = px - GP[d, k, lb, 0]
                    rby = py - GP[d, k, lb, 1]
                    vbx = GV[d, k, lb, 0] - omb * rby
                    vby = GV[d, k, lb, 1] + omb * rbx
                if la > 0:
                    rax = px - GP[d, k, la, 0]
                    ray = py - GP[d, k, la, 1]
                    vax = GV[d, k, la, 0] - oma * ray
                    vay = GV[d, k, la, 1] + oma * rax
                v = tx * (vbx - vax) + ty * (vby - vay)
                qv = math.sqrt(v * v + sm * sm)
                sv = v / qv
                absn = -N if N < 0.0 else N
                ff = -(mu * absn * sv + visc * v)
                ffv[f] = ff
                kv = -(mu * absn * sm * sm / (qv * qv * qv) + visc)  # df/dv
                dfdx[f, 0] = -mu * (-1.0 if N < 0.0 else 1.0) * sv
                for side in range(2):
                    link = lb if side == 0 else la
                    if link == 0:
                        continue
                    sg = 1.0 if side == 0 else -1.0
                    arm = (rbx * ty - rby * tx) if side == 0 else (rax * ty - ray * tx)
                    r = 3 * (link - 1)
                    g[r] += sg * ff * tx
                    g[r + 1] += sg * ff * ty
                    g[r + 2] += sg * ff * arm
                    J[r, c0] += sg * tx * dfdx[f, 0]
                    J[r + 1, c0] += sg * ty * dfdx[f, 0]
                    J[r + 2, c0] += sg * arm * dfdx[f, 0]
                for j in range(n_act):
                    tFF[f, j] = 0.0
                for e in range(fr_ptr[f], fr_ptr[f + 1]):
                    p = fr_p[e]
                    j = jpos[p]
                    dpx = tGEO[i, 0, j]
                    dpy = tGEO[i, 1, j]
                    dtx = tGEO[i, 3, j]
                    dty = -tGEO[i, 2, j]
                    dvbx = dvby = drbx = drby = 0.0
                    dvax = dvay = drax = dray = 0.0
                    if lb > 0:
                        dom = _d(DT, 1, ql + lb, 0, j)
                        drbx = dpx - tGP[lb, 0, j]
                        drby = dpy - tGP[lb, 1, j]
                        dvbx = tGV[lb, 0, j] - dom * rby - omb * drby
                        dvby = tGV[lb, 1, j] + dom * rbx + omb * drbx
                    if la > 0:
                        dom = _d(DT, 1, ql + la, 0, j)
                        drax = dpx - tGP[la, 0, j]
                        dray = dpy - tGP[la, 1, j]
                        dvax = tGV[la, 0, j] - dom * ray - oma * dray
                        dvay = tGV[la, 1, j] + dom * rax + oma * drax
                    dv = (dtx * (vbx - vax) + tx * (dvbx - dvax) + dty * (vby - vay)
                          + ty * (dvby - dvay))
                    df = kv * dv
                    tFF[f, j] = df
                    for side in range(2):
                        link = lb if side == 0 else la
                        if link == 0:
                            continue
                        sg = 1.0 if side == 0 else -1.0
                        if side == 0:
                            arm = rbx * ty - rby * tx
                            darm = drbx * ty + rbx * dty - drby * tx - rby * dtx
                        else:
                            arm = rax * ty - ray * tx
                            darm = drax * ty + rax * dty - dray * tx - ray * dtx
                        r = 3 * (link - 1)
                        R[r, j] -= sg * (df * tx + ff * dtx)
                        R[r + 1, j] -= sg * (df * ty + ff * dty)
                        R[r + 2, j] -= sg * (df * arm + ff * darm)
            for r in range(n_eq):
                G0[d, k, r] = g[r]
            # ---- J dX/dp = R, block by block (the last block first), every column at once ------
            for blk in range(blk_ptr.shape[0] - 2, -1, -1):
                r0 = blk_ptr[blk]
                nb = blk_ptr[blk + 1] - r0
                for a in range(nb):
                    ra = rperm[r0 + a]
                    for b in range(nb):
                        M[a, b] = J[ra, cperm[r0 + b]]
                    for j in range(n_act):
                        B[a, j] = R[ra, j]
                for c in range(cpl_ptr[blk], cpl_ptr[blk + 1]):
                    a = cpl_row[c]
                    cc = cpl_col[c]
                    w = J[rperm[r0 + a], cc]
                    if w != 0.0:
                        for j in range(n_act):
                            B[a, j] -= w * Yk[cc, j]
                # LU with partial pivoting, applied to the right-hand sides as it goes
                for a in range(nb):
                    best = a
                    for b in range(a + 1, nb):
                        if abs(M[b, a]) > abs(M[best, a]):
                            best = b
                    piv[a] = best
                    if best != a:
                        for b in range(nb):
                            tmp = M[a, b]
                            M[a, b] = M[best, b]
                            M[best, b] = tmp
                        for j in range(n_act):
                            tmp = B[a, j]
                            B[a, j] = B[best, j]
                            B[best, j] = tmp
                    for b in range(a + 1, nb):
                        fct = M[b, a] / M[a, a]
                        if fct != 0.0:
                            for c in range(a + 1, nb):
                                M[b, c] -= fct * M[a, c]
                            for j in range(n_act):
                                B[b, j] -= fct * B[a, j]
                for a in range(nb - 1, -1, -1):
                    for c in range(a + 1, nb):
                        w = M[a, c]
                        if w != 0.0:
                            for j in range(n_act):
                                B[a, j] -= w * B[c, j]
                    inv = 1.0 / M[a, a]
                    cy = cperm[r0 + a]
                    for j in range(n_act):
                        B[a, j] *= inv
                        Yk[cy, j] = B[a, j]
                    for j in range(n_act):
                        dX[d, k, cy, act[j]] = B[a, j]
            # ---- the bearings: the sums of shaft_bearings, differentiated ----------------------
            if not shaft:
                continue
            # BA rows: sum of forces x, y; their moments x, y; dH/dt x, y; sum of m a x, y
            BA[:, :] = 0.0
            for bi in range(bp_int.shape[0]):
                b_c0 = bp_int[bi, 0]
                b_i = bp_int[bi, 1]
                b_f = bp_int[bi, 2]
                b_sg = bp_f[bi, 0]
                b_z = bp_f[bi, 1]
                b_rev = bp_int[bi, 3] == 1
                b_nx = geo[b_i, 2]
                b_ny = geo[b_i, 3]
                b_N = X[d, k, b_c0]
                for j in range(n_act):
                    if b_rev:
                        b_fx = Yk[b_c0, j]
                        b_fy = Yk[b_c0 + 1, j]
                    else:
                        b_dnx = tGEO[b_i, 2, j]
                        b_dny = tGEO[b_i, 3, j]
                        b_dN = Yk[b_c0, j]
                        b_fx = b_dN * b_nx + b_N * b_dnx
                        b_fy = b_dN * b_ny + b_N * b_dny
                        if b_f >= 0:  # friction along the tangent (ny, -nx)
                            b_dff = tFF[b_f, j] + dfdx[b_f, 0] * b_dN
                            b_fx += b_dff * b_ny + ffv[b_f] * b_dny
                            b_fy -= b_dff * b_nx + ffv[b_f] * b_dnx
                    BA[0, j] += b_sg * b_fx
                    BA[1, j] += b_sg * b_fy
                    BA[2, j] -= b_z * b_sg * b_fy
                    BA[3, j] += b_z * b_sg * b_fx
            for bi in range(bl_int.shape[0]):
                b_z = bl_z[bi]
                lj = bl_int[bi]
                for j in range(n_act):
                    BA[0, j] += tLF[lj, 0, j]
                    BA[1, j] += tLF[lj, 1, j]
                    BA[2, j] -= b_z * tLF[lj, 1, j]
                    BA[3, j] += b_z * tLF[lj, 0, j]
            for bi in range(bm_int.shape[0]):
                b_li = bm_int[bi]
                b_w = OM[d, k, b_li]
                b_e = EP[d, k, b_li]
                b_cth = math.cos(TH[d, k, b_li])
                b_sth = math.sin(TH[d, k, b_li])
                b_jxz = b_cth * bm_f[bi, 0] - b_sth * bm_f[bi, 1]
                b_jyz = b_sth * bm_f[bi, 0] + b_cth * bm_f[bi, 1]
                b_m = 1e-3 * bm_f[bi, 2]
                for j in range(n_act):
                    b_dth = _d(DT, 0, ql + b_li, 0, j)
                    b_dw = _d(DT, 1, ql + b_li, 0, j)
                    b_de = _d(DT, 2, ql + b_li, 0, j)
                    b_djxz = -b_jyz * b_dth
                    b_djyz = b_jxz * b_dth
                    BA[4, j] += 1e-3 * (b_djxz * b_e + b_jxz * b_de - b_djyz * b_w * b_w
                                        - 2.0 * b_jyz * b_w * b_dw)
                    BA[5, j] += 1e-3 * (b_djyz * b_e + b_jyz * b_de + b_djxz * b_w * b_w
                                        + 2.0 * b_jxz * b_w * b_dw)
                    BA[6, j] += b_m * tGA[b_li, 0, j]
                    BA[7, j] += b_m * tGA[b_li, 1, j]
            for bi in range(bc_int.shape[0]):
                b_ci = bc_int[bi]
                b_z = bc_z[bi]
                for j in range(n_act):
                    b_dm = tCWm[b_ci, j]
                    b_dmax = b_dm * cwa[b_ci, 0] + cwm[b_ci] * tCWa[b_ci, 0, j]
                    b_dmay = b_dm * cwa[b_ci, 1] + cwm[b_ci] * tCWa[b_ci, 1, j]
                    BA[6, j] += 1e-3 * b_dmax
                    BA[7, j] += 1e-3 * b_dmay
                    BA[4, j] -= 1e-3 * b_z * b_dmay
                    BA[5, j] += 1e-3 * b_z * b_dmax
                    BA[1, j] -= b_dm * gravity
                    BA[2, j] += b_z * b_dm * gravity
            # B_f + B_r = sum m a - sum F; z x B terms = dH/dt - M (two equations each)
            for j in range(n_act):
                b_nx_ = BA[6, j] - BA[0, j]
                b_ny_ = BA[7, j] - BA[1, j]
                b_bfy = (BA[4, j] - BA[2, j] + z_rear * b_ny_) / (z_rear - z_front)
                b_bfx = (BA[5, j] - BA[3, j] - z_rear * b_nx_) / (z_front - z_rear)
                dBf[d, k, 0, j] = b_bfx
                dBf[d, k, 1, j] = b_bfy
                dBr[d, k, 0, j] = b_nx_ - b_bfx
                dBr[d, k, 1, j] = b_ny_ - b_bfy
    return 0

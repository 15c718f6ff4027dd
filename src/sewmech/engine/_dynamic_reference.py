"""The second implementation of :func:`sewmech.engine.dynamic_sensitivity.dynamics_sensitivities`:
the whole residual of the force equations in complex-safe numpy, evaluated at the state plus i h
times each parameter's tangent (one complex-step direction per parameter), dG/dX the same way
along every unknown, and a dense solve per position.

It is slow (tens of inverse dynamics) and shares no code with the compiled kernel
(:mod:`sewmech.engine._force_tangents`) beyond the kinematic tangents and the bearing sums
(:func:`sewmech.engine.dynamics.shaft_bearings`): the tests hold the kernel against it, every
derivative by every parameter, to 1e-12.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from . import _kernels as K
from .dynamic_sensitivity import DynamicsSensitivities, _travel, _travel_derivative
from .dynamics import GRAVITY, DynamicsPlan, DynamicsResult, bearing_reactions
from .errors import AnalysisError
from .machine import Machine
from .sensitivity import sensitivities
from .spec import SHAFT

#: the complex step: the state moves by i h along each tangent (no difference is taken, so h
#: only has to keep h^2 terms below round-off)
H = 1e-30

#: the largest complex state one call builds, bytes (designs are taken in chunks below it)
MAX_BYTES = 2**30


class _Model:
    """The equilibrium equations of a prepared dynamics call, evaluated in complex-safe numpy
    for any leading axes (directions of the complex step, designs): the same equations as the
    compiled force kernel (:func:`sewmech._kernels.force_solve`), the loads', springs' and
    friction's applied forces."""

    def __init__(self, plan: DynamicsPlan):
        from .dynamics import _pair_table

        m = plan.machine
        self.machine = m
        self.plan = plan
        self.table, self.angles, self.cam_rows = _pair_table(m)
        self.terms = m.terms
        self.lm = plan.masses
        self.n_links = len(m.link_names)
        self.n_eq = 3 * (self.n_links - 1)
        self.gravity = GRAVITY if plan.gravity else 0.0
        self.loads = plan._loads
        self.springs = plan._springs
        self.friction = plan._friction
        self.cws = plan.counterweights
        # the points and parameters the equations read (a parameter that moves none of them
        # and enters no equation changes no force: its derivatives are 0)
        pts = {int(r[3]) for r in self.table if r[3] >= 0}
        used = {int(r[6]) for r in self.table if r[6] >= 0}
        for r in self.table:
            for k in range(r[9], r[9] + r[10]):
                t = self.terms[self.cam_rows[k]]
                if t[0] == K.TERM_POINT:
                    pts.add(int(t[4]))
                    continue
                if t[3] == K.SRC_PARAM:
                    used.add(int(t[4]))
                if t[7] >= 0:
                    used.add(int(t[7]))
        pts |= {int(o) for o in self.lm.origins if o >= 0}
        for cw in self.cws:
            pts.add(m.point_index(cw.origin))
            used |= {int(i) for i in cw.params}
        L = self.loads
        for j in range(len(L)):
            pts.add(int(L.points[j]))
            pts |= {int(q) for q in L.toward[j]}
        for _, pa, _, pb in self.springs.ends:
            pts |= {int(pa), int(pb)}
        used |= {p.ratio_param for p in m.pairs if p.kind == "driver" and p.input == SHAFT}
        self.points_read = np.array(sorted(pts), dtype=np.int64)
        self.params_read = np.array(sorted(used), dtype=np.int64)

    def active(self, ds: dict) -> np.ndarray:
        """The parameters whose tangent moves anything the equations read (n_params,)."""
        n_p = ds["P"].shape[0]
        act = np.zeros(n_p, dtype=bool)
        act[self.params_read] = True
        for key in ("P", "V", "A"):
            x = ds[key][..., self.points_read, :]
            act |= np.any(x != 0.0, axis=tuple(range(1, x.ndim)))
        for key in ("TH", "OM", "EP", "S", "SD", "SDD", "travel"):
            if key in ds:
                x = ds[key]
                act |= np.any(x != 0.0, axis=tuple(range(1, x.ndim)))
        return act

    # ---- motion ---------------------------------------------------------------------------
    def com(self, s: dict) -> tuple:
        """The links' centres of mass: position, velocity, acceleration (..., n_phi, n_links,
        2), from their frames' origins and angles."""
        return self._frame_points(s, self.lm.origins, self.lm.com_u, self.lm.com_v,
                                  np.arange(self.n_links))

    def _frame_points(self, s, origins, u, v, links):
        """Points at (u, v) of the frames of ``links`` (origin point ``origins``): position,
        velocity, acceleration (..., n_phi, n, 2); u, v broadcast against (..., 1, n)."""
        org = np.maximum(origins, 0)
        P, V, A = (s[k][..., org, :] for k in ("P", "V", "A"))
        th, om, ep = (s[k][..., links] for k in ("TH", "OM", "EP"))
        c, sn = np.cos(th), np.sin(th)
        rx = c * u - sn * v
        ry = sn * u + c * v
        gp = np.stack([P[..., 0] + rx, P[..., 1] + ry], axis=-1)
        gv = np.stack([V[..., 0] - om * ry, V[..., 1] + om * rx], axis=-1)
        ga = np.stack([A[..., 0] - ep * ry - om * om * rx, A[..., 1] + ep * rx - om * om * ry],
                      axis=-1)
        none = origins < 0  # a link without points: its frame at the origin, not moving
        if none.any():
            for x in (gp, gv, ga):
                x[..., none, :] = 0.0
        return gp, gv, ga

    def counterweights(self, s: dict) -> tuple | None:
        """Each counterweight's mass (..., 1, n_cw) kg and its motion (..., n_phi, n_cw, 2)."""
        if not self.cws:
            return None
        prm = s["prm"]
        m, u, v = [], [], []
        for cw in self.cws:
            a, b, c = (prm[..., i] for i in cw.params)
            if cw.by_moment:  # S, angle, radius
                m.append(a / c)
                u.append(c * np.cos(b))
                v.append(c * np.sin(b))
            else:
                m.append(a)
                u.append(b)
                v.append(c)
        m, u, v = (np.stack(x, axis=-1) for x in (m, u, v))
        origins = np.array([self.machine.point_index(cw.origin) for cw in self.cws])
        links = np.array([cw.link_index for cw in self.cws])
        p, vv, a = self._frame_points(s, origins, u, v, links)
        return m, p, vv, a

    # ---- the pairs --------------------------------------------------------------------------
    def geometry(self, s: dict) -> list:
        """Per pair: (x, y, cos, sin) of its force point and single force's direction (as the
        kernel's _pair_geometry), None for drivers."""
        P, TH, S, prm = s["P"], s["TH"], s["S"], s["prm"]
        out = []
        for i, row in enumerate(self.table):
            kind = row[0]
            if kind == K.PAIR_DRIVER:
                out.append(None)
                continue
            if kind == K.PAIR_CAM:
                xx, xy = self._cam_point(row, s)
            else:
                xx, xy = P[..., row[3], 0], P[..., row[3], 1]
            if kind == K.PAIR_REVOLUTE:
                out.append((xx, xy, None, None))
                continue
            a = TH[..., row[4]] if row[4] >= 0 else S[..., row[5]]
            a = a + self.angles[i]
            if row[6] >= 0:
                a = a + prm[..., row[6]]
            if kind != K.PAIR_CAM:
                a = a + 0.5 * math.pi
            out.append((xx, xy, np.cos(a), np.sin(a)))
        return out

    def _cam_point(self, row, s):
        P, TH, S, prm = s["P"], s["TH"], s["S"], s["prm"]
        sx = sy = 0.0
        for r in range(row[9], row[9] + row[10]):
            t = self.terms[self.cam_rows[r]]
            sg = float(t[2])
            if t[0] == K.TERM_POINT:
                sx = sx + sg * P[..., t[4], 0]
                sy = sy + sg * P[..., t[4], 1]
                continue
            L = prm[..., t[4]] if t[3] == K.SRC_PARAM else S[..., t[4]]
            a = TH[..., t[6]] if t[5] == K.SRC_LINK else S[..., t[6]]
            if t[7] >= 0:
                a = a + prm[..., t[7]]
            sx = sx + sg * L * np.cos(a)
            sy = sy + sg * L * np.sin(a)
        sign = float(row[8])
        return -sign * sx, -sign * sy

    # ---- the equations ------------------------------------------------------------------------
    def residual(self, X: np.ndarray, s: dict, parts: dict | None = None) -> np.ndarray:
        """G(X, s) (..., n_phi, n_eq): the pairs' forces on every moving link less its inertia
        force and weight, plus the applied forces (rows 3 (link - 1) + x, y, moment about its
        centre of mass; N, N mm). ``parts``: filled with what the derived quantities need
        (geometry, centres of mass, counterweights, load forces, friction)."""
        gp, gv, ga = self.com(s)
        geo = self.geometry(s)
        dtype = np.result_type(X, s["P"])
        shape = np.broadcast_shapes(X.shape[:-1], s["P"].shape[:-2])
        G = np.zeros(shape + (self.n_eq,), dtype=dtype)
        for i, row in enumerate(self.table):
            kind, la, lb, col = row[0], row[1], row[2], row[7]
            if kind == K.PAIR_DRIVER:
                G[..., 3 * (lb - 1) + 2] += X[..., col]
                continue
            xx, xy, fx, fy = geo[i]
            for link, sg in ((lb, 1.0), (la, -1.0)):
                if link == 0:
                    continue
                r = 3 * (link - 1)
                dx = xx - gp[..., link, 0]
                dy = xy - gp[..., link, 1]
                if kind == K.PAIR_REVOLUTE:
                    Fx, Fy = X[..., col], X[..., col + 1]
                    G[..., r] += sg * Fx
                    G[..., r + 1] += sg * Fy
                    G[..., r + 2] += sg * (dx * Fy - dy * Fx)
                    continue
                N = X[..., col]
                G[..., r] += sg * fx * N
                G[..., r + 1] += sg * fy * N
                G[..., r + 2] += sg * (dx * fy - dy * fx) * N
                if kind == K.PAIR_PRISMATIC:  # the guide's couple
                    G[..., r + 2] += sg * X[..., col + 1]
        # inertia forces and weights of the links (B), less the applied forces (XB)
        lm = self.lm
        for li in range(1, self.n_links):
            r = 3 * (li - 1)
            G[..., r] -= 1e-3 * lm.mass[li] * ga[..., li, 0]
            G[..., r + 1] -= 1e-3 * lm.mass[li] * ga[..., li, 1] + self.gravity * lm.mass[li]
            G[..., r + 2] -= 1e-3 * lm.inertia[li] * s["EP"][..., li]
        cw = self.counterweights(s)
        if cw is not None:
            m, p, _, a = cw
            for k, c in enumerate(self.cws):
                li = c.link_index
                r = 3 * (li - 1)
                fx = 1e-3 * m[..., k] * a[..., k, 0]
                fy = 1e-3 * m[..., k] * a[..., k, 1] + self.gravity * m[..., k]
                dx = p[..., k, 0] - gp[..., li, 0]
                dy = p[..., k, 1] - gp[..., li, 1]
                G[..., r] -= fx
                G[..., r + 1] -= fy
                G[..., r + 2] -= dx * fy - dy * fx
        XB = np.zeros_like(G)
        LF = self._loads(s, gp, XB)
        self._springs(s, gp, XB)
        FF = self._friction(X, s, geo, gp, gv, XB)
        G += XB
        if parts is not None:
            parts.update(geo=geo, com=(gp, gv, ga), cw=cw, LF=LF, FF=FF)
        return G

    def _loads(self, s, gp, XB):
        """The process loads' forces (..., n_phi, n_loads, 2) where they act (as solved), added
        to XB."""
        from .loads import add_point_force, smooth_sign

        L = self.loads
        if not len(L):
            return None
        on = s["load_on"]  # (..., n_phi, n_loads), fixed
        P, V = s["P"], s["V"]
        out = []
        for j, spec in enumerate(L.specs):
            pi = L.points[j]
            d = L.direction[j]
            v = V[..., pi, :]
            if spec.law == "resistive":
                if d is not None:
                    u = np.array(d)
                    f = -spec.force_N * smooth_sign(v[..., 0] * u[0] + v[..., 1] * u[1],
                                                    spec.smooth_mm_s)
                    F = f[..., None] * u
                else:
                    speed2 = v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]
                    F = -spec.force_N * (v / np.sqrt(speed2 + spec.smooth_mm_s ** 2)[..., None])
            else:
                if d is not None:
                    u = np.broadcast_to(np.array(d), P.shape[:-2] + (2,))
                else:  # the bisector of the unit vectors toward the given points
                    u = 0.0
                    for q in L.toward[j]:
                        e = P[..., q, :] - P[..., pi, :]
                        u = u + e / np.sqrt(e[..., :1] ** 2 + e[..., 1:] ** 2)
                    u = u / np.sqrt(u[..., :1] ** 2 + u[..., 1:] ** 2)
                f = spec.force_N
                if spec.law == "elastic":
                    f = f + spec.rate_N_per_mm * s["travel"][..., j]
                F = np.broadcast_to(f, P.shape[:-2])[..., None] * u
            F = F * on[..., j, None]
            add_point_force(XB, L.links[j], P[..., pi, :], F, gp)
            out.append(F)
        return np.stack(out, axis=-2)

    def _springs(self, s, gp, XB):
        from .loads import add_couple, add_point_force

        sp = self.springs
        P, V, TH, OM = s["P"], s["V"], s["TH"], s["OM"]
        for j, (la, pa, lb, pb) in enumerate(sp.ends):
            d = P[..., pb, :] - P[..., pa, :]
            L = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])
            u = d / L[..., None]
            dv = V[..., pb, :] - V[..., pa, :]
            Ld = u[..., 0] * dv[..., 0] + u[..., 1] * dv[..., 1]
            T = sp.k[j] * (L - sp.free[j]) + sp.c[j] * Ld
            F = T[..., None] * u
            add_point_force(XB, la, P[..., pa, :], F, gp)
            add_point_force(XB, lb, P[..., pb, :], -F, gp)
        for j, (la, lb) in enumerate(sp.torsion_links):
            rel = TH[..., lb] - TH[..., la]
            turns = np.floor((np.real(rel) - sp.free_angle[j] + math.pi) / (2.0 * math.pi))
            d = rel - sp.free_angle[j] - 2.0 * math.pi * turns
            w = OM[..., lb] - OM[..., la]
            M = -(sp.kt[j] * d + sp.ct[j] * w)
            add_couple(XB, lb, M)
            add_couple(XB, la, -M)

    def _friction(self, X, s, geo, gp, gv, XB):
        """The friction of every frictional pair (as the friction kernel), added to XB; returns
        each one's moment or force on the pair's second link (..., n_phi, n_fr)."""
        fr = self.friction
        if fr is None:
            return None
        OM = s["OM"]
        out = []
        for i, (kind, la, lb, c) in enumerate(fr.ints):
            mu, rad, visc, sm = fr.values[i]
            pair_i = fr.pair_index[i]
            if kind == K.PAIR_REVOLUTE:
                fx, fy = X[..., c], X[..., c + 1]
                w = OM[..., lb] - OM[..., la]
                v = rad * w
                m = -(mu * rad * np.sqrt(fx * fx + fy * fy) * v / np.sqrt(v * v + sm * sm)
                      + visc * w)
                if lb > 0:
                    XB[..., 3 * (lb - 1) + 2] += m
                if la > 0:
                    XB[..., 3 * (la - 1) + 2] -= m
                out.append(m)
                continue
            n = X[..., c]
            px, py, cx, cy = geo[pair_i]
            tx, ty = cy, -cx  # the tangent: the normal turned -90 deg

            def point_velocity(link, px=px, py=py):
                return (gv[..., link, 0] - OM[..., link] * (py - gp[..., link, 1]),
                        gv[..., link, 1] + OM[..., link] * (px - gp[..., link, 0]))

            vbx, vby = point_velocity(lb)
            vax, vay = point_velocity(la)
            v = tx * (vbx - vax) + ty * (vby - vay)
            absn = np.where(np.real(n) < 0.0, -n, n)  # |n|, analytic on each side
            f = -(mu * absn * v / np.sqrt(v * v + sm * sm) + visc * v)
            fx, fy = f * tx, f * ty
            for link, sg in ((lb, 1.0), (la, -1.0)):
                if link > 0:
                    r = 3 * (link - 1)
                    XB[..., r] += sg * fx
                    XB[..., r + 1] += sg * fy
                    XB[..., r + 2] += sg * ((px - gp[..., link, 0]) * fy
                                            - (py - gp[..., link, 1]) * fx)
            out.append(f)
        return np.stack(out, axis=-1)


def _state(res: DynamicsResult, plan: DynamicsPlan) -> dict:
    """The real state of a dynamics result as (D, n_phi, ...) arrays for :class:`_Model`."""
    kin = res.kin
    n_d = int(np.prod(kin.batch_shape, dtype=np.int64))
    n_phi = kin.phi.shape[0]

    def flat(x):
        return np.asarray(x, dtype=float).reshape((n_d, n_phi) + x.shape[len(kin.batch_shape)
                                                                          + 1:])

    s = {"P": flat(kin.p), "V": flat(kin.v), "A": flat(kin.a), "TH": flat(kin.theta),
         "OM": flat(kin.omega), "EP": flat(kin.epsilon), "S": flat(kin.q),
         "SD": flat(kin.q_dot), "SDD": flat(kin.q_ddot),
         "prm": np.asarray(res.params, dtype=float).reshape(n_d, 1, -1)}
    if len(plan._loads):
        s["load_on"] = flat(res.load_on)
        s["travel"] = _travel(plan, s)
    return s


def _tangent_state(plan, s: dict, sens, scale: float, n_batch: int) -> dict:
    """The state's tangents (n_params, D, n_phi, ...) along every parameter: the kinematic
    tangents (the rates scaled from the file's speed to the call's), the parameters' unit
    vectors, the elastic loads' travel."""
    n_d, n_phi = s["P"].shape[:2]
    n_p = s["prm"].shape[-1]

    def t(x, f=1.0):
        x = np.asarray(x, dtype=float)
        x = x.reshape((n_d, n_phi) + x.shape[n_batch + 1:])
        return np.moveaxis(x, -1, 0) * f

    d = {"P": t(sens.dp), "V": t(sens.dv, scale), "A": t(sens.da, scale * scale),
         "TH": t(sens.dtheta), "OM": t(sens.domega, scale),
         "EP": t(sens.depsilon, scale * scale), "S": t(sens.dq), "SD": t(sens.dqd, scale),
         "SDD": t(sens.dqdd, scale * scale)}
    d["prm"] = np.broadcast_to(np.eye(n_p).reshape(n_p, 1, 1, n_p), (n_p, n_d, 1, n_p))
    if "travel" in s:  # (the compiled path's: a kinematic input, like the tangents above)
        d["travel"] = np.moveaxis(_travel_derivative(plan, s, sens, scale)[0], -1, 0)
    return d


def reference_sensitivities(machine: Machine, phi: ArrayLike, *,
                            params: ArrayLike | None = None, inputs=None,
                            rpm: float | None = None, loads=None,
                            gravity: bool = True) -> DynamicsSensitivities:
    """:func:`sewmech.engine.dynamic_sensitivity.dynamics_sensitivities` by the complex step
    through the whole residual in numpy (:class:`_Model`), one direction per parameter (see
    the module doc)."""
    rpm = machine.rpm if rpm is None else float(rpm)
    plan = DynamicsPlan(machine, phi, rpm=rpm, loads=loads, gravity=gravity)
    res = plan(params, inputs=inputs)
    if not res.kin.all_feasible:
        raise AnalysisError(f"machine '{machine.name}'", "cannot be assembled at some of the"
                            " angles: the derivatives are not defined there",
                            "Choose angles where it assembles (sewmech check)")
    model = _Model(plan)
    s = _state(res, plan)
    batch = res.kin.batch_shape
    n_d, n_phi = s["P"].shape[:2]
    n_eq = model.n_eq
    n_p = s["prm"].shape[-1]
    X = np.asarray(res.unknowns, dtype=float).reshape(n_d, n_phi, n_eq).copy()
    sens = sensitivities(machine, phi, params=params, inputs=inputs, rates=True)
    scale = rpm / machine.rpm
    ds = _tangent_state(plan, s, sens, scale, len(batch))
    # designs in chunks: the complex state of one design is (n_params + n_eq) times its size
    per_design = (n_p + n_eq) * n_phi * (s["P"].shape[2] * 6 + 64) * 16
    step = max(1, int(MAX_BYTES // max(per_design, 1)))
    dX = np.zeros((n_d, n_phi, n_eq, n_p))  # (the kernel fills the active columns)
    dT = np.empty((n_d, n_phi, n_p))
    dF = np.empty((n_d, n_phi, 2, n_p))
    dM = np.empty((n_d, n_phi, n_p))
    has_shaft = machine.spec.shaft is not None
    dBf = np.empty((n_d, n_phi, 2, n_p)) if has_shaft else None
    dBr = np.empty((n_d, n_phi, 2, n_p)) if has_shaft else None
    worst = 0.0
    act = model.active(ds)
    ds = {k: v[act] for k, v in ds.items()}  # the others' derivatives are 0
    for x in (dX, dT, dF, dM, dBf, dBr):
        if x is not None:
            x[..., ~act] = 0.0
    for d0 in range(0, n_d, step):
        d1 = min(n_d, d0 + step)
        sd = {k: v[d0:d1] for k, v in s.items()}
        tsd = {k: v[:, d0:d1] for k, v in ds.items()}
        Xd = X[d0:d1]
        G0 = model.residual(Xd, sd)
        scale_f = max(float(np.abs(Xd).max()), 1.0)
        worst = max(worst, float(np.abs(G0).max()) / scale_f)
        # dG/dX: every unknown a direction
        eye = np.eye(n_eq).reshape(n_eq, 1, 1, n_eq)
        J = np.imag(model.residual(Xd[None] + 1j * H * eye, sd)) / H  # (n_eq, D, n_phi, rows)
        J = np.moveaxis(J, 0, -1)  # (D, n_phi, rows, cols)
        # dG/ds ds/dp: every parameter a direction
        sc = {k: sd[k][None] + 1j * H * tsd[k] if k in tsd else sd[k] for k in sd}
        parts: dict = {}
        Gs = np.imag(model.residual(Xd[None], sc, parts)) / H  # (n_p, D, n_phi, n_eq)
        rhs = -np.moveaxis(Gs, 0, -1)  # (D, n_phi, n_eq, n_p)
        dXd = np.linalg.solve(J, rhs)
        dX[d0:d1, ..., act] = dXd
        # the derived quantities from the complex unknowns and state
        Xc = Xd[None] + 1j * H * np.moveaxis(dXd, -1, 0)
        if model.friction is not None:  # the friction of the complex unknowns (the rest of
            gp, gv, _ = parts["com"]  # what the derived quantities read is the state's)
            parts["FF"] = model._friction(Xc, sc, parts["geo"], gp, gv,
                                          np.zeros(Xc.shape, dtype=complex))
        T, F, M = _driving_and_shaking(model, Xc, sc, parts)
        dT[d0:d1, ..., act] = np.moveaxis(np.imag(T) / H, 0, -1)
        dF[d0:d1, ..., act] = np.moveaxis(np.imag(F) / H, 0, -1)
        dM[d0:d1, ..., act] = np.moveaxis(np.imag(M) / H, 0, -1)
        if has_shaft:
            b = _bearings(model, res, Xc, sc, parts, d0, d1)
            dBf[d0:d1, ..., act] = np.moveaxis(np.imag(b.front) / H, 0, -1)
            dBr[d0:d1, ..., act] = np.moveaxis(np.imag(b.rear) / H, 0, -1)

    def shape(x):
        return None if x is None else x.reshape(batch + x.shape[1:])

    return DynamicsSensitivities(res, machine.parameter_names, shape(dX), shape(dT), shape(dF),
                                 shape(dM), shape(dBf), shape(dBr), worst)


def _driving_and_shaking(model: _Model, Xc, sc, parts):
    """The driving torque (sum of the shaft's drivers' torques times their ratios), the
    shaking force -sum m a_G and moment -sum (I alpha + r_G x m a_G) about the origin, the
    counterweights included; complex."""
    m = model.machine
    prm = sc["prm"]
    T = 0.0
    for pair, row in zip(m.pairs, model.table, strict=True):
        if pair.kind == "driver" and pair.input == SHAFT:
            T = T + Xc[..., row[7]] * prm[..., pair.ratio_param]
    gp, _, ga = parts["com"]
    mass, inertia = model.lm.mass, model.lm.inertia
    F = -1e-3 * np.einsum("l,...lc->...c", mass, ga)
    cross = gp[..., 0] * ga[..., 1] - gp[..., 1] * ga[..., 0]
    M = -1e-3 * (np.einsum("l,...l->...", mass, cross)
                 + np.einsum("l,...l->...", inertia, sc["EP"]))
    cw = parts["cw"]
    if cw is not None:
        mc, p, _, a = cw
        mc = mc[..., 0, :]  # (the masses have a phi axis of 1 here)
        F = F - 1e-3 * np.einsum("...c,...kcx->...kx", mc, a)
        M = M - 1e-3 * np.einsum("...c,...kc->...k", mc, p[..., 0] * a[..., 1]
                                 - p[..., 1] * a[..., 0])
    return np.broadcast_to(T, F.shape[:-1]), F, M


class _ComplexResult:
    """What :func:`sewmech.engine.dynamics.bearing_reactions` reads of a result, complex."""

    def __init__(self, model, res, Xc, sc, parts, d0, d1):
        self.machine = model.machine
        self.pairs = model.machine.pairs
        self.gravity = res.gravity
        self.mass_props = res.mass_props
        self.load_links = res.load_links
        self._model, self._Xc, self._parts = model, Xc, parts
        self._columns = res._columns
        self.kin = _ComplexKin(sc)
        self.com_a = parts["com"][2]
        LF = parts["LF"]
        self.load_force = LF if LF is not None else np.zeros(Xc.shape[:-1] + (0, 2))
        cw = parts["cw"]
        if cw is None:
            self.counterweights = None
        else:
            mc, p, _, a = cw
            rc = res.counterweights
            self.counterweights = _CW(rc.names, rc.links, mc[..., 0, :], rc.z, a)
        fr = model.friction
        self._fr = {} if fr is None else {name: parts["FF"][..., i]
                                          for i, name in enumerate(fr.names)}

    def total_force(self, name):
        c, pair = self._columns[name]
        X = self._Xc
        if pair.kind == "revolute":
            return X[..., c:c + 2]
        i = self.pairs.index(pair)
        _, _, nx, ny = self._parts["geo"][i]
        F = np.stack([X[..., c] * nx, X[..., c] * ny], axis=-1)
        if name in self._fr:
            F = F + self._fr[name][..., None] * np.stack([ny, -nx], axis=-1)
        return F


@dataclass
class _CW:
    names: tuple
    links: np.ndarray
    mass: np.ndarray
    z: np.ndarray
    a: np.ndarray


class _ComplexKin:
    def __init__(self, sc):
        self.theta, self.omega, self.epsilon = sc["TH"], sc["OM"], sc["EP"]


def _bearings(model, res, Xc, sc, parts, d0, d1):
    return bearing_reactions(_ComplexResult(model, res, Xc, sc, parts, d0, d1))


# ---- the compiled derivatives -------------------------------------------------------------------

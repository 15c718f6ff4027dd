"""Exact design sensitivities of the inverse dynamics: d(pair forces, driving torque, shaking
force and moment, bearing reactions) / d(every parameter), at every shaft angle.

The force analysis solves, at every position, the equilibrium of every moving link,

    G(X, s) = A(s) X - B(s) + XB(X, s) = 0,

for the pair unknowns X (forces, the drivers' torques), where the state s is the motion (the
points' positions, velocities and accelerations, the links' angles and rates, the joint
variables) and the design's parameters: A holds the pairs' geometry (moment arms, contact
normals), B the links' and counterweights' inertia forces and weights, XB the applied forces
(process loads, springs and dampers, and the friction, which depends on X itself). A design
parameter p moves the state along its exact kinematic tangent ds/dp
(:mod:`sewmech.engine.sensitivity`, with the rates); implicit differentiation of G = 0 gives

    (dG/dX) dX/dp = -(dG/ds) ds/dp,

with dG/dX = A + dXB/dX (A alone without friction) and dG/ds ds/dp = (dA/dp) X - dB/dp +
dXB/dp: the derivative of the force solve.

:func:`dynamics_sensitivities` takes both in a compiled kernel
(:mod:`sewmech.engine._force_tangents`): each term of G (a pair, a link's inertia, a
counterweight, a load, a spring, a frictional pair) is differentiated only along the
parameters that move what it reads (the kinematic tangents are compact: each quantity's
derivatives by its support), by hand where it is products and sums and by the complex step
where it has roots and quotients; dG/dX has the block upper-triangular pattern of A, so every
parameter's dX/dp comes from one block solve per position. The derived quantities (driving
torque, shaking force and moment, bearing reactions) follow from dX/dp and the state's
tangents. :mod:`sewmech.engine._dynamic_reference` is a second implementation of the same
equations (the whole residual in complex-safe numpy, evaluated at s + i h ds/dp, one direction
per parameter, and a dense solve): slow, and what the tests hold the kernel against.

What is held fixed: where each process load acts (its windows and conditions) is the turn's as
solved; at an angle where a load switches on or off, the forces jump and have no derivative
there (the derivative returned is that of the side the solve took). A threshold that moves with
the design (``within_of_max``) moves where a load acts, not its force.

Derivatives are in internal units per unit of the parameter (mm, rad, kg mm, ...): N and N mm
per unit. Constant shaft speed (``rpm``) only.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from . import _kernels as K
from .dynamics import GRAVITY, DynamicsPlan, DynamicsResult
from .errors import AnalysisError
from .machine import Machine
from .sensitivity import sensitivities
from .spec import SHAFT


@dataclass
class DynamicsSensitivities:
    """The inverse dynamics of a batch of designs and their derivatives by every parameter.

    result : the :class:`~sewmech.engine.dynamics.DynamicsResult` the derivatives belong to;
    parameter_names; dX : batch + (n_phi, n_unknowns, n_params), d(every pair unknown)/d(each
    parameter) (N or N mm per parameter unit; the unknowns as ``result.unknowns`` lays them
    out); input_torque, shaking_moment : batch + (n_phi, n_params), N mm per unit;
    shaking_force : batch + (n_phi, 2, n_params), N per unit; bearings_front,
    bearings_rear : batch + (n_phi, 2, n_params) or None without ``[shaft]``."""

    result: DynamicsResult
    parameter_names: tuple[str, ...]
    dX: np.ndarray
    input_torque: np.ndarray
    shaking_force: np.ndarray
    shaking_moment: np.ndarray
    bearings_front: np.ndarray | None
    bearings_rear: np.ndarray | None
    residual: float

    def pair(self, name: str) -> np.ndarray:
        """d(unknowns of one pair)/d(parameters), batch + (n_phi, k, n_params) (as
        :meth:`DynamicsResult.pair` lays them out)."""
        c, pair = self.result._columns[name]
        from .dynamics import _N_UNKNOWN

        return self.dX[..., c:c + _N_UNKNOWN[pair.kind], :]

    def parameter(self, name: str) -> int:
        from .errors import name_index

        return name_index(self.parameter_names, name, "parameter")


def _travel(plan: DynamicsPlan, s: dict) -> np.ndarray:
    """Each elastic load's travel past its first threshold (D, n_phi, n_loads; 0 for the
    other loads), as :meth:`LoadTables.masks` finds it (only that condition's channel read)."""
    from .channels import channel_values

    L = plan._loads
    out = np.zeros(s["P"].shape[:2] + (len(L),))
    for j, spec in enumerate(L.specs):
        if spec.law != "elastic":
            continue
        for ref, c in L.conditions[j]:
            if c.above is None and c.below is None:
                continue
            val, _ = channel_values(ref, s, L.thread)
            with np.errstate(invalid="ignore"):
                out[..., j] = np.maximum(val - c.above if c.above is not None else
                                         c.below - val, 0.0)
            break
    return out


@dataclass(frozen=True)
class _Terms:
    """What the compiled derivative kernel (:func:`sewmech.engine._force_tangents.
    force_tangents`) needs of a machine besides its loads: the tables of its counterweights,
    springs and frictional pairs, and the parameters each term's support holds (CSR lists of
    parameter indices: per link, pair geometry, pair, counterweight, spring, torsion spring,
    frictional pair), from the kinematic tangents' supports."""

    qm: np.ndarray  # each quantity's support size (a point: per coordinate)
    link_sup: tuple
    lists: dict
    cw_int: np.ndarray
    sp_int: np.ndarray
    sp_f: np.ndarray
    ts_int: np.ndarray
    ts_f: np.ndarray
    fr_int: np.ndarray
    fr_f: np.ndarray
    fr_pair: np.ndarray
    used: frozenset
    csr: dict  # the lists as CSR (ptr, parameters) arrays
    read_q: np.ndarray  # the quantities the terms read (the loads' points apart)
    ent_q: np.ndarray  # every support entry: its quantity, offset in the rows, parameter
    ent_off: np.ndarray
    ent_p: np.ndarray


def _csr(sets) -> tuple[np.ndarray, np.ndarray]:
    ptr = np.zeros(len(sets) + 1, dtype=np.int64)
    ptr[1:] = np.cumsum([len(x) for x in sets])
    idx = np.array([p for x in sets for p in sorted(x)], dtype=np.int64)
    return ptr, idx


@lru_cache(maxsize=16)
def _terms(machine: Machine) -> _Terms:
    from .dynamics import _pair_table, link_masses
    from .friction import FrictionTables
    from .sensitivity import _plan
    from .springs import SpringTables

    plan = _plan(machine, None)
    lay = plan.layout
    sup = [frozenset(int(p) for p in s) for s in plan.support]
    n_pt, n_l = len(machine.point_names), len(machine.link_names)

    def pt(i):
        return sup[i]

    def lk(i):
        return sup[n_pt + i]

    def var(i):
        return sup[n_pt + n_l + i]

    lm = link_masses(machine)
    link_sup = tuple(pt(int(o)) | lk(li) if o >= 0 and li > 0 else frozenset()
                     for li, o in enumerate(lm.origins))
    table, _, cam_rows = _pair_table(machine)
    terms = machine.terms
    geo, pair = [], []
    for row in table:
        kind = row[0]
        s: set = set()
        if kind != K.PAIR_DRIVER:
            if kind == K.PAIR_CAM:
                for r in range(row[9], row[9] + row[10]):
                    t = terms[cam_rows[r]]
                    if t[0] == K.TERM_POINT:
                        s |= pt(int(t[4]))
                        continue
                    s |= {int(t[4])} if t[3] == K.SRC_PARAM else var(int(t[4]))
                    s |= lk(int(t[6])) if t[5] == K.SRC_LINK else var(int(t[6]))
                    if t[7] >= 0:
                        s.add(int(t[7]))
            else:
                s |= pt(int(row[3]))
            if kind != K.PAIR_REVOLUTE:
                s |= lk(int(row[4])) if row[4] >= 0 else var(int(row[5]))
                if row[6] >= 0:
                    s.add(int(row[6]))
        geo.append(s)
        pair.append(set() if kind == K.PAIR_DRIVER else
                    s | link_sup[int(row[1])] | link_sup[int(row[2])])
    cws = machine.counterweights
    cw_int = np.array([[c.link_index, machine.point_index(c.origin), int(c.by_moment),
                        *c.params] for c in cws], dtype=np.int64).reshape(-1, 6)
    cw = [set(int(i) for i in c.params) | pt(machine.point_index(c.origin)) | lk(c.link_index)
          | link_sup[c.link_index] for c in cws]
    sp = SpringTables.build(machine)
    sp_int = np.array(sp.ends, dtype=np.int64).reshape(-1, 4)
    sp_f = np.stack([sp.k, sp.free, sp.c], axis=-1).reshape(-1, 3)
    springs = [pt(pa) | pt(pb) | link_sup[la] | link_sup[lb] for la, pa, lb, pb in sp.ends]
    ts_int = np.array(sp.torsion_links, dtype=np.int64).reshape(-1, 2)
    ts_f = np.stack([sp.kt, sp.free_angle, sp.ct], axis=-1).reshape(-1, 3)
    torsion = [lk(la) | lk(lb) for la, lb in sp.torsion_links]
    fr = FrictionTables.build(machine)
    if fr is None:
        fr_int, fr_f, fr_pair, friction = (np.zeros((0, 4), dtype=np.int64), np.zeros((0, 4)),
                                           np.zeros(0, dtype=np.int64), [])
    else:
        fr_int, fr_f = fr.ints, fr.values
        fr_pair = np.asarray(fr.pair_index, dtype=np.int64)
        friction = [lk(int(la)) | lk(int(lb)) if kind == K.PAIR_REVOLUTE else
                    geo[i] | link_sup[int(la)] | link_sup[int(lb)]
                    for (kind, la, lb, _), i in zip(fr.ints, fr.pair_index, strict=True)]
    lists = {"lk": link_sup, "geo": geo, "pr": pair, "cw": cw, "sp": springs, "ts": torsion,
             "fr": friction}
    used = frozenset().union(*(x for v in lists.values() for x in v))
    used |= {p.ratio_param for p in machine.pairs if p.kind == "driver" and p.input == SHAFT}
    # the points the terms read: the links' frame origins, the pairs' points and cam loops'
    # points, the counterweights' origins, the springs' ends (every link and variable)
    read_q = np.ones(len(sup), dtype=bool)
    read_q[:n_pt] = False
    pts = {int(o) for o in lm.origins if o >= 0}
    pts |= {int(r[3]) for r in table if r[0] != K.PAIR_DRIVER and r[3] >= 0}
    pts |= {int(terms[t, 4]) for t in cam_rows if terms[t, 0] == K.TERM_POINT}
    pts |= {machine.point_index(c.origin) for c in cws}
    pts |= {int(x) for la, pa, lb, pb in sp.ends for x in (pa, pb)}
    read_q[sorted(pts)] = True
    qoff = np.asarray(lay.qoff, dtype=np.int64)
    ent_q = np.concatenate([np.full(len(s), q, dtype=np.int64)
                            for q, s in enumerate(plan.support)])
    ent_off = np.concatenate([qoff[q] + np.arange(len(s), dtype=np.int64)
                              for q, s in enumerate(plan.support)])
    ent_p = np.concatenate([np.asarray(s, dtype=np.int64) for s in plan.support])
    out = _Terms(np.asarray(lay.qm, dtype=np.int64),
                 link_sup, lists, cw_int, sp_int, sp_f, ts_int, ts_f, fr_int, fr_f, fr_pair,
                 frozenset(used), {k: _csr(v) for k, v in lists.items()}, read_q, ent_q,
                 ent_off, ent_p)
    for a in (out.qm, out.cw_int, out.sp_int, out.sp_f, out.ts_int, out.ts_f,
              out.fr_int, out.fr_f, out.fr_pair, out.read_q, out.ent_q, out.ent_off, out.ent_p,
              *(x for v in out.csr.values() for x in v)):
        a.setflags(write=False)
    return out


def _entries(terms: _Terms, jpos: np.ndarray, load_points) -> tuple:
    """Every support entry of an active parameter and of a quantity a term reads (the points
    the terms read, the loads' ``load_points``, every link and variable): its quantity, its
    offset in the compact tangents' rows and the parameter's active column (the kernel's
    ent_q, ent_off, ent_j)."""
    read = terms.read_q
    if len(load_points):
        read = read.copy()
        read[np.asarray(load_points, dtype=np.int64)] = True
    j = jpos[terms.ent_p]
    keep = (j >= 0) & read[terms.ent_q]
    return terms.ent_q[keep], terms.ent_off[keep], j[keep]


def _load_tables(plan: DynamicsPlan, terms: _Terms, travel_sup: list) -> tuple:
    """The loads as the kernel takes them: (link, point, law, fixed direction) and (force N,
    smoothing speed mm/s, rate N/mm, direction), the toward points (CSR) and each load's
    support (its point, the toward points, its travel's condition and its link)."""
    from ._force_tangents import LAW_CONSTANT, LAW_ELASTIC, LAW_RESISTIVE
    from .sensitivity import _plan

    L = plan._loads
    sup = _plan(plan.machine, None).support
    law = {"resistive": LAW_RESISTIVE, "constant": LAW_CONSTANT, "elastic": LAW_ELASTIC}
    ints, vals, tw, sets = [], [], [], []
    for j, spec in enumerate(L.specs):
        d = L.direction[j]
        ints.append((L.links[j], L.points[j], law[spec.law], int(d is not None)))
        vals.append((spec.force_N, spec.smooth_mm_s, spec.rate_N_per_mm if spec.law ==
                     "elastic" else 0.0, *(d if d is not None else (0.0, 0.0))))
        tw.append(tuple(int(q) for q in L.toward[j]))
        s = set(int(p) for p in sup[L.points[j]]) | travel_sup[j] | terms.link_sup[L.links[j]]
        for q in L.toward[j]:
            s |= set(int(p) for p in sup[q])
        sets.append(s)
    tw_ptr = np.zeros(len(tw) + 1, dtype=np.int64)
    tw_ptr[1:] = np.cumsum([len(t) for t in tw])
    return (np.array(ints, dtype=np.int64).reshape(-1, 4), np.array(vals).reshape(-1, 5),
            tw_ptr, np.array([q for t in tw for q in t], dtype=np.int64), sets)


def _travel_derivative(plan: DynamicsPlan, s: dict, sens, scale: float
                       ) -> tuple[np.ndarray, list]:
    """d(travel)/d(parameter) of each elastic load (D, n_phi, n_loads, n_params) and each
    load's support of it: the derivative of its first above/below condition's channel where
    the travel is positive (0 elsewhere), from the compact kinematic tangents."""
    from .threadpath import path_length_gradient

    L = plan._loads
    m = plan.machine
    n_p = len(m.parameter_names)
    n_pt, n_l = len(m.point_names), len(m.link_names)
    shape = s["P"].shape[:2]
    out = np.zeros(shape + (len(L), n_p))
    sets = [set() for _ in range(len(L))]
    if "travel" not in s:
        return out, sets
    cp = sens._plan
    n = shape[0] * shape[1]

    def dense(level, q, comp=0):
        from .sensitivity import _lanes

        off, mq = int(cp.layout.qoff[q]) + comp * int(cp.layout.qm[q]), int(cp.layout.qm[q])
        x = np.zeros((n, n_p))
        x[:, cp.support[q]] = _lanes(sens._t[level], off, mq, n)
        return x.reshape(shape + (n_p,))

    for j, spec in enumerate(L.specs):
        if spec.law != "elastic":
            continue
        for ref, c in L.conditions[j]:
            if c.above is None and c.below is None:
                continue
            if ref.kind == "thread":
                pts = list(L.thread.points)
                g = path_length_gradient(s["P"][:, :, pts], L.thread.rho)  # (D, n_phi, g, 2)
                dval = sum(g[:, :, i, comp, None] * dense(0, q, comp)
                           for i, q in enumerate(pts) for comp in (0, 1))
            else:
                from .channels import KINDS

                level = {"P": 0, "V": 1, "A": 2, "TH": 0, "OM": 1, "EP": 2, "S": 0, "SD": 1,
                         "SDD": 2}[KINDS[ref.kind][0]]
                base = {"p": 0, "v": 0, "a": 0}.get(ref.kind)
                if base is not None:
                    dval = dense(level, ref.index, ref.comp)
                elif KINDS[ref.kind][0] in ("TH", "OM", "EP"):
                    dval = dense(level, n_pt + ref.index)
                else:
                    dval = dense(level, n_pt + n_l + ref.index)
                dval = dval * scale ** level  # (the tangents' rates are the file's speed's)
            moving = s["travel"][..., j] > 0.0
            out[..., j, :] = np.where(moving[..., None], dval if c.above is not None else -dval,
                                      0.0)
            sets[j] = set(int(p) for p in np.flatnonzero(np.any(out[..., j, :] != 0.0,
                                                                axis=(0, 1))))
            break
    return out, sets


def dynamics_sensitivities(machine: Machine, phi: ArrayLike, *, params: ArrayLike | None = None,
                           inputs=None, rpm: float | None = None, loads=None,
                           gravity: bool = True) -> DynamicsSensitivities:
    """The inverse dynamics (:func:`sewmech.engine.dynamics.inverse_dynamics`, same arguments)
    and its exact derivatives by every parameter (``machine.parameter_names``): see the module
    doc. Every position must assemble. Units: N, N mm per unit of each parameter."""
    from . import _force_tangents as FT
    from ._threads import run_chunks
    from .kinematics import kernel_input

    rpm = machine.rpm if rpm is None else float(rpm)
    plan = DynamicsPlan(machine, phi, rpm=rpm, loads=loads, gravity=gravity)
    res = plan(params, inputs=inputs)
    kin = res.kin
    if not kin.all_feasible:
        raise AnalysisError(f"machine '{machine.name}'", "cannot be assembled at some of the"
                            " angles: the derivatives are not defined there",
                            "Choose angles where it assembles (sewmech check)")
    # (the analysis' own kinematics, when it ran at the file's speed: the tangents' rates are
    # taken at that speed)
    sens = sensitivities(machine, phi, params=params, inputs=inputs, rates=True,
                         kin=kin if rpm == machine.rpm else None)
    terms = _terms(machine)
    batch = kin.batch_shape
    n_d = int(np.prod(batch, dtype=np.int64))
    n_phi = kin.phi.shape[0]
    n_p = len(machine.parameter_names)
    scale = rpm / machine.rpm

    def flat(x):
        return kernel_input(np.asarray(x, dtype=float).reshape(
            (n_d, n_phi) + x.shape[len(batch) + 1:]))

    s = {k: flat(x) for k, x in (("P", kin.p), ("V", kin.v), ("A", kin.a), ("TH", kin.theta),
                                  ("OM", kin.omega), ("EP", kin.epsilon), ("S", kin.q),
                                  ("SD", kin.q_dot), ("SDD", kin.q_ddot))}
    n_ld = len(plan._loads)
    if n_ld:
        s["travel"] = _travel(plan, s)
        travel = kernel_input(s["travel"])
        dtr, travel_sup = _travel_derivative(plan, s, sens, scale)
    else:
        travel = kernel_input(np.zeros((n_d, n_phi, 0)))
        dtr, travel_sup = np.zeros((n_d, n_phi, 0, n_p)), []
    ld_int, ld_f, tw_ptr, tw_pts, ld_sets = _load_tables(plan, terms, travel_sup)
    used = set(terms.used).union(*ld_sets) if ld_sets else set(terms.used)
    act = np.array(sorted(used), dtype=np.int64)
    n_act = len(act)
    jpos = np.full(n_p, -1, dtype=np.int64)
    jpos[act] = np.arange(n_act)
    csr = terms.csr
    ld_ptr, ld_p = _csr(ld_sets)
    bearings = _bearing_tables(machine, tuple(plan._load_links))
    n_eq = plan.structure.pattern.shape[0]
    dX = np.zeros((n_d, n_phi, n_eq, n_p))  # (the kernel fills the active columns)
    dSF = np.empty((n_d, n_phi, 2, n_act))
    dSM = np.empty((n_d, n_phi, n_act))
    has_shaft = machine.spec.shaft is not None
    dBf = np.empty((n_d, n_phi, 2, n_act) if has_shaft else (0, 0, 2, n_act))
    dBr = np.empty_like(dBf)
    G0 = np.empty((n_d, n_phi, n_eq))
    st = plan.structure
    lm = plan.masses
    X = flat(res.unknowns)
    on = flat(res.load_on) if n_ld else kernel_input(np.zeros((n_d, n_phi, 0)))
    dtravel = kernel_input(dtr[..., act]) if n_ld else kernel_input(np.zeros((n_d, n_phi, 0,
                                                                                n_act)))
    ki = kernel_input
    prm = np.asarray(res.params, dtype=float).reshape(n_d, -1)
    args = (
        s["P"], s["V"], s["A"], s["TH"], s["OM"], s["EP"], s["S"], ki(prm),
        flat(res.com_p), flat(res.com_v), flat(res.com_a), X, travel, dtravel, on,
        *(ki(t) for t in sens._t), terms.qm,
        *_entries(terms, jpos, [*plan._loads.points, *tw_pts]),
        scale, scale * scale,
        ki(st.table), ki(st.angles), ki(st.cam_rows), ki(machine.terms), ki(lm.mass),
        ki(lm.inertia), ki(lm.com_u), ki(lm.com_v), ki(lm.origins),
        GRAVITY if gravity else 0.0, terms.cw_int, ld_int, ld_f, tw_ptr, tw_pts,
        terms.sp_int, terms.sp_f, terms.ts_int, terms.ts_f, terms.fr_int, terms.fr_f,
        terms.fr_pair, len(machine.point_names),
        *csr["lk"], *csr["geo"], *csr["pr"], *csr["cw"], ld_ptr, ld_p, *csr["sp"], *csr["ts"],
        *csr["fr"], jpos, ki(st.blk_ptr), ki(st.rperm), ki(st.cperm), ki(st.cpl_ptr),
        ki(st.cpl_row), ki(st.cpl_col), *bearings, act, dX, dSF, dSM, dBf, dBr, G0)
    if n_d > 1:  # designs in chunks on the threads (each is a couple of milliseconds)
        run_chunks(FT.force_tangents, n_d, args)
    else:
        FT.force_tangents(0, n_d, *args)
    worst = float(np.abs(G0).max()) / max(float(np.abs(X).max()), 1.0) if G0.size else 0.0

    def full(x, shape):
        out = np.zeros(shape + (n_p,))
        out[..., act] = x
        return out.reshape(batch + shape[1:] + (n_p,))

    # the driving torque: sum of the shaft drivers' torques times their speed ratios
    dT = np.zeros((n_d, n_phi, n_act))
    dT_ratio = np.zeros((n_d, n_phi, n_p))
    for pair, row in zip(machine.pairs, st.table, strict=True):
        if pair.kind == "driver" and pair.input == SHAFT:
            dT += dX[:, :, row[7]][..., act] * prm[:, None, pair.ratio_param, None]
            dT_ratio[:, :, pair.ratio_param] += X[:, :, row[7]]
    dT = full(dT, (n_d, n_phi)) + dT_ratio.reshape(batch + (n_phi, n_p))
    out = dict(dT=dT, dF=full(dSF, (n_d, n_phi, 2)), dM=full(dSM, (n_d, n_phi)))
    if has_shaft:
        out["dBf"] = full(dBf, (n_d, n_phi, 2))
        out["dBr"] = full(dBr, (n_d, n_phi, 2))
    return DynamicsSensitivities(res, machine.parameter_names,
                                 dX.reshape(batch + (n_phi, n_eq, n_p)), out["dT"], out["dF"],
                                 out["dM"], out.get("dBf"), out.get("dBr"), worst)


@lru_cache(maxsize=16)
def _bearing_tables(m: Machine, load_links: tuple) -> tuple:
    """What the kernel's bearing part reads (see :func:`sewmech.engine._force_tangents.
    force_tangents`): the pairs, loads, links with mass and counterweights that
    :func:`sewmech.engine.dynamics.shaft_bearings` sums, with their planes."""
    from .dynamics import _pair_table, shaft_mass, shaft_pairs
    from .friction import FrictionTables

    shaft = m.spec.shaft
    bp_int, bp_f, bl_int, bl_z, bm_int, bm_f, bc_int, bc_z = [], [], [], [], [], [], [], []
    zf = zr = 0.0
    if shaft is not None:
        names = m.link_names
        zf, zr = float(shaft.bearings["front"]), float(shaft.bearings["rear"])
        fr = FrictionTables.build(m)
        fr_of = {} if fr is None else {int(i): f for f, i in enumerate(fr.pair_index)}
        columns = _pair_table(m)[0][:, 7]
        for lname, z in shaft.links.items():
            li = names.index(lname)
            for pair, sign in shaft_pairs(shaft, m.pairs, lname):
                i = m.pairs.index(pair)
                rev = pair.kind == "revolute"
                bp_int.append((int(columns[i]), i, -1 if rev else fr_of.get(i, -1), int(rev)))
                bp_f.append((sign, float(z)))
            for k, li_load in enumerate(load_links):
                if li_load == li:
                    bl_int.append(k)
                    bl_z.append(float(z))
            mp = shaft_mass(m.masses, lname)
            if mp is None:
                continue
            J = mp.about(np.zeros(3))  # about the axis point at z = 0
            bm_int.append(li)
            bm_f.append((float(J[0, 2]), float(J[1, 2]), float(mp.mass)))
        for k, c in enumerate(m.counterweights):
            if names[c.link_index] in shaft.links:
                bc_int.append(k)
                bc_z.append(float(c.z))
    ints = np.int64
    out = (np.array(bp_int, dtype=ints).reshape(-1, 4), np.array(bp_f).reshape(-1, 2),
           np.array(bl_int, dtype=ints), np.array(bl_z, dtype=float),
           np.array(bm_int, dtype=ints), np.array(bm_f).reshape(-1, 3),
           np.array(bc_int, dtype=ints), np.array(bc_z, dtype=float))
    for a in out:
        a.setflags(write=False)
    return (*out, zf, zr)

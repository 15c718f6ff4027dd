"""Metrics and the whole-turn assembly check for batches of designs, values only, and one
metric with its derivative: what the design problems (:mod:`sewmech.design.problem`, whose
``batch_values`` and assembly margin build on this, and :mod:`sewmech.design.optimize`) and the
sweeps (:mod:`sewmech.design.sweep`) evaluate.

Units: parameters internal (mm, rad) unless a function says file units; metrics in their own
units (mm, deg for the ``*_deg`` metrics, rad for link angles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engine.errors import OptionError, SewmechError
from ..engine.machine import Machine
from ..sewing.thread_gradients import THREAD_FIGURES, thread_gradient
from ._models import ref_key

#: how far (mm) every closed-form unit must stay from failing to assemble at the grid angles of
#: the searches' assembly check: a margin m(phi) that clears this at 1 deg steps cannot fall
#: below zero between them unless |m''| exceeds 0.01 / (h^2 / 8) = 260 mm/rad^2, several times
#: what the links of a sewing machine give (their lengths, 10-130 mm). Without it a search
#: pressed against the assembly limit ended a few micrometres beyond it between grid angles.
ASSEMBLY_CLEARANCE_MM = 0.01


def setting_extremes(machine: Machine) -> dict[str, np.ndarray] | None:
    """Both ends of every setting input (rad; its default where a range is not declared), as
    a (2, 1) column per input to broadcast against a batch of designs; None without inputs."""
    if not machine.spec.inputs:
        return None
    return {n: np.array([math.radians(i.min_deg if i.min_deg is not None else i.default_deg),
                         math.radians(i.max_deg if i.max_deg is not None else i.default_deg)]
                        )[:, None]
            for n, i in machine.spec.inputs.items()}


def _setting_extremes(machine: Machine) -> list[dict | None]:
    """The setting inputs at their lower and at their upper ends (rad), or [None]: one
    design's two calls (:func:`setting_extremes` as two dicts)."""
    ext = setting_extremes(machine)
    if ext is None:
        return [None]
    return [{n: float(v[k, 0]) for n, v in ext.items()} for k in (0, 1)]


#: designs per kinematics call of the whole-turn assembly check: 256 x 2 settings x 360
#: angles of JB1-3's points are about 0.3 GB, whatever the batch
ASSEMBLY_CHUNK = 256


def assembles_on_grid(machine: Machine, P: np.ndarray) -> np.ndarray:
    """Which designs of the batch P (m, n_params) assemble over the whole turn as the searches
    and sweeps see it: on a 1 deg grid at both ends of every setting input, every closed-form
    unit's assembly margin at least :data:`ASSEMBLY_CLEARANCE_MM` at every grid angle. One
    kinematics call of all 360 angles per :data:`ASSEMBLY_CHUNK` designs: the definition that
    :func:`assembles_batch` decides from a tenth of the positions. (m,) bool."""
    from ..engine.kinematics import kinematics
    from ..engine.margins import conditions

    P = np.atleast_2d(np.asarray(P, dtype=float))
    phi = np.radians(np.arange(360.0))
    inputs = setting_extremes(machine)
    # every unit solved (asking for no outputs would solve none), but only the points and the
    # links the margins read kept when they need every unit (less memory and time)
    points = list(machine.point_names)
    links = sorted({lk for c in conditions(machine, np.asarray(machine.defaults))
                    for lk in c.links})
    sel = {"points": points, "links": links, "variables": []} \
        if len(machine.selection(points, links, [])[-1]) == len(machine.program) else {}
    ok = np.empty(len(P), dtype=bool)
    for a in range(0, len(P), ASSEMBLY_CHUNK):
        Q = P[a:a + ASSEMBLY_CHUNK]
        m = len(Q)
        r = kinematics(machine, phi, params=Q if inputs is None else Q[None, :, :],
                       inputs=inputs, on_failure="mask", **sel)
        good = r.feasible.reshape(-1, m, len(phi)).all(axis=(0, 2))
        for c in conditions(machine, Q.T[:, :, None]):  # (n_params, m, 1): per design
            margin = np.asarray(c.fn(r)[0]).reshape(-1, m, len(phi))
            good &= np.where(np.isnan(margin), -np.inf, margin).min(axis=(0, 2)) >= \
                ASSEMBLY_CLEARANCE_MM
        ok[a:a + m] = good
    return ok


#: the located assembly check's coarse grid (deg; a divisor of 360, so that its angles are
#: angles of the 1 deg grid)
COARSE_STEP_DEG = 10
#: the least room (mm) between a margin's interpolant and the clearance for a design to be
#: taken as assembling without its 1 deg grid
HERMITE_FLOOR_MM = 1e-4
#: the largest residual (mm) of a point's motion across a coarse step (its displacement against
#: the integral of its velocity by the trapezoid rule with end corrections, h^5 p^(5) / 720 for
#: a smooth motion; at most 0.016 mm on the shipped JB1-3 sweep, whose cams' arcs join with a
#: jump in acceleration) before the step is taken as a possible change of assembly branch
BRANCH_JUMP_MM = 0.03


@dataclass
class AssemblyCounts:
    """What :func:`assembles_batch` did: designs decided on the coarse grid, and designs
    checked again on the whole 1 deg grid (a margin close to the clearance between coarse
    angles, or a point that moved across a coarse step more than its velocity says)."""

    coarse: int = 0
    whole_grid: int = 0

    def add(self, other: AssemblyCounts) -> None:
        self.coarse += other.coarse
        self.whole_grid += other.whole_grid


def assembles_batch(machine: Machine, P: np.ndarray, *,
                    counts: AssemblyCounts | None = None) -> np.ndarray:
    """Which designs of the batch P (m, n_params) assemble over the whole turn: the answer of
    :func:`assembles_on_grid` (the 1 deg grid at both ends of every setting input, every
    closed-form unit's margin at least :data:`ASSEMBLY_CLEARANCE_MM`) from its subset on a
    :data:`COARSE_STEP_DEG` grid:

    - a design with a margin below the clearance at a coarse angle fails on the grid too:
      decided;
    - a design whose every margin stays above the clearance between coarse angles on the cubic
      Hermite interpolant of its values and exact slopes (at omega = 1 rad/s rates are
      derivatives in phi), by at least the interpolation error's bound (the largest 4th
      difference / 96: four times the error h^4 |m''''| / 384 the differences estimate) plus
      :data:`HERMITE_FLOOR_MM`, and whose points that depend on a loop unit all move across
      every coarse step as their velocities say (:data:`BRANCH_JUMP_MM`: no loop unit changed
      branch between coarse angles), assembles at every grid angle: decided;
    - the others, and those a loop unit fails at a coarse angle (where the loop solver fails
      may depend on the steps it takes), are checked on the whole grid.

    ``counts`` (an :class:`AssemblyCounts`) receives how many took each way. (m,) bool."""
    from ..engine.margins import conditions

    P = np.atleast_2d(np.asarray(P, dtype=float))
    n = 360 // COARSE_STEP_DEG
    h = math.radians(COARSE_STEP_DEG)
    phi = np.arange(n + 1) * h  # (the turn's end too, for the last step's interpolant)
    inputs = setting_extremes(machine)
    looped = _looped_points(machine)
    # the conditions and loop-hung points whose support holds a parameter that varies within
    # the batch are evaluated for every design; the others (a sweep of the feed's dimensions
    # leaves the needle bar, take-up and hook alike in every design) for its first alone
    n_cond = len(conditions(machine, np.asarray(machine.defaults)))
    own = np.ones(n_cond, dtype=bool)
    own_pts = np.ones(len(looped), dtype=bool)
    if len(P) > 1:
        varying = set(np.nonzero(np.ptp(P, axis=0) > 0.0)[0].tolist())
        own, own_pts = _depends_on(machine, looped, varying)
    ok = np.empty(len(P), dtype=bool)
    unsure = np.zeros(len(P), dtype=bool)
    shared = None
    if not (own.all() and own_pts.all()):
        shared = _coarse(machine, P[:1], ~own, [p for p, o in zip(looped, own_pts) if not o],
                         phi, n, h, inputs)
    step = ASSEMBLY_CHUNK * COARSE_STEP_DEG  # (the same memory as a chunk of the whole grid)
    for a in range(0, len(P), step):
        Q = P[a:a + step]
        feasible, fails, room, smooth = _coarse(
            machine, Q, own, [p for p, o in zip(looped, own_pts) if o], phi, n, h, inputs)
        if shared is not None:
            feasible &= shared[0][0]
            fails |= shared[1][0]
            room = np.minimum(room, shared[2][0])
            smooth &= shared[3][0]
        ok[a:a + len(Q)] = feasible & ~fails
        # a loop unit's failure may depend on the steps the solver took: the grid decides
        unsure[a:a + len(Q)] = ~fails & (~feasible | ~smooth | ~(room >= ASSEMBLY_CLEARANCE_MM))
    if unsure.any():
        ok[unsure] = assembles_on_grid(machine, P[unsure])
    if counts is not None:
        counts.add(AssemblyCounts(int(len(P) - unsure.sum()), int(unsure.sum())))
    return ok


def _depends_on(machine: Machine, looped: list[str], varying: set) -> tuple[np.ndarray,
                                                                            np.ndarray]:
    """Which assembly conditions (in :func:`sewmech.engine.margins.conditions`' order) and
    which of the ``looped`` points depend on a parameter in ``varying``: the support of what
    the condition's unit writes (its own parameters and its inputs'), of the point."""
    from ..engine.margins import conditions
    from ..engine.sensitivity import _plan

    sup = _plan(machine, None).support
    n_pt, n_l = len(machine.point_names), len(machine.link_names)
    offset = {"p": 0, "l": n_pt, "v": n_pt + n_l}
    row_of = {u: r for r, u in enumerate(machine.kernel_unit_of_row) if u >= 0}
    own = []
    for c in conditions(machine, np.asarray(machine.defaults)):
        params: set = set()
        for tag, i in machine._row_io[row_of[c.unit]][1]:
            params |= {int(q) for q in sup[offset[tag] + i]}
        own.append(bool(params & varying))
    pts = [bool({int(q) for q in sup[machine.point_index(p)]} & varying) for p in looped]
    return np.array(own, dtype=bool), np.array(pts, dtype=bool)


def _coarse(machine: Machine, Q: np.ndarray, which: np.ndarray, looped: list[str],
            phi: np.ndarray, n: int, h: float, inputs) -> tuple:
    """The coarse grid's verdicts for the designs Q (m, n_params) on the assembly conditions
    ``which`` (a mask over :func:`sewmech.engine.margins.conditions`) and the ``looped``
    points: every position solved (m,), a margin below the clearance at a coarse angle (m,),
    the least margin on the interpolants less their error (m,), no branch jump (m,)."""
    from ..engine.kinematics import kinematics
    from ..engine.margins import conditions

    m = len(Q)
    conds = [c for c, w in zip(conditions(machine, np.asarray(machine.defaults)), which) if w]
    # only what the margins read and the points that hang on loop units: a closed-form unit
    # is not solved itself (its margins, read from its inputs, say whether it assembles), and
    # the fixed points and points on links cannot fail
    sel = {"points": sorted({p for c in conds for p in c.points} | set(looped)),
           "links": sorted({lk for c in conds for lk in c.links}), "variables": []}
    if not sel["points"] and not sel["links"]:
        return (np.ones(m, dtype=bool), np.zeros(m, dtype=bool), np.full(m, np.inf),
                np.ones(m, dtype=bool))
    r = kinematics(machine, phi, params=Q if inputs is None else Q[None, :, :],
                   inputs=inputs, omega=1.0, on_failure="mask",
                   max_step_deg=COARSE_STEP_DEG, **sel)
    feasible = r.feasible.reshape(-1, m, n + 1)[..., :n].all(axis=(0, 2))
    fails = np.zeros(m, dtype=bool)  # a margin below the clearance at a coarse angle
    room = np.full(m, np.inf)  # the least margin on the interpolants less their error
    per_design = conditions(machine, Q.T[:, :, None])  # (n_params, m, 1): per design
    for c, w in zip(per_design, which):
        if not w:
            continue
        y, dy = (np.asarray(v).reshape(-1, m, n + 1) for v in c.fn(r))
        fails |= (y[..., :n] < ASSEMBLY_CLEARANCE_MM).any(axis=(0, 2))
        room = np.minimum(room, _hermite_room(y, dy * h))
    smooth = np.ones(m, dtype=bool)
    if looped:
        at = [r.point_names.index(name) for name in looped]
        p, v, acc = (x[..., at, :].reshape((-1, m, n + 1, len(at), 2))
                     for x in (r.p, r.v, r.a))
        e = np.abs(np.diff(p, axis=2) - h * (v[:, :, :-1] + 0.5 * np.diff(v, axis=2))
                   + h * h / 12.0 * np.diff(acc, axis=2))
        smooth = (e <= BRANCH_JUMP_MM).all(axis=(0, 2, 3, 4))  # (False where NaN)
    return feasible, fails, room, smooth


def _looped_points(machine: Machine) -> list[str]:
    """The points that depend on a loop unit (the only units whose solution, continued from
    angle to angle, can change branch)."""
    from ..engine import _kernels as K

    if not machine.has_loops:
        return []
    loop_rows = {k for k, row in enumerate(machine.program) if int(row[0]) == K.OP_LOOP}
    return [name for name in machine.point_names
            if loop_rows & set(int(k) for k in machine.selection([name], [], [])[-1])]


def _hermite_room(y: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Each design's least margin between coarse angles less its interpolation error: y (s,
    m, n + 1) a margin at n + 1 equally spaced angles of a turn, its start and its end (s
    settings, m designs), d its slopes times the step. The cubic Hermite interpolant of each
    step is read at the 1 deg grid's angles between, and the error bound (the largest |4th
    difference| / 96) taken off. Where a cheaper lower bound of the interpolant (the least end
    value less 4/27 of both end slopes' sizes: the values' weights are positive and sum to 1,
    the slopes' are at most 4/27 in size) already clears :data:`ASSEMBLY_CLEARANCE_MM`, that
    bound is returned instead. (m,)"""
    y0, d0, y1, d1 = y[..., :-1], d[..., :-1], y[..., 1:], d[..., 1:]
    with np.errstate(invalid="ignore"):
        d4 = np.diff(y, n=4, axis=2)
        err = np.where(np.isfinite(d4), np.abs(d4), np.inf).max(axis=(0, 2)) / 96.0
        bound = np.minimum(y0, y1) - 4.0 / 27.0 * (np.abs(d0) + np.abs(d1))
        room = np.where(np.isnan(bound), -np.inf, bound).min(axis=(0, 2)) - err \
            - HERMITE_FLOOR_MM
    near = np.nonzero(~(room >= ASSEMBLY_CLEARANCE_MM))[0]
    if near.size:
        k = COARSE_STEP_DEG
        t = (np.arange(1, k) / k)[:, None, None, None]
        t2, t3 = t * t, t * t * t
        y0, d0, y1, d1 = (x[:, near] for x in (y0, d0, y1, d1))
        H = ((2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * d0 + (3 * t2 - 2 * t3) * y1
             + (t3 - t2) * d1)
        low = np.where(np.isnan(H), -np.inf, H).min(axis=(0, 1, 3))
        room[near] = low - err[near] - HERMITE_FLOOR_MM
    return room


#: the needle-thread balance's figures (:func:`sewmech.sewing.thread.thread_balance`) as
#: metrics: metric name -> ThreadBalance property; their exact derivatives are
#: :func:`sewmech.sewing.thread_gradients.thread_gradient`'s
THREAD_METRICS = THREAD_FIGURES


def _channel_inputs(machine: Machine, ref) -> dict | None:
    """The setting inputs (rad) a channel or range metric is read at: the stitch regulator at
    ``ref.regulator_deg`` where given, else the machine's working setting (None)."""
    return _regulator_inputs(machine, ref.regulator_deg)


def _regulator_inputs(machine: Machine, regulator_deg: float | None) -> dict | None:
    """The stitch regulator at ``regulator_deg`` (rad), or None (the working setting)."""
    s = machine.spec.sewing
    if regulator_deg is None or s is None or s.regulator is None:
        return None
    return {s.regulator: math.radians(regulator_deg)}


#: the prefixes of the channels of rates and accelerations (their derivatives need the
#: sensitivities' ``rates``)
RATE_PREFIXES = ("v", "a", "omega", "epsilon", "qd", "qdd")


def metric_value(machine: Machine, ref, P: np.ndarray, *, forces=None):
    """A metric of the design P with its derivative by every parameter where sewmech has it
    (:class:`~sewmech.design.metrics.MetricValue`: ``d`` None for a value-only metric; a
    max- or min-type metric with its pieces); ``ref`` names it (``metric``, ``regulator_deg``,
    ``phi_deg``, ``at``, as a problem file's :class:`~sewmech.design.problem.MetricRef`);
    ``forces``: the force analysis prepared for the force metrics
    (:class:`~sewmech.design._dynamic_metrics.ForceMetrics`; default the file's speed, 2 deg,
    gravity). Raises SewmechError where the design cannot be evaluated."""
    from ..sewing.gradients import METRICS
    from . import metrics as km
    from ._dynamic_metrics import ForceMetrics, is_dynamic

    name = ref.metric
    if name in THREAD_METRICS:
        g = thread_gradient(machine, name, params=P)
        return km.MetricValue(g.value, g.d_dparam)
    if name in METRICS:
        feed = name in ("stitch_length", "feed_lift", "dog_height_at_needle_plate")
        reg = ref.regulator_deg
        if feed and reg is None:
            s = machine.spec.sewing
            if s is None or s.regulator is None:
                raise OptionError("metric", f"{name} needs a machine with a stitch regulator")
            reg = machine.spec.inputs[s.regulator].default_deg
        g = METRICS[name](machine, reg, params=P)
        return km.MetricValue(g.value, g.d_dparam)
    inputs = _channel_inputs(machine, ref)
    if is_dynamic(name):
        return (forces or ForceMetrics(machine)).value(name, P, inputs)
    if km.is_kinematic_family(name):
        return km.metric_value(machine, name, P, inputs)
    if getattr(ref, "at", None):
        return km.event_value(machine, name, ref.at, P, inputs, math.radians(ref.phi_deg))
    from ..engine.sensitivity import sensitivities

    try:  # (a rate or an acceleration at the file's speed, as the batches read them)
        S = sensitivities(machine, np.radians([ref.phi_deg]), params=P, inputs=inputs,
                          outputs=[name], rates=name.split("_")[0] in RATE_PREFIXES)
        v, d, _ = S.channel(name)
    except KeyError as exc:
        raise OptionError("metric", exc.args[0]) from None
    return km.MetricValue(float(v[0]), d[0])


def _metric(machine: Machine, ref, P: np.ndarray) -> tuple[float, np.ndarray | None]:
    """:func:`metric_value` as (value, derivative by every parameter or None)."""
    mv = metric_value(machine, ref, P)
    return mv.value, mv.d


def metric_batch(machine: Machine, refs, P: np.ndarray, ok: np.ndarray | None = None, *,
                 forces=None, pieces: dict | None = None) -> tuple[dict, np.ndarray]:
    """The metrics ``refs`` (each with ``metric``, ``regulator_deg``, ``phi_deg`` and ``at``:
    a sewing metric, a thread metric, a metric of :mod:`sewmech.design.metrics` or of the force
    analysis, or a channel at ``phi_deg`` or at an event) for the batch of designs P (m,
    n_parameters; internal units), values only, and which designs assemble over the whole turn
    (:func:`assembles_batch`, unless given as ``ok``): ({:func:`ref_key`: values (m,)}, (m,)
    bool). Values of designs that do not assemble are NaN. ``forces``: as for
    :func:`metric_value`. ``pieces`` (a dict) receives, per key of a max- or min-type metric,
    each design's pieces (a list of arrays)."""
    from ..engine.kinematics import kinematics
    from ..sewing.gradients import METRICS, metric_values
    from . import metrics as km
    from ._dynamic_metrics import ForceMetrics, is_dynamic

    m = machine
    P = np.atleast_2d(np.asarray(P, dtype=float))
    if ok is None:
        ok = assembles_batch(m, P)
    out = {}
    dynamic = [ref for ref in refs if is_dynamic(ref.metric)]
    if dynamic:  # one force analysis per regulator setting
        forces = forces or ForceMetrics(m)
        rows = np.nonzero(ok)[0]
        for reg in {ref.regulator_deg for ref in dynamic}:
            names = sorted({ref.metric for ref in dynamic if ref.regulator_deg == reg})
            got: dict = {}
            vals = forces.values(names, P[rows], _regulator_inputs(m, reg),
                                 got if pieces is not None else None)
            for name in names:
                key = ref_key(next(r for r in dynamic if r.metric == name
                                   and r.regulator_deg == reg))
                full = np.full(len(P), np.nan)
                full[rows] = vals[name]
                out[key] = full
                if pieces is not None:
                    per = [np.zeros(0)] * len(P)
                    for j, k in enumerate(rows):
                        per[k] = got[name][j]
                    pieces[key] = per
    for ref in refs:
        key = ref_key(ref)
        if key in out:
            continue
        name = ref.metric
        if km.is_kinematic_family(name):
            got_p: list = []
            vals = km.metric_batch_values(m, name, P, _channel_inputs(m, ref), got_p)
            if pieces is not None:
                pieces[key] = got_p
        elif getattr(ref, "at", None):
            vals = km.event_batch(m, name, ref.at, P, _channel_inputs(m, ref),
                                  math.radians(ref.phi_deg))
        elif name in THREAD_METRICS:  # (one design at a time: the thread balance has no batch)
            from ..sewing.thread import thread_balance

            vals = np.full(len(P), np.nan)
            for k in np.nonzero(ok)[0]:
                try:
                    vals[k] = getattr(thread_balance(m, params=P[k]), THREAD_METRICS[name])
                except SewmechError:
                    pass
        elif name in METRICS:
            reg = ref.regulator_deg
            if reg is None and m.spec.sewing is not None and m.spec.sewing.regulator:
                reg = m.spec.inputs[m.spec.sewing.regulator].default_deg
            vals = metric_values(m, name, reg, P)
        else:
            k = kinematics(m, np.radians([ref.phi_deg]), params=P,
                           inputs=_channel_inputs(m, ref), on_failure="mask")
            vals = k.channel(name)[0][..., 0]
        out[key] = np.where(ok, vals, np.nan)
    return out, ok

"""Metrics and the whole-turn assembly check for batches of designs, values only, and one
metric with its derivative: what the design problems (:mod:`sewmech.design.problem`, whose
``batch_values`` and assembly margin build on this, and :mod:`sewmech.design.optimize`) and the
sweeps (:mod:`sewmech.design.sweep`) evaluate.

Units: parameters internal (mm, rad) unless a function says file units; metrics in their own
units (mm, deg for the ``*_deg`` metrics, rad for link angles).
"""

from __future__ import annotations

import math

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


def assembles_batch(machine: Machine, P: np.ndarray) -> np.ndarray:
    """Which designs of the batch P (m, n_params) assemble over the whole turn as the searches
    and sweeps see it: on a 1 deg grid at both ends of every setting input, every closed-form
    unit's assembly margin at least :data:`ASSEMBLY_CLEARANCE_MM` at every grid angle. One
    kinematics call per :data:`ASSEMBLY_CHUNK` designs. (m,) bool."""
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

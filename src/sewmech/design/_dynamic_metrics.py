"""The force analysis' figures as metrics of a design, for design problems, sweeps, tolerances
and ``sensitivity``: one :class:`~sewmech.engine.dynamics.DynamicsPlan` call per batch of
designs and setting, on the grid of a ``[dynamics]`` table (``rpm``, ``step_deg``,
``gravity``: the same table in problem and sweep files).

A peak is the largest value at the grid's angles (``step_deg``), a least force the least; each
is max-type (min-type) over its *pieces*, the grid's values, which are each smooth in the
design (:mod:`sewmech.design.metrics`). Units: N, N m (torques and moments, as every table of
sewmech gives them), W.

**Exact gradients** (:data:`GRADIENTS`): the peak and RMS driving torque, the peak force in a
pair, the peak bearing reaction, the peak shaking force and moment and the least contact force
come with their exact derivatives by every parameter, from the derivative of the force solve
(:func:`sewmech.engine.dynamic_sensitivity.dynamics_sensitivities`): each piece's derivative
is that of the quantity at its grid angle (|F|' = F.F'/|F|), a peak's that of its largest
piece (the envelope theorem at the located extreme, as for the kinematic maxima), the RMS's
mean(T T')/RMS. The friction loss stays value-only (derivative-free methods, sweeps). Where a
process load switches on or off at a grid angle, the force there has no derivative (the
side the solve took is given).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..engine.machine import Machine
from .metrics import MetricNameError, MetricValue, split

#: the force analysis' metrics: name -> (unit, what its argument names or None, kind
#: ("max": the largest of its pieces, "min": the least, None: smooth), what it is)
DYNAMIC_METRICS = {
    "peak_torque": ("N m", None, "max", "the largest |driving torque| on the upper shaft"),
    "rms_torque": ("N m", None, None, "the RMS of the driving torque over the turn"),
    "peak_force": ("N", "pair", "max", "the largest |force| in a pair (a pin, guide, cam or"
                                       " slot)"),
    "peak_bearing_reaction": ("N", "bearing", "max", "the largest |reaction| of the upper"
                                                     " shaft's bearings (both, or :front or"
                                                     " :rear)"),
    "peak_shaking_force": ("N", None, "max", "the largest |shaking force| on the frame"),
    "peak_shaking_moment": ("N m", None, "max", "the largest |shaking moment| about the"
                                                " frame's origin"),
    "friction_loss": ("W", None, None, "the turn's mean friction power"),
    "least_contact_force": ("N", "contact", "min", "the least force of a one-sided contact"
                                                   " over the turn"),
}

#: the exact gradients of the force analysis' metrics: metric family -> function
#: (machine, settings, metric name, P (n_params,), inputs) -> MetricValue with ``d`` (and
#: ``pieces_d``); filled below (every family but the friction loss)
GRADIENTS: dict[str, Callable[..., MetricValue]] = {}


def is_dynamic(name: str) -> bool:
    return split(name)[0] in DYNAMIC_METRICS


def has_gradient(name: str) -> bool:
    return split(name)[0] in GRADIENTS


def unit_of(name: str) -> str:
    return DYNAMIC_METRICS[split(name)[0]][0]


def _force_pairs(machine: Machine) -> list[str]:
    return [p.name for p in machine.pairs if p.kind != "driver"]


def _contacts(machine: Machine) -> list[str]:
    from ..engine.contacts import one_sided_pairs

    return [p.name for p in one_sided_pairs(machine)]


def check_name(machine: Machine, name: str) -> bool:
    """Whether ``name`` is a force-analysis metric ``machine`` can evaluate (True), not one
    (False), or one whose argument it lacks (:class:`MetricNameError`)."""
    import difflib

    family, arg = split(name)
    if family not in DYNAMIC_METRICS:
        return False
    what = DYNAMIC_METRICS[family][1]

    def near(x, known):
        got = difflib.get_close_matches(x, known, n=3)
        return f"Did you mean {', '.join(got)}?" if got else ""

    if what is None:
        if arg is not None:
            raise MetricNameError(f"{family} takes no argument (got ':{arg}')",
                                  f"Give {family}")
    elif what == "bearing":
        if machine.spec.shaft is None:
            raise MetricNameError(f"{family}: machine '{machine.name}' has no [shaft] table"
                                  " (the upper shaft's bearings)", "Choose another metric")
        if arg not in (None, "front", "rear"):
            raise MetricNameError(f"'{arg}' is not a bearing of the upper shaft",
                                  f"Give {family}, {family}:front or {family}:rear")
    else:
        known = _force_pairs(machine) if what == "pair" else _contacts(machine)
        kind = "a pair with a force" if what == "pair" else "a one-sided contact"
        if arg is None or arg not in known:
            raise MetricNameError(f"{family} needs {kind} of '{machine.name}'"
                                  + (f"; '{arg}' is none" if arg else ""),
                                  near(arg or "", known) or
                                  (f"Give {family}:NAME with one of: {', '.join(known)}"
                                   if known else f"'{machine.name}' has none"))
    if not machine.masses and not machine.spec.loads:
        raise MetricNameError(f"{family}: machine '{machine.name}' has neither [masses] nor"
                              " [[loads]]: every force of its analysis is 0",
                              "Give the moving links' masses ([masses.LINK])")
    return True


def _grid(step_deg: float) -> np.ndarray:
    n = round(360.0 / step_deg)
    return np.arange(n) * (2.0 * math.pi / n)


class ForceMetrics:
    """The force analysis prepared once for a machine and a ``[dynamics]`` table (``settings``:
    ``rpm``, ``step_deg``, ``gravity``; None: the file's speed, 2 deg, with gravity), read for
    batches of designs."""

    def __init__(self, machine: Machine, settings=None):
        from ..engine.dynamics import DynamicsPlan

        self.machine = machine
        rpm = getattr(settings, "rpm", None)
        step = getattr(settings, "step_deg", 2.0)
        gravity = getattr(settings, "gravity", True)
        self.settings = settings
        self.phi = _grid(step)
        self.plan = DynamicsPlan(machine, self.phi, rpm=rpm, gravity=gravity,
                                 on_failure="mask")

    def curves(self, names: list[str], P: np.ndarray, inputs=None) -> dict[str, np.ndarray]:
        """Each metric's curve over the grid for the designs P (m, n_params): (m, n_phi) (its
        unit); NaN rows for designs whose force equations are singular somewhere."""
        from ..engine.dynamics import SingularForceSystem

        m = len(P)
        out = {n: np.full((m, len(self.phi)), np.nan) for n in names}
        if m == 0:
            return out
        try:
            self._fill(out, names, P, inputs, slice(None))
        except SingularForceSystem:  # one design at a time, the singular ones left NaN
            for k in range(m):
                try:
                    self._fill(out, names, P[k:k + 1], inputs, slice(k, k + 1))
                except SingularForceSystem:
                    pass
        return out

    def _fill(self, out: dict, names: list[str], P: np.ndarray, inputs, rows) -> None:
        r = self.plan(P, inputs=inputs)
        for name in names:
            family, arg = split(name)
            if family == "peak_torque":
                c = np.abs(r.input_torque) * 1e-3
            elif family == "rms_torque":
                c = r.input_torque * 1e-3
            elif family == "peak_force":
                c = r.magnitude(arg)
            elif family == "peak_bearing_reaction":
                b = r.bearings
                sides = [b.front, b.rear] if arg is None else [getattr(b, arg)]
                c = np.max([np.linalg.norm(s, axis=-1) for s in sides], axis=0)
            elif family == "peak_shaking_force":
                c = np.linalg.norm(r.shaking_force, axis=-1)
            elif family == "peak_shaking_moment":
                c = np.abs(r.shaking_moment) * 1e-3
            elif family == "friction_loss":
                c = r.friction_power * 1e-3
            else:  # least_contact_force
                c = np.asarray(r.pair(arg))[..., 0]
            out[name][rows] = np.asarray(c, dtype=float).reshape(len(P), -1)

    def values(self, names: list[str], P: np.ndarray, inputs=None,
               pieces: dict | None = None) -> dict[str, np.ndarray]:
        """Each metric for the designs P (m, n_params), values only: {name: (m,)}; NaN where a
        design does not assemble or its forces cannot be solved. ``pieces`` receives each
        max- or min-type metric's pieces per design (its grid values)."""
        curves = self.curves(names, P, inputs)
        out = {}
        for name, c in curves.items():
            family = split(name)[0]
            bad = ~np.all(np.isfinite(c), axis=1)
            if family == "rms_torque":
                v = np.sqrt(np.mean(c * c, axis=1))
            elif family == "friction_loss":
                v = np.mean(c, axis=1)
            elif family == "least_contact_force":
                v = np.min(c, axis=1)
            else:
                v = np.max(c, axis=1)
            out[name] = np.where(bad, np.nan, v)
            if pieces is not None:
                pieces[name] = [c[k] if DYNAMIC_METRICS[family][2] else np.zeros(0)
                                for k in range(len(P))]
        return out

    def value(self, name: str, P: np.ndarray, inputs=None) -> MetricValue:
        """One metric of one design, with its exact derivative where :data:`GRADIENTS` has
        it (else ``d`` None)."""
        from ..engine.errors import AnalysisError

        family = split(name)[0]
        if family in GRADIENTS:
            return GRADIENTS[family](self.machine, self.settings, name, P, inputs)
        got: dict = {}
        v = self.values([name], np.atleast_2d(P), inputs, got)[name][0]
        if not np.isfinite(v):
            raise AnalysisError(f"machine '{self.machine.name}'", f"{name} cannot be formed on"
                                " this design (it does not assemble somewhere in the turn, or"
                                " its force equations are singular)")
        kind = DYNAMIC_METRICS[family][2]
        pcs = got[name][0]
        return MetricValue(float(v), None, kind, pcs, None, self.phi[:len(pcs)].copy())


# ---- the exact gradients -------------------------------------------------------------------
#: the last design's derivatives (a problem reads several force metrics of one design)
_LAST: dict = {}


def _sensitivities(machine: Machine, settings, P: np.ndarray, inputs):
    """:func:`~sewmech.engine.dynamic_sensitivity.dynamics_sensitivities` of one design on the
    ``[dynamics]`` table's grid (the last design's kept)."""
    from ..engine.dynamic_sensitivity import dynamics_sensitivities

    rpm = getattr(settings, "rpm", None)
    step = getattr(settings, "step_deg", 2.0)
    gravity = getattr(settings, "gravity", True)
    P = np.asarray(P, dtype=float)
    key = (rpm, step, gravity, P.tobytes(),
           None if inputs is None else tuple(sorted(inputs.items())))
    entry = _LAST.get("entry")  # (one read and one write: no other thread's half-made entry)
    if entry is not None and entry[0] is machine and entry[1] == key:
        return entry[2]
    value = dynamics_sensitivities(machine, _grid(step), params=P, inputs=inputs, rpm=rpm,
                                   gravity=gravity)
    _LAST["entry"] = (machine, key, value)
    return value


def _norm_d(v: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|v| over the last axis but one (v (n, 2), dv (n, 2, n_p)) and its derivative."""
    n = np.linalg.norm(v, axis=-1)
    safe = np.where(n > 0, n, 1.0)
    return n, np.einsum("ij,ijk->ik", v / safe[:, None], dv)


def _curve_d(machine: Machine, ds, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The metric's curve over the grid (its unit) and its derivative (n_phi, n_params)."""
    r = ds.result
    family, arg = split(name)
    if family in ("peak_torque", "rms_torque"):
        T, dT = r.input_torque * 1e-3, ds.input_torque * 1e-3
        if family == "peak_torque":
            return np.abs(T), np.sign(T)[:, None] * dT
        return T, dT
    if family == "peak_shaking_moment":
        M, dM = r.shaking_moment * 1e-3, ds.shaking_moment * 1e-3
        return np.abs(M), np.sign(M)[:, None] * dM
    if family == "peak_shaking_force":
        return _norm_d(r.shaking_force, ds.shaking_force)
    if family == "peak_bearing_reaction":
        sides = [("front", r.bearings.front, ds.bearings_front),
                 ("rear", r.bearings.rear, ds.bearings_rear)]
        got = [_norm_d(v, dv) for side, v, dv in sides if arg in (None, side)]
        if len(got) == 1:
            return got[0]
        (a, da), (b, db) = got  # the larger side at each angle (its derivative: envelope)
        return np.maximum(a, b), np.where((a >= b)[:, None], da, db)
    c, pair = r._columns[arg]
    x, dx = r.pair(arg), ds.pair(arg)
    if family == "least_contact_force":
        return x[:, 0], dx[:, 0, :]
    if pair.kind == "revolute":
        return _norm_d(x, dx)
    return np.abs(x[:, 0]), np.sign(x[:, 0])[:, None] * dx[:, 0, :]


def _exact(machine: Machine, settings, name: str, P, inputs) -> MetricValue:
    """A force metric of one design with its exact derivative by every parameter (see the
    module doc)."""
    from ..engine.errors import AnalysisError

    ds = _sensitivities(machine, settings, P, inputs)
    v, d = _curve_d(machine, ds, name)
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(d))):
        raise AnalysisError(f"machine '{machine.name}'", f"{name} cannot be formed on this"
                            " design (its force equations are singular somewhere in the"
                            " turn)")
    family = split(name)[0]
    phi = _grid(getattr(settings, "step_deg", 2.0))
    if family == "rms_torque":
        rms = math.sqrt(float(np.mean(v * v)))
        return MetricValue(rms, (v[:, None] * d).mean(axis=0) / rms if rms > 0 else
                           np.zeros(d.shape[1]))
    kind = DYNAMIC_METRICS[family][2]
    k = int(np.argmax(v) if kind == "max" else np.argmin(v))
    return MetricValue(float(v[k]), d[k].copy(), kind, v.copy(), d.copy(), phi.copy())


for _family in ("peak_torque", "rms_torque", "peak_force", "peak_bearing_reaction",
                "peak_shaking_force", "peak_shaking_moment", "least_contact_force"):
    GRADIENTS[_family] = _exact

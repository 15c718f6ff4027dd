"""Design problems: which dimensions to choose, what they should achieve, what they must keep
(a TOML file), and their solution by the JB report's methods or scipy's.

```toml
[problem]
name = "four-bar swing"
machine = "fourbar-benchmark"      # a shipped machine or a file (relative to this one)

[[variables]]                      # values in the parameter's file unit: mm, or deg for angles
parameter = "B.u"
lower = 10.0
upper = 20.0                       # start: the machine's value unless given

[objective]
form = "weighted_sum"              # or "weighted_uniform" (needs targets)
[[objective.parts]]
metric = "range:theta_rocker"      # a sewing metric, a channel at phi_deg, or range:CHANNEL
target = 0.9                       # (the metric's unit: mm, rad, deg for the *_deg metrics)
weight = 1.0

[[constraints]]
metric = "p_C_y"
phi_deg = 90.0
min = 0.0                          # and/or max
```

Metrics: the exact-derivative sewing metrics (:data:`sewmech.sewing.gradients.METRICS`, at
``regulator_deg`` where they read the feed), a channel (``p_POINT_x``, ``theta_LINK``, ...) at
``phi_deg``, or ``range:CHANNEL``, the channel's travel over a turn (its maximum minus its
minimum). Every one comes with its derivative by every parameter, so SLSQP gets exact
gradients. The mechanism must assemble over the whole turn (at both ends of every setting
input): a design that does not is infinitely bad to the derivative-free methods, and an answer
that does not is reported failed whatever the method.

This module reads problem files and evaluates a problem's objective and constraints
(:class:`Problem`); :mod:`sewmech.design.evaluate` evaluates metrics and the whole-turn
assembly for batches of designs (shared with the sweeps), :mod:`sewmech.design.optimize`
solves a problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..engine.errors import MachineFileError, SewmechError
from ..engine.machine import Machine, load_machine, shipped_machines
from ..engine.paths import user_path
from ..engine.spec import ValueHint, load_toml_model
from ._models import (
    MAX_WEIGHT,
    SCALE_RANGE,
    VALUE_LIMIT,
    Bounds,
    DynamicsTable,
    Header,
    MetricRef,
    Strict,
    check_bounds,
    check_limit,
    check_range,
    file_unit,
    ref_key,
)
from .evaluate import (
    _setting_extremes,
    assembles_batch,
    metric_batch,
    metric_value,
)


class ProblemInfo(Header):
    """The ``[problem]`` table."""


class Variable(Bounds):
    start: float | None = None

    @field_validator("start")
    @classmethod
    def _start_size(cls, v):
        if v is not None:
            check_range(v, -VALUE_LIMIT, VALUE_LIMIT, "a start (mm, or deg for an angle)")
        return v

    @model_validator(mode="after")
    def _start(self):
        if self.start is not None and not self.lower <= self.start <= self.upper:
            raise ValueError(f"start {self.start} is outside {self.lower} .. {self.upper}")
        return self


class Part(MetricRef):
    target: float | None = None
    sense: Literal["target", "min", "max"] = "target"
    weight: float = 1.0
    scale: float | None = None

    @field_validator("target")
    @classmethod
    def _target_size(cls, v):
        return check_limit(v, "a target")

    @field_validator("weight")
    @classmethod
    def _weight(cls, v):
        return check_range(v, 0.0, MAX_WEIGHT, "a weight")

    @field_validator("scale")
    @classmethod
    def _scale(cls, v):
        if v is not None:
            check_range(v, *SCALE_RANGE, "a scale (in the metric's unit)")
        return v

    @model_validator(mode="after")
    def _target(self):
        if self.sense == "target" and self.target is None:
            raise ValueError("give a target, or sense = \"min\" or \"max\"")
        return self


class Objective(Strict):
    form: Literal["weighted_sum", "weighted_uniform"] = "weighted_sum"
    parts: list[Part] = Field(min_length=1)

    @model_validator(mode="after")
    def _uniform(self):
        if self.form == "weighted_uniform" and any(p.sense != "target" for p in self.parts):
            raise ValueError("weighted_uniform needs a target for every part")
        if not any(p.weight > 0.0 for p in self.parts):
            raise ValueHint("every part has weight 0: the objective would be 0 for every"
                            " design", "Give a part a weight > 0")
        return self


class Constraint(MetricRef):
    min: float | None = None
    max: float | None = None
    equals: float | None = None

    @field_validator("min", "max", "equals")
    @classmethod
    def _limit(cls, v):
        return check_limit(v)

    @model_validator(mode="after")
    def _bound(self):
        if self.equals is not None:
            if self.min is not None or self.max is not None:
                raise ValueHint("give equals, or min and/or max, not both", "An equality is"
                                " equals = VALUE (or min = max = VALUE)")
            return self
        if self.min is None and self.max is None:
            raise ValueError("give min, max, both, or equals")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueHint(f"need min <= max, got {self.min:g} .. {self.max:g}: no design"
                            " could meet it", "Swap them, or give the bound you meant")
        return self

    @property
    def equality(self) -> float | None:
        """The value of an equality (``equals``, or min = max), else None."""
        if self.equals is not None:
            return self.equals
        if self.min is not None and self.min == self.max:
            return self.min
        return None

    @property
    def bounds(self) -> list[tuple[str, float]]:
        """("min", b) and ("max", b) for each bound (an equality both at its value)."""
        lo = self.equals if self.equals is not None else self.min
        hi = self.equals if self.equals is not None else self.max
        return [(k, b) for k, b in (("min", lo), ("max", hi)) if b is not None]


class ProblemSpec(Strict):
    problem: ProblemInfo
    variables: list[Variable] = Field(min_length=1)
    objective: Objective
    constraints: list[Constraint] = Field(default_factory=list)
    dynamics: DynamicsTable | None = None


def load_problem(path: str | Path) -> tuple[ProblemSpec, Machine]:
    """Read and validate a problem file and load its machine; errors name the file and key."""
    path = user_path(path)
    spec = load_toml_model(path, ProblemSpec, "problem file", "docs/design.md")
    ref = spec.problem.machine
    local = path.parent / Path(ref).expanduser()
    if not local.is_file() and ref not in shipped_machines():
        raise MachineFileError(str(path), "problem", "machine", f"'{ref}' is neither a machine"
                               f" file beside the problem file ({local}) nor a shipped machine",
                               "Give a path relative to the problem file, or one of "
                               + ", ".join(sorted(shipped_machines())))
    machine = load_machine(str(local) if local.is_file() else ref)
    check_problem(spec, machine, str(path))
    return spec, machine


def check_problem(spec: ProblemSpec, machine: Machine, where: str = "problem") -> None:
    """What the schema cannot know, against the problem's machine: every variable a parameter
    of it, its bounds and start inside the parameter's domain, every metric one that sewmech
    can evaluate on it (an unknown one is named with those it resembles). Errors name
    ``where`` (the file), the table and the key."""
    names = machine.parameter_names
    for k, v in enumerate(spec.variables):
        if v.parameter not in names:
            import difflib

            near = difflib.get_close_matches(v.parameter, names, n=3)
            raise MachineFileError(where, "variables", f"{k}.parameter", f"'{v.parameter}' is"
                                   f" not a parameter of '{machine.name}'",
                                   f"Did you mean {', '.join(near)}?" if near else
                                   f"`sewmech check {machine.name} --parameters` lists them")
        unit = machine.parameter_units[names.index(v.parameter)]
        check_bounds(where, "variables", k, v, machine, file_unit(unit)[1], v.start)
    refs = [("objective.parts", k, p) for k, p in enumerate(spec.objective.parts)]
    refs += [("constraints", k, c) for k, c in enumerate(spec.constraints)]
    channels = None
    for table, k, ref in refs:
        channels = _check_metric(where, table, k, ref, machine, channels)
    if spec.dynamics is not None:
        n = round(360.0 / spec.dynamics.step_deg)
        if not math.isclose(n * spec.dynamics.step_deg, 360.0, rel_tol=1e-9):
            raise MachineFileError(where, "dynamics", "step_deg", f"{spec.dynamics.step_deg:g}"
                                   " deg does not divide 360", "Give a step such as 1, 2 or 5")


#: how each form of objective is made dimensionless from its parts' values f (their own units):
#: w is a part's weight, t its target, s its scale (``scale`` if given, else |t| for a target
#: and |f| at the start for a minimum or maximum)
OBJECTIVE_FORMS = {
    "weighted_sum": "the sum of the parts' w ((f - t) / s)^2 (a target t), w f / s (min) and"
                    " -w f / s (max)",
    "weighted_uniform": "the largest of the parts' w |f - t| / s",
}


def metric_unit(machine: Machine, name: str) -> str:
    """The unit of a problem's metric (as the metric gives it: mm, deg for the ``*_deg``
    metrics, a channel's own unit: rad for link angles)."""
    from ..engine.kinematics import kinematics
    from ..sewing.gradients import METRICS
    from . import metrics as km
    from ._dynamic_metrics import is_dynamic
    from ._dynamic_metrics import unit_of as dynamic_unit
    from .evaluate import THREAD_METRICS

    if name in METRICS or name in THREAD_METRICS:
        return "deg" if name.endswith("_deg") else "mm"
    if is_dynamic(name):
        return dynamic_unit(name)
    if km.is_kinematic_family(name):
        return km.unit_of(machine, name)
    channel = name
    try:
        return kinematics(machine, [0.0], on_failure="mask").channel(channel)[1]
    except KeyError:
        return ""


#: the metrics read off the feed (they need a stitch regulator and read it at a setting)
FEED_METRICS = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


def _in_range(where: str, table: str, k: int, ref: MetricRef, machine: Machine) -> None:
    inp = machine.spec.inputs[machine.spec.sewing.regulator]
    lo = inp.min_deg if inp.min_deg is not None else -180.0
    hi = inp.max_deg if inp.max_deg is not None else 180.0
    if not lo <= ref.regulator_deg <= hi:
        raise MachineFileError(where, table, f"{k}.regulator_deg", f"{ref.regulator_deg:g}"
                               f" deg is outside the regulator's range {lo:g} .. {hi:g} deg",
                               "Give a setting within it")


def _check_metric(where: str, table: str, k: int, ref: MetricRef, machine: Machine,
                  channels: list[str] | None) -> list[str]:
    """A problem file's metric against what sewmech can evaluate on its machine, where it
    enters: an unknown name is an error located at its table and key, with the known metrics
    it resembles. Returns the machine's channel names (computed once)."""
    import difflib

    from ..engine.kinematics import kinematics
    from ..sewing.gradients import METRICS, missing_roles
    from .evaluate import THREAD_METRICS

    name = ref.metric
    if channels is None:
        channels = kinematics(machine, [0.0], on_failure="mask").channel_names()
    key = f"{k}.metric"
    s = machine.spec.sewing
    if name in METRICS:
        if name in FEED_METRICS and (s is None or s.regulator is None):
            raise MachineFileError(where, table, key, f"{name} needs a machine with a stitch"
                                   f" regulator ([sewing] regulator); '{machine.name}' has"
                                   " none", "Choose another metric")
        lacks = missing_roles(machine, name)
        if lacks is not None:
            raise MachineFileError(where, table, key, lacks, "Choose another metric, or name"
                                   " the role in the machine file (docs/machine-files.md)")
        if name in FEED_METRICS and ref.regulator_deg is not None:
            _in_range(where, table, k, ref, machine)
        if name not in FEED_METRICS and ref.regulator_deg is not None:
            raise MachineFileError(where, table, f"{k}.regulator_deg", f"{name} does not"
                                   " depend on the regulator", "Leave out regulator_deg")
        return channels
    if name in THREAD_METRICS:
        if ref.regulator_deg is not None:
            raise MachineFileError(where, table, f"{k}.regulator_deg", f"{name} does not"
                                   " depend on the regulator", "Leave out regulator_deg")
        return channels
    from . import metrics as km
    from ._dynamic_metrics import check_name as check_dynamic

    if ref.at is not None and not (name in channels and not name.startswith("range:")):
        raise MachineFileError(where, table, f"{k}.at", f"{name}: only a channel is read at an"
                               " event", "Leave out at, or give a channel (p_POINT_x,"
                               " theta_LINK, q_VAR, or a rate)")
    try:
        if ref.at is not None:
            km.check_event(machine, ref.at, channels)
            km.check_read_at_event(name)
        known_family = km.check_name(machine, name, channels) or check_dynamic(machine, name)
    except km.MetricNameError as exc:
        raise MachineFileError(where, table, f"{k}.at" if ref.at is not None and
                               name in channels else key, exc.what, exc.hint) from None
    channel = name.split(":", 1)[1] if name.startswith("range:") else name
    if known_family or channel in channels:
        if ref.regulator_deg is not None:  # (read at that setting)
            if s is None or s.regulator is None:
                raise MachineFileError(where, table, f"{k}.regulator_deg", f"machine"
                                       f" '{machine.name}' has no stitch regulator",
                                       "Leave out regulator_deg")
            _in_range(where, table, k, ref, machine)
        return channels
    from ._dynamic_metrics import DYNAMIC_METRICS

    known = [*METRICS, *THREAD_METRICS, *DYNAMIC_METRICS]
    near = difflib.get_close_matches(name, [*known, *channels], n=3)
    raise MachineFileError(where, table, key, f"unknown metric '{name}'",
                           f"Did you mean {', '.join(near)}?" if near
                           else f"Metrics: {', '.join(known)}; min:, max:, range:, mean:,"
                           " rms:CHANNEL; transmission_angle_min:, transmission_angle_"
                           "deviation:UNIT; pressure_angle_max:CAM; or a channel (p_POINT_x,"
                           " theta_LINK, q_VAR) at phi_deg or at an event (docs/design.md)")


class Problem:
    """A problem ready to evaluate: the variables x in file units (mm, deg), the metrics and
    their derivatives by x, the objective and the constraints g(x) >= 0.

    ``evaluations`` counts the distinct designs evaluated (one at a time, or in batches)."""

    def __init__(self, spec: ProblemSpec, machine: Machine, where: str = "problem"):
        check_problem(spec, machine, where)
        self.spec, self.machine, self.where = spec, machine, where
        names = machine.parameter_names
        self.index = np.array([names.index(v.parameter) for v in spec.variables])
        units = [machine.parameter_units[j] for j in self.index]
        #: internal units per file unit of each variable (deg -> rad, g -> kg, g cm -> kg mm)
        self.factor = np.array([file_unit(u)[1] for u in units])
        self.units = tuple(file_unit(u)[0] for u in units)
        self.lower = np.array([v.lower for v in spec.variables])
        self.upper = np.array([v.upper for v in spec.variables])
        defaults = np.asarray(machine.defaults)[self.index] / self.factor
        self.start = np.array([v.start if v.start is not None else d
                               for v, d in zip(spec.variables, defaults, strict=True)])
        self.names = tuple(v.parameter for v in spec.variables)
        self.evaluations = 0
        self._designs: set = set()
        self._memo: dict = {}
        self._scales = None
        self._forces = None

    # ---- metrics -------------------------------------------------------------------------------
    def params(self, x: np.ndarray) -> np.ndarray:
        P = np.array(self.machine.defaults, dtype=float)
        P[self.index] = np.asarray(x, dtype=float) * self.factor
        return P

    @property
    def forces(self):
        """The force analysis prepared for the problem's force metrics (its ``[dynamics]``
        table), made on first use."""
        if self._forces is None:
            from ._dynamic_metrics import ForceMetrics

            self._forces = ForceMetrics(self.machine, self.spec.dynamics)
        return self._forces

    def metric(self, ref: MetricRef, x: np.ndarray) -> tuple[float, np.ndarray | None]:
        """A metric's value and its derivative by the variables (per file unit) at x (None for
        a value-only metric); raises SewmechError where the design cannot be evaluated (it
        does not assemble)."""
        mv = self.metric_value(ref, x)
        return mv.value, mv.d

    def metric_value(self, ref: MetricRef, x: np.ndarray):
        """:func:`~sewmech.design.evaluate.metric_value` of the design x, its derivatives (and
        its pieces') by the variables (per file unit)."""
        from dataclasses import replace

        design = tuple(np.asarray(x, dtype=float))

        def compute():
            from ._dynamic_metrics import is_dynamic

            mv = metric_value(self.machine, ref, self.params(x),
                              forces=self.forces if is_dynamic(ref.metric) else None)
            scale = self.factor
            return replace(mv, d=None if mv.d is None else mv.d[self.index] * scale,
                           pieces_d=None if mv.pieces_d is None else
                           mv.pieces_d[:, self.index] * scale)

        return self._remember(("metric", ref_key(ref), design), design, compute)

    @property
    def has_gradients(self) -> bool:
        """Whether every metric of the problem comes with its exact derivative (SLSQP needs
        it)."""
        from . import metrics as km
        from ._dynamic_metrics import has_gradient, is_dynamic

        for ref in self.refs:
            name = ref.metric
            if is_dynamic(name) and not has_gradient(name):
                return False
            if km.is_kinematic_family(name) and not km.has_gradient(name):
                return False
        return True

    def value_only_metrics(self) -> list[str]:
        """The problem's metrics without an exact derivative (yet)."""
        from . import metrics as km
        from ._dynamic_metrics import has_gradient, is_dynamic

        return sorted({r.metric for r in self.refs
                       if (is_dynamic(r.metric) and not has_gradient(r.metric))
                       or (km.is_kinematic_family(r.metric) and not km.has_gradient(r.metric))})

    @property
    def refs(self) -> list[MetricRef]:
        """Every metric reference of the objective and the constraints."""
        return [*self.spec.objective.parts, *self.spec.constraints]

    def _remember(self, key, design: tuple, compute):
        """``compute()`` once per key (the last 256 kept), each distinct design counted once in
        :attr:`evaluations`."""
        if key not in self._memo:
            if design not in self._designs:
                self._designs.add(design)
                self.evaluations += 1
            if len(self._memo) > 256:
                self._memo.clear()
            self._memo[key] = compute()
        return self._memo[key]

    def design_ok(self, x: np.ndarray) -> bool:
        """The design assembles over the whole turn as the searches see it (the kinematics on
        a 1 deg grid at the setting inputs' extremes, every closed-form unit at least
        :data:`~sewmech.design.evaluate.ASSEMBLY_CLEARANCE_MM` from failing at every grid angle, which keeps it
        assembled between the grid angles too). The answer's verdict is :meth:`report`'s exact
        proof."""
        key = ("assembles", tuple(np.asarray(x, dtype=float)))
        if key not in self._memo:
            self._memo[key] = bool(assembles_batch(self.machine,
                                                   self.params(x)[None, :])[0])
        return self._memo[key]

    # ---- the objective and the constraints -----------------------------------------------------
    def _part_scales(self) -> np.ndarray:
        if self._scales is None:
            out = []
            for p in self.spec.objective.parts:
                if p.scale is not None:
                    out.append(p.scale)
                elif p.sense == "target":
                    out.append(abs(p.target) if p.target else 1.0)
                else:
                    v, _ = self.metric(p, self.start)
                    out.append(abs(v) if v else 1.0)
            self._scales = np.array(out)
        return self._scales

    def parts(self, x: np.ndarray) -> list[dict]:
        """Each part of the objective at x in its own unit: ``metric``, ``regulator_deg``,
        ``phi_deg``, ``unit``, ``sense``, ``target``, ``weight``, ``scale`` (the s that
        divides it, :data:`OBJECTIVE_FORMS`) and ``value`` (None where it cannot be formed)."""
        out = []
        for p, sc in zip(self.spec.objective.parts, self._part_scales(), strict=True):
            try:
                v = float(self.metric(p, x)[0])
            except SewmechError:
                v = None
            out.append({"metric": p.metric, "regulator_deg": p.regulator_deg,
                        "phi_deg": p.phi_deg, "unit": metric_unit(self.machine, p.metric),
                        "sense": p.sense, "target": p.target, "weight": p.weight,
                        "scale": float(sc), "value": v})
        return out

    def objective(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective (dimensionless, :data:`OBJECTIVE_FORMS`) and its gradient by x."""
        x = np.asarray(x, dtype=float)
        parts = self.spec.objective.parts
        s = self._part_scales()
        terms, grads = [], []
        for p, sc in zip(parts, s, strict=True):
            v, d = self.metric(p, x)
            if d is None:  # a value-only metric: no gradient of the whole
                d = np.full(len(x), np.nan)
            if p.sense == "target":
                if self.spec.objective.form == "weighted_uniform":
                    terms.append(p.weight * abs(v - p.target) / sc)
                    grads.append(p.weight * np.sign(v - p.target) * d / sc)
                else:
                    terms.append(p.weight * ((v - p.target) / sc) ** 2)
                    grads.append(p.weight * 2.0 * (v - p.target) / sc ** 2 * d)
            else:
                sign = 1.0 if p.sense == "min" else -1.0
                terms.append(sign * p.weight * v / sc)
                grads.append(sign * p.weight * d / sc)
        if self.spec.objective.form == "weighted_uniform":
            k = int(np.argmax(terms))
            return float(terms[k]), grads[k]
        return float(sum(terms)), np.sum(grads, axis=0)

    def constraints(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """g(x) >= 0 for every bound of every constraint: values, their gradients (m, n) and
        names."""
        g, J, names = [], [], []
        for c in self.spec.constraints:
            v, d = self.metric(c, x)
            if d is None:
                d = np.full(len(x), np.nan)
            for side, b in c.bounds:
                sign = 1.0 if side == "min" else -1.0
                g.append(sign * (v - b))
                J.append(sign * d)
                names.append(f"{c.metric} {'>=' if side == 'min' else '<='} {b:g}")
        return np.array(g), np.array(J).reshape(len(g), len(x)), names

    def assembly_margin(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """The smallest assembly margin (mm) of any closed-form unit over the whole turn, at
        both ends of every setting input, and its derivative by the variables (mm per file
        unit): the margin that SLSQP keeps at least :data:`~sewmech.design.evaluate.ASSEMBLY_CLEARANCE_MM`. Each
        condition's margin (:func:`sewmech.engine.margins.conditions`) is read on a 1 deg grid
        from the points it names (so also where its unit fails), its least value located by
        Brent's method on its slope; the derivative is the margin's at that angle (where its
        slope is 0 the angle's motion does not change it), by central differences of the
        variables in one kinematics call."""
        key = ("margin", tuple(np.asarray(x, dtype=float)))
        if key not in self._memo:
            self._memo[key] = _smallest_margin(self, np.asarray(x, dtype=float))
        return self._memo[key]

    # ---- values only, for the derivative-free methods and the population methods ------------
    def batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For a batch of designs X (m, n_variables; file units), values only: the objective
        (m,), the constraints g (m, n_g), >= 0 where met, in the order and units of
        :meth:`constraints`, and which designs assemble over the whole turn (m,). One
        kinematics call per metric (:func:`batch_values`: events on a 1 deg grid refined on
        its Hermite interpolant, about 1e-7 of the located ones where the path is smooth; the
        stitch lengths located on the exact kinematics); NaN where a design does not
        assemble."""
        vals, ok = batch_values(self, X)
        spec = self.spec
        uniform = spec.objective.form == "weighted_uniform"
        terms = []
        for p, sc in zip(spec.objective.parts, self._part_scales(), strict=True):
            v = vals[ref_key(p)]
            if p.sense == "target":
                dev = (v - p.target) / sc
                terms.append(p.weight * (np.abs(dev) if uniform else dev ** 2))
            else:
                terms.append((1.0 if p.sense == "min" else -1.0) * p.weight * v / sc)
        f = np.max(terms, axis=0) if uniform else np.sum(terms, axis=0)
        g = []
        for c in spec.constraints:
            v = vals[ref_key(c)]
            for side, b in c.bounds:
                g.append(v - b if side == "min" else b - v)
        return f, (np.column_stack(g) if g else np.zeros((len(f), 0))), ok

    def constraint_scales(self) -> np.ndarray:
        """The size of each bound of :meth:`constraints` (at least 1), to compare violations."""
        return np.array([max(abs(b), 1.0) for c in self.spec.constraints
                         for _, b in c.bounds])

    def value(self, x: np.ndarray) -> tuple[float, np.ndarray, bool]:
        """:meth:`batch` of one design (remembered): objective, constraints, assembles."""
        design = tuple(np.asarray(x, dtype=float))

        def compute():
            f, g, ok = self.batch(np.asarray(design)[None, :])
            return float(f[0]), g[0], bool(ok[0])

        return self._remember(("value", design), design, compute)

    # ---- the epigraph form: what every method solves -----------------------------------------
    def form(self, x: np.ndarray) -> FormPoint:
        """The problem at the design x in its epigraph form (:class:`FormPoint`), from the
        exact metrics with their derivatives by the variables (NaN for a value-only metric);
        ``ok`` False where a metric cannot be formed on the design."""
        design = tuple(np.asarray(x, dtype=float))

        def compute():
            try:
                mvs = [self.metric_value(r, x) for r in self.refs]
            except SewmechError:
                return FormPoint.undefined(len(x))
            return self._form(mvs, len(x))

        return self._remember(("form", design), design, compute)

    def form_values(self, x: np.ndarray) -> FormPoint:
        """:meth:`form` from values alone (:func:`batch_values`, one kinematics call per
        metric), as the derivative-free methods read it; ``ok`` False where the design does not
        assemble over the whole turn or a metric cannot be formed."""
        from .metrics import MetricValue

        design = tuple(np.asarray(x, dtype=float))

        def compute():
            pieces: dict = {}
            try:
                vals, ok = batch_values(self, np.asarray(design)[None, :], pieces)
            except SewmechError:
                return FormPoint.undefined(len(x))
            if not ok[0]:
                return FormPoint.undefined(len(x))
            mvs = []
            for r in self.refs:
                key = ref_key(r)
                v = float(vals[key][0])
                if not math.isfinite(v):
                    return FormPoint.undefined(len(x))
                pcs = pieces.get(key, [np.zeros(0)])[0]
                mvs.append(MetricValue(v, None, _kind_of(r.metric) if len(pcs) else None,
                                       np.asarray(pcs, dtype=float)))
            return self._form(mvs, len(x), exact=False)

        return self._remember(("form_values", design), design, compute)

    def _form(self, mvs: list, n: int, exact: bool = True) -> FormPoint:
        """The epigraph form from every metric's value (and pieces) in :attr:`refs` order."""
        spec = self.spec
        parts = spec.objective.parts
        uniform = spec.objective.form == "weighted_uniform"
        nan = np.full(n, np.nan)

        def grad(mv):
            return mv.d if mv.d is not None else nan

        def pieces(mv, kind):
            """The pieces (values, derivatives, angles) of a max- or min-type metric of that
            kind, else the value itself as one piece."""
            if mv.kind == kind and len(mv.pieces):
                pd = mv.pieces_d if mv.pieces_d is not None else np.full((len(mv.pieces), n),
                                                                        np.nan)
                ph = mv.pieces_phi if len(mv.pieces_phi) == len(mv.pieces) else \
                    np.full(len(mv.pieces), np.nan)
                return np.asarray(mv.pieces, dtype=float), pd, ph
            return np.array([mv.value]), grad(mv)[None, :], np.array([np.nan])

        smooth, smooth_d = 0.0, np.zeros(n)
        groups = []  # (values, derivatives, tags)
        uni_v, uni_d, uni_t = [], [], []
        for i, (p, sc, mv) in enumerate(zip(parts, self._part_scales(), mvs[:len(parts)],
                                            strict=True)):
            w = p.weight
            if uniform:
                for side, kind in ((1.0, "max"), (-1.0, "min")):
                    v, d, ph = pieces(mv, kind) if (mv.kind == kind) else (
                        np.array([mv.value]), grad(mv)[None, :], np.array([np.nan]))
                    uni_v.append(side * w * (v - p.target) / sc)
                    uni_d.append(side * w * d / sc)
                    uni_t.append(np.stack([np.full(len(v), 2 * i + (side < 0)), ph], axis=1))
                continue
            if p.sense == "min" and mv.kind == "max" and len(mv.pieces):
                v, d, ph = pieces(mv, "max")
                groups.append((w * v / sc, w * d / sc, np.stack([np.full(len(v), i), ph], 1)))
            elif p.sense == "max" and mv.kind == "min" and len(mv.pieces):
                v, d, ph = pieces(mv, "min")
                groups.append((-w * v / sc, -w * d / sc,
                               np.stack([np.full(len(v), i), ph], 1)))
            elif p.sense == "target":
                smooth += w * ((mv.value - p.target) / sc) ** 2
                smooth_d = smooth_d + w * 2.0 * (mv.value - p.target) / sc ** 2 * grad(mv)
            else:
                sign = 1.0 if p.sense == "min" else -1.0
                smooth += sign * w * mv.value / sc
                smooth_d = smooth_d + sign * w * grad(mv) / sc
        if uniform:
            groups.append((np.concatenate(uni_v), np.concatenate(uni_d),
                           np.concatenate(uni_t)))
        g, gd, gt, h, hd = [], [], [], [], []
        for i, (c, mv) in enumerate(zip(spec.constraints, mvs[len(parts):], strict=True)):
            eq = c.equality
            if eq is not None:
                sc = max(abs(eq), 1.0)
                h.append((mv.value - eq) / sc)
                hd.append(grad(mv) / sc)
                continue
            for side, b in c.bounds:
                sc = max(abs(b), 1.0)
                v, d, ph = pieces(mv, side == "max" and "max" or "min")
                sign = 1.0 if side == "min" else -1.0
                g.append(sign * (v - b) / sc)
                gd.append(sign * d / sc)
                gt.append(np.stack([np.full(len(v), 2 * i + (side == "max")), ph], axis=1))
        cat = np.concatenate
        return FormPoint(
            smooth=float(smooth), smooth_d=smooth_d if exact else None,
            groups=[q[0] for q in groups], groups_d=[q[1] for q in groups] if exact else None,
            groups_tag=[q[2] for q in groups],
            g=cat(g) if g else np.zeros(0), g_d=(cat(gd) if gd else np.zeros((0, n)))
            if exact else None, g_tag=cat(gt) if gt else np.zeros((0, 2)),
            h=np.array(h), h_d=(np.array(hd).reshape(len(h), n)) if exact else None, ok=True)

    def report(self, x: np.ndarray) -> dict:
        """Each constraint's value and whether it holds (to 1e-9 of its scale), and whether the
        design assembles over the whole turn (always a constraint): proved exactly
        (:func:`sewmech.engine.assembly.prove_assembly`, every margin's minimum between the grid
        angles located) at both ends of every setting input. A metric that cannot be formed
        for the design has no value and does not hold."""
        from ..engine.assembly import prove_assembly

        P = self.params(x)
        proofs = [prove_assembly(self.machine, params=P, inputs=inputs)
                  for inputs in _setting_extremes(self.machine)]
        ok = all(p.ok for p in proofs)
        smallest = [p.smallest.value_mm for p in proofs if p.smallest is not None]
        out = {"assembles over the whole turn": {
            "value": float(ok), "satisfied": ok, "min": 1.0, "max": None,
            "smallest_margin_mm": min(smallest) if smallest else None,
            **({} if smallest else {"smallest_margin_note": "none: no closed-form unit's"
                                    " margin was located (the machine has no such unit, or"
                                    " it fails to assemble)"}),
            "failures": [f"{f.unit}: {f.from_deg:.6g}..{f.to_deg:.6g} deg, {f.reason}"
                         for p in proofs for f in p.failures]}}
        for c in self.spec.constraints:
            try:
                v, _ = self.metric(c, x)
            except SewmechError:
                v = math.nan
            eq = c.equality
            if eq is not None:
                ok = abs(v - eq) <= EQUALITY_TOL * max(1.0, abs(eq))
            else:
                ok = (c.min is None or v >= c.min - 1e-9 * max(1.0, abs(c.min))) and (
                    c.max is None or v <= c.max + 1e-9 * max(1.0, abs(c.max)))
            name = c.metric if c.metric not in out else f"{c.metric} ({len(out)})"
            out[name] = {"value": v if math.isfinite(v) else None, "satisfied": bool(ok),
                         "min": c.min if eq is None else eq, "max": c.max if eq is None else eq}
            if eq is not None:
                out[name]["equals"] = eq
                out[name]["tolerance"] = EQUALITY_TOL * max(1.0, abs(eq))
            if not math.isfinite(v):  # JSON has no NaN: null, and why beside it
                out[name]["note"] = ("not defined: the metric cannot be formed on the design"
                                     " (it does not assemble where the metric is read)")
        return out


@dataclass
class FormPoint:
    """A problem at one design in its epigraph form, what every method solves: minimise

        smooth(x) + sum_j max_i q_ji(x)   subject to   g(x) >= 0,  h(x) = 0

    where ``smooth`` is the sum of the objective's smooth parts, each group q_j the pieces of
    one max-type part (a largest value over the turn to minimise, a least to maximise: its
    local extremes, each smooth; every part's two sides in the weighted uniform form), ``g``
    every inequality, a max-type metric's bound once per piece, and ``h`` the equalities, each
    divided by its bound's size (at least 1). With an epigraph variable t_j per group
    (q_ji <= t_j) the problem is smooth where the maximum has a kink.

    ``*_d`` are the derivatives by the variables (per file unit; None from values alone, NaN
    rows for a value-only metric); ``*_tag`` tell the pieces apart: (source, shaft angle rad or
    NaN) per piece, the source a part (groups) or a constraint's side (g)."""

    smooth: float
    groups: list
    g: np.ndarray
    h: np.ndarray
    ok: bool
    smooth_d: np.ndarray | None = None
    groups_d: list | None = None
    g_d: np.ndarray | None = None
    h_d: np.ndarray | None = None
    groups_tag: list = field(default_factory=list)
    g_tag: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @classmethod
    def undefined(cls, n: int) -> FormPoint:
        return cls(math.inf, [], np.zeros(0), np.zeros(0), False)

    @property
    def objective(self) -> float:
        """The problem's objective (as :meth:`Problem.objective`)."""
        if not self.ok:
            return math.inf
        return self.smooth + sum(float(q.max()) for q in self.groups if len(q))


def _kind_of(name: str) -> str | None:
    """Whether a metric is max-type ("max"), min-type ("min") or neither (None)."""
    from . import metrics as km
    from ._dynamic_metrics import DYNAMIC_METRICS

    family = name.partition(":")[0]
    if family in DYNAMIC_METRICS:
        return DYNAMIC_METRICS[family][2]
    if family in ("max", "range", "transmission_angle_deviation", km.PRESSURE):
        return "max"
    if family in ("min", "transmission_angle_min"):
        return "min"
    return None


#: how close (relative to max(1, |value|), in the metric's unit) an equality constraint must be
#: met for an answer to meet it
EQUALITY_TOL = 1e-6


def batch_values(problem: Problem, X: np.ndarray, pieces: dict | None = None
                 ) -> tuple[dict, np.ndarray]:
    """Every metric of the problem for a batch of designs X (m, n_variables; file units), one
    kinematics batch call per metric, and which designs assemble over the whole turn (at both
    ends of every setting input): ({:func:`~sewmech.design._models.ref_key`: values (m,)},
    (m,) bool). Values of designs that do not assemble are NaN (masked by the caller, never
    used). ``pieces`` (a dict) receives the max- and min-type metrics' pieces per design."""
    m = problem.machine
    X = np.atleast_2d(np.asarray(X, dtype=float))
    P = np.tile(np.asarray(m.defaults, dtype=float), (len(X), 1))
    P[:, problem.index] = X * problem.factor
    forces = problem.forces if any(_is_dynamic(r.metric) for r in problem.refs) else None
    return metric_batch(m, problem.refs, P, forces=forces, pieces=pieces)


def _is_dynamic(name: str) -> bool:
    from ._dynamic_metrics import is_dynamic

    return is_dynamic(name)


def _smallest_margin(problem: Problem, x: np.ndarray) -> tuple[float, np.ndarray]:
    """See :meth:`Problem.assembly_margin`."""
    from scipy.optimize import brentq

    from ..engine.kinematics import kinematics
    from ..engine.margins import conditions

    m = problem.machine
    P = problem.params(x)
    h = math.radians(1.0)
    grid = np.arange(360) * h
    best = (math.inf, None, None, None)
    for inputs in _setting_extremes(m):
        for ci, c in enumerate(conditions(m, P)):
            def margin(phi, c=c, inputs=inputs, params=P):
                r = kinematics(m, np.atleast_1d(phi), params=params, inputs=inputs, omega=1.0,
                               points=c.points, links=c.links, variables=(),
                               on_failure="mask")
                return c.fn(r)

            v, dv = (np.asarray(a, dtype=float) for a in margin(grid))
            if not np.isfinite(v).any():
                continue
            k = int(np.nanargmin(v))
            phi_min, v_min = grid[k], float(v[k])
            j = (k - 1) % 360 if dv[k] > 0 else (k + 1) % 360
            lo_, hi_ = sorted((grid[k], grid[k] + (h if j == (k + 1) % 360 else -h)))
            try:
                s0 = float(margin(lo_)[1][0])
                s1 = float(margin(hi_)[1][0])
                if s0 < 0.0 < s1:
                    phi_min = brentq(lambda t: float(margin(t)[1][0]), lo_, hi_, xtol=1e-12)
                    v_min = float(margin(phi_min)[0][0])
            except ValueError:
                pass
            if v_min < best[0]:
                best = (v_min, ci, inputs, phi_min)
    v_min, ci, inputs, phi_min = best
    if ci is None:  # no closed-form unit, or none whose inputs assemble: nothing to hold
        return (math.inf if not conditions(m, P) else -1.0), np.zeros(len(x))
    # the margin at that angle for the variables stepped up and down, one batch call
    n = len(x)
    step = 1e-6 * np.maximum(1.0, np.abs(x))
    X = np.concatenate([x + np.diag(step), x - np.diag(step)])
    PP = np.tile(P, (2 * n, 1))
    PP[:, problem.index] = X * problem.factor
    c = conditions(m, PP.T[:, :, None])[ci]  # (the same condition, for the stepped designs)
    r = kinematics(m, np.array([phi_min]), params=PP, inputs=inputs, omega=1.0,
                   points=c.points, links=c.links, variables=(), on_failure="mask")
    vals = np.asarray(c.fn(r)[0], dtype=float).reshape(2 * n)
    up, down = vals[:n], vals[n:]
    # a step that leaves what the parameter may be (a counterweight's static moment below 0 at
    # its bound) has no margin: the one-sided difference on the other side
    return v_min, np.where(np.isfinite(up) & np.isfinite(down), (up - down) / (2.0 * step),
                           np.where(np.isfinite(up), (up - v_min) / step,
                                    np.where(np.isfinite(down), (v_min - down) / step, 0.0)))

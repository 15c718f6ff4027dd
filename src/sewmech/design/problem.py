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
    Header,
    MetricRef,
    Strict,
    check_bounds,
    check_limit,
    check_range,
)
from .evaluate import (
    _metric,
    _setting_extremes,
    assembles_batch,
    metric_batch,
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

    @field_validator("min", "max")
    @classmethod
    def _limit(cls, v):
        return check_limit(v)

    @model_validator(mode="after")
    def _bound(self):
        if self.min is None and self.max is None:
            raise ValueError("give min, max or both")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueHint(f"need min <= max, got {self.min:g} .. {self.max:g}: no design"
                            " could meet it", "Swap them, or give the bound you meant")
        return self


class ProblemSpec(Strict):
    problem: ProblemInfo
    variables: list[Variable] = Field(min_length=1)
    objective: Objective
    constraints: list[Constraint] = Field(default_factory=list)


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
        check_bounds(where, "variables", k, v, machine,
                     math.pi / 180.0 if unit == "rad" else 1.0, v.start)
    refs = [("objective.parts", k, p) for k, p in enumerate(spec.objective.parts)]
    refs += [("constraints", k, c) for k, c in enumerate(spec.constraints)]
    channels = None
    for table, k, ref in refs:
        channels = _check_metric(where, table, k, ref, machine, channels)


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
    from .evaluate import THREAD_METRICS

    if name in METRICS or name in THREAD_METRICS:
        return "deg" if name.endswith("_deg") else "mm"
    channel = name.split(":", 1)[1] if name.startswith("range:") else name
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
    channel = name.split(":", 1)[1] if name.startswith("range:") else name
    if channel in channels:
        if name.startswith("range:") and channel.split("_")[0] not in ("p", "theta", "q"):
            raise MachineFileError(where, table, key, f"{name}: a range is of a position"
                                   " channel (p_POINT_x, theta_LINK, q_VAR)",
                                   "Give range: and a position channel")
        if ref.regulator_deg is not None:  # the channel at that setting
            if s is None or s.regulator is None:
                raise MachineFileError(where, table, f"{k}.regulator_deg", f"machine"
                                       f" '{machine.name}' has no stitch regulator",
                                       "Leave out regulator_deg")
            _in_range(where, table, k, ref, machine)
        return channels
    known = [*METRICS, *THREAD_METRICS]
    ranges = [f"range:{c}" for c in channels if c.split("_")[0] in ("p", "theta", "q")]
    near = difflib.get_close_matches(name, ranges if name.startswith("range:") else
                                     [*known, *channels, *ranges], n=3)
    what = f"'{channel}' is not a channel of '{machine.name}'" if name.startswith("range:") \
        else f"unknown metric '{name}'"
    raise MachineFileError(where, table, key, what, f"Did you mean {', '.join(near)}?" if near
                           else f"Metrics: {', '.join(known)}, range:CHANNEL, or a channel"
                           " (p_POINT_x, theta_LINK, q_VAR) at phi_deg (docs/design.md)")


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
        #: internal units per file unit of each variable (deg -> rad)
        self.factor = np.array([math.pi / 180.0 if u == "rad" else 1.0 for u in units])
        self.units = tuple("deg" if u == "rad" else u for u in units)
        self.lower = np.array([v.lower for v in spec.variables])
        self.upper = np.array([v.upper for v in spec.variables])
        defaults = np.asarray(machine.defaults)[self.index] / self.factor
        self.start = np.array([v.start if v.start is not None else d
                               for v, d in zip(spec.variables, defaults)])
        self.names = tuple(v.parameter for v in spec.variables)
        self.evaluations = 0
        self._designs: set = set()
        self._memo: dict = {}
        self._scales = None

    # ---- metrics -------------------------------------------------------------------------------
    def params(self, x: np.ndarray) -> np.ndarray:
        P = np.array(self.machine.defaults, dtype=float)
        P[self.index] = np.asarray(x, dtype=float) * self.factor
        return P

    def metric(self, ref: MetricRef, x: np.ndarray) -> tuple[float, np.ndarray]:
        """A metric's value and its derivative by the variables (per file unit) at x; raises
        SewmechError where the design cannot be evaluated (it does not assemble)."""
        design = tuple(np.asarray(x, dtype=float))

        def compute():
            value, d = _metric(self.machine, ref, self.params(x))
            return value, None if d is None else d[self.index] * self.factor

        return self._remember((ref.metric, ref.regulator_deg, ref.phi_deg, design), design,
                              compute)

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
        for p, sc in zip(self.spec.objective.parts, self._part_scales()):
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
        for p, sc in zip(parts, s):
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
            if c.min is not None:
                g.append(v - c.min)
                J.append(d)
                names.append(f"{c.metric} >= {c.min:g}")
            if c.max is not None:
                g.append(c.max - v)
                J.append(-d)
                names.append(f"{c.metric} <= {c.max:g}")
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
        its Hermite interpolant, within about 1e-7 of the located ones); NaN where a design
        does not assemble."""
        vals, ok = batch_values(self, X)
        spec = self.spec
        uniform = spec.objective.form == "weighted_uniform"
        terms = []
        for p, sc in zip(spec.objective.parts, self._part_scales()):
            v = vals[(p.metric, p.regulator_deg, p.phi_deg)]
            if p.sense == "target":
                dev = (v - p.target) / sc
                terms.append(p.weight * (np.abs(dev) if uniform else dev ** 2))
            else:
                terms.append((1.0 if p.sense == "min" else -1.0) * p.weight * v / sc)
        f = np.max(terms, axis=0) if uniform else np.sum(terms, axis=0)
        g = []
        for c in spec.constraints:
            v = vals[(c.metric, c.regulator_deg, c.phi_deg)]
            if c.min is not None:
                g.append(v - c.min)
            if c.max is not None:
                g.append(c.max - v)
        return f, (np.column_stack(g) if g else np.zeros((len(f), 0))), ok

    def constraint_scales(self) -> np.ndarray:
        """The size of each bound of :meth:`constraints` (at least 1), to compare violations."""
        return np.array([max(abs(b), 1.0) for c in self.spec.constraints
                         for b in (c.min, c.max) if b is not None])

    def value(self, x: np.ndarray) -> tuple[float, np.ndarray, bool]:
        """:meth:`batch` of one design (remembered): objective, constraints, assembles."""
        design = tuple(np.asarray(x, dtype=float))

        def compute():
            f, g, ok = self.batch(np.asarray(design)[None, :])
            return float(f[0]), g[0], bool(ok[0])

        return self._remember(("value", design), design, compute)

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
            ok = (c.min is None or v >= c.min - 1e-9 * max(1.0, abs(c.min))) and (
                c.max is None or v <= c.max + 1e-9 * max(1.0, abs(c.max)))
            name = c.metric if c.metric not in out else f"{c.metric} ({len(out)})"
            out[name] = {"value": v if math.isfinite(v) else None, "satisfied": bool(ok),
                         "min": c.min, "max": c.max}
            if not math.isfinite(v):  # JSON has no NaN: null, and why beside it
                out[name]["note"] = ("not defined: the metric cannot be formed on the design"
                                     " (it does not assemble where the metric is read)")
        return out


def batch_values(problem: Problem, X: np.ndarray) -> tuple[dict, np.ndarray]:
    """Every metric of the problem for a batch of designs X (m, n_variables; file units), one
    kinematics batch call per metric, and which designs assemble over the whole turn (at both
    ends of every setting input): ({(metric, regulator_deg, phi_deg): values (m,)}, (m,) bool).
    Values of designs that do not assemble are NaN (masked by the caller, never used)."""
    m = problem.machine
    X = np.atleast_2d(np.asarray(X, dtype=float))
    P = np.tile(np.asarray(m.defaults, dtype=float), (len(X), 1))
    P[:, problem.index] = X * problem.factor
    return metric_batch(m, [*problem.spec.objective.parts, *problem.spec.constraints], P)


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
    return v_min, (vals[:n] - vals[n:]) / (2.0 * step)

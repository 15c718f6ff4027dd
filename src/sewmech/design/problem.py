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
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..engine.errors import MachineFileError, OptionError, SewmechError
from ..engine.machine import Machine, load_machine
from ..engine.spec import load_toml_model
from ..sewing.thread_gradients import THREAD_FIGURES, thread_gradient


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class ProblemInfo(_Spec):
    name: str
    machine: str
    description: str = ""


class Variable(_Spec):
    parameter: str
    lower: float
    upper: float
    start: float | None = None

    @model_validator(mode="after")
    def _order(self):
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)
                and self.lower < self.upper):
            raise ValueError(f"need lower < upper, got {self.lower} .. {self.upper}")
        if self.start is not None and not self.lower <= self.start <= self.upper:
            raise ValueError(f"start {self.start} is outside {self.lower} .. {self.upper}")
        return self


class MetricRef(_Spec):
    metric: str
    regulator_deg: float | None = None
    phi_deg: float = 0.0


class Part(MetricRef):
    target: float | None = None
    sense: Literal["target", "min", "max"] = "target"
    weight: float = Field(1.0, ge=0.0)
    scale: float | None = Field(None, gt=0.0)

    @model_validator(mode="after")
    def _target(self):
        if self.sense == "target" and self.target is None:
            raise ValueError("give a target, or sense = \"min\" or \"max\"")
        return self


class Objective(_Spec):
    form: Literal["weighted_sum", "weighted_uniform"] = "weighted_sum"
    parts: list[Part] = Field(min_length=1)

    @model_validator(mode="after")
    def _uniform(self):
        if self.form == "weighted_uniform" and any(p.sense != "target" for p in self.parts):
            raise ValueError("weighted_uniform needs a target for every part")
        return self


class Constraint(MetricRef):
    min: float | None = None
    max: float | None = None

    @model_validator(mode="after")
    def _bound(self):
        if self.min is None and self.max is None:
            raise ValueError("give min, max or both")
        return self


class ProblemSpec(_Spec):
    problem: ProblemInfo
    variables: list[Variable] = Field(min_length=1)
    objective: Objective
    constraints: list[Constraint] = Field(default_factory=list)


def load_problem(path: str | Path) -> tuple[ProblemSpec, Machine]:
    """Read and validate a problem file and load its machine; errors name the file and key."""
    path = Path(path).expanduser()
    where = str(path)
    spec = load_toml_model(path, ProblemSpec, "problem file", "docs/design.md")
    ref = spec.problem.machine
    local = (path.parent / ref)
    machine = load_machine(str(local) if local.is_file() else ref)
    names = machine.parameter_names
    for k, v in enumerate(spec.variables):
        if v.parameter not in names:
            import difflib

            near = difflib.get_close_matches(v.parameter, names, n=3)
            raise MachineFileError(where, "variables", f"{k}.parameter", f"'{v.parameter}' is"
                                   f" not a parameter of '{machine.name}'",
                                   f"Did you mean {', '.join(near)}?" if near else
                                   f"`sewmech check {machine.name} --parameters` lists them")
    return spec, machine


class Problem:
    """A problem ready to evaluate: the variables x in file units (mm, deg), the metrics and
    their derivatives by x, the objective and the constraints g(x) >= 0.

    ``evaluations`` counts the distinct designs evaluated (one at a time, or in batches)."""

    def __init__(self, spec: ProblemSpec, machine: Machine):
        self.spec, self.machine = spec, machine
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
        :data:`ASSEMBLY_CLEARANCE_MM` from failing at every grid angle, which keeps it
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

    def objective(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective (dimensionless) and its gradient by x."""
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
        unit): the margin that SLSQP keeps at least :data:`ASSEMBLY_CLEARANCE_MM`. Each
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
        return out


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


def _metric(machine: Machine, ref: MetricRef, P: np.ndarray) -> tuple[float, np.ndarray | None]:
    """A metric's value and its derivative by every parameter (None for a value-only metric),
    for the design P."""
    from ..sewing.gradients import METRICS

    name = ref.metric
    if name in THREAD_METRICS:
        g = thread_gradient(machine, name, params=P)
        return g.value, g.d_dparam
    if name in METRICS:
        feed = name in ("stitch_length", "feed_lift", "dog_height_at_needle_plate")
        reg = ref.regulator_deg
        if feed and reg is None:
            s = machine.spec.sewing
            if s is None or s.regulator is None:
                raise OptionError("metric", f"{name} needs a machine with a stitch regulator")
            reg = machine.spec.inputs[s.regulator].default_deg
        g = METRICS[name](machine, reg, params=P)
        return g.value, g.d_dparam
    from ..engine.sensitivity import sensitivities

    if name.startswith("range:"):
        from ..engine.extremes import extremes

        channel = name.split(":", 1)[1]
        ex = extremes(machine, channel, params=P)
        phi = np.array([ex.maximum.phi, ex.minimum.phi])
        S = sensitivities(machine, phi, params=P, outputs=[channel])
        v, d, _ = S.channel(channel)
        return float(v[0] - v[1]), d[0] - d[1]
    try:
        S = sensitivities(machine, np.radians([ref.phi_deg]), params=P, outputs=[name])
        v, d, _ = S.channel(name)
    except KeyError as exc:
        raise OptionError("metric", exc.args[0]) from None
    return float(v[0]), d[0]


def _channel_rates(channel: str) -> tuple[str, str]:
    """The rate and acceleration channels of a position channel (for locating its extremes)."""
    kind, _, rest = channel.partition("_")
    pairs = {"p": ("v", "a"), "theta": ("omega", "epsilon"), "q": ("qd", "qdd")}
    if kind not in pairs:
        raise OptionError("metric", f"range:{channel}: a range is of a position channel"
                          " (p_POINT_x, theta_LINK, q_VAR)")
    return f"{pairs[kind][0]}_{rest}", f"{pairs[kind][1]}_{rest}"


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


def metric_batch(machine: Machine, refs, P: np.ndarray, ok: np.ndarray | None = None
                 ) -> tuple[dict, np.ndarray]:
    """The metrics ``refs`` (each with ``metric``, ``regulator_deg``, ``phi_deg``: a sewing
    metric, a thread metric, ``range:CHANNEL`` or a channel at ``phi_deg``) for the batch of
    designs P (m, n_parameters; internal units), values only, and which designs assemble over
    the whole turn (:func:`assembles_batch`, unless given as ``ok``): ({(metric,
    regulator_deg, phi_deg): values (m,)}, (m,) bool). Values of designs that do not assemble
    are NaN."""
    from ..engine._events import extreme_rows
    from ..engine.kinematics import kinematics
    from ..sewing.gradients import METRICS, metric_values

    m = machine
    P = np.atleast_2d(np.asarray(P, dtype=float))
    phi = np.radians(np.arange(360.0))
    if ok is None:
        ok = assembles_batch(m, P)
    out = {}
    for ref in refs:
        key = (ref.metric, ref.regulator_deg, ref.phi_deg)
        if key in out:
            continue
        name = ref.metric
        if name in THREAD_METRICS:  # (one design at a time: the thread balance has no batch)
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
        elif name.startswith("range:"):
            channel = name.split(":", 1)[1]
            rate, acc = _channel_rates(channel)
            k = kinematics(m, phi, params=P, omega=1.0, on_failure="mask")
            V, S, C = (k.channel(c)[0].reshape(len(P), len(phi)) for c in (channel, rate, acc))
            if channel.startswith("theta_"):
                V = np.unwrap(V, axis=1)
            h = 2.0 * math.pi / len(phi)
            vals = extreme_rows(V, S, C, h, +1)[1] - extreme_rows(V, S, C, h, -1)[1]
        else:
            k = kinematics(m, np.radians([ref.phi_deg]), params=P, on_failure="mask")
            vals = k.channel(name)[0][..., 0]
        out[key] = np.where(ok, vals, np.nan)
    return out, ok


# ---- solving --------------------------------------------------------------------------------------

METHODS = ("golden", "cyclic", "powell", "slsqp", "de", "nsga2")


def optimize(problem: Problem, method: str = "powell", *, tol: float = 1e-7, seed: int = 0):
    """Solve ``problem`` by ``method`` (:data:`METHODS`): golden (one variable, bounds only),
    cyclic or powell (the JB report's interior penalty over the constraints and the bounds,
    variables scaled to their ranges), slsqp (scipy, with the metrics' exact gradients), de
    (scipy's differential evolution, a whole population per batch call, ``seed``), nsga2
    (pymoo's NSGA-II over the objective's parts as separate objectives, a whole population per
    batch call; the compromise nearest the ideal point is the answer, the front in ``front``).
    Returns an OptimizeResult with x (file units), fun, objective_start, constraints (name ->
    value, satisfied), status ("success" when converged with every constraint met, else
    "failed"), n_evaluations, history."""
    from scipy.optimize import OptimizeResult

    from .methods import golden_section, interior_penalty

    if method not in METHODS:
        raise OptionError("--method", f"unknown method {method!r}",
                          f"Choose one of {', '.join(METHODS)}")
    lo, hi = problem.lower, problem.upper
    span = hi - lo

    def to_x(u):
        return lo + np.asarray(u, dtype=float) * span

    def f_of(x):  # a design that does not assemble over the whole turn is infinitely bad
        try:
            if not problem.design_ok(x):
                return math.inf
            return problem.objective(x)[0]
        except SewmechError:
            return math.inf

    def fv_of(x):  # the same from values only (the derivative-free searches)
        try:
            f, _, ok = problem.value(x)
        except SewmechError:
            return math.inf
        return f if ok and math.isfinite(f) else math.inf

    f0 = f_of(problem.start)
    converged = True
    message = ""
    history: list[float] = []
    if method == "golden":
        if len(problem.names) != 1 or problem.spec.constraints:
            raise OptionError("--method", "golden searches one variable within its bounds,"
                              " without constraints", "Use powell, cyclic or slsqp")
        r = golden_section(lambda t: fv_of(np.array([t])), lo[0], hi[0], tol=tol * span[0])
        x, history, message = np.array(r.x), r.history, r.message
    elif method in ("cyclic", "powell"):
        def g_all(u):
            try:
                _, g, ok = problem.value(to_x(u))
            except SewmechError:
                return np.array([-1.0])
            if not (ok and np.all(np.isfinite(g))):
                return np.array([-1.0])
            return np.concatenate([g, u, 1.0 - u])

        u0 = (problem.start - lo) / span
        if not np.all(g_all(u0) > 0):
            raise OptionError("problem", "the start is not strictly inside every constraint"
                              " and bound, which the interior penalty needs",
                              "Give a start (variables' start) that meets every constraint")
        r = interior_penalty(lambda u: fv_of(to_x(u)), g_all, u0, method=method, tol=tol)
        x, history, message, converged = to_x(r.x), r.history, r.message, r.status == 0
    elif method == "nsga2":
        x, history, message, converged, front = _nsga2(problem, seed)
    elif method == "de":
        x, history, message, converged = _differential_evolution(problem, seed, tol)
        # polished like scipy's own polish, but with the constraints and exact gradients
        xp, ok_p = _slsqp(problem, x, lo, hi, tol, [])
        if ok_p and f_of(xp) <= f_of(x) and all(
                c["satisfied"] for c in problem.report(xp).values()):
            x = xp
            message += "; polished by SLSQP"
    else:
        x, converged = _slsqp(problem, problem.start, lo, hi, tol, history)
        message = "SLSQP " + ("converged" if converged else "did not converge")
    x = np.clip(x, lo, hi)
    fx = f_of(x)
    report = problem.report(x)
    ok = converged and math.isfinite(fx) and all(c["satisfied"] for c in report.values())
    res = OptimizeResult(x=x, fun=fx, objective_start=f0, constraints=report,
                         status="success" if ok else "failed", success=ok, message=message,
                         n_evaluations=problem.evaluations, history=history, method=method)
    if method == "nsga2":
        res.front = front
    return res


def _slsqp(problem: Problem, x0, lo, hi, tol: float, history: list) -> tuple[np.ndarray, bool]:
    """SLSQP from x0 with the metrics' exact gradients, the bounds and the constraints."""
    from scipy.optimize import minimize

    def guarded(x):  # the constraints where the design can be evaluated, else all unmet
        try:
            return problem.constraints(x)[:2]
        except SewmechError:
            k = sum((c.min is not None) + (c.max is not None) for c in problem.spec.constraints)
            return -np.ones(k), np.zeros((k, len(x)))

    # every closed-form unit kept ASSEMBLY_CLEARANCE_MM from failing to assemble anywhere in
    # the turn (a machine of loop units alone has no margin to hold)
    from ..engine.margins import conditions

    cons = [] if not conditions(problem.machine, problem.params(x0)) else [
        {"type": "ineq",
         "fun": lambda x: np.array([problem.assembly_margin(x)[0] - ASSEMBLY_CLEARANCE_MM]),
         "jac": lambda x: problem.assembly_margin(x)[1][None, :]}]
    if problem.spec.constraints:
        cons.append({"type": "ineq", "fun": lambda x: guarded(x)[0],
                     "jac": lambda x: guarded(x)[1]})

    def fg(x):
        try:
            return problem.objective(x)
        except SewmechError:
            return math.inf, np.zeros(len(x))

    if problem.spec.objective.form == "weighted_uniform":
        return _slsqp_uniform(problem, x0, lo, hi, tol, history, cons)
    r = minimize(fg, x0, jac=True, method="SLSQP", bounds=list(zip(lo, hi)), constraints=cons,
                 options={"ftol": tol * 1e-2, "maxiter": 300},
                 callback=lambda xk: history.append(fg(xk)[0]))
    return np.array(r.x), bool(r.success)


def _slsqp_uniform(problem: Problem, x0, lo, hi, tol: float, history: list, cons: list
                   ) -> tuple[np.ndarray, bool]:
    """The weighted uniform form (a maximum, not smooth where two parts are equal) as SLSQP's
    smooth epigraph problem: minimise t over (x, t) subject to
    t >= +-w_i (f_i(x) - t_i) / s_i for every part, besides the problem's constraints."""
    from scipy.optimize import minimize

    parts = problem.spec.objective.parts
    scales = problem._part_scales()
    n = len(x0)

    def part_rows(z):
        x = z[:n]
        g, J = [], []
        for p, sc in zip(parts, scales):
            v, d = problem.metric(p, x)
            for sign in (1.0, -1.0):
                g.append(z[n] - sign * p.weight * (v - p.target) / sc)
                J.append(np.concatenate([-sign * p.weight * d / sc, [1.0]]))
        return np.array(g), np.array(J)

    zcons = [{"type": "ineq", "fun": lambda z: part_rows(z)[0],
              "jac": lambda z: part_rows(z)[1]}]
    for c in cons:
        zcons.append({"type": "ineq", "fun": (lambda z, c=c: c["fun"](z[:n])),
                      "jac": (lambda z, c=c: np.hstack([c["jac"](z[:n]),
                                                        np.zeros((len(c["fun"](z[:n])), 1))]))})
    t0 = problem.objective(np.asarray(x0, dtype=float))[0]
    r = minimize(lambda z: (z[n], np.concatenate([np.zeros(n), [1.0]])),
                 np.concatenate([x0, [t0]]), jac=True, method="SLSQP",
                 bounds=list(zip(lo, hi)) + [(0.0, None)], constraints=zcons,
                 options={"ftol": tol * 1e-2, "maxiter": 300},
                 callback=lambda zk: history.append(float(zk[n])))
    return np.array(r.x[:n]), bool(r.success)


def _penalised(problem: Problem, X: np.ndarray) -> np.ndarray:
    """The objective of a batch of designs, a design that violates a constraint valued
    1e6 (1 + its violations in units of their bounds' sizes), one that does not assemble 1e12:
    the population never holds a NaN."""
    f, g, ok = problem.batch(X)
    # Deb's rule: any design that meets every constraint beats any that does not, and of two
    # that do not, the one that violates less wins
    viol = np.sum(np.maximum(0.0, -g) / problem.constraint_scales(), axis=1)
    f = np.where(viol > 0, 1e6 * (1.0 + viol), f)
    return np.where(ok & np.isfinite(f) & np.isfinite(viol), f, 1e12)


def _differential_evolution(problem: Problem, seed: int, tol: float):
    """scipy's differential evolution over the variables' box, each generation one batch call
    (``vectorized``), the constraints as penalties; polished by nothing (the caller reports
    the answer's constraints exactly)."""
    from scipy.optimize import differential_evolution

    history: list[float] = []
    n = len(problem.names)

    def f(Xt):  # scipy passes (n_variables, population)
        vals = _penalised(problem, Xt.T)
        problem.evaluations += Xt.shape[1]
        history.append(float(np.min(vals)))
        return vals

    r = differential_evolution(f, list(zip(problem.lower, problem.upper)), seed=seed,
                               vectorized=True, updating="deferred", tol=1e-8,
                               popsize=max(8, 4 * n), maxiter=300, polish=False,
                               x0=problem.start)
    return np.array(r.x), history, str(r.message), bool(r.success)


def _part_values(problem: Problem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each objective part as its own objective (to minimise: the normalised deviation from a
    target, or -+ the normalised value), the constraints as g <= 0 (pymoo's sign), and which
    designs assemble, for a batch of designs."""
    vals, ok = batch_values(problem, X)
    spec = problem.spec
    F = []
    for p, sc in zip(spec.objective.parts, problem._part_scales()):
        v = vals[(p.metric, p.regulator_deg, p.phi_deg)]
        if p.sense == "target":
            F.append(np.abs(v - p.target) / sc)
        else:
            F.append((1.0 if p.sense == "min" else -1.0) * v / sc)
    G = []
    for c in spec.constraints:
        v = vals[(c.metric, c.regulator_deg, c.phi_deg)]
        if c.min is not None:
            G.append((c.min - v) / max(abs(c.min), 1.0))
        if c.max is not None:
            G.append((v - c.max) / max(abs(c.max), 1.0))
    F = np.column_stack(F)
    G = np.column_stack(G) if G else np.zeros((len(X), 0))
    # a design that does not assemble: every objective and constraint very bad, never NaN
    F = np.where(ok[:, None] & np.isfinite(F), F, 1e12)
    G = np.where(ok[:, None] & np.isfinite(G), G, 1e12)
    return F, G, ok


def _nsga2(problem: Problem, seed: int):
    """pymoo's NSGA-II over the parts of the objective, each generation one batch call; the
    answer is the front's design nearest the ideal point in objectives scaled to the front's
    ranges. Returns (x, history, message, converged, front)."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem as PymooProblem
    from pymoo.optimize import minimize as pymoo_minimize

    parts = problem.spec.objective.parts
    if len(parts) < 2:
        raise OptionError("--method", "nsga2 needs at least two objective parts (it finds the"
                          " front between them)", "Use slsqp or de for one objective")
    n_con = sum((c.min is not None) + (c.max is not None) for c in problem.spec.constraints)
    history: list[float] = []

    class Wrapped(PymooProblem):
        def __init__(self):
            super().__init__(n_var=len(problem.names), n_obj=len(parts), n_ieq_constr=n_con,
                             xl=problem.lower, xu=problem.upper)

        def _evaluate(self, X, out, *args, **kwargs):
            F, G, _ = _part_values(problem, X)
            problem.evaluations += len(X)
            out["F"] = F
            if n_con:
                out["G"] = G
            history.append(float(np.min(F.sum(axis=1))))

    pop = max(24, 12 * len(problem.names))
    r = pymoo_minimize(Wrapped(), NSGA2(pop_size=pop), ("n_gen", 60), seed=seed, verbose=False)
    if r.X is None:
        return (problem.start.copy(), history,
                "NSGA-II found no design that meets every constraint", False,
                {"x": [], "f": [], "parts": [p.metric for p in parts]})
    X = np.atleast_2d(r.X)
    F = np.atleast_2d(r.F)
    lo, hi = F.min(axis=0), F.max(axis=0)
    z = (F - lo) / np.where(hi > lo, hi - lo, 1.0)
    k = int(np.argmin(np.linalg.norm(z, axis=1)))
    front = {"x": X.tolist(), "f": F.tolist(), "parts": [p.metric for p in parts],
             "compromise": k}
    message = f"NSGA-II, {len(X)} designs on the front; the compromise nearest the ideal point"
    return X[k], history, message, True, front

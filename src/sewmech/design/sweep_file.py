"""Sweep files: which dimensions of a machine to vary, how to sample them, and what to record of
every design (a TOML file, docs/sweeps.md).

```toml
[sweep]
name = "JB1-3 feed"
machine = "jb1-3"                  # a shipped machine or a file (relative to this one)

[sampling]
method = "sobol"                   # "grid", "random", "lhs" (Latin hypercube) or "sobol"
designs = 100000                   # how many (random, lhs, sobol; a grid has its own count)
seed = 1

[[parameters]]                     # bounds in the parameter's file unit: mm, or deg for angles
parameter = "lift_cam.arc0.cx"
lower = 0.9
upper = 1.8
# points = 5                       # grid only: values from lower to upper, both included

[[outputs]]                        # one column per output
metric = "stitch_length"           # a problem file's metric (docs/design.md): a sewing metric,
regulator_deg = 30.0               # min:, max:, range:, mean:, rms:CHANNEL, a transmission
name = "stitch_30"                 # angle, a force metric (peak_torque, ...), or a channel at
min = 3.6                          # phi_deg or at an event; name: the column (default: the
max = 4.2                          # metric and its setting); limits: else not feasible

[dynamics]                         # for the force metrics (peak_torque N m, ...)
rpm = 1000.0                       # default: the machine file's [speed]
step_deg = 2.0

[curves]                           # optional: whole channels over a turn, to Zarr
channels = ["p_feed_dog.tip_x", "p_feed_dog.tip_y"]
step_deg = 5.0
inputs = { regulator = 30.0 }      # setting inputs, deg (default: the machine's defaults)
```

Every key is checked where it enters (:func:`load_sweep`): an unknown parameter, metric or
channel is named with the ones it resembles, and the error names the file, the table and the
key.
"""

from __future__ import annotations

import difflib
import hashlib
import math
import os
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ..engine.errors import MachineFileError
from ..engine.machine import Machine, load_machine, machine_from_toml, shipped_machines
from ..engine.paths import user_path
from ..engine.spec import ValueHint, load_toml_model, read_toml_text
from . import metrics as km
from ._models import (
    Bounds,
    DynamicsTable,
    Header,
    MetricRef,
    Strict,
    check_bounds,
    check_limit,
    file_unit,
)

DOC = "docs/sweeps.md"
#: the most designs a sweep file may ask for (a grid's product included)
MAX_DESIGNS = 10**10


class SweepInfo(Header):
    """The ``[sweep]`` table."""


class Sampling(Strict):
    method: Literal["grid", "random", "lhs", "sobol"]
    designs: int | None = Field(None, ge=1, le=MAX_DESIGNS)
    seed: int = Field(0, ge=0, le=2**32 - 1)  # (numpy's and scipy's generators' seeds)

    @model_validator(mode="after")
    def _count(self):
        if self.method == "grid" and self.designs is not None:
            raise ValueError("a grid's size is the product of the parameters' points: leave"
                             " out designs")
        if self.method != "grid" and self.designs is None:
            raise ValueError(f"give designs, how many designs the {self.method} sample draws")
        return self


class SweepParameter(Bounds):
    points: int | None = Field(None, ge=2, le=100_000)


class Output(MetricRef):
    name: str | None = Field(None, min_length=1, max_length=100)
    min: float | None = None
    max: float | None = None

    @field_validator("min", "max")
    @classmethod
    def _limit(cls, v):
        return check_limit(v)

    @model_validator(mode="after")
    def _limits(self):
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueHint(f"need min <= max, got {self.min} .. {self.max}: no design could"
                            " be feasible", "Swap them, or give the limit you meant")
        return self

    @property
    def column(self) -> str:
        if self.name:
            return self.name
        if self.regulator_deg is not None:
            return f"{self.metric}@{self.regulator_deg:g}deg"
        if self.at is not None:
            return f"{self.metric}@{self.at}"
        if ":" in self.metric or _is_sewing_metric(self.metric) or _is_dynamic(self.metric):
            return self.metric
        return f"{self.metric}@{self.phi_deg:g}deg"


Dynamics = DynamicsTable  # (the same table in problem files)


class Curves(Strict):
    channels: list[str] = Field(min_length=1)
    step_deg: float = Field(5.0, ge=0.1, le=90.0)
    inputs: dict[str, float] = Field(default_factory=dict)


class SweepSpec(Strict):
    sweep: SweepInfo
    sampling: Sampling
    parameters: list[SweepParameter] = Field(min_length=1, max_length=64)
    outputs: list[Output] = Field(default_factory=list)
    dynamics: Dynamics | None = None
    curves: Curves | None = None


def _is_dynamic(name: str) -> bool:
    from ._dynamic_metrics import is_dynamic

    return is_dynamic(name)


def _is_sewing_metric(name: str) -> bool:
    from ..sewing.gradients import METRICS

    return name in METRICS


class Sweep:
    """A validated sweep file with its machine: what the runner records and ships to workers.

    ``text`` and ``machine_text`` are the two files' contents (a worker on another machine
    rebuilds the sweep from them, :meth:`from_texts`); ``digest`` identifies the pair."""

    def __init__(self, spec: SweepSpec, machine: Machine, text: str, file: str,
                 machine_text: str, machine_file: str):
        self.spec, self.machine = spec, machine
        self.text, self.file = text, file
        self.machine_text, self.machine_file = machine_text, machine_file
        names = machine.parameter_names
        self.index = [names.index(p.parameter) for p in spec.parameters]
        units = [machine.parameter_units[j] for j in self.index]
        #: internal units per file unit of each parameter (deg -> rad, g -> kg, g cm -> kg mm)
        self.factor = [file_unit(u)[1] for u in units]
        self.units = tuple(file_unit(u)[0] for u in units)
        self.names = tuple(p.parameter for p in spec.parameters)
        #: the parameters' columns: angles in deg, named so (``regulator.phase_deg``)
        self.columns = tuple(f"{n}_deg" if u == "deg" else n
                             for n, u in zip(self.names, self.units))

    @property
    def n_designs(self) -> int:
        s = self.spec
        if s.sampling.method == "grid":
            return math.prod(p.points for p in s.parameters)
        return int(s.sampling.designs)

    @property
    def sweep_sha256(self) -> str:
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()

    @property
    def machine_sha256(self) -> str:
        return hashlib.sha256(self.machine_text.encode("utf-8")).hexdigest()

    @classmethod
    def from_texts(cls, text: str, file: str, machine_text: str, machine_file: str) -> Sweep:
        """The sweep rebuilt from the two files' texts (no file is read: a worker elsewhere)."""
        from ..engine.spec import _parse_toml, validate_model

        spec = validate_model(SweepSpec, _parse_toml(text, file), file, DOC)
        return cls(spec, machine_from_toml(machine_text, machine_file), text, file,
                   machine_text, machine_file)


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file and load its machine; every problem a MachineFileError
    naming the file, the table and the key."""
    path = user_path(path)
    where = str(path)
    spec = load_toml_model(path, SweepSpec, "sweep file", DOC)
    text = read_toml_text(path, "sweep file")
    ref = spec.sweep.machine
    local = path.parent / ref
    if local.is_file():
        machine_path = local
    elif ref in shipped_machines():
        machine_path = shipped_machines()[ref]
    else:
        raise MachineFileError(where, "sweep", "machine", f"'{ref}' is neither a file beside"
                               " the sweep file nor a shipped machine", "Give a path relative"
                               " to the sweep file or one of "
                               f"{', '.join(sorted(shipped_machines()))}")
    machine = load_machine(str(machine_path))
    machine_text = read_toml_text(machine_path)
    _check(spec, machine, where)
    return Sweep(spec, machine, text, where, machine_text, str(machine_path))


def _near(name: str, names) -> str:
    near = difflib.get_close_matches(name, list(names), n=3)
    return f"Did you mean {', '.join(near)}?" if near else ""


def _regulator_in_range(where: str, k: int, o, machine: Machine) -> None:
    spec_in = machine.spec.inputs[machine.spec.sewing.regulator]
    lo = spec_in.min_deg if spec_in.min_deg is not None else -180.0
    hi = spec_in.max_deg if spec_in.max_deg is not None else 180.0
    if not lo <= o.regulator_deg <= hi:
        raise MachineFileError(where, "outputs", f"{k}.regulator_deg", f"{o.regulator_deg:g}"
                               f" deg is outside the regulator's range {lo:g} .. {hi:g} deg")


def available_memory() -> int:
    """Bytes of memory this machine can give a process now (Linux's MemAvailable; else the
    free physical pages)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 2**62  # unknown: no bound from here


#: the most designs of a Sobol sample (scipy's 30-bit sequence; its 64-bit one cannot be
#: fast-forwarded to a chunk's first design)
SOBOL_MAX = 2**30

#: a Latin hypercube is drawn whole (every design's stratum depends on all the others): its
#: n x d numbers and scipy's temporaries, about this many times their size
LHS_MEMORY_FACTOR = 4


def _check_lhs_memory(n: int, d: int, where: str) -> None:
    need = LHS_MEMORY_FACTOR * 8 * n * d
    have = available_memory()
    if need > have:
        most = have // (LHS_MEMORY_FACTOR * 8 * max(d, 1))
        raise MachineFileError(where, "sampling", "designs", f"a Latin hypercube is drawn"
                               f" whole: {n:,} designs of {d} parameters need about"
                               f" {need / 2**30:.1f} GiB, more than the {have / 2**30:.1f} GiB"
                               f" this machine has free (at most about {most:,} designs)",
                               "Use method = \"sobol\" or \"random\" (drawn chunk by chunk,"
                               " any number of designs), or fewer designs")


def _family(where: str, k: int, o, machine: Machine, channels) -> None:
    """An output of a metric family (docs/design.md) against the machine: the located error of
    :mod:`sewmech.design.metrics` or :mod:`sewmech.design._dynamic_metrics`."""
    from ._dynamic_metrics import check_name as check_dynamic

    try:
        km.check_name(machine, o.metric, channels) or check_dynamic(machine, o.metric)
    except km.MetricNameError as exc:
        raise MachineFileError(where, "outputs", f"{k}.metric", exc.what, exc.hint) from None


def _check(spec: SweepSpec, machine: Machine, where: str) -> None:
    """What the schema cannot know: names against the machine, grid points, column names."""
    from ..engine.kinematics import kinematics
    from ..sewing.gradients import METRICS, missing_roles

    names = machine.parameter_names
    seen = set()
    for k, p in enumerate(spec.parameters):
        if p.parameter not in names:
            raise MachineFileError(where, "parameters", f"{k}.parameter", f"'{p.parameter}' is"
                                   f" not a parameter of '{machine.name}'",
                                   _near(p.parameter, names) or f"`sewmech check"
                                   f" {machine.name} --parameters` lists them")
        if p.parameter.startswith("input."):
            raise MachineFileError(where, "parameters", f"{k}.parameter", f"'{p.parameter}' is"
                                   " a setting input, which the outputs choose themselves",
                                   "Give regulator_deg on an output instead")
        if p.parameter in seen:
            raise MachineFileError(where, "parameters", f"{k}.parameter", f"'{p.parameter}' is"
                                   " given twice", "Give each parameter once")
        seen.add(p.parameter)
        unit = machine.parameter_units[names.index(p.parameter)]
        check_bounds(where, "parameters", k, p, machine, file_unit(unit)[1])
        grid = spec.sampling.method == "grid"
        if grid and p.points is None:
            raise MachineFileError(where, "parameters", f"{k}.points", "a grid needs points,"
                                   " how many values from lower to upper", "Give e.g. points = 5")
        if not grid and p.points is not None:
            raise MachineFileError(where, "parameters", f"{k}.points", f"points is for a grid;"
                                   f" a {spec.sampling.method} sample draws its designs",
                                   "Leave out points, or use method = \"grid\"")
    if spec.sampling.method == "grid":
        n = math.prod(p.points for p in spec.parameters)
        if n > MAX_DESIGNS:
            raise MachineFileError(where, "parameters", "points", f"the grid has {n:.3g}"
                                   f" designs, more than {MAX_DESIGNS:.0e}",
                                   "Use fewer points, or a sobol sample")
    if spec.sampling.method == "lhs":
        _check_lhs_memory(spec.sampling.designs, len(spec.parameters), where)
    if spec.sampling.method == "sobol" and spec.sampling.designs > SOBOL_MAX:
        raise MachineFileError(where, "sampling", "designs", f"a Sobol sample has at most"
                               f" 2**30 = {SOBOL_MAX:,} designs (its 30-bit direction"
                               f" numbers), got {spec.sampling.designs:,}",
                               "Use method = \"random\" for more designs, or several Sobol"
                               " sweeps with different seeds")
    probe = kinematics(machine, [0.0])
    channels = probe.channel_names()
    columns = {p.parameter for p in spec.parameters}
    columns |= {f"{p.parameter}_deg" for p in spec.parameters}
    columns |= {"design", "assembles", "feasible"}
    s = machine.spec.sewing
    for k, o in enumerate(spec.outputs):
        name = o.metric
        if name in METRICS:
            feed = name in ("stitch_length", "feed_lift", "dog_height_at_needle_plate")
            lacks = missing_roles(machine, name)
            if lacks is not None:  # (every chunk failed on it, 3 attempts each)
                raise MachineFileError(where, "outputs", f"{k}.metric", lacks,
                                       "Choose another metric, or name the role in the"
                                       " machine file (docs/machine-files.md)")
            if o.regulator_deg is not None and not feed:
                raise MachineFileError(where, "outputs", f"{k}.regulator_deg", f"{name} does"
                                       " not depend on the regulator", "Leave out"
                                       " regulator_deg")
            if feed and o.regulator_deg is not None:
                _regulator_in_range(where, k, o, machine)
        elif _is_dynamic(name):
            if spec.dynamics is None:
                raise MachineFileError(where, "outputs", f"{k}.metric", f"{name} comes from"
                                       " the force analysis, which needs a [dynamics] table",
                                       "Add [dynamics] (rpm and step_deg have defaults)")
            if o.regulator_deg is not None:
                raise MachineFileError(where, "outputs", f"{k}.regulator_deg", "the force"
                                       " analysis runs at the machine's working setting",
                                       "Leave out regulator_deg")
            _family(where, k, o, machine, channels)
        elif km.is_kinematic_family(name) and not name.startswith("range:"):
            _family(where, k, o, machine, channels)
            if o.regulator_deg is not None:  # (read at that setting)
                if s is None or s.regulator is None:
                    raise MachineFileError(where, "outputs", f"{k}.regulator_deg", f"machine"
                                           f" '{machine.name}' has no stitch regulator",
                                           "Leave out regulator_deg")
                _regulator_in_range(where, k, o, machine)
        elif name.startswith("range:") or name in channels:
            channel = name.split(":", 1)[1] if name.startswith("range:") else name
            if channel not in channels:
                raise MachineFileError(where, "outputs", f"{k}.metric", f"'{channel}' is not a"
                                       f" channel of '{machine.name}'", _near(channel, channels))
            if name.startswith("range:") and channel.split("_")[0] not in ("p", "theta", "q"):
                raise MachineFileError(where, "outputs", f"{k}.metric", f"{name}: a range is of"
                                       " a position channel (p_POINT_x, theta_LINK, q_VAR)")
            if o.regulator_deg is not None:  # (the channel at that setting)
                if s is None or s.regulator is None:
                    raise MachineFileError(where, "outputs", f"{k}.regulator_deg", f"machine"
                                           f" '{machine.name}' has no stitch regulator",
                                           "Leave out regulator_deg")
                _regulator_in_range(where, k, o, machine)
            if name.startswith("range:"):
                _family(where, k, o, machine, channels)
        else:
            from ._dynamic_metrics import DYNAMIC_METRICS

            known = [*METRICS, *DYNAMIC_METRICS]
            raise MachineFileError(where, "outputs", f"{k}.metric", f"unknown metric '{name}'",
                                   _near(name, [*known, *channels]) or
                                   f"Metrics: {', '.join(known)}, range:CHANNEL, or a channel"
                                   " (p_POINT_x, theta_LINK, q_VAR) at phi_deg")
        if o.at is not None:
            if name not in channels:
                raise MachineFileError(where, "outputs", f"{k}.at", f"{name}: only a channel is"
                                       " read at an event", "Leave out at, or give a channel")
            try:
                km.check_event(machine, o.at, channels)
                km.check_read_at_event(name)
            except km.MetricNameError as exc:
                raise MachineFileError(where, "outputs", f"{k}.at", exc.what, exc.hint) \
                    from None
        if o.column in columns:
            raise MachineFileError(where, "outputs", f"{k}.name", f"the column '{o.column}' is"
                                   " already taken (by a parameter or another output)",
                                   "Give this output its own name")
        columns.add(o.column)
    if not spec.outputs and spec.curves is None:
        raise MachineFileError(where, "outputs", "", "the sweep records nothing but whether"
                               " each design assembles", "Add [[outputs]] (e.g. metric ="
                               " \"stitch_length\") or [curves]")
    if spec.dynamics is not None and not any(_is_dynamic(o.metric) for o in spec.outputs):
        raise MachineFileError(where, "dynamics", "", "no output reads the force analysis",
                               "Add an output peak_torque or peak_shaking_force (or another"
                               " force metric, docs/design.md), or remove [dynamics]")
    if spec.curves is not None:
        c = spec.curves
        for j, ch in enumerate(c.channels):
            if ch not in channels:
                raise MachineFileError(where, "curves", f"channels.{j}", f"'{ch}' is not a"
                                       f" channel of '{machine.name}'", _near(ch, channels))
        if len(set(c.channels)) != len(c.channels):
            raise MachineFileError(where, "curves", "channels", "a channel is given twice")
        n = round(360.0 / c.step_deg)
        if not math.isclose(n * c.step_deg, 360.0, rel_tol=1e-9):
            raise MachineFileError(where, "curves", "step_deg", f"{c.step_deg:g} deg does not"
                                   " divide 360", "Give a step such as 1, 2, 5 or 10")
        for name, deg in c.inputs.items():
            if name not in machine.spec.inputs:
                raise MachineFileError(where, "curves", f"inputs.{name}", f"'{machine.name}'"
                                       f" has no input '{name}'",
                                       f"Inputs: {', '.join(machine.spec.inputs) or 'none'}")
            i = machine.spec.inputs[name]
            lo = i.min_deg if i.min_deg is not None else -1e6
            hi = i.max_deg if i.max_deg is not None else 1e6
            if not lo <= deg <= hi:
                raise MachineFileError(where, "curves", f"inputs.{name}", f"{deg:g} deg is"
                                       f" outside its range {lo:g} .. {hi:g} deg")
    if spec.dynamics is not None:
        d = spec.dynamics
        n = round(360.0 / d.step_deg)
        if not math.isclose(n * d.step_deg, 360.0, rel_tol=1e-9):
            raise MachineFileError(where, "dynamics", "step_deg", f"{d.step_deg:g} deg does not"
                                   " divide 360", "Give a step such as 1, 2 or 5")

"""The pieces the design layer's TOML files share (problem, sweep and tolerance files): the
strict base model, the file's header table, a parameter's bounds, a reference to a metric, and
the ranges their numbers must lie in. Each file's own models build on these; the files are read
and validated by :func:`sewmech.engine.spec.load_toml_model`.

Every number of these files is checked where it enters: finite (``nan`` and ``inf`` are
refused, with the file, the table and the key) and inside a range that a machine can have
(docs/errors.md lists them); a parameter's bounds are checked against its own domain when the
file's machine is known (:func:`check_bounds`)."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..engine.errors import MachineFileError
from ..engine.kinematics import MIN_RPM
from ..engine.spec import ValueHint

#: the largest magnitude of a metric's value in a design file (a target, a constraint's or an
#: output's limit, a parameter's bounds), in the metric's unit (mm, deg, rad, N, N m): a
#: kilometre, far beyond any sewing machine, and far from overflow in the objective's squares
VALUE_LIMIT = 1e6
#: the largest magnitude of a shaft angle in a design file, deg (as ``--phi-deg``)
ANGLE_LIMIT_DEG = 1e6
#: a stitch regulator's setting, deg: within one turn either way (then within the machine's
#: own declared range, checked against its file)
REGULATOR_LIMIT_DEG = 360.0
#: an objective part's weight: 0 (left out) .. this (weights are relative)
MAX_WEIGHT = 1e6
#: an objective part's scale, in the metric's unit: a nanometre (1e-6 mm, or 1e-6 deg or rad)
#: to a kilometre
SCALE_RANGE = (1e-6, 1e6)


def check_range(value: float, lo: float, hi: float, what: str, hint: str = "") -> float:
    """``value`` if it lies in lo .. hi, else a ValueError that says what it must be and what
    to do (the model's error names the file, the table and the key). A NaN fails too."""
    if not lo <= value <= hi:
        raise ValueHint(f"{what} must be in {lo:g} .. {hi:g}", hint or "Check the value and"
                        " its unit (docs/errors.md gives every range and why)")
    return value


class Strict(BaseModel):
    """No unknown keys, numbers and flags as TOML gives them (a quoted "38.0" is refused), and
    every number finite (``nan`` and ``inf`` are refused where they are read)."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class Header(Strict):
    """A file's ``[problem]`` or ``[sweep]`` table: its name, machine and description."""

    name: str
    machine: str
    description: str = ""


class Bounds(Strict):
    """A parameter (as ``Machine.parameter_names``) and its range, in its file unit (mm, deg for
    angles)."""

    parameter: str
    lower: float
    upper: float

    @field_validator("lower", "upper")
    @classmethod
    def _size(cls, v):
        return check_range(v, -VALUE_LIMIT, VALUE_LIMIT, "a bound (mm, or deg for an angle)")

    @model_validator(mode="after")
    def _order(self):
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)
                and self.lower < self.upper):
            raise ValueError(f"need lower < upper, got {self.lower} .. {self.upper}")
        return self


class MetricRef(Strict):
    """A metric, at a regulator setting (deg) where it reads one, or a channel at phi_deg or at
    an event (``at``: ``max:CHANNEL``, ``min:CHANNEL``, ``rising:CHANNEL=LEVEL``,
    ``falling:CHANNEL=LEVEL``; a crossing the first at or after phi_deg)."""

    metric: str
    regulator_deg: float | None = None
    phi_deg: float = 0.0
    at: str | None = Field(None, min_length=1, max_length=200)

    @field_validator("regulator_deg")
    @classmethod
    def _setting(cls, v):
        if v is not None:
            check_range(v, -REGULATOR_LIMIT_DEG, REGULATOR_LIMIT_DEG, "a regulator setting (deg)")
        return v

    @field_validator("phi_deg")
    @classmethod
    def _angle(cls, v):
        return check_range(v, -ANGLE_LIMIT_DEG, ANGLE_LIMIT_DEG, "a shaft angle (deg)")


def check_limit(value: float | None, what: str = "a limit") -> float | None:
    """A metric's target or limit (its unit): None, or within +-:data:`VALUE_LIMIT`."""
    if value is not None:
        check_range(value, -VALUE_LIMIT, VALUE_LIMIT, f"{what} (in the metric's unit)")
    return value


def file_unit(unit: str) -> tuple[str, float]:
    """A parameter's unit in problem and sweep files, as in machine files and ``--set``
    (:data:`sewmech.engine.machine.FILE_UNITS`: deg, g, g cm) and the internal units per that
    unit (rad per deg, kg per g, kg mm per g cm; 1 for mm and the rest)."""
    from ..engine.machine import FILE_UNITS

    shown, per_internal = FILE_UNITS.get(unit, (unit, 1.0))
    return shown, 1.0 / per_internal


def check_bounds(where: str, table: str, k: int, b: Bounds, machine, factor: float,
                 start: float | None = None) -> None:
    """A parameter's bounds (and a start, file units; ``factor`` turns them into internal
    units) inside the parameter's own domain (:attr:`Machine.parameter_lo` ..
    ``parameter_hi``: a length positive, a setting input inside its declared range, ...): a
    design outside it is never evaluated, so a search or a sweep there could find nothing.
    Raises :class:`MachineFileError` at ``table[k].lower`` (``upper``, ``start``)."""
    from ..engine.machine import domain_message

    j = machine.parameter_names.index(b.parameter)
    lo, hi = float(machine.parameter_lo[j]), float(machine.parameter_hi[j])
    unit = machine.parameter_units[j]
    for key, value in (("lower", b.lower), ("upper", b.upper), ("start", start)):
        if value is None:
            continue
        x = value * factor
        if not lo <= x <= hi:
            what, hint = domain_message(b.parameter, x, unit, lo, hi, file_units=True)
            raise MachineFileError(where, table, f"{k}.{key}", f"{b.parameter} {what}", hint)


class DynamicsTable(Strict):
    """A ``[dynamics]`` table (problem and sweep files): the force analysis' speed (rev/min;
    default the machine file's), its grid of shaft angles (deg, dividing 360) and gravity."""

    rpm: float | None = Field(None, ge=MIN_RPM, le=20_000.0)
    step_deg: float = Field(2.0, ge=0.1, le=30.0)
    gravity: bool = True


def ref_key(ref) -> tuple:
    """The key of a metric reference in the evaluations' tables: (metric, regulator_deg,
    phi_deg), and the event where one is given."""
    key = (ref.metric, ref.regulator_deg, ref.phi_deg)
    at = getattr(ref, "at", None)
    return key if at is None else key + (at,)

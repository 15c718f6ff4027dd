"""Tolerance files: how accurately each dimension is made, validated where it enters.

```toml
[defaults]
it_grade = 9               # lengths without an entry: +- IT/2 of their nominal size (ISO 286-1)
angle_deg = 0.0            # angles without an entry, +- deg (0: held exact)
distribution = "normal"    # "normal": a tolerance is 3 standard deviations; "uniform": the band
exclude = ["O.x", "O.y"]   # parameters held exact

[parameters]               # +- mm for lengths, +- deg for angles, +- for ratios
"needle_bar.length" = 0.02
"regulator.phase" = 0.25

[cost]                     # allocation: making parameter j to +- t costs b_j / t (default b = 1)
"needle_bar.length" = 2.0
```

Every key is checked: an unknown parameter is named with the ones it resembles, a tolerance must
be a finite number >= 0, a grade one of the tabulated ones. Units: the file's mm and deg, turned
into internal mm and rad by :func:`tolerances_of`.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from ..engine.errors import MachineFileError, OptionError
from ..engine.machine import Machine
from ..engine.spec import ValueHint, load_toml_model
from ._models import Strict

#: ISO 286-1 nominal size ranges (upper limits, mm) and standard tolerances IT5 .. IT13 (um)
#: (ISO 286-1:2010, "Geometrical product specifications - ISO code system for tolerances on
#: linear sizes", Table 1)
IT_RANGES_MM = (3, 6, 10, 18, 30, 50, 80, 120, 180, 250, 315, 400, 500)
IT_TABLE_UM = {
    5: (4, 5, 6, 8, 9, 11, 13, 15, 18, 20, 23, 25, 27),
    6: (6, 8, 9, 11, 13, 16, 19, 22, 25, 29, 32, 36, 40),
    7: (10, 12, 15, 18, 21, 25, 30, 35, 40, 46, 52, 57, 63),
    8: (14, 18, 22, 27, 33, 39, 46, 54, 63, 72, 81, 89, 97),
    9: (25, 30, 36, 43, 52, 62, 74, 87, 100, 115, 130, 140, 155),
    10: (40, 48, 58, 70, 84, 100, 120, 140, 160, 185, 210, 230, 250),
    11: (60, 75, 90, 110, 130, 160, 190, 220, 250, 290, 320, 360, 400),
    12: (100, 120, 150, 180, 210, 250, 300, 350, 400, 460, 520, 570, 630),
    13: (140, 180, 220, 270, 330, 390, 460, 540, 630, 720, 810, 890, 970),
}


def it_tolerance_mm(nominal_mm: float, grade: int) -> float:
    """The standard tolerance (the whole band, mm) of grade ``grade`` for a nominal size (mm,
    its magnitude; up to 500 mm)."""
    size = abs(float(nominal_mm))
    if grade not in IT_TABLE_UM:
        raise OptionError("it_grade", f"IT{grade} is not tabulated",
                          f"Choose one of {', '.join(f'IT{g}' for g in IT_TABLE_UM)}")
    if size > IT_RANGES_MM[-1]:
        raise OptionError("it_grade", f"a nominal size of {size:g} mm is beyond the table's"
                          f" {IT_RANGES_MM[-1]} mm", "Give its tolerance in [parameters]")
    k = next(i for i, hi in enumerate(IT_RANGES_MM) if size <= hi)
    return IT_TABLE_UM[grade][k] * 1e-3


#: the widest tolerance a file may give, +- in the parameter's unit (mm, deg, or 1 for a
#: ratio): ten times the whole band of IT13 at 500 mm (0.97 mm), the coarsest the IT table has
MAX_TOLERANCE = 10.0
#: the largest cost weight (``[cost]``): weights are relative, 0 leaves a parameter free
MAX_COST = 1e6


class Defaults(Strict):
    it_grade: int | None = 9
    angle_deg: float = 0.0
    distribution: Literal["normal", "uniform"] = "normal"
    exclude: list[str] = Field(default_factory=list)

    @field_validator("it_grade")
    @classmethod
    def _grade(cls, v):
        if v is not None and v not in IT_TABLE_UM:
            raise ValueError(f"IT{v} is not tabulated; choose {min(IT_TABLE_UM)} ..."
                             f" {max(IT_TABLE_UM)}")
        return v

    @field_validator("angle_deg")
    @classmethod
    def _finite(cls, v):
        if not 0.0 <= v <= MAX_TOLERANCE:  # (a NaN fails too)
            raise ValueHint(f"a tolerance +- deg must be a finite number >= 0 and at most"
                            f" {MAX_TOLERANCE:g} deg", "Give the angles' tolerance, e.g. 0.05")
        return v


class ToleranceSpec(Strict):
    """A validated tolerance file (see the module docstring)."""

    defaults: Defaults = Field(default_factory=Defaults)
    parameters: dict[str, float] = Field(default_factory=dict)
    cost: dict[str, float] = Field(default_factory=dict)

    @field_validator("parameters")
    @classmethod
    def _values(cls, d):
        for k, v in d.items():
            if not (math.isfinite(v) and 0.0 <= v <= MAX_TOLERANCE):
                raise ValueHint(f"'{k}' = {v!r}: a tolerance is a finite number >= 0 and at"
                                f" most {MAX_TOLERANCE:g} (+- mm, deg, or 1 for a ratio)",
                                "Give the tolerance, e.g. 0.02 (mm); 0 holds it exact")
        return d

    @field_validator("cost")
    @classmethod
    def _costs(cls, d):
        for k, v in d.items():
            if not (math.isfinite(v) and 0.0 <= v <= MAX_COST):
                raise ValueHint(f"'{k}' = {v!r}: a cost weight is a finite number >= 0 and at"
                                f" most {MAX_COST:g} (weights are relative)",
                                "Give e.g. 2.0 (twice the default cost); 0 leaves it free")
        return d


def load_tolerance_file(path: str | Path) -> ToleranceSpec:
    """Read and validate a tolerance file; errors name the file and the key."""
    return load_toml_model(path, ToleranceSpec, "tolerance file", "docs/accuracy.md")


def _is_dimension(machine: Machine, j: int) -> bool:
    """A parameter that a drawing tolerances: not a setting input, a counterweight, a loop's
    starting guess or a speed ratio."""
    name = machine.parameter_names[j]
    cw = {c.name for c in machine.counterweights}
    return not (name.startswith("input.") or name.split(".")[0] in cw or ".init." in name
                or machine.parameter_units[j] not in ("mm", "rad"))


def tolerances_of(machine: Machine, spec: ToleranceSpec | None, where: str = "tolerances"
                  ) -> np.ndarray:
    """Each parameter's tolerance (+-, internal units: mm, rad; 0: held exact) from ``spec``
    (default: :class:`ToleranceSpec` defaults, IT9 on every length)."""
    spec = spec if spec is not None else ToleranceSpec()
    names = machine.parameter_names
    for table, keys in (("parameters", spec.parameters), ("cost", spec.cost),
                        ("defaults", {k: 0 for k in spec.defaults.exclude})):
        for k in keys:
            if k not in names:
                near = difflib.get_close_matches(k, names, n=3)
                hint = f"Did you mean {', '.join(near)}?" if near else \
                    f"`sewmech check {machine.name} --parameters` lists them"
                raise MachineFileError(where, table, k, f"'{k}' is not a parameter of"
                                       f" '{machine.name}'", hint)
    tol = np.zeros(len(names))
    d = spec.defaults
    for j, name in enumerate(names):
        unit = machine.parameter_units[j]
        if name in spec.parameters:
            v = spec.parameters[name]
            tol[j] = math.radians(v) if unit == "rad" else v
        elif name in d.exclude or not _is_dimension(machine, j):
            continue
        elif unit == "mm" and d.it_grade is not None:
            tol[j] = 0.5 * it_tolerance_mm(machine.defaults[j], d.it_grade)
        elif unit == "rad":
            tol[j] = math.radians(d.angle_deg)
    return tol


#: the angular tolerance (+- deg) that ranks the angles beside the lengths by their effect where
#: no tolerance file gives one (``sewmech sensitivity``): a point 30 mm from its pivot moves by
#: 0.026 mm when the angle moves by 0.05 deg, IT9's half-band on a length of 18-30 mm
RANKING_ANGLE_DEG = 0.05


def ranking_tolerances(machine: Machine, spec: ToleranceSpec | None = None,
                       where: str = "tolerances") -> np.ndarray:
    """The tolerances (+-, internal units) by which derivatives of different units are compared:
    a derivative times its parameter's tolerance is what that tolerance moves the output by.
    ``spec``'s (:func:`tolerances_of`), or by default IT9 on every length and
    +-:data:`RANKING_ANGLE_DEG` on every angle; 0 where a parameter is not a made dimension (a
    setting input, a speed ratio, a counterweight, a loop's starting guess)."""
    if spec is None:
        spec = ToleranceSpec(defaults=Defaults(angle_deg=RANKING_ANGLE_DEG))
    return tolerances_of(machine, spec, where)


def costs_of(machine: Machine, spec: ToleranceSpec | None) -> np.ndarray:
    """Each parameter's cost weight b_j (cost b_j / t_j of a tolerance +- t_j; default 1)."""
    b = np.ones(len(machine.parameter_names))
    for k, v in (spec.cost if spec is not None else {}).items():
        b[machine.parameter_names.index(k)] = v
    return b

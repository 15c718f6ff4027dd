"""The pieces the design layer's TOML files share (problem, sweep and tolerance files): the
strict base model, the file's header table, a parameter's bounds, a reference to a metric.
Each file's own models build on these; the files are read and validated by
:func:`sewmech.engine.spec.load_toml_model`."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, model_validator


class Strict(BaseModel):
    """No unknown keys, and numbers and flags as TOML gives them (a quoted "38.0" is refused)."""

    model_config = ConfigDict(extra="forbid", strict=True)


class Header(Strict):
    """A file's ``[problem]`` or ``[sweep]`` table: its name, machine and description."""

    name: str
    machine: str
    description: str = ""


class Bounds(Strict):
    """A parameter (as ``Machine.parameter_names``) and its range, in its file unit."""

    parameter: str
    lower: float
    upper: float

    @model_validator(mode="after")
    def _order(self):
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)
                and self.lower < self.upper):
            raise ValueError(f"need lower < upper, got {self.lower} .. {self.upper}")
        return self


class MetricRef(Strict):
    """A metric, at a regulator setting (deg) where it reads one, or a channel at phi_deg."""

    metric: str
    regulator_deg: float | None = None
    phi_deg: float = 0.0

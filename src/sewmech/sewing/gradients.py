"""Exact derivatives of the sewing metrics by every design parameter, by the chain rule from the
position sensitivities (:mod:`sewmech.engine.sensitivity`), events included.

An event angle moves with the design: where a channel crosses a level, y(phi*, p) = level, so
d phi*/dp = -(dy/dp) / (dy/dphi); a value read at the event moves by dx/dp + dx/dphi dphi*/dp.
(At an extremum dy/dphi = 0 and the value's derivative is just dy/dp.)

The stitch length is the dog's travel between rising through the throat plate and dropping
through it again (:func:`sewmech.sewing.feed.feed_cycles`):
stitch = fwd (x(phi_fall) - x(phi_rise)) with y(phi_rise) = y(phi_fall) = plate.

Units: mm per parameter unit (mm, rad, 1); the regulator's input ``input.NAME`` is a parameter
too (mm per rad of regulator setting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engine.errors import AnalysisError
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from ..engine.sensitivity import sensitivities
from .feed import _roles, feed_cycles


@dataclass(frozen=True)
class Gradient:
    """A metric's value (its unit), its derivative by every parameter (``d_dparam``, aligned
    with ``parameter_names``), and the event angles it was read at (deg)."""

    metric: str
    value: float
    unit: str
    parameter_names: tuple[str, ...]
    d_dparam: np.ndarray
    events_deg: dict

    def as_dict(self) -> dict[str, float]:
        return {n: float(x) for n, x in zip(self.parameter_names, self.d_dparam)}


def crossing_angles(machine: Machine, point: str, level: float, phi0: np.ndarray, *,
                    params=None, inputs=None, tol: float = 1e-12, max_iter: int = 20
                    ) -> np.ndarray:
    """The shaft angles (rad) near ``phi0`` where ``point``'s height equals ``level`` (mm), by
    Newton's method on the exact kinematics."""
    phi = np.array(phi0, dtype=float)
    for _ in range(max_iter):
        r = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0, points=[point],
                       links=[], variables=[])
        pm = r.point(point)
        y = pm.p[..., 1] - level
        step = y / pm.v[..., 1]  # (omega = 1: v is d/dphi)
        phi = phi - step
        if np.all(np.abs(y) <= tol * max(1.0, abs(level))):
            return phi
    raise AnalysisError(f"machine '{machine.name}'", f"the crossing of {point} with the level"
                        f" {level:g} mm did not converge near {np.degrees(phi0)} deg")


def stitch_length_gradient(machine: Machine, regulator_deg: float, *, params=None) -> Gradient:
    """The signed stitch length (mm, + forward) at a regulator setting (deg) and its exact
    derivative by every parameter (mm per parameter unit), the rise and fall through the plate
    located to 1e-12 mm and differentiated with the design."""
    s = _roles(machine)
    c = feed_cycles(machine, regulator_deg, params=params)
    if not (np.isfinite(c.rise_deg) and np.isfinite(c.fall_deg)):
        raise AnalysisError(f"machine '{machine.name}'", f"at regulator {regulator_deg:g} deg"
                            " the feed dog does not rise through the plate and drop again: no"
                            " stitch length to differentiate", "Choose a setting that feeds")
    inputs = {s.regulator: math.radians(regulator_deg)}
    dog = s.feed_dog
    phi = crossing_angles(machine, dog, s.plate_y, np.radians([float(c.rise_deg),
                                                               float(c.fall_deg)]),
                          params=params, inputs=inputs)
    S = sensitivities(machine, phi, params=params, inputs=inputs)
    x, dx, _ = S.channel(f"p_{dog}_x")
    _, dy, _ = S.channel(f"p_{dog}_y")
    rate = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0, points=[dog],
                      links=[], variables=[]).point(dog).v  # d/dphi
    dphi = -dy / rate[..., 1, None]
    dX = dx + rate[..., 0, None] * dphi
    fwd = 1.0 if s.forward == "+x" else -1.0
    return Gradient("stitch_length", float(fwd * (x[1] - x[0])), "mm",
                    machine.parameter_names, fwd * (dX[1] - dX[0]),
                    {"rise": float(np.degrees(phi[0])), "fall": float(np.degrees(phi[1]))})

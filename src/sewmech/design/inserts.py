"""Building a counterweight: the drilled lead insert of the balancing paper.

The balancing paper in our sources puts the extra counterweight on the main shaft as a split
steel block with a hole at radius r from the shaft's axis, filled with lead, and builds it 2.5 to
3 times stronger than computed (a margin for the errors of the model). The machine is then
measured, and the counterweight is trimmed by drilling holes into the lead until the x and y
vibration velocities are equal (:mod:`sewmech.design.vibration`). This module sizes the insert
and the trimming holes.

A hole of diameter d and depth h whose axis is at radius r from the shaft, filled with a
material of density rho_f in a body of density rho_b, adds the static moment

    S = (rho_f - rho_b) * pi d^2 / 4 * h * r

(the hole's material replaces the body's, and a slender hole's mass acts at its axis); a hole
drilled into the lead removes rho_f * pi d^2 / 4 * h * r.

Units: static moments g cm, lengths mm, masses g, densities kg/m^3 (:data:`MATERIALS`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..engine.errors import OptionError
from ..engine.mass import MATERIALS

_G_PER_MM3 = 1e-6  # kg/m^3 -> g/mm^3
_GMM_PER_GCM = 10.0

#: the paper's margin: the built counterweight's static moment over the computed one
FACTOR = (2.5, 3.0)


@dataclass(frozen=True)
class Insert:
    """A filled hole: diameter_mm, depth_mm, radius_mm (of its axis), filler and body
    materials, the filler's mass_g, the body material it replaces (removed_g), and the static
    moment it adds, s_gcm."""

    diameter_mm: float
    depth_mm: float
    radius_mm: float
    filler: str
    body: str
    mass_g: float
    removed_g: float
    s_gcm: float

    def to_json(self) -> dict:
        return asdict(self)


def _density(name: str, option: str) -> float:
    if name not in MATERIALS:
        raise OptionError(option, f"unknown material {name!r}",
                          f"Choose one of {', '.join(MATERIALS)}")
    return MATERIALS[name] * _G_PER_MM3


def _positive(**values) -> None:
    for k, v in values.items():
        if v is not None and not (math.isfinite(v) and v > 0):
            raise OptionError(k, f"must be a number > 0, got {v!r}")


def insert(s_gcm: float, radius_mm: float, *, depth_mm: float | None = None,
           diameter_mm: float | None = None, filler: str = "lead",
           body: str = "steel") -> Insert:
    """The filled hole at ``radius_mm`` that adds the static moment ``s_gcm`` (g cm): give its
    depth (e.g. the block's thickness) for the diameter, or its diameter for the depth."""
    _positive(s_gcm=s_gcm, radius_mm=radius_mm, depth_mm=depth_mm, diameter_mm=diameter_mm)
    if (depth_mm is None) == (diameter_mm is None):
        raise OptionError("depth_mm", "give the hole's depth or its diameter (one of them)")
    rf, rb = _density(filler, "filler"), _density(body, "body")
    if not rf > rb:
        raise OptionError("filler", f"{filler} is not denser than {body}: filling a hole with"
                          " it removes static moment", "Use lead in steel or cast iron")
    s_gmm = s_gcm * _GMM_PER_GCM
    area = s_gmm / ((rf - rb) * radius_mm * (depth_mm if depth_mm is not None else 1.0))
    if depth_mm is not None:
        d, h = math.sqrt(4.0 * area / math.pi), depth_mm
    else:
        d = diameter_mm
        h = s_gmm / ((rf - rb) * radius_mm * math.pi * d * d / 4.0)
    vol = math.pi * d * d / 4.0 * h
    return Insert(d, h, radius_mm, filler, body, rf * vol, rb * vol,
                  (rf - rb) * vol * radius_mm / _GMM_PER_GCM)


def trim_hole(s_remove_gcm: float, radius_mm: float, depth_mm: float,
              material: str = "lead") -> float:
    """Diameter (mm) of a hole of ``depth_mm`` at ``radius_mm`` drilled into ``material`` that
    removes the static moment ``s_remove_gcm`` (g cm)."""
    _positive(s_remove_gcm=s_remove_gcm, radius_mm=radius_mm, depth_mm=depth_mm)
    rho = _density(material, "material")
    return math.sqrt(4.0 * s_remove_gcm * _GMM_PER_GCM / (math.pi * rho * radius_mm * depth_mm))


def build_extra(s_add_gcm: float, radius_mm: float, depth_mm: float, *,
                factor: float = 3.0, filler: str = "lead", body: str = "steel") -> dict:
    """The paper's extra counterweight for a computed static moment ``s_add_gcm`` (g cm): built
    ``factor`` (2.5 .. 3) times stronger with a filled hole of ``depth_mm`` at ``radius_mm``,
    and the hole to drill into the filler, at the same radius and depth, that brings it back to
    the computed value (the starting point of the measured trimming). Returns a dict with
    s_add_gcm, factor, s_built_gcm, insert (:class:`Insert` as a dict), trim_diameter_mm and
    the steel alternative: the mass (g) a plain steel counterweight of the same static moment
    needs at the same radius."""
    _positive(s_add_gcm=s_add_gcm, factor=factor)
    if not (FACTOR[0] <= factor <= FACTOR[1]):
        raise OptionError("factor", f"{factor:g} is outside the paper's margin"
                          f" {FACTOR[0]:g} .. {FACTOR[1]:g}", "Give e.g. 3")
    built = factor * s_add_gcm
    ins = insert(built, radius_mm, depth_mm=depth_mm, filler=filler, body=body)
    return {"s_add_gcm": s_add_gcm, "factor": factor, "s_built_gcm": built,
            "insert": ins.to_json(),
            "trim_diameter_mm": trim_hole(built - s_add_gcm, radius_mm, depth_mm, filler),
            "steel_only_mass_g": built * _GMM_PER_GCM / radius_mm}

"""Building a counterweight: the drilled lead insert of the balancing paper.

The balancing paper in our sources puts the extra counterweight on the main shaft as a split
steel block with a hole at radius r from the shaft's axis, filled with lead, and builds it 2.5 to
3 times stronger than computed (a margin for the errors of the model). The machine is then
measured, and the counterweight is trimmed by drilling holes into the lead until the x and y
vibration velocities are equal (:mod:`sewmech.design.vibration`). This module sizes the insert
so that the lead can take the whole margin, what the steel block must supply besides, and the
trimming holes.

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


def build_extra(s_add_gcm: float, radius_mm: float, *, depth_mm: float | None = None,
                diameter_mm: float | None = None, factor: float = 3.0, filler: str = "lead",
                body: str = "steel") -> dict:
    """The paper's extra counterweight for a computed static moment ``s_add_gcm`` (g cm): built
    ``factor`` (2.5 .. 3) times stronger, a block of ``body`` material with a hole at
    ``radius_mm`` filled with ``filler``, to be trimmed back on the machine by drilling into
    the filler. The insert holds just enough filler for the whole margin: drilled out
    completely it removes (factor - 1) * S_add, so its volume is
    V = (factor - 1) S_add / (rho_filler r); its depth is ``depth_mm`` (default: the radius) or
    follows from ``diameter_mm``. The block supplies the rest of the static moment.

    Returns a dict (g cm, mm, g): s_add_gcm, factor, s_built_gcm; insert (:class:`Insert` as a
    dict, its s_gcm the filler's gain over the body material it replaces); hole_edge_mm, the
    distance from the shaft's axis to the hole's inner edge (it must clear the shaft's bore);
    body_s_gcm and body_mass_g, what the block itself must supply (its mass as if at the same
    radius); trim_diameter_mm, the hole into the filler (of the insert's depth, at its radius)
    that brings the counterweight back to S_add, the starting point of the measured trimming;
    trim_diameter_body_mm, the same hole drilled into the body material instead; and
    body_only_mass_g, the mass of a plain block of the body material at that radius with the
    built static moment."""
    _positive(s_add_gcm=s_add_gcm, factor=factor, radius_mm=radius_mm)
    if not (FACTOR[0] <= factor <= FACTOR[1]):
        raise OptionError("factor", f"{factor:g} is outside the paper's margin"
                          f" {FACTOR[0]:g} .. {FACTOR[1]:g}", "Give e.g. 3")
    rf, rb = _density(filler, "filler"), _density(body, "body")
    built = factor * s_add_gcm
    remove = built - s_add_gcm
    volume = remove * _GMM_PER_GCM / (rf * radius_mm)  # mm^3 of filler
    if depth_mm is None and diameter_mm is None:
        depth_mm = radius_mm
    if depth_mm is not None and diameter_mm is not None:
        raise OptionError("depth_mm", "give the hole's depth or its diameter (one of them)")
    if depth_mm is not None:
        _positive(depth_mm=depth_mm)
        diameter_mm = math.sqrt(4.0 * volume / (math.pi * depth_mm))
    gain = (rf - rb) * volume * radius_mm / _GMM_PER_GCM
    ins = insert(gain, radius_mm, diameter_mm=diameter_mm, filler=filler, body=body)
    body_s = built - ins.s_gcm
    return {"s_add_gcm": s_add_gcm, "factor": factor, "s_built_gcm": built,
            "insert": ins.to_json(), "hole_edge_mm": radius_mm - ins.diameter_mm / 2.0,
            "body_s_gcm": body_s, "body_mass_g": body_s * _GMM_PER_GCM / radius_mm,
            "trim_diameter_mm": trim_hole(remove, radius_mm, ins.depth_mm, filler),
            "trim_diameter_body_mm": trim_hole(remove, radius_mm, ins.depth_mm, body),
            "body_only_mass_g": built * _GMM_PER_GCM / radius_mm}

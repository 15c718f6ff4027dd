"""Building a counterweight: the drilled lead insert of the balancing paper.

The balancing paper in our sources puts the extra counterweight on the main shaft as a steel
block with a hole at radius r from the shaft's axis, filled with lead, and builds it 2.5 to 3
times stronger than computed (a margin for the errors of the model). The machine is then
measured, and the counterweight is trimmed by drilling holes into the lead until the x and y
vibration velocities are equal (:mod:`sewmech.design.vibration`). This module sizes the insert
so that the lead can take the whole margin, and the part around it so that it can be made.

A hole of diameter d and depth h whose axis is at radius r from the shaft, filled with a
material of density rho_f in a body of density rho_b, adds the static moment

    S = (rho_f - rho_b) * pi d^2 / 4 * h * r

(the hole's material replaces the body's, and a slender hole's mass acts at its axis); a hole
drilled into the lead removes rho_f * pi d^2 / 4 * h * r.

The part (:func:`build_extra`): a steel cup, a cylinder whose axis is parallel to the shaft at
radius r, with a blind hole on its axis that holds the lead; it is clamped to the shaft by a
split collar, whose static moment about the axis is nil and is not counted. Its size is not
free: the lead holds the margin, (factor - 1) S_add, and the steel is then S_add / r of mass,
so both volumes are fixed; the cup must clear the shaft (outer diameter at most 2 r - bore)
and keep a stated wall of steel round the lead and under it. When no cup does, the recipe is
refused with what to change, never given with a hole that cuts into the shaft.

Units: static moments g cm, lengths mm, masses g, densities kg/m^3 (:data:`MATERIALS`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..engine.errors import AnalysisError, OptionError
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
    if d >= 2.0 * radius_mm:
        raise OptionError("diameter_mm" if depth_mm is None else "depth_mm",
                          f"the hole would be {d:.3g} mm across at {radius_mm:g} mm from the"
                          " axis: it would cross the axis", "Give a deeper hole (a smaller"
                          " diameter) or a larger radius")
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


#: the least steel between the lead and anything else (the shaft, the cup's outside, its
#: bottom), mm: what the recipe keeps unless told otherwise
WALL_MM = 2.0

#: the margins tried when none is given, strongest first (the paper's 3 down to its 2.5)
FACTORS = (3.0, 2.9, 2.8, 2.7, 2.6, 2.5)


class NotBuildable(AnalysisError):
    """No lead-insert counterweight within the stated limits holds the margin: ``where`` is
    the counterweight (its table in the machine file when the caller names it), the message
    says which limit fails and the hint what to change."""


@dataclass(frozen=True)
class _Cup:
    """One candidate: the cup's diameter D and length T, the hole's d and h, mm."""

    D: float
    T: float
    d: float
    h: float


def _cup(volume: float, steel: float, room: float, wall: float, depth: float | None,
         diameter: float | None) -> _Cup | str:
    """The shortest steel cup (outer diameter at most ``room``) that holds ``volume`` mm^3 of
    filler in a blind hole with ``wall`` mm of steel round it and under it, the cup's whole
    steel being ``steel`` mm^3; the hole's ``depth`` or ``diameter`` if given. A string says
    why there is none.

    The cup's volume is fixed (steel + filler: pi/4 D^2 T), so the widest cup is the
    shortest. With the hole as wide as the side walls allow (d = D - 2 w) the bottom left,
    T - h, is g(D) + w with g(D) = 4 (steel + volume) / (pi D^2) - 4 volume / (pi (D - 2w)^2)
    - w, which rises to one maximum, at D* = 2 w / (1 - (volume / (steel + volume))^(1/3)),
    and falls after it: the answer is the largest D <= room with g(D) >= 0."""
    total = steel + volume
    if depth is not None or diameter is not None:
        if depth is not None:
            h = depth
            d = math.sqrt(4.0 * volume / (math.pi * h))
        else:
            d = diameter
            h = 4.0 * volume / (math.pi * d * d)
        D = min(room, math.sqrt(4.0 * total / (math.pi * (h + wall))))
        if D < d + 2.0 * wall:
            return (f"a hole {d:.3g} mm across and {h:.3g} mm deep needs a cup at least"
                    f" {d + 2.0 * wall:.3g} mm across, and a cup of this steel that covers"
                    f" its depth is at most {D:.3g} mm across"
                    + (f" (the room round the shaft: {room:.3g} mm)" if D == room else ""))
        return _Cup(D, 4.0 * total / (math.pi * D * D), d, h)

    def g(D):
        return 4.0 * total / (math.pi * D * D) - 4.0 * volume / (math.pi * (D - 2.0 * wall) ** 2) \
            - wall

    if room <= 2.0 * wall:
        return f"the room round the shaft, {room:.3g} mm across, is no more than two walls"
    D_star = 2.0 * wall / (1.0 - (volume / total) ** (1.0 / 3.0))
    if g(room) >= 0.0:
        D = room
    elif D_star < room and g(D_star) >= 0.0:
        from scipy.optimize import brentq

        D = brentq(g, D_star, room, xtol=1e-13 * room)
    else:
        return (f"the steel ({steel:.4g} mm^3) cannot enclose the filler ({volume:.4g} mm^3)"
                f" with {wall:g} mm walls in a cup at most {room:.3g} mm across")
    d = D - 2.0 * wall
    return _Cup(D, 4.0 * total / (math.pi * D * D), d, 4.0 * volume / (math.pi * d * d))


def _plan(s_add_gcm: float, radius_mm: float, bore_mm: float, wall_mm: float, factor: float,
          rf: float, rb: float, depth_mm, diameter_mm) -> _Cup | str:
    s_add = s_add_gcm * _GMM_PER_GCM  # g mm
    volume = (factor - 1.0) * s_add / (rf * radius_mm)  # the filler: the whole margin
    steel = s_add / (rb * radius_mm)  # what is left with the filler drilled out is S_add
    return _cup(volume, steel, 2.0 * (radius_mm - bore_mm / 2.0), wall_mm, depth_mm,
                diameter_mm)


def build_extra(s_add_gcm: float, radius_mm: float, *, bore_mm: float,
                wall_mm: float = WALL_MM, depth_mm: float | None = None,
                diameter_mm: float | None = None, factor: float | None = None,
                max_s_gcm: float | None = None, filler: str = "lead", body: str = "steel",
                where: str = "lead insert") -> dict:
    """The paper's extra counterweight for a computed static moment ``s_add_gcm`` (g cm), built
    ``factor`` (2.5 .. 3) times stronger and trimmed back on the machine by drilling into the
    filler, as a part that can be made: a steel cup (a cylinder of ``body`` material) whose
    axis is parallel to the shaft at ``radius_mm`` (the counterweight's radius), with a blind
    hole on that axis filled with ``filler``.

    The filler holds just the whole margin: drilled out completely it removes
    (factor - 1) S_add, so its volume is V = (factor - 1) S_add / (rho_filler r), and the steel
    left is S_add / r of mass. The cup clears the shaft, a bore of ``bore_mm`` (its diameter),
    so its outer diameter D is at most 2 r - bore; the hole has at least ``wall_mm`` of steel
    round it and under it (so its edge stays bore / 2 + wall from the shaft's axis). Of the
    cups that hold it the shortest is chosen (:func:`_cup`); ``depth_mm`` or ``diameter_mm``
    fix the hole instead. ``factor`` None: the strongest of :data:`FACTORS` that can be built
    and stays within ``max_s_gcm`` (the space's limit, g cm; None: no limit).

    Raises :class:`NotBuildable` (``where`` names the counterweight) when no cup within these
    limits holds the margin, with what to change.

    Returns a dict (g cm, mm, g): s_add_gcm, factor, s_built_gcm; insert (:class:`Insert` as a
    dict, its s_gcm the filler's gain over the body material it replaces); block (the cup:
    diameter_mm, length_mm, radius_mm of its axis, side_wall_mm, bottom_mm, steel_g, mass_g,
    swept_radius_mm the circle it turns in); bore_mm, wall_mm; hole_edge_mm, the distance from
    the shaft's axis to the hole's inner edge, and clearance_mm, the steel between the hole and
    the bore (at least wall_mm); body_s_gcm and body_mass_g, the cup as if solid steel;
    trim_diameter_mm, the hole into the filler (of the insert's depth, at its radius) that
    brings the counterweight back to S_add, the starting point of the measured trimming;
    trim_diameter_body_mm, the same hole drilled into the body material instead; and
    body_only_mass_g, the mass of a plain block of the body material at that radius with the
    built static moment."""
    _positive(s_add_gcm=s_add_gcm, radius_mm=radius_mm, bore_mm=bore_mm, wall_mm=wall_mm,
              max_s_gcm=max_s_gcm)
    if depth_mm is not None and diameter_mm is not None:
        raise OptionError("depth_mm", "give the hole's depth or its diameter (one of them)")
    _positive(depth_mm=depth_mm, diameter_mm=diameter_mm)
    if factor is not None:
        _positive(factor=factor)
        if not (FACTOR[0] <= factor <= FACTOR[1]):
            raise OptionError("factor", f"{factor:g} is outside the paper's margin"
                              f" {FACTOR[0]:g} .. {FACTOR[1]:g}", "Give e.g. 3")
    rf, rb = _density(filler, "filler"), _density(body, "body")
    if not rf > rb:
        raise OptionError("filler", f"{filler} is not denser than {body}: filling a hole with"
                          " it removes static moment", "Use lead in steel or cast iron")
    room = f"radius {radius_mm:g} mm on a {bore_mm:g} mm shaft"
    if radius_mm - bore_mm / 2.0 <= wall_mm:
        raise NotBuildable(where, f"the counterweight's radius {radius_mm:g} mm leaves"
                           f" {radius_mm - bore_mm / 2.0:.3g} mm outside the {bore_mm:g} mm"
                           f" shaft: no room for a hole with {wall_mm:g} mm walls",
                           "Give it a larger radius_mm")
    factors = FACTORS if factor is None else (factor,)
    why = {}
    over_limit = False
    for f in factors:
        over_limit = max_s_gcm is not None and f * s_add_gcm > max_s_gcm * (1.0 + 1e-12)
        if over_limit:
            why[f] = (f"built {f:g} x it has {f * s_add_gcm:.4g} g cm, more than the"
                      f" {max_s_gcm:g} g cm the space allows (max_static_moment_gcm)")
            continue
        plan = _plan(s_add_gcm, radius_mm, bore_mm, wall_mm, f, rf, rb, depth_mm, diameter_mm)
        if isinstance(plan, str):
            why[f] = plan
            continue
        return _recipe(s_add_gcm, radius_mm, bore_mm, wall_mm, f, plan, filler, body, rf, rb,
                       lowered=factor is None and f < FACTORS[0], why=why)
    last = factors[-1]
    text = (f"no lead-insert counterweight of S_add = {s_add_gcm:.4g} g cm at {room} can be"
            f" built: {why[last]}" + (f" (even with the paper's least margin, {last:g} x)"
                                      if len(factors) > 1 else ""))
    raise NotBuildable(where, text, _what_to_change(s_add_gcm, radius_mm, bore_mm, wall_mm,
                                                    last, rf, rb, depth_mm, diameter_mm,
                                                    over_limit))


def _what_to_change(s_add_gcm, radius_mm, bore_mm, wall_mm, factor, rf, rb, depth_mm,
                    diameter_mm, over_limit: bool) -> str:
    """The hint of a counterweight that cannot be built: the limit to raise, or the radii
    that would hold it."""
    if over_limit:
        return (f"Allow it {factor * s_add_gcm:.4g} g cm (max_static_moment_gcm) if the space"
                f" has room, or build it plain: {s_add_gcm * _GMM_PER_GCM / radius_mm:.3g} g of"
                " steel at its radius, without a margin to trim")
    ok = [r for r in np.linspace(bore_mm / 2.0 + wall_mm, 4.0 * radius_mm, 400)[1:]
          if not isinstance(_plan(s_add_gcm, r, bore_mm, wall_mm, factor, rf, rb, depth_mm,
                                  diameter_mm), str)]
    free = "Leave the hole's size free, or give" if depth_mm or diameter_mm else "Give"
    if ok:
        return (f"{free} the counterweight a radius_mm between {min(ok):.3g} and"
                f" {max(ok):.3g} mm and balance again (its mass is S / r), or allow walls"
                f" thinner than {wall_mm:g} mm")
    return (f"No radius holds it with {wall_mm:g} mm walls: allow thinner walls"
            f"{' or leave the hole free' if depth_mm or diameter_mm else ''}, or build it"
            f" plain: {s_add_gcm * _GMM_PER_GCM / radius_mm:.3g} g of steel at its radius,"
            " without a margin to trim")


def _recipe(s_add_gcm, radius_mm, bore_mm, wall_mm, factor, cup: _Cup, filler, body, rf, rb,
            lowered: bool, why: dict) -> dict:
    built = factor * s_add_gcm
    remove = built - s_add_gcm
    ins = insert((rf - rb) * math.pi * cup.d ** 2 / 4.0 * cup.h * radius_mm / _GMM_PER_GCM,
                 radius_mm, diameter_mm=cup.d, filler=filler, body=body)
    body_s = built - ins.s_gcm
    steel_g = s_add_gcm * _GMM_PER_GCM / radius_mm
    edge = radius_mm - ins.diameter_mm / 2.0
    out = {"s_add_gcm": s_add_gcm, "factor": factor, "s_built_gcm": built,
           "insert": ins.to_json(),
           "block": {"shape": "cylinder", "diameter_mm": cup.D, "length_mm": cup.T,
                     "radius_mm": radius_mm, "side_wall_mm": (cup.D - cup.d) / 2.0,
                     "bottom_mm": cup.T - cup.h, "steel_g": steel_g,
                     "mass_g": steel_g + ins.mass_g, "swept_radius_mm": radius_mm + cup.D / 2.0},
           "bore_mm": bore_mm, "wall_mm": wall_mm, "hole_edge_mm": edge,
           "clearance_mm": edge - bore_mm / 2.0,
           "body_s_gcm": body_s, "body_mass_g": body_s * _GMM_PER_GCM / radius_mm,
           "trim_diameter_mm": trim_hole(remove, radius_mm, ins.depth_mm, filler),
           "trim_diameter_body_mm": trim_hole(remove, radius_mm, ins.depth_mm, body),
           "body_only_mass_g": built * _GMM_PER_GCM / radius_mm}
    if lowered:
        out["factor_note"] = (f"{factor:g} x, not {FACTORS[0]:g} x: "
                              + "; ".join(f"{f:g} x: {w}" for f, w in why.items()))
    return out

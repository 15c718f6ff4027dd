"""The embroidery paper's design method for its double-crank thread take-up ([Kozlov-take-up]),
as a synthesis that writes a machine file.

From the thread the base machine draws per cycle (l2, the "stroke" of the take-up: 124 mm for
the class 131) and its needle crank AB (17.5 mm): the drag-link four-bar ABCD from the paper's
relative lengths K1 = BC/AB, K2 = DC/AB, K3 = AD/AB (0.93, 0.62, 0.38), the crank DE = l2 / 4,
the rod EF (the paper: 2 - 2.5 DE; it took 80 mm = 2.58 DE for l2 = 124, which is the default
ratio here), and the frame angle alpha and the angle beta from the paper's two design positions
(phi1 = 60 deg, phi2 = phi1 + 240 deg, the angle C1 D C2 = 180 deg), computed by
:func:`sewmech.sewing.embroidery.design`. The study of alpha and beta that follows is the one
sewmech already has (:mod:`sewmech.sewing.embroidery`); the machine file written here has the
same points and units as ``embroidery-131``, so that study runs on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .synthesis import SynthesisError, _fmt, grashof

#: the paper's relative lengths K1 = BC/AB, K2 = DC/AB, K3 = AD/AB
PAPER_K = (0.93, 0.62, 0.38)
#: the rod EF over the crank DE in the paper's case: 80 mm for DE = 124 / 4 = 31 mm
PAPER_EF_RATIO = 80.0 / 31.0
#: the thread guides M and N: on the eye's line, this far below its lowest point and apart, mm
#: (our choice: the paper places them "from constructive considerations")
GUIDE_GAP_MM = 15.0


@dataclass(frozen=True)
class TakeUpSynthesis:
    """The embroidery take-up designed by the paper's method. Lengths mm, angles deg:
    ab, bc, cd, ad (the four-bar), de, ef; alpha_deg (the frame line AD from +x), beta_deg (DE
    clockwise from DC); text : the machine file; eye_top_deg, eye_bottom_deg : the shaft angles
    of the eye's extremes; drawn_mm : the thread drawn per cycle (2 x the eye's stroke: the
    paper's l2); dc_turn_deg : how far DC turns from phi1 to phi2 (180 by the method);
    grashof : the four-bar's type (a double crank); notes : free choices and findings."""

    ab: float
    bc: float
    cd: float
    ad: float
    de: float
    ef: float
    alpha_deg: float
    beta_deg: float
    design_alpha_deg: float
    design_beta_deg: float
    text: str
    eye_top_deg: float
    eye_bottom_deg: float
    drawn_mm: float
    dc_turn_deg: float
    grashof: object
    notes: tuple[str, ...] = field(default_factory=tuple)


def synthesize_take_up(*, crank_mm: float = 17.5, stroke_mm: float = 124.0,
                       k: tuple[float, float, float] = PAPER_K, ef_mm: float | None = None,
                       lengths_mm: tuple[float, float, float] | None = None,
                       alpha_deg: float | None = None, beta_deg: float | None = None,
                       phi1_deg: float = 60.0, phi12_deg: float = 240.0,
                       name: str = "take-up") -> TakeUpSynthesis:
    """The paper's take-up for a crank AB of ``crank_mm`` and thread drawn ``stroke_mm`` per
    cycle. ``lengths_mm`` (BC, CD, AD) replaces the K's by lengths as drawn (the paper prints
    16.3, 10.9, 6.6); ``alpha_deg``, ``beta_deg`` lay the file out at another pair than the
    design positions give (the study's choice: the paper took beta 35, alpha 10)."""
    from ..engine.kinematics import kinematics
    from ..engine.machine import load_machine, machine_from_toml
    from ..sewing.embroidery import design

    for opt, v in (("--crank-mm", crank_mm), ("--stroke-mm", stroke_mm)):
        if not (math.isfinite(v) and 0.0 < v <= 1e4):
            raise SynthesisError(opt, f"must be a length in (0, 10000] mm, got {v:g}")
    if lengths_mm is not None:
        bc, cd, ad = (float(v) for v in lengths_mm)
        if not all(math.isfinite(v) and v > 0 for v in (bc, cd, ad)):
            raise SynthesisError("--lengths-mm", "BC, CD and AD must be lengths > 0 mm")
        k = (bc / crank_mm, cd / crank_mm, ad / crank_mm)
    k1, k2, k3 = (float(v) for v in k)
    if not all(math.isfinite(v) and v > 0 for v in (k1, k2, k3)):
        raise SynthesisError("--k", f"K1, K2, K3 must be ratios > 0, got {k1:g}, {k2:g}, {k3:g}")
    ab = float(crank_mm)
    bc, cd, ad = k1 * ab, k2 * ab, k3 * ab
    g = grashof(ab, bc, cd, ad)
    if g.kind != "double-crank":
        raise SynthesisError("--k" if lengths_mm is None else "--lengths-mm", f"the four-bar"
                             f" AB {ab:g}, BC {bc:.4g}, CD {cd:.4g}, AD {ad:.4g} mm is a"
                             f" {g.text}, not the drag link (double crank) the take-up needs:"
                             " DC must turn fully with AB", "Make AD the shortest link with"
                             " AD + the longest <= the other two (the paper: K3 = 0.38 <"
                             " K2 = 0.62 < K1 = 0.93 < 1)")
    de = stroke_mm / 4.0
    ef = PAPER_EF_RATIO * de if ef_mm is None else float(ef_mm)
    if not (math.isfinite(ef) and ef > de):
        raise SynthesisError("--ef-mm", f"the rod EF ({ef:g} mm) must be longer than the crank DE"
                             f" ({de:g} mm), or F cannot follow E", "The paper: EF = 2 - 2.5 DE")
    template = load_machine("embroidery-131")
    try:
        d = design(template, ab=ab, k1=k1, k2=k2, k3=k3, l2=stroke_mm, ef=ef,
                   phi1_deg=phi1_deg, phi12_deg=phi12_deg)
    except ValueError as exc:
        raise SynthesisError("--k", f"no frame angle alpha turns DC by half a turn while AB turns"
                             f" {phi12_deg:g} deg from {phi1_deg:g} deg ({exc})", "Change the"
                             " relative lengths") from None
    alpha = d.alpha_deg if alpha_deg is None else float(alpha_deg)
    beta = d.beta_deg if beta_deg is None else float(beta_deg)
    notes = [f"AB {ab:g} mm; BC = K1 AB, DC = K2 AB, AD = K3 AB with K = {k1:.6g}, {k2:.6g},"
             f" {k3:.6g}" + (" (from the lengths given)" if lengths_mm is not None else ""),
             f"DE = l2 / 4 = {de:.6g} mm; EF = {ef:.6g} mm"
             + (f" ({PAPER_EF_RATIO:.4g} DE, the paper's own ratio: 80 mm for DE 31 mm)"
                if ef_mm is None else " (given)"),
             f"the design positions phi1 = {phi1_deg:g} deg, phi2 = {phi1_deg + phi12_deg:g}"
             f" deg with DC half a turn apart give alpha = {d.alpha_deg:.6g} deg and beta ="
             f" {d.beta_deg:.6g} deg (DE along the eye's line, up, at phi1)"]
    if alpha_deg is not None or beta_deg is not None:
        notes.append(f"laid out at alpha = {alpha:g} deg, beta = {beta:g} deg (given)")
    text = _text(name, ab, bc, cd, ad, de, ef, alpha, beta, 0.0, 0.0, notes)
    m = machine_from_toml(text, f"{name}.toml")
    phi = np.radians(np.arange(0.0, 360.0, 0.25))
    r = kinematics(m, phi, points=["F"], links=["DC"], variables=[], on_failure="mask")
    if not r.feasible.all():
        bad = float(np.degrees(phi[int(np.argmin(r.feasible))]))
        raise SynthesisError("--alpha-deg/--beta-deg", f"the take-up laid out at alpha ="
                             f" {alpha:g}, beta = {beta:g} deg cannot be assembled at phi ="
                             f" {bad:g} deg", "Lay it out at the design positions' angles")
    yF = r.point("F").p[:, 1]
    low = float(yF.min())
    m_y = low - GUIDE_GAP_MM
    n_y = m_y - GUIDE_GAP_MM
    text = _text(name, ab, bc, cd, ad, de, ef, alpha, beta, m_y, n_y, notes)
    top = float(np.degrees(phi[int(np.argmax(yF))]))
    bottom = float(np.degrees(phi[int(np.argmin(yF))]))
    p12 = np.radians(np.linspace(phi1_deg, phi1_deg + phi12_deg, 481))
    base = m.parameters({"E.u": de * math.cos(math.radians(-d.beta_deg)),
                         "E.v": de * math.sin(math.radians(-d.beta_deg)),
                         "D.x": ad * math.cos(math.radians(d.alpha_deg)),
                         "D.y": ad * math.sin(math.radians(d.alpha_deg))})
    th = np.unwrap(kinematics(m, p12, params=base, points=[], links=["DC"],
                              variables=[]).link("DC").theta)
    return TakeUpSynthesis(ab, bc, cd, ad, de, ef, alpha, beta, d.alpha_deg, d.beta_deg, text,
                           top, bottom, float(2.0 * np.ptp(yF)),
                           float(np.degrees(abs(th[-1] - th[0]))), g, tuple(notes))


def _text(name, ab, bc, cd, ad, de, ef, alpha, beta, m_y, n_y, notes) -> str:
    a, b = math.radians(alpha), math.radians(beta)
    dx, dy = ad * math.cos(a), ad * math.sin(a)
    eu, ev = de * math.cos(-b), de * math.sin(-b)
    head = "".join(f"# {line}\n" for line in notes)
    return f"""# The double-crank thread take-up of an embroidery semi-automatic, designed by the
# method of A. Z. Kozlov ([Kozlov-take-up]) with `sewmech synthesize embroidery-take-up`.
{head}# Conventions as embroidery-131 (docs/embroidery.md): A on the main shaft at the origin,
# phi = 0 at the needle's top with AB up, counter-clockwise; C left of B -> D; F above E on the
# vertical through D; the thread guides M and N on the eye's line below its lowest point.

[machine]
name = "{name}"
title = "Double-crank take-up (Kozlov's method): AB {ab:g}, l2 {4.0 * de:g} mm"

[convention]
reference_event = "needle at its top dead centre"
reference_phi_deg = 0.0
reference_link = "AB"
reference_angle_deg = 90.0

[speed]
rpm = 1000.0

[points.A]
x = 0.0
y = 0.0

[points.D]                    # AD at alpha from +x
x = {_fmt(dx)}
y = {_fmt(dy)}

[points.M]                    # thread guides on the eye's line, below its lowest point
x = {_fmt(dx)}
y = {_fmt(m_y)}

[points.N]
x = {_fmt(dx)}
y = {_fmt(n_y)}

[[units]]
type = "crank"
name = "AB"
pivot = "A"
phase_deg = 90.0
points = {{ B = [{_fmt(ab)}, 0.0] }}

[[units]]
type = "rrr"
name = "four_bar"
joints = ["B", "D"]
new = "C"
links = ["BC", "DC"]
lengths = [{_fmt(bc)}, {_fmt(cd)}]   # BC = K1 AB, DC = K2 AB
branch = 1

[[units]]
type = "point"
name = "crank_DE"
link = "DC"
origin = "D"
points = {{ E = [{_fmt(eu)}, {_fmt(ev)}] }}   # DE = l2 / 4 at beta clockwise from DC

[[units]]
type = "rrp"
name = "slider_F"
pin = "E"
rod = "EF"
length = {_fmt(ef)}
new = "F"
slider = "slider_F"
guide_point = "D"
guide_angle_deg = 90.0
variable = "F_travel"
branch = 1

[[units]]
type = "point"
name = "eye"
link = "slider_F"
origin = "F"
points = {{ Q = [0.0, 0.0] }}

[thread]
take_up = [0, 2]
guides = [ {{ point = "M" }}, {{ point = "Q" }}, {{ point = "N" }} ]
"""

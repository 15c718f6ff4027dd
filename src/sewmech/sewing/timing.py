"""Timing of stitch formation: loop lift, shuttle swing, take-up lag, the needle windows, and
the relative position of the hook drive on the upper shaft.

Everything here reads the machine through its ``[sewing]`` roles (needle point and eye, shuttle
link and point, take-up eye, throat plate), so it works for any lockstitch machine file. Angles
are returned in degrees (``*_deg``) because they are read by people; lengths in mm.

The bands the checks use are the published facts of the household oscillating-shuttle class
(docs/references.md): shuttle swing 206-210 deg (the encyclopaedia entry on household sewing
machines, [EC-household-machine]), loop lift 2.0-2.5 mm (Soviet household machines,
[Melnikov-seamstress]), the take-up eye's top lagging the needle's top
([Thread-holder-timing]).
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np

from ..engine.errors import MachineFileError
from ..engine.evaluation import evaluation
from ..engine.extremes import crossings, extremes
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from ..engine.spec import SewingSpec

SHUTTLE_SWING_DEG = (206.0, 210.0)  # [EC-household-machine]
LOOP_LIFT_MM = (2.0, 2.5)  # [Melnikov-seamstress]
# [Thread-holder-timing]: "a few millimeters (around 1/8 inch)"; read as 1.5-6 mm
NEEDLE_DESCENT_AT_TAKE_UP_TOP_MM = (1.5, 6.0)


def roles(machine: Machine) -> SewingSpec:
    """The machine's ``[sewing]`` table; a clear error if the file has none."""
    if machine.spec.sewing is None:
        raise ValueError(f"machine '{machine.name}' ({machine.file}) has no [sewing] table: add"
                         " one naming needle_point, needle_eye and plate_y (docs/machine-files.md)")
    return machine.spec.sewing


def _need(value, key: str, machine: Machine):
    if value is None:
        raise ValueError(f"machine '{machine.name}': [sewing] {key} is not set; this analysis"
                         f" needs it ({machine.file})")
    return value


def _wrap_deg(x: float) -> float:
    """Angle difference into (-180, 180] deg."""
    return -((-x + 180.0) % 360.0 - 180.0)


def _y(machine, point, phi, params):
    r = evaluation(machine, params).at([phi], points=[point], links=[], variables=[])
    return float(r.point(point).p[0, 1])


@dataclass(frozen=True)
class NeedleStroke:
    """Needle point dead centres: shaft angles (deg) and heights (mm, frame y)."""

    top_phi_deg: float
    top_y: float
    bottom_phi_deg: float
    bottom_y: float

    @property
    def stroke(self) -> float:
        """Needle-bar stroke, mm."""
        return self.top_y - self.bottom_y


def needle_stroke(machine: Machine, params=None) -> NeedleStroke:
    """Top and bottom dead centres of the needle point (to 1e-9 rad)."""
    ex = extremes(machine, f"p_{roles(machine).needle_point}_y", params=params)
    hi, lo = ex.maximum, ex.minimum
    return NeedleStroke(hi.phi_deg % 360.0, hi.value, lo.phi_deg % 360.0, lo.value)


@dataclass(frozen=True)
class LoopLift:
    """The moment the shuttle point passes the needle on its seizing pass.

    phi_deg: shaft angle; after_bdc_deg: shaft angle after the needle's bottom dead centre;
    rise_mm: needle rise from its bottom dead centre (the loop lift); point_above_eye_mm: height
    of the shuttle point above the needle eye; shuttle_deg: angle of the shuttle link.
    """

    phi_deg: float
    after_bdc_deg: float
    rise_mm: float
    point_above_eye_mm: float
    shuttle_deg: float


def loop_lift(machine: Machine, params=None) -> LoopLift:
    """Needle rise from BDC when the shuttle point first crosses the needle line after BDC.

    The needle line is the vertical through the needle point at BDC; the seizing pass is the
    first crossing after BDC with the shuttle point above its shaft axis.
    """
    s = roles(machine)
    sp = _need(s.shuttle_point, "shuttle_point", machine)
    link = _need(s.shuttle_link, "shuttle_link", machine)
    ns = needle_stroke(machine, params)
    bdc = math.radians(ns.bottom_phi_deg)
    ev = evaluation(machine, params)
    r_bdc = ev.at([bdc], points=[s.needle_point], links=[], variables=[])
    x_needle = float(r_bdc.point(s.needle_point).p[0, 0])
    axis = _shuttle_axis(machine)
    best = None
    for c in crossings(machine, f"p_{sp}_x", x_needle, params=params, phi0=bdc):
        r = ev.at([c.phi], points=[sp, axis, s.needle_point, s.needle_eye], links=[link],
                  variables=[])
        if r.point(sp).p[0, 1] > r.point(axis).p[0, 1]:
            best = (c.phi, r)
            break
    if best is None:
        raise ValueError(f"machine '{machine.name}': the shuttle point '{sp}' never passes the"
                         " needle line above its shaft axis; check the shuttle point and the"
                         " hook drive")
    phi, r = best
    y_pt = float(r.point(s.needle_point).p[0, 1])
    return LoopLift(
        phi_deg=math.degrees(phi) % 360.0,
        after_bdc_deg=math.degrees(phi - bdc),
        rise_mm=y_pt - ns.bottom_y,
        point_above_eye_mm=float(r.point(sp).p[0, 1] - r.point(s.needle_eye).p[0, 1]),
        shuttle_deg=math.degrees(float(r.link(link).theta[0])),
    )


def _shuttle_axis(machine: Machine) -> str:
    """The origin point of the unit that places the shuttle point (its shaft axis)."""
    sp = roles(machine).shuttle_point
    for u in machine.spec.units:
        if u.type == "point" and sp in u.points:
            return u.origin
    raise ValueError(f"machine '{machine.name}': the shuttle point '{sp}' must be placed by a"
                     " 'point' unit on the shuttle link, with the shaft axis as its origin")


@dataclass(frozen=True)
class Swing:
    """Extreme angles of an oscillating link (deg, shaft angles of the reversals) and swing."""

    min_deg: float
    min_phi_deg: float
    max_deg: float
    max_phi_deg: float
    swing_deg: float


def shuttle_swing(machine: Machine, params=None) -> Swing:
    """Angle range of the shuttle link over one revolution (reversals to 1e-9 rad)."""
    link = _need(roles(machine).shuttle_link, "shuttle_link", machine)
    ex = extremes(machine, f"theta_{link}", params=params)
    lo, hi = ex.minimum, ex.maximum
    # the swing is measured along the motion (the grid's angles between the two reversals),
    # so that it does not depend on the angle wrap
    a, b = sorted((lo.phi, hi.phi))
    g = evaluation(machine, params).grid
    inside = (g.phi > a) & (g.phi < b)
    th = np.unwrap(np.concatenate([[lo.value if a == lo.phi else hi.value],
                                   g.link(link).theta[inside],
                                   [hi.value if b == hi.phi else lo.value]]))
    return Swing(math.degrees(lo.value), lo.phi_deg % 360.0, math.degrees(hi.value),
                 hi.phi_deg % 360.0, abs(math.degrees(th[-1] - th[0])))


def needle_descent_at_take_up_top(machine: Machine, params=None) -> float:
    """How far (mm) the needle point has come down from its top when the take-up eye is at
    its highest ([Thread-holder-timing]: a few millimetres, about 1/8 in, on household machines)."""
    eye = _need(roles(machine).take_up_eye, "take_up_eye", machine)
    top = extremes(machine, f"p_{eye}_y", params=params).maximum
    return needle_stroke(machine, params).top_y - _y(machine, roles(machine).needle_point,
                                                     top.phi, params)


def take_up_lag_deg(machine: Machine, params=None) -> float:
    """Shaft angle by which the take-up eye's top follows the needle's top, deg (> 0: lags)."""
    eye = _need(roles(machine).take_up_eye, "take_up_eye", machine)
    top_eye = extremes(machine, f"p_{eye}_y", params=params).maximum.phi_deg
    return _wrap_deg(top_eye - needle_stroke(machine, params).top_phi_deg)


@dataclass(frozen=True)
class Window:
    """A shaft-angle window [start_deg, end_deg] (end may exceed 360 when it wraps)."""

    name: str
    start_deg: float
    end_deg: float

    @property
    def length_deg(self) -> float:
        return self.end_deg - self.start_deg

    def contains(self, phi_deg):
        """Mask of the shaft angles (deg, any range) inside the window."""
        return (np.asarray(phi_deg) - self.start_deg) % 360.0 <= self.length_deg


def below_level_window(machine: Machine, point: str, level: float, name: str,
                       params=None) -> Window:
    """Where ``point`` is below height ``level`` (mm): from its falling to its rising crossing."""
    cs = crossings(machine, f"p_{point}_y", level, params=params)
    down = [c for c in cs if c.direction < 0]
    up = [c for c in cs if c.direction > 0]
    if len(down) != 1 or len(up) != 1:
        raise ValueError(f"machine '{machine.name}': '{point}' crosses y = {level:g} mm"
                         f" {len(cs)} times per revolution; expected once down and once up")
    start = down[0].phi_deg % 360.0
    end = up[0].phi_deg % 360.0
    return Window(name, start, end if end > start else end + 360.0)


def needle_windows(machine: Machine, params=None) -> tuple[Window, Window]:
    """(needle point in the fabric, needle point below the throat plate)."""
    s = roles(machine)
    ns = needle_stroke(machine, params)
    lo, hi = ns.bottom_y, ns.top_y
    for key, level in (("plate_y", s.plate_y), ("fabric_thickness",
                                                s.plate_y + s.fabric_thickness)):
        if not lo < level < hi:
            what = "plate_y" if key == "plate_y" else "plate_y + fabric_thickness"
            raise MachineFileError(machine.file, "sewing", key, f"the needle point"
                                   f" '{s.needle_point}' moves between y = {lo:.6g} and"
                                   f" {hi:.6g} mm, so it never passes {what} = {level:g} mm",
                                   "Give the throat plate's top (frame y, mm) and the fabric"
                                   " so that the needle passes through them")
    return (below_level_window(machine, s.needle_point, s.plate_y + s.fabric_thickness,
                               "needle in fabric", params),
            below_level_window(machine, s.needle_point, s.plate_y, "needle below plate", params))


# ---- relative position of the hook drive ----------------------------------------------------------


@dataclass(frozen=True)
class HookTiming:
    """Settings that put the shuttle point at the needle at the target loop lift.

    overrides: parameter values (internal units) to pass to ``Machine.parameters``;
    phase_deg: the hook crank's phase on the upper shaft; point_uv: the shuttle point's local
    coordinates on the shuttle link (mm); meet_phi_deg: shaft angle of the meeting.
    """

    overrides: dict
    phase_deg: float
    point_uv: tuple[float, float]
    meet_phi_deg: float


def set_hook_timing(machine: Machine, loop_lift_mm: float = 2.2,
                    seize_after_reversal_deg: float = 25.0, params=None) -> HookTiming:
    """Phase the hook crank and place the shuttle point for a target loop lift.

    The shuttle point passes the needle line (at the top of its circle) when the needle has
    risen ``loop_lift_mm`` from bottom dead centre, at ``seize_after_reversal_deg`` of shuttle
    rotation after the shuttle's counter-clockwise swing begins (its angle minimum). This is the
    report's determination of the mechanisms' relative positions (各机构间相对位置的确定) for the
    hook: the crank phase sets *when*, the point's angle on the shuttle driver sets *where*.
    Requires the hook crank to turn with the shaft at ratio 1.
    """
    s = roles(machine)
    crank = _need(s.hook_crank, "hook_crank", machine)
    link = _need(s.shuttle_link, "shuttle_link", machine)
    sp = _need(s.shuttle_point, "shuttle_point", machine)
    spec = next(u for u in machine.spec.units if u.name == crank)
    if spec.ratio != 1.0 or spec.input != "shaft":
        raise ValueError(f"hook crank '{crank}' must turn with the shaft at ratio 1")
    p = machine.defaults if params is None else np.asarray(params, dtype=float)
    ns = needle_stroke(machine, p)
    # 1. when: the shaft angle at which the needle has risen loop_lift_mm after BDC
    bdc = math.radians(ns.bottom_phi_deg)
    rise = [c for c in crossings(machine, f"p_{s.needle_point}_y", ns.bottom_y + loop_lift_mm,
                                 params=p, phi0=bdc) if c.direction > 0]
    if not rise or not 0.0 < loop_lift_mm < ns.stroke:
        raise ValueError(f"loop lift {loop_lift_mm} mm is outside the needle stroke"
                         f" ({ns.stroke:.3f} mm)")
    phi_meet = rise[0].phi
    # 2. the shaft angle (at the present phase) where the shuttle is seize_after_reversal_deg
    #    past its minimum, moving counter-clockwise
    sw = shuttle_swing(machine, p)
    if not 0.0 < seize_after_reversal_deg < sw.swing_deg:
        raise ValueError(f"seize_after_reversal_deg must lie inside the shuttle swing"
                         f" (0, {sw.swing_deg:.1f}) deg")
    lo = math.radians(sw.min_phi_deg)
    theta_target = math.radians(sw.min_deg + seize_after_reversal_deg)
    lvl = [c for c in crossings(machine, f"theta_{link}", _wrap_rad(theta_target), params=p,
                                phi0=lo) if c.direction > 0]
    phi_s = lvl[0].phi
    # 3. shift the crank phase: with ratio 1 a phase change is a shift of the shaft angle
    i_phase = machine.parameter_index(f"{crank}.phase")
    new_phase = float(p[i_phase] + (phi_s - phi_meet))
    # 4. where: the point's angle on the shuttle driver so that it is on the needle line, above
    #    the shaft axis, at the meeting
    axis = _shuttle_axis(machine)
    r = kinematics(machine, np.array([phi_s]), params=p)
    ax, ay = r.point(axis).p[0]
    x_needle = float(kinematics(machine, np.array([bdc]), params=p).point(s.needle_point).p[0, 0])
    iu, iv = machine.parameter_index(f"{sp}.u"), machine.parameter_index(f"{sp}.v")
    radius = math.hypot(p[iu], p[iv])
    if abs(x_needle - ax) > radius:
        raise ValueError(f"the shuttle point's circle (radius {radius:.2f} mm about '{axis}')"
                         " does not reach the needle line")
    gamma = math.acos((x_needle - ax) / radius)  # above the axis
    local = gamma - float(r.link(link).theta[0])
    uv = (radius * math.cos(local), radius * math.sin(local))
    overrides = {f"{crank}.phase": new_phase, f"{sp}.u": uv[0], f"{sp}.v": uv[1]}
    return HookTiming(overrides, math.degrees(new_phase) % 360.0, uv,
                      math.degrees(phi_meet) % 360.0)


def _wrap_rad(x: float) -> float:
    return math.atan2(math.sin(x), math.cos(x))


# ---- checks against the facts of the machine class ---------------------------------------------


@dataclass(frozen=True)
class Check:
    """One computed check: value (unit), the expectation in words, pass/fail, and its source."""

    name: str
    value: float
    unit: str
    expected: str
    passed: bool
    source: str


def __getattr__(name: str):
    """``timing.check_timing``: the aggregate of every check lives in
    :mod:`sewmech.sewing.checks` (it reads the feed, which reads this module); this name is
    kept for code written against it."""
    if name == "check_timing":
        return importlib.import_module(f"{__package__}.checks").check_timing
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

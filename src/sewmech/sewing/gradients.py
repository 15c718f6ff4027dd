"""Exact derivatives of the sewing metrics by every design parameter, by the chain rule from the
position sensitivities (:mod:`sewmech.engine.sensitivity`), events included.

An event angle moves with the design: where a channel crosses a level, y(phi*, p) = level, so
d phi*/dp = -(dy/dp) / (dy/dphi); a value read at the event moves by dx/dp + dx/dphi dphi*/dp.
(At an extremum dy/dphi = 0 and the value's derivative is just dy/dp.)

At an extremum the angle's motion does not change the value to first order (dy/dphi = 0):
the lift's derivative is dy/dp at the top.

The stitch length is the dog's travel between rising through the throat plate and dropping
through it again (:func:`sewmech.sewing.feed.feed_cycles`):
stitch = fwd (x(phi_fall) - x(phi_rise)) with y(phi_rise) = y(phi_fall) = plate.

Units: mm per parameter unit (mm, rad, 1); the regulator's input ``input.NAME`` is a parameter
too (mm per rad of regulator setting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..engine._events import at_rows, crossing_rows, extreme_rows
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
    #: the derivative of an event's shaft angle by every parameter (rad per parameter unit),
    #: by event name, where the metric's derivative needed it
    events_d: dict = field(default_factory=dict, repr=False)

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
    S = sensitivities(machine, phi, params=params, inputs=inputs,
                      outputs=[f"p_{dog}_x", f"p_{dog}_y"])
    x, dx, _ = S.channel(f"p_{dog}_x")
    _, dy, _ = S.channel(f"p_{dog}_y")
    rate = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0, points=[dog],
                      links=[], variables=[]).point(dog).v  # d/dphi
    dphi = -dy / rate[..., 1, None]
    dX = dx + rate[..., 0, None] * dphi
    fwd = 1.0 if s.forward == "+x" else -1.0
    return Gradient("stitch_length", float(fwd * (x[1] - x[0])), "mm",
                    machine.parameter_names, fwd * (dX[1] - dX[0]),
                    {"rise": float(np.degrees(phi[0])), "fall": float(np.degrees(phi[1]))},
                    {"rise": dphi[0], "fall": dphi[1]})


def extremum_angle(machine: Machine, point: str, axis: int, phi0: float, *, params=None,
                   inputs=None, tol: float = 1e-13, max_iter: int = 30) -> float:
    """The shaft angle (rad) near ``phi0`` where ``point``'s coordinate ``axis`` (0: x, 1: y)
    is stationary, by Newton's method on its rate and acceleration per shaft angle."""
    phi = float(phi0)
    for _ in range(max_iter):
        r = kinematics(machine, np.array([phi]), params=params, inputs=inputs, omega=1.0,
                       points=[point], links=[], variables=[])
        pm = r.point(point)
        rate, acc = float(pm.v[0, axis]), float(pm.a[0, axis])
        step = rate / acc
        phi -= step
        if abs(step) <= tol:
            return phi
    raise AnalysisError(f"machine '{machine.name}'", f"the extremum of {point} near"
                        f" {math.degrees(phi0):.6g} deg did not converge")


def feed_lift_gradient(machine: Machine, regulator_deg: float, *, params=None) -> Gradient:
    """The dog's lift above the throat plate (mm) at a regulator setting (deg) and its exact
    derivative: dy/dp at the top of the lift (the top's angle moves, the value does not to first
    order)."""
    s = _roles(machine)
    c = feed_cycles(machine, regulator_deg, params=params)
    inputs = {s.regulator: math.radians(regulator_deg)}
    phi = extremum_angle(machine, s.feed_dog, 1, math.radians(float(c.top_deg)), params=params,
                         inputs=inputs)
    S = sensitivities(machine, np.array([phi]), params=params, inputs=inputs, rates=True,
                      outputs=[f"p_{s.feed_dog}_y"])
    y, dy, _ = S.channel(f"p_{s.feed_dog}_y")
    # the top moves too (v_y = 0 there): d phi / dp = -w (d v_y / dp) / a_y at the speed w
    _, dv, _ = S.channel(f"v_{s.feed_dog}_y")
    w = float(S.kin.omega_shaft[..., 0])
    dtop = -w * dv[0] / float(S.kin.point(s.feed_dog).a[..., 0, 1])
    return Gradient("feed_lift", float(y[0] - s.plate_y), "mm", machine.parameter_names,
                    dy[0], {"top": math.degrees(phi), "regulator": regulator_deg},
                    {"top": dtop})


def dog_height_at_needle_plate_gradient(machine: Machine, regulator_deg: float, *,
                                        params=None) -> Gradient:
    """The dog's height above the plate (mm) when the needle point reaches the plate going
    down, at a regulator setting (deg), and its exact derivative: both the dog and the event
    (the needle's crossing) move with the design."""
    from .timing import needle_windows

    s = _roles(machine)
    inputs = {s.regulator: math.radians(regulator_deg)}
    start = needle_windows(machine, params)[1].start_deg
    phi = crossing_angles(machine, s.needle_point, s.plate_y, np.radians([start]),
                          params=params, inputs=inputs)
    S = sensitivities(machine, phi, params=params, inputs=inputs,
                      outputs=[f"p_{s.needle_point}_y", f"p_{s.feed_dog}_y"])
    _, dyn, _ = S.channel(f"p_{s.needle_point}_y")
    yd, dyd, _ = S.channel(f"p_{s.feed_dog}_y")
    r = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0,
                   points=[s.needle_point, s.feed_dog], links=[], variables=[])
    dphi = -dyn[0] / r.point(s.needle_point).v[0, 1]
    d = dyd[0] + r.point(s.feed_dog).v[0, 1] * dphi
    return Gradient("dog_height_at_needle_plate", float(yd[0] - s.plate_y), "mm",
                    machine.parameter_names, d,
                    {"needle_at_plate": float(np.degrees(phi[0])), "regulator": regulator_deg},
                    {"needle_at_plate": dphi})


def _top(machine: Machine, point: str, params, also: tuple[str, ...] = ()
         ) -> tuple[float, np.ndarray, object]:
    """The shaft angle (rad) of ``point``'s highest position and its derivative by every
    parameter: at the top v_y = 0, so d phi/dp = -(d v_y/dp) / (d v_y/dphi) = -w (d v_y/dp) / a_y
    at the file's constant speed w. Also returns the sensitivities there (with rates) of the
    point and of the points ``also``."""
    from ..engine.extremes import extremes

    phi0 = extremes(machine, f"p_{point}_y", params=params).maximum.phi
    phi = extremum_angle(machine, point, 1, phi0, params=params)
    S = sensitivities(machine, np.array([phi]), params=params, rates=True,
                      outputs=[f"p_{q}_y" for q in (point, *also)])
    _, dv, _ = S.channel(f"v_{point}_y")
    w = float(S.kin.omega_shaft[..., 0])
    a = float(S.kin.point(point).a[..., 0, 1])
    return phi, -w * dv[0] / a, S


def _needle_roles(machine: Machine):
    """The machine's [sewing] roles for the needle's, the take-up's and the hook's metrics:
    its needle point (a machine without a feed dog has these metrics too)."""
    from .timing import roles

    return roles(machine)


def _with_take_up(machine: Machine):
    """The machine's [sewing] roles, which must name the take-up's thread eye."""
    s = _needle_roles(machine)
    if s.take_up_eye is None:
        raise AnalysisError(f"machine '{machine.name}'", "has no take_up_eye in [sewing]",
                            "Name the take-up's thread eye there")
    return s


def needle_top_gradient(machine: Machine, regulator_deg: float | None = None, *,
                        params=None) -> Gradient:
    """The shaft angle of the needle's top dead centre (deg, 0 .. 360) and its derivative by
    every parameter (deg per unit). (The regulator does not move it; the argument keeps the
    metrics' signature.)"""
    s = _needle_roles(machine)
    phi, dphi, _ = _top(machine, s.needle_point, params)
    return Gradient("needle_top_deg", math.degrees(phi) % 360.0, "deg", machine.parameter_names,
                    np.degrees(dphi), {"needle_top": math.degrees(phi) % 360.0})


def take_up_lag_gradient(machine: Machine, regulator_deg: float | None = None, *,
                         params=None) -> Gradient:
    """How far (deg of shaft) the take-up eye's top follows the needle's top (> 0: lags), and
    its derivative by every parameter (deg per unit)."""
    s = _with_take_up(machine)
    pn, dn, _ = _top(machine, s.needle_point, params)
    pe, de, _ = _top(machine, s.take_up_eye, params)
    lag = (math.degrees(pe - pn) + 180.0) % 360.0 - 180.0
    return Gradient("take_up_lag_deg", lag, "deg", machine.parameter_names, np.degrees(de - dn),
                    {"needle_top": math.degrees(pn) % 360.0,
                     "take_up_top": math.degrees(pe) % 360.0})


def needle_descent_at_take_up_top_gradient(machine: Machine, regulator_deg: float | None = None,
                                           *, params=None) -> Gradient:
    """How far (mm) the needle point has come down from its top when the take-up eye is at its
    highest, and its derivative: the needle's top value moves by dy/dp (an extremum), its
    height at the eye's top by dy/dp + dy/dphi dphi_eye/dp."""
    s = _with_take_up(machine)
    pn, _, Sn = _top(machine, s.needle_point, params)
    pe, de, Se = _top(machine, s.take_up_eye, params, also=(s.needle_point,))
    yn, dyn, _ = Sn.channel(f"p_{s.needle_point}_y")
    ye, dye, _ = Se.channel(f"p_{s.needle_point}_y")
    w = float(Se.kin.omega_shaft[..., 0])
    slope = float(Se.kin.point(s.needle_point).v[..., 0, 1]) / w  # dy/dphi at the eye's top
    d = dyn[0] - (dye[0] + slope * de)
    return Gradient("needle_descent_at_take_up_top", float(yn[0] - ye[0]), "mm",
                    machine.parameter_names, d,
                    {"needle_top": math.degrees(pn) % 360.0,
                     "take_up_top": math.degrees(pe) % 360.0})


def _extreme(machine: Machine, channel: str, which: str, params) -> tuple[float, object]:
    """The shaft angle (rad) of a channel's maximum or minimum (``which``), located to 1e-9 rad
    (:func:`sewmech.extremes`), and the sensitivities there."""
    from ..engine.extremes import extremes

    ex = extremes(machine, channel, params=params)
    phi = (ex.maximum if which == "max" else ex.minimum).phi
    return phi, sensitivities(machine, np.array([phi]), params=params, rates=True,
                              outputs=[channel])


def loop_lift_gradient(machine: Machine, regulator_deg: float | None = None, *,
                       params=None) -> Gradient:
    """The loop lift (mm): the needle's rise from its bottom dead centre when the shuttle point
    passes the needle line (:func:`sewmech.sewing.timing.loop_lift`), and its derivative. The
    needle line X (the needle point's x at the bottom) and the meeting angle both move:
    X' = dx/dp + x_dot dphi_bdc/dp, dphi_meet/dp = -(dx_sp/dp - X') / (dx_sp/dphi), and the rise
    = y(phi_meet) - y(phi_bdc) moves by dy/dp + y' dphi_meet/dp - dy/dp(bdc) (an extremum)."""
    from .timing import loop_lift, roles

    s = roles(machine)
    ll = loop_lift(machine, params)
    needle, sp = s.needle_point, s.shuttle_point
    pb, Sb = _extreme(machine, f"p_{needle}_y", "min", params)
    w = float(Sb.kin.omega_shaft[..., 0])
    _, dvb, _ = Sb.channel(f"v_{needle}_y")
    dphi_b = -w * dvb[0] / float(Sb.kin.point(needle).a[..., 0, 1])
    _, dxb, _ = Sb.channel(f"p_{needle}_x")
    dX = dxb[0] + float(Sb.kin.point(needle).v[..., 0, 0]) / w * dphi_b
    _, dyb, _ = Sb.channel(f"p_{needle}_y")
    pm = math.radians(ll.phi_deg)
    # the meeting angle as the march reaches it (after the bottom)
    pm = pb + ((pm - pb) % (2.0 * math.pi))
    Sm = sensitivities(machine, np.array([pm]), params=params, rates=True,
                       outputs=[f"p_{sp}_x", f"p_{needle}_y"])
    _, dxs, _ = Sm.channel(f"p_{sp}_x")
    dphi_m = -(dxs[0] - dX) / (float(Sm.kin.point(sp).v[..., 0, 0]) / w)
    _, dym, _ = Sm.channel(f"p_{needle}_y")
    d = dym[0] + float(Sm.kin.point(needle).v[..., 0, 1]) / w * dphi_m - dyb[0]
    return Gradient("loop_lift", ll.rise_mm, "mm", machine.parameter_names, d,
                    {"needle_bottom": math.degrees(pb) % 360.0, "meet": ll.phi_deg})


def shuttle_swing_gradient(machine: Machine, regulator_deg: float | None = None, *,
                           params=None) -> Gradient:
    """The shuttle's swing (deg, between its two reversals) and its derivative: the reversals'
    angles move, the values at them do not to first order."""
    from .timing import roles, shuttle_swing

    link = roles(machine).shuttle_link
    sw = shuttle_swing(machine, params)
    _, Shi = _extreme(machine, f"theta_{link}", "max", params)
    _, Slo = _extreme(machine, f"theta_{link}", "min", params)
    d = np.degrees(Shi.channel(f"theta_{link}")[1][0] - Slo.channel(f"theta_{link}")[1][0])
    if abs(((sw.max_deg - sw.min_deg) - sw.swing_deg + 180.0) % 360.0 - 180.0) > 1e-6:
        d = -d  # the swing runs from the maximum down to the minimum across the wrap
    return Gradient("shuttle_swing_deg", sw.swing_deg, "deg", machine.parameter_names, d,
                    {"max": sw.max_phi_deg, "min": sw.min_phi_deg})


#: the [sewing] roles each metric reads, besides the needle point every [sewing] table names
METRIC_ROLES = {"stitch_length": ("feed_dog", "regulator"),
                "feed_lift": ("feed_dog", "regulator"),
                "dog_height_at_needle_plate": ("feed_dog", "regulator"),
                "needle_top_deg": (), "take_up_lag_deg": ("take_up_eye",),
                "needle_descent_at_take_up_top": ("take_up_eye",),
                "loop_lift": ("shuttle_link", "shuttle_point"),
                "shuttle_swing_deg": ("shuttle_link",)}


def missing_roles(machine: Machine, metric: str) -> str | None:
    """What the machine lacks to give ``metric`` (a key of :data:`METRICS`), in words, or None:
    files that name a metric (sweeps, problems) are refused where they name it, not after
    every design has failed on it."""
    s = machine.spec.sewing
    if s is None:
        return (f"{metric} needs a [sewing] table (the needle point and the parts of stitch"
                f" formation); '{machine.name}' has none")
    lack = [r for r in METRIC_ROLES[metric] if getattr(s, r) is None]
    if lack:
        return f"{metric} needs [sewing] {' and '.join(lack)}, which '{machine.name}' does not name"
    return None


#: the metrics with exact derivatives: name -> function(machine, regulator_deg, params=)
METRICS = {"stitch_length": stitch_length_gradient, "feed_lift": feed_lift_gradient,
           "dog_height_at_needle_plate": dog_height_at_needle_plate_gradient,
           "needle_top_deg": needle_top_gradient, "take_up_lag_deg": take_up_lag_gradient,
           "needle_descent_at_take_up_top": needle_descent_at_take_up_top_gradient,
           "loop_lift": loop_lift_gradient, "shuttle_swing_deg": shuttle_swing_gradient}


#: a stitch shorter than this fraction of the regulator's longest one is round-off of no stitch
#: (at the zero mark the dog moves only up and down: JB1-3 computes 9e-7 mm there, 2e-7 of its
#: 4.08 mm)
DEGENERATE_STITCH = 1e-6


def require_a_stitch(machine: Machine, metric: str, value: float, regulator_deg: float, *,
                     option: str = "regulator_deg", give: str = "regulator_deg={deg:g}",
                     params=None, working_deg: float | None = None) -> None:
    """Refuse a feed metric that is degenerate at the setting: the stitch length where it is
    round-off of zero (below :data:`DEGENERATE_STITCH` of the longest stitch at the ends of the
    regulator's travel), whose tolerances and derivatives would be those of a stitch that does
    not exist. The error names the metric, the setting and ``option``, and suggests a setting
    in ``give``'s form (``{deg}``): the machine's working setting, or the forward end of the
    regulator's travel where the working setting is the one refused (``working_deg``: the
    working setting, default the machine file's; a ``--set`` of the input changes the file's).
    Other metrics pass."""
    from ..engine.errors import OptionError
    from .feed import regulator_range_deg

    if metric != "stitch_length":
        return
    lo, hi = regulator_range_deg(machine)
    longest = float(np.nanmax(np.abs(feed_cycles(machine, [lo, hi], params=params).stitch_mm)))
    if not abs(value) <= DEGENERATE_STITCH * longest:
        return
    s = _roles(machine)
    working = machine.spec.inputs[s.regulator].default_deg if working_deg is None \
        else working_deg
    if regulator_deg != working:
        suggest, why = working, "the machine's working setting"
    else:
        suggest, why = hi, ("the forward end of the regulator's travel; the machine file's"
                            f" [inputs.{s.regulator}] default_deg should be its working setting")
    raise OptionError(option, f"{metric} at regulator {regulator_deg:g} deg is {value:.2g} mm:"
                      f" round-off of no stitch (below {DEGENERATE_STITCH:g} of the longest,"
                      f" {longest:.3g} mm; the regulator's zero mark), so its tolerances and"
                      " derivatives would be those of a stitch that does not exist",
                      f"Give a setting that feeds, e.g. {give.format(deg=suggest)} ({why})")


def metric_values(machine: Machine, name: str, regulator_deg: float, params: np.ndarray,
                  step_deg: float = 1.0) -> np.ndarray:
    """The metric ``name`` (a key of :data:`METRICS`) for a batch of designs ``params``
    (batch, n_params) at a regulator setting (deg), in one kinematics call: the events on a
    ``step_deg`` grid refined on its cubic Hermite interpolant, the stitch length's then
    located on the exact kinematics (as the feed figures are: :func:`feed_cycles`). At 1 deg
    the interpolant's lift is within 2e-7 mm of the located one on the shipped sweep's
    designs, more where a cam's arcs join near an event. NaN for a design that cannot be
    assembled."""
    if name == "stitch_length":
        return feed_cycles(machine, regulator_deg, params=params, step_deg=step_deg,
                           on_failure="mask").stitch_mm
    if name == "feed_lift":
        return feed_cycles(machine, regulator_deg, params=params, step_deg=step_deg,
                           on_failure="mask").lift_mm
    if name in ("needle_top_deg", "take_up_lag_deg", "needle_descent_at_take_up_top"):
        return _timing_values(machine, name, params, step_deg)
    if name in ("loop_lift", "shuttle_swing_deg"):
        return _hook_values(machine, name, params, step_deg)
    if name != "dog_height_at_needle_plate":
        raise KeyError(f"unknown metric {name!r}; metrics: {', '.join(METRICS)}")
    s = _roles(machine)
    n = round(360.0 / step_deg)
    h = 2.0 * math.pi / n
    r = kinematics(machine, np.arange(n) * h, params=params,
                   inputs={s.regulator: math.radians(regulator_deg)}, omega=1.0,
                   points=[s.needle_point, s.feed_dog], links=[], variables=[],
                   on_failure="mask")
    N = r.point(s.needle_point)
    D = r.point(s.feed_dog)
    m = int(np.prod(params.shape[:-1]))
    ph, dirn, t = crossing_rows((N.p[..., 1] - s.plate_y).reshape(m, n),
                                N.v[..., 1].reshape(m, n), h)
    # the needle's one crossing going down per design
    down = np.where(dirn < 0, 1.0, np.inf)
    k = np.argmin(down, axis=1)
    ok = np.isfinite(down[np.arange(m), k]) & r.feasible.reshape(m, n).all(axis=1)
    y = at_rows(D.p[..., 1].reshape(m, n), D.v[..., 1].reshape(m, n), k,
                t[np.arange(m), k], h) - s.plate_y
    return np.where(ok, y, np.nan).reshape(params.shape[:-1])


def _timing_values(machine: Machine, name: str, params: np.ndarray, step_deg: float
                   ) -> np.ndarray:
    """The needle-top and take-up timing metrics for a batch of designs, from a ``step_deg``
    grid with each top refined on the Hermite interpolant of its slope."""
    s = _with_take_up(machine) if name != "needle_top_deg" else _needle_roles(machine)
    n = round(360.0 / step_deg)
    h = 2.0 * math.pi / n
    pts = [s.needle_point] + ([s.take_up_eye] if s.take_up_eye else [])
    r = kinematics(machine, np.arange(n) * h, params=params, omega=1.0, points=pts, links=[],
                   variables=[], on_failure="mask")
    m = int(np.prod(params.shape[:-1]))
    ok = r.feasible.reshape(m, n).all(axis=1)

    def rows(point):
        pm = r.point(point)
        return (pm.p[..., 1].reshape(m, n), pm.v[..., 1].reshape(m, n),
                pm.a[..., 1].reshape(m, n))

    Yn, Vn, An = rows(s.needle_point)
    top_n, y_top = extreme_rows(Yn, Vn, An, h, +1)
    if name == "needle_top_deg":
        out = np.degrees(top_n) % 360.0
    else:
        Ye, Ve, Ae = rows(s.take_up_eye)
        top_e, _ = extreme_rows(Ye, Ve, Ae, h, +1)
        if name == "take_up_lag_deg":
            out = (np.degrees(top_e - top_n) + 180.0) % 360.0 - 180.0
        else:
            x = (top_e % (2.0 * math.pi)) / h
            k = np.floor(x).astype(np.int64) % n
            out = y_top - at_rows(Yn, Vn, k, x - np.floor(x), h)
    return np.where(ok, out, np.nan).reshape(params.shape[:-1])


def _hook_values(machine: Machine, name: str, params: np.ndarray, step_deg: float) -> np.ndarray:
    """The loop lift and the shuttle's swing for a batch of designs, from a ``step_deg`` grid
    refined on the Hermite interpolants (as :func:`sewmech.sewing.timing.loop_lift` and
    :func:`~sewmech.sewing.timing.shuttle_swing` locate them on one design)."""
    from .timing import _need, _shuttle_axis

    s = _needle_roles(machine)
    _need(s.shuttle_link, "shuttle_link", machine)
    if name == "loop_lift":
        _need(s.shuttle_point, "shuttle_point", machine)
    n = round(360.0 / step_deg)
    h = 2.0 * math.pi / n
    m = int(np.prod(params.shape[:-1]))
    link = s.shuttle_link
    if name == "shuttle_swing_deg":
        r = kinematics(machine, np.arange(n) * h, params=params, omega=1.0, points=[],
                       links=[link], variables=[], on_failure="mask")
        lm = r.link(link)
        th = np.unwrap(lm.theta.reshape(m, n), axis=1)
        w, e = lm.omega.reshape(m, n), lm.epsilon.reshape(m, n)
        # (a closed turn: the unwrapped angle comes back, so the rows are periodic)
        _, hi = extreme_rows(th, w, e, h, +1)
        _, lo = extreme_rows(th, w, e, h, -1)
        ok = r.feasible.reshape(m, n).all(axis=1)
        return np.where(ok, np.degrees(hi - lo), np.nan).reshape(params.shape[:-1])
    needle, sp, axis = s.needle_point, s.shuttle_point, _shuttle_axis(machine)
    r = kinematics(machine, np.arange(n) * h, params=params, omega=1.0,
                   points=[needle, sp, axis], links=[], variables=[], on_failure="mask")
    N, S, A = r.point(needle), r.point(sp), r.point(axis)
    rows = np.arange(m)

    def g(pm, c):
        return (pm.p[..., c].reshape(m, n), pm.v[..., c].reshape(m, n),
                pm.a[..., c].reshape(m, n))

    Yn, Vn, An = g(N, 1)
    Xn, VXn, _ = g(N, 0)
    bdc, y_bdc = extreme_rows(Yn, Vn, An, h, -1)
    xb = bdc / h
    kb = np.floor(xb).astype(np.int64) % n
    X = at_rows(Xn, VXn, kb, xb - np.floor(xb), h)
    Xs, VXs, _ = g(S, 0)
    ph, _, t = crossing_rows(Xs - X[:, None], VXs, h)
    k = np.arange(n)[None, :].repeat(m, axis=0)
    Ys, VYs, _ = g(S, 1)
    Ya, VYa, _ = g(A, 1)
    above = (at_rows_all(Ys, VYs, k, t, h) > at_rows_all(Ya, VYa, k, t, h))
    after = np.where(np.isfinite(ph) & above, (ph - bdc[:, None]) % (2.0 * math.pi), np.inf)
    j = np.argmin(after, axis=1)
    found = np.isfinite(after[rows, j])
    y_meet = at_rows(Yn, Vn, j, t[rows, j], h)
    ok = found & r.feasible.reshape(m, n).all(axis=1)
    return np.where(ok, y_meet - y_bdc, np.nan).reshape(params.shape[:-1])


def at_rows_all(V: np.ndarray, S: np.ndarray, k: np.ndarray, t: np.ndarray, h: float
                ) -> np.ndarray:
    """Hermite values of periodic rows V (m, n) (slopes S) in every interval k (m, n) at
    fractions t (m, n)."""
    from ..engine._events import herm

    r = np.arange(V.shape[0])[:, None]
    k1 = (k + 1) % V.shape[-1]
    return herm(V[r, k], V[r, k1], S[r, k], S[r, k1], h, t)

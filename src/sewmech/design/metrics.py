"""The metrics a design problem, a sweep, a tolerance analysis and ``sensitivity`` read besides
the sewing and thread figures: a channel's least, largest, travel, mean and RMS over the turn, a
channel at an event, the transmission angle of every dyad, slider and rotating guide, the
pressure angle at a cam contact, and the force analysis' figures
(:mod:`sewmech.design._dynamic_metrics`).

Names (``CHANNEL`` as ``sewmech kinematics --json`` names it, e.g. ``p_C_y``, ``theta_rocker``,
``v_needle.point_y``, ``epsilon_rocker``):

- ``min:CHANNEL``, ``max:CHANNEL``: its least / largest value over the turn, every local
  extreme located on the exact kinematics (Newton's method on its rate, Brent's on the rate of
  a rate, a bounded Brent search for an acceleration, whose rate sewmech does not compute);
  ``range:CHANNEL`` (a position channel): max - min; ``mean:CHANNEL``, ``rms:CHANNEL``: over
  360 equal steps of the turn (exact for a periodic curve of fewer than 180 harmonics);
- ``transmission_angle_min:UNIT``: the least transmission angle of an ``rrr``, ``rrp`` or
  ``rpr`` unit over the turn (deg, 0 .. 90: the acute angle at which its driven link takes the
  force, 90 the best); ``transmission_angle_deviation:UNIT``: its worst deviation from 90 deg
  (= 90 - the least, the unit's largest pressure angle). The signed deviation psi(phi) (deg)
  of each kind: ``rrr``, the angle between its two links less 90 deg (the force comes along
  the first, the new joint moves square to the second); ``rrp``, the rod against the slider's
  guide; ``rpr``, the slot against the line from the pivot to the pin (the force is square to
  the slot, the slotted link's point moves square to that line); each wrapped to (-90, 90].
  The deviation is max |psi| over the turn: the largest of psi at its local maxima and -psi at
  its local minima;
- ``pressure_angle_max:CAM_PAIR``: the largest pressure angle of a cam contact
  (:func:`sewmech.sewing.transmission.pressure_angles`) at 1 deg steps (value only);
- a channel at an event (``at = "max:CHANNEL"``, ``"min:CHANNEL"``, ``"rising:CHANNEL=LEVEL"``
  or ``"falling:CHANNEL=LEVEL"`` beside the metric): read where that position channel is
  largest, least, or crosses the level upward or downward (the first such crossing at or after
  ``phi_deg``).

Every kinematic metric here has its exact derivative by every parameter: a least or largest
value by the envelope theorem (the derivative at the extreme's located angle: the angle's own
motion does not change the value to first order), a mean or RMS from the derivatives at each
of its angles, a channel at an event with the event's motion (d phi*/dp = -(dz'/dp) / z'' at an
extreme of z, -(dz/dp) / z' at a crossing). A least or largest value is max-type: it is the
largest (or least) of its *pieces*, the local extremes, each smooth in the design, which the
optimiser's epigraph form takes one by one (:mod:`sewmech.design.optimize`).

Rates and accelerations are at the machine file's speed; link angles are unwrapped over the
turn from phi = 0 (a link that turns a whole revolution has no least or largest angle).
Values in the channel's unit, or deg; derivatives per parameter unit (mm, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..engine.errors import AnalysisError
from ..engine.evaluation import newton_in_bracket
from ..engine.machine import Machine

#: a channel's aggregates over the turn: name -> what it is (docs/design.md)
AGGREGATES = {"min": "its least value over the turn", "max": "its largest value over the turn",
              "range": "its travel over the turn (max - min; a position channel)",
              "mean": "its mean over the turn", "rms": "its root mean square over the turn"}
#: the transmission-angle metrics (deg) of a unit (rrr, rrp, rpr)
TRANSMISSION = {"transmission_angle_min": "the least transmission angle over the turn",
                "transmission_angle_deviation": "the worst deviation of the transmission"
                                                " angle from 90 deg over the turn"}
#: the largest pressure angle of a cam contact over the turn (deg; value only)
PRESSURE = "pressure_angle_max"
#: the units whose transmission angle sewmech forms
TRANSMISSION_UNITS = ("rrr", "rrp", "rpr")
#: the events a channel can be read at: where a position channel is largest, least, or
#: crosses a level upward or downward
EVENTS = ("max", "min", "rising", "falling")
#: the steps of the turn over which a mean or an RMS is taken (and the batches' grid)
N_TURN = 360


@dataclass(frozen=True)
class MetricValue:
    """A metric of one design: its value (its unit) and derivative by every parameter
    (``d``, aligned with ``Machine.parameter_names``; None for a value-only metric). A
    max-type metric (``kind`` "max") is the largest of its ``pieces`` (each smooth in the
    design: a local extreme over the turn), a min-type one ("min") the least; ``pieces_d``
    their derivatives (k, n_params) or None, ``pieces_phi`` the shaft angles they are read at
    (rad; NaN where none)."""

    value: float
    d: np.ndarray | None
    kind: str | None = None
    pieces: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pieces_d: np.ndarray | None = None
    pieces_phi: np.ndarray = field(default_factory=lambda: np.zeros(0))


class MetricNameError(Exception):
    """A metric name of a known family whose argument the machine does not have: what is
    wrong and what to do (the file checks turn it into a located error)."""

    def __init__(self, what: str, hint: str = ""):
        super().__init__(what)
        self.what, self.hint = what, hint


def split(name: str) -> tuple[str, str | None]:
    """``(family, argument)`` of a metric name: ``("max", "p_C_y")`` of ``max:p_C_y``,
    ``("p_C_y", None)`` of a plain name."""
    family, sep, arg = name.partition(":")
    return (family, arg) if sep else (name, None)


def is_kinematic_family(name: str) -> bool:
    """Whether ``name`` is a metric of this module (an aggregate, a transmission or pressure
    angle)."""
    family, arg = split(name)
    return arg is not None and (family in AGGREGATES or family in TRANSMISSION
                                or family == PRESSURE)


def has_gradient(name: str) -> bool:
    """Whether this module gives the metric's exact derivative (every kinematic metric but the
    cam pressure angle)."""
    return split(name)[0] != PRESSURE


# ---- names ---------------------------------------------------------------------------------
def _kind(channel: str) -> str:
    return channel.partition("_")[0]


def position_channel(channel: str) -> str:
    """The position channel a channel is the rate or acceleration of (itself for a
    position)."""
    kind, _, rest = channel.partition("_")
    base = {"p": "p", "v": "p", "a": "p", "theta": "theta", "omega": "theta",
            "epsilon": "theta", "q": "q", "qd": "q", "qdd": "q"}[kind]
    return f"{base}_{rest}"


def _level(channel: str) -> int:
    """0 for a position channel, 1 for a rate, 2 for an acceleration."""
    return {"p": 0, "theta": 0, "q": 0, "v": 1, "omega": 1, "qd": 1, "a": 2, "epsilon": 2,
            "qdd": 2}[_kind(channel)]


def _near(name: str, known) -> str:
    import difflib

    near = difflib.get_close_matches(name, list(known), n=3)
    return f"Did you mean {', '.join(near)}?" if near else ""


def transmission_units(machine: Machine) -> list[str]:
    """The units whose transmission angle sewmech forms (rrr, rrp, rpr), in file order."""
    return [u.name for u in machine.spec.units if u.type in TRANSMISSION_UNITS]


def cam_pairs(machine: Machine) -> list[str]:
    """The cam contacts whose pressure angle sewmech forms."""
    return [p.name for p in machine.pairs if p.kind == "cam"]


def check_name(machine: Machine, name: str, channels: list[str]) -> bool:
    """Whether ``name`` is a metric of this module that ``machine`` can evaluate (True); False
    for a name of another kind (a sewing metric, a plain channel, a force-analysis metric);
    :class:`MetricNameError` for a name of this module's families whose argument the machine
    lacks, saying which it has."""
    family, arg = split(name)
    if arg is None:
        return False
    if family in AGGREGATES:
        if arg not in channels:
            raise MetricNameError(f"'{arg}' is not a channel of '{machine.name}'",
                                  _near(name, [f"{family}:{c}" for c in channels]) or
                                  "Channels: p_POINT_x, theta_LINK, q_VAR, their rates and"
                                  " accelerations (sewmech kinematics --json)")
        if family == "range" and _level(arg) != 0:
            raise MetricNameError(f"{name}: a range is of a position channel (p_POINT_x,"
                                  " theta_LINK, q_VAR)", "Give range: and a position channel")
        _check_not_turning(machine, name, arg)
        return True
    if family in TRANSMISSION:
        units = transmission_units(machine)
        if arg not in units:
            raise MetricNameError(f"'{arg}' is not an rrr, rrp or rpr unit of '{machine.name}'",
                                  _near(arg, [f"{u}" for u in units]) or
                                  (f"Its units with a transmission angle: {', '.join(units)}"
                                   if units else "It has none"))
        return True
    if family == PRESSURE:
        pairs = cam_pairs(machine)
        if arg not in pairs:
            raise MetricNameError(f"'{arg}' is not a cam contact of '{machine.name}'",
                                  _near(arg, pairs) or (f"Its cam contacts: {', '.join(pairs)}"
                                                        if pairs else "It has none"))
        return True
    return False


def _check_not_turning(machine: Machine, name: str, channel: str) -> None:
    """A link angle's least, largest, mean and RMS over the turn exist only for a link that
    does not turn a whole revolution (checked on the file's design)."""
    if _kind(channel) != "theta":
        return
    from ..engine.kinematics import kinematics

    phi = np.arange(N_TURN) * (2.0 * math.pi / N_TURN)
    r = kinematics(machine, phi, omega=1.0, on_failure="mask", points=[],
                   links=[channel.partition("_")[2]], variables=[])
    th = np.unwrap(r.channel(channel)[0])
    if np.all(np.isfinite(th)) and abs(th[-1] + (th[-1] - th[-2]) - th[0]) > math.pi:
        raise MetricNameError(f"{name}: the link turns a whole revolution over the turn, so"
                              " its angle has no least, largest or mean value",
                              f"Use its rate (omega_{channel.partition('_')[2]}) or the angle"
                              " of a link that swings")


def check_event(machine: Machine, at: str, channels: list[str]) -> None:
    """An event (``max:CHANNEL``, ``min:CHANNEL``, ``rising:CHANNEL=LEVEL``,
    ``falling:CHANNEL=LEVEL``) against the machine; MetricNameError otherwise."""
    kind, sep, rest = at.partition(":")
    if not sep or kind not in EVENTS:
        raise MetricNameError(f"'{at}' is not an event", "Give max:CHANNEL, min:CHANNEL,"
                              " rising:CHANNEL=LEVEL or falling:CHANNEL=LEVEL (a position"
                              " channel and a level in its unit)")
    channel, eq, level = rest.partition("=")
    if kind in ("rising", "falling"):
        try:
            lv = float(level) if eq else math.nan
        except ValueError:
            lv = math.nan
        if not (math.isfinite(lv) and abs(lv) <= 1e6):
            raise MetricNameError(f"'{at}': a crossing needs a finite level within +-1e6 of the"
                                  " channel's unit", f"Give e.g. {kind}:{channel}=0")
    elif eq:
        raise MetricNameError(f"'{at}': an extreme takes no level", f"Give {kind}:{channel}")
    if channel not in channels:
        raise MetricNameError(f"'{channel}' is not a channel of '{machine.name}'",
                              _near(channel, channels))
    if _level(channel) != 0:
        raise MetricNameError(f"'{at}': an event is of a position channel (p_POINT_x,"
                              " theta_LINK, q_VAR)", "Give a position channel")


def check_read_at_event(name: str) -> None:
    """A channel read at an event: a position or a rate (its rate along the turn is known)."""
    if _level(name) == 2:
        raise MetricNameError(f"{name} at an event: an acceleration's rate along the turn is"
                              " not computed, so its value at a moving event has no exact"
                              " derivative", "Read a position or a rate there, or give phi_deg")


def unit_of(machine: Machine, name: str) -> str:
    """The unit of a metric of this module (the channel's, or deg)."""
    family, arg = split(name)
    if family in TRANSMISSION or family == PRESSURE:
        return "deg"
    from ..engine.kinematics import kinematics

    try:
        return kinematics(machine, [0.0], on_failure="mask").channel(arg)[1]
    except KeyError:
        return ""


# ---- one design, exactly -------------------------------------------------------------------
def _w(machine: Machine) -> float:
    """The machine file's shaft speed, rad/s."""
    from ..engine.kinematics import rpm_to_rad_s

    return rpm_to_rad_s(machine.rpm)


def _selection(channels) -> dict:
    """The points, links and variables some channels read (for a kinematics call)."""
    pts, lks, vrs = set(), set(), set()
    for c in channels:
        kind, _, rest = c.partition("_")
        if kind in ("p", "v", "a"):
            pts.add(rest.rpartition("_")[0])
        elif kind in ("theta", "omega", "epsilon"):
            lks.add(rest)
        else:
            vrs.add(rest)
    return {"points": sorted(pts), "links": sorted(lks), "variables": sorted(vrs)}


def _triple(r, channel: str, w: float) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """A channel of a result at omega = 1 rad/s as (value, d/dphi, d2/dphi2) at the file's speed
    ``w`` (a rate is w times its position's d/dphi; its d/dphi is w times the position's second;
    an acceleration's d/dphi is not computed: None)."""
    base = position_channel(channel)
    kind, _, rest = base.partition("_")
    rate = {"p": "v", "theta": "omega", "q": "qd"}[kind] + "_" + rest
    acc = {"p": "a", "theta": "epsilon", "q": "qdd"}[kind] + "_" + rest
    v, s, c = (r.channel(x)[0] for x in (base, rate, acc))
    level = _level(channel)
    if level == 0:
        return v, s, c
    if level == 1:
        return w * s, w * c, None
    return w * w * c, None, None


def _root(fn, a: float, b: float, fa: float, fb: float, xtol: float = 1e-14) -> float:
    """The root of ``fn`` (t -> (f, f') or (f, None)) in [a, b] where f changes sign: Newton's
    method kept inside the bracket where f' is known, else Brent's method."""
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if fn(0.5 * (a + b))[1] is None:
        from scipy.optimize import brentq

        return float(brentq(lambda t: fn(t)[0], a, b, xtol=xtol, rtol=1e-15))
    return newton_in_bracket(fn, a, b, fa, fb, xtol)


def _stationary(ev, phi_grid: np.ndarray, v: np.ndarray, s: np.ndarray | None,
                at) -> list[tuple[float, int]]:
    """Every local extreme of a periodic curve over the turn: (shaft angle rad, +1 max / -1
    min). ``v``, ``s``: its values and slope on the evaluation's grid (``s`` None: no slope);
    ``at(t)`` its (value, slope, curvature) at one angle (slope, curvature None where not
    known). Sign changes of the slope bracket each extreme, refined by :func:`_root`; without
    a slope, each grid extreme is refined by a bounded Brent search on the values."""
    h = float(phi_grid[1] - phi_grid[0])
    out = []
    if s is not None:
        scale = float(np.max(np.abs(s))) if len(s) else 0.0
        if scale == 0.0 or not np.isfinite(scale):
            return []
        sn = np.roll(s, -1)
        for i in np.flatnonzero(((s > 0) & (sn <= 0)) | ((s < 0) & (sn >= 0))):
            a = float(phi_grid[i])
            kind = 1 if s[i] > 0 else -1

            def fn(t):
                _, sl, cu = at(t)
                return sl, cu

            out.append((_root(fn, a, a + h, float(s[i]), float(sn[i])), kind))
        return out
    from scipy.optimize import minimize_scalar

    vp, vn = np.roll(v, 1), np.roll(v, -1)
    for kind in (1, -1):
        for i in np.flatnonzero((kind * v >= kind * vp) & (kind * v > kind * vn)):
            a = float(phi_grid[i])
            r = minimize_scalar(lambda t, k=kind: -k * at(t)[0], bounds=(a - h, a + h),
                                method="bounded", options={"xatol": 1e-12})
            out.append((float(r.x), kind))
    return sorted(out)


def _inputs_params(machine: Machine, P: np.ndarray, inputs) -> np.ndarray:
    return machine.parameters(inputs=inputs, base=P) if inputs else np.asarray(P, dtype=float)


def _channel_curve(machine: Machine, channel: str, P, inputs):
    """The evaluation of one design and a channel's (grid, values, slope, at(t)) at the file's
    speed; a link angle unwrapped from phi = 0."""
    from ..engine.evaluation import evaluation

    w = _w(machine)
    ev = evaluation(machine, P, inputs)
    base = position_channel(channel)
    sel = _selection([base])
    v, s, _ = _triple(ev.grid, channel, w)
    theta = _kind(channel) == "theta"
    if theta:
        raw = v
        v = np.unwrap(raw)

    def at(t):
        r = ev.at([t], **sel)
        x, sl, cu = _triple(r, channel, w)
        x0 = float(x[0])
        if theta:  # onto the unwrapped branch of the grid angle below
            k = ev._below(t)
            x0 = float(v[k] + (np.mod(x0 - raw[k] + math.pi, 2.0 * math.pi) - math.pi))
        return (x0, None if sl is None else float(sl[0]), None if cu is None else float(cu[0]))

    return ev, v, s, at


def _extremes_of_channel(machine: Machine, channel: str, P, inputs
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Every local extreme of a channel over the turn: angles (rad) and kinds (+1/-1)."""
    ev, v, s, at = _channel_curve(machine, channel, P, inputs)
    found = _stationary(ev, ev.phi, v, s, at)
    if not found:  # a constant: its value anywhere is both its least and its largest
        found = [(0.0, 1), (0.0, -1)]
    phi = np.array([f[0] for f in found])
    return phi, np.array([f[1] for f in found])


def _sens_channel(machine: Machine, channel: str, phi: np.ndarray, P, inputs
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A channel's values and derivatives by every parameter at the angles ``phi`` (its link
    angles unwrapped as the turn's curve from phi = 0)."""
    from ..engine.sensitivity import sensitivities

    S = sensitivities(machine, phi, params=P, inputs=inputs, outputs=[channel],
                      rates=_level(channel) > 0)
    v, d, _ = S.channel(channel)
    if _kind(channel) == "theta":
        v = v + _turns(machine, channel, phi, v, P, inputs)
    return np.asarray(v, dtype=float), np.asarray(d, dtype=float)


def _turns(machine: Machine, channel: str, phi: np.ndarray, v: np.ndarray, P, inputs):
    """The multiples of 2 pi that put link angles read at ``phi`` onto the turn's unwrapped
    curve (from its value at phi = 0)."""
    from ..engine.evaluation import evaluation

    ev = evaluation(machine, P, inputs)
    raw = ev.grid.channel(channel)[0]
    un = np.unwrap(raw)
    k = np.array([ev._below(t) for t in np.atleast_1d(phi)])
    near = un[k] + (np.mod(v - raw[k] + math.pi, 2.0 * math.pi) - math.pi)
    return near - v


def aggregate_value(machine: Machine, family: str, channel: str, P, inputs=None
                    ) -> MetricValue:
    """``min``, ``max``, ``range``, ``mean`` or ``rms`` of a channel for one design ``P``,
    with its exact derivative (see the module doc)."""
    if family in ("mean", "rms"):
        phi = np.arange(N_TURN) * (2.0 * math.pi / N_TURN)
        v, d = _sens_channel(machine, channel, phi, P, inputs)
        if family == "mean":
            return MetricValue(float(v.mean()), d.mean(axis=0))
        rms = math.sqrt(float(np.mean(v * v)))
        return MetricValue(rms, (v[:, None] * d).mean(axis=0) / rms if rms > 0 else
                           np.zeros(d.shape[1]))
    phi, kinds = _extremes_of_channel(machine, channel, P, inputs)
    v, d = _sens_channel(machine, channel, phi, P, inputs)
    hi, lo = kinds > 0, kinds < 0
    if family == "max":
        k = int(np.argmax(np.where(hi, v, -np.inf)))
        return MetricValue(float(v[k]), d[k], "max", v[hi], d[hi], phi[hi])
    if family == "min":
        k = int(np.argmin(np.where(lo, v, np.inf)))
        return MetricValue(float(v[k]), d[k], "min", v[lo], d[lo], phi[lo])
    # the range: the largest of every local maximum less every local minimum
    pv = (v[hi][:, None] - v[lo][None, :]).ravel()
    pd = (d[hi][:, None, :] - d[lo][None, :, :]).reshape(len(pv), -1)
    k = int(np.argmax(pv))
    return MetricValue(float(pv[k]), pd[k], "max", pv, pd, np.full(len(pv), np.nan))


# ---- the transmission angle ----------------------------------------------------------------
def _unit(machine: Machine, name: str):
    for u in machine.spec.units:
        if u.name == name:
            return u
    raise KeyError(name)


def _wrap90(x: np.ndarray) -> np.ndarray:
    """An angle between two lines (rad) to (-pi/2, pi/2]."""
    return np.pi / 2 - np.mod(np.pi / 2 - x, np.pi)


def _psi_parts(machine: Machine, unit: str):
    """What psi (rad) of a unit is made of: (kind, link a, link b, pin, pivot, shift): psi =
    wrap90(theta_a - theta_b - shift) for rrr and rrp, wrap90(theta_a - atan2(pin - pivot))
    for rpr."""
    u = _unit(machine, unit)
    if u.type == "rrr":
        return ("links", u.links[0], u.links[1], None, None, math.pi / 2)
    if u.type == "rrp":
        return ("links", u.rod, u.slider, None, None, 0.0)
    return ("slot", u.link, None, u.pin, u.pivot, 0.0)


def _psi_channels(parts) -> list[str]:
    kind, a, b, pin, pivot, _ = parts
    if kind == "links":
        return [f"theta_{a}", f"theta_{b}"]
    return [f"theta_{a}", f"p_{pin}_x", f"p_{pin}_y", f"p_{pivot}_x", f"p_{pivot}_y"]


def _psi(r, parts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """psi (rad) and its first two derivatives by the shaft angle from a result at omega = 1."""
    kind, a, b, pin, pivot, shift = parts
    if kind == "links":
        la, lb = r.link(a), r.link(b)
        return (_wrap90(la.theta - lb.theta - shift), la.omega - lb.omega,
                la.epsilon - lb.epsilon)
    la, P1, P0 = r.link(a), r.point(pin), r.point(pivot)
    dx, dy = (P1.p - P0.p)[..., 0], (P1.p - P0.p)[..., 1]
    vx, vy = (P1.v - P0.v)[..., 0], (P1.v - P0.v)[..., 1]
    ax, ay = (P1.a - P0.a)[..., 0], (P1.a - P0.a)[..., 1]
    D = dx * dx + dy * dy
    N = dx * vy - dy * vx
    a1 = N / D
    a2 = ((dx * ay - dy * ax) * D - N * 2.0 * (dx * vx + dy * vy)) / (D * D)
    return (_wrap90(la.theta - np.arctan2(dy, dx)), la.omega - a1, la.epsilon - a2)


def transmission_value(machine: Machine, family: str, unit: str, P, inputs=None
                       ) -> MetricValue:
    """``transmission_angle_min`` or ``transmission_angle_deviation`` (deg) of a unit for one
    design, with its exact derivative: max |psi| over the turn is the largest of psi at its
    local maxima and -psi at its local minima, each located and differentiated at its angle."""
    from ..engine.evaluation import evaluation
    from ..engine.sensitivity import sensitivities

    parts = _psi_parts(machine, unit)
    channels = _psi_channels(parts)
    sel = _selection(channels)
    ev = evaluation(machine, P, inputs)
    v, s, _ = _psi(ev.grid, parts)

    def at(t):
        x, sl, cu = _psi(ev.at([t], **sel), parts)
        return float(x[0]), float(sl[0]), float(cu[0])

    found = _stationary(ev, ev.phi, v, s, at)
    if not found:  # psi constant over the turn: |psi| at any angle, from both sides
        found = [(0.0, 1), (0.0, -1)]
    phi = np.array([f[0] for f in found])
    kinds = np.array([f[1] for f in found], dtype=float)
    S = sensitivities(machine, phi, params=P, inputs=inputs, outputs=channels)
    kind, a, b, pin, pivot, shift = parts
    r = S.kin
    psi = _psi(r, parts)[0]
    if kind == "links":
        d = S.channel(f"theta_{a}")[1] - S.channel(f"theta_{b}")[1]
    else:
        P1, P0 = r.point(pin).p, r.point(pivot).p
        dx, dy = P1[..., 0] - P0[..., 0], P1[..., 1] - P0[..., 1]
        ddx = S.channel(f"p_{pin}_x")[1] - S.channel(f"p_{pivot}_x")[1]
        ddy = S.channel(f"p_{pin}_y")[1] - S.channel(f"p_{pivot}_y")[1]
        dal = (dx[:, None] * ddy - dy[:, None] * ddx) / (dx * dx + dy * dy)[:, None]
        d = S.channel(f"theta_{a}")[1] - dal
    deg = 180.0 / math.pi
    pieces = kinds * np.asarray(psi, dtype=float) * deg  # psi at maxima, -psi at minima
    pieces_d = kinds[:, None] * d * deg
    k = int(np.argmax(pieces))
    if family == "transmission_angle_deviation":
        return MetricValue(float(pieces[k]), pieces_d[k], "max", pieces, pieces_d, phi)
    return MetricValue(90.0 - float(pieces[k]), -pieces_d[k], "min", 90.0 - pieces, -pieces_d,
                       phi)


def psi_curve(machine: Machine, unit: str, phi: np.ndarray, P=None, inputs=None) -> np.ndarray:
    """The signed deviation psi (deg) of a unit's transmission angle from 90 deg at the shaft
    angles ``phi`` (rad) for the designs ``P`` (batch + (n_params,)): batch + (n_phi,); NaN where
    the mechanism does not assemble."""
    from ..engine.kinematics import kinematics

    parts = _psi_parts(machine, unit)
    r = kinematics(machine, phi, params=P, inputs=inputs, omega=1.0, on_failure="mask",
                   **_selection(_psi_channels(parts)))
    return np.degrees(_psi(r, parts)[0])


# ---- a channel at an event -----------------------------------------------------------------
def parse_event(at: str) -> tuple[str, str, float]:
    """(kind, channel, level) of an event (level NaN for an extreme)."""
    kind, _, rest = at.partition(":")
    channel, eq, level = rest.partition("=")
    return kind, channel, float(level) if eq else math.nan


def _event_angle(machine: Machine, at: str, P, inputs, phi_from: float) -> float:
    """The shaft angle (rad) of an event for one design, located on the exact kinematics."""
    kind, channel, level = parse_event(at)
    ev, v, s, curve_at = _channel_curve(machine, channel, P, inputs)
    if kind in ("max", "min"):
        found = _stationary(ev, ev.phi, v, s, curve_at)
        want = 1 if kind == "max" else -1
        cands = [t for t, k in found if k == want]
        if not cands:
            raise AnalysisError(f"machine '{machine.name}'", f"{channel} has no {kind} over"
                                " the turn (it is constant)", "Choose another event")
        vals = [curve_at(t)[0] for t in cands]
        return float(cands[int(np.argmax(want * np.array(vals)))])
    f = v - level
    fn_ = np.roll(f, -1)
    up = kind == "rising"
    idx = np.flatnonzero(((f < 0) & (fn_ >= 0)) if up else ((f > 0) & (fn_ <= 0)))
    if not len(idx):
        raise AnalysisError(f"machine '{machine.name}'", f"{channel} does not cross {level:g}"
                            f" {'upward' if up else 'downward'} over the turn",
                            "Give a level the channel passes")
    h = ev.h
    roots = []
    for i in idx:
        a = float(ev.phi[i])

        def fn(t):
            x, sl, _ = curve_at(t)
            return x - level, sl

        roots.append(_root(fn, a, a + h, float(f[i]), float(fn_[i])))
    start = phi_from % (2.0 * math.pi)
    return min(roots, key=lambda t: (t - start) % (2.0 * math.pi))


def event_value(machine: Machine, channel: str, at: str, P, inputs=None,
                phi_from: float = 0.0) -> MetricValue:
    """A channel (a position or a rate) read at an event, for one design, with its exact
    derivative: the channel's own plus its rate along the turn times the event angle's
    derivative (at an extreme of z: d phi*/dp = -(dz'/dp) / z''; at a crossing:
    -(dz/dp) / z', z' and z'' by the shaft angle)."""
    from ..engine.evaluation import evaluation
    from ..engine.sensitivity import sensitivities

    kind, z, level = parse_event(at)
    phi = _event_angle(machine, at, P, inputs, phi_from)
    w = _w(machine)
    rate_z = {"p": "v", "theta": "omega", "q": "qd"}[_kind(z)] + "_" + z.partition("_")[2]
    outs = sorted({channel, z, rate_z})
    S = sensitivities(machine, np.array([phi]), params=P, inputs=inputs, outputs=outs,
                      rates=True)
    ev = evaluation(machine, P, inputs)
    r = ev.at([phi], **_selection([position_channel(channel), z]))
    _, z1, z2 = _triple(r, z, w)
    if kind in ("max", "min"):
        dphi = -(S.channel(rate_z)[1][0] / w) / float(z2[0])
    else:
        dphi = -S.channel(z)[1][0] / float(z1[0])
    x, slope, _ = _triple(r, channel, w)
    value = float(S.channel(channel)[0][0])
    if _kind(channel) == "theta":
        value += float(_turns(machine, channel, np.array([phi]), np.array([value]), P,
                              inputs)[0])
    return MetricValue(value, S.channel(channel)[1][0] + float(slope[0]) * dphi)


# ---- batches, values only -------------------------------------------------------------------
def _local_extremes_rows(V: np.ndarray, S: np.ndarray | None, h: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every local extreme of the periodic rows V (m, n): (row, value, kind +1/-1) of each,
    located on the cubic Hermite interpolant of V with slopes S (where S changes sign; S None:
    the slopes of the fourth-order central differences of V)."""
    if S is None:  # the slope by the fourth-order central difference of the periodic rows
        S = (8.0 * (np.roll(V, -1, axis=1) - np.roll(V, 1, axis=1))
             - (np.roll(V, -2, axis=1) - np.roll(V, 2, axis=1))) / (12.0 * h)
    Vn, Sn = np.roll(V, -1, axis=1), np.roll(S, -1, axis=1)
    mask = ((S > 0) & (Sn <= 0)) | ((S < 0) & (Sn >= 0))
    r, i = np.nonzero(mask)
    y0, y1, m0, m1 = V[r, i], Vn[r, i], S[r, i], Sn[r, i]
    # the Hermite cubic's slope (per unit t) is a t^2 + b t + c: its root in [0, 1]
    a = 6.0 * (y0 - y1) + 3.0 * h * (m0 + m1)
    b = -6.0 * (y0 - y1) - 4.0 * h * m0 - 2.0 * h * m1
    c = h * m0
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
        q = -0.5 * (b + np.copysign(disc, b))
        t1 = np.where(q != 0.0, c / q, 0.0)
        t2 = np.where(a != 0.0, q / a, np.where(b != 0.0, -c / b, 0.0))
    # the slope changes sign once in the interval: its root is the one in [0, 1] (of the two,
    # the nearer to it: a root on an end may come out a rounding beyond it)
    t1 = np.where(np.isfinite(t1), t1, np.inf)
    t2 = np.where(np.isfinite(t2), t2, np.inf)
    out1 = np.maximum(-t1, t1 - 1.0)
    out2 = np.maximum(-t2, t2 - 1.0)
    t = np.clip(np.where(out1 <= out2, t1, t2), 0.0, 1.0)
    t2_, t3 = t * t, t * t * t
    val = ((2 * t3 - 3 * t2_ + 1) * y0 + (t3 - 2 * t2_ + t) * h * m0 + (-2 * t3 + 3 * t2_) * y1
           + (t3 - t2_) * h * m1)
    return r, val, np.where(m0 > 0, 1, -1)


def _pieces_rows(m: int, rows, vals, kinds, want: int) -> list[np.ndarray]:
    return [vals[(rows == k) & (kinds == want)] for k in range(m)]


def aggregate_batch(machine: Machine, family: str, channel: str, P: np.ndarray, inputs=None,
                    pieces: list | None = None) -> np.ndarray:
    """An aggregate of a channel for a batch of designs P (m, n_params), values only, from one
    kinematics call on :data:`N_TURN` angles at omega = 1 (the extremes on the Hermite
    interpolant of the grid, about 1e-7 of the located ones where the channel is smooth, more
    where a cam's arcs join near an extreme; an acceleration's with the slopes of its
    fourth-order central differences). NaN where
    a design does not assemble. ``pieces`` (a list) receives each design's pieces."""
    from ..engine.kinematics import kinematics

    m = len(P)
    n = N_TURN
    h = 2.0 * math.pi / n
    phi = np.arange(n) * h
    if family in ("mean", "rms"):
        k = kinematics(machine, phi, params=P, inputs=inputs, on_failure="mask",
                       **_selection([channel]))
        V = k.channel(channel)[0].reshape(m, n)
        if _kind(channel) == "theta":
            V = np.unwrap(V, axis=1)
        out = V.mean(axis=1) if family == "mean" else np.sqrt(np.mean(V * V, axis=1))
        if pieces is not None:
            pieces.extend([np.zeros(0)] * m)
        return out
    k = kinematics(machine, phi, params=P, inputs=inputs, omega=1.0, on_failure="mask",
                   **_selection([position_channel(channel)]))
    V, S, _ = _triple(k, channel, _w(machine))
    V = V.reshape(m, n)
    S = None if S is None else S.reshape(m, n)
    if _kind(channel) == "theta":
        V = np.unwrap(V, axis=1)
    feasible = k.feasible.reshape(m, n).all(axis=1)
    rows, vals, kinds = _local_extremes_rows(V, S, h)
    hi = _pieces_rows(m, rows, vals, kinds, 1)
    lo = _pieces_rows(m, rows, vals, kinds, -1)
    out = np.full(m, np.nan)
    got = []
    for j in range(m):
        a = hi[j] if len(hi[j]) else V[j, :1]
        b = lo[j] if len(lo[j]) else V[j, :1]
        if family == "max":
            p = a
        elif family == "min":
            p = b
        else:
            p = (a[:, None] - b[None, :]).ravel()
        got.append(p)
        out[j] = (np.min(p) if family == "min" else np.max(p)) if feasible[j] else np.nan
    if pieces is not None:
        pieces.extend(got)
    return out


def transmission_batch(machine: Machine, family: str, unit: str, P: np.ndarray, inputs=None,
                       pieces: list | None = None) -> np.ndarray:
    """A transmission-angle metric (deg) for a batch of designs, values only (psi's extremes
    on the Hermite interpolant of :data:`N_TURN` angles); NaN where a design does not
    assemble."""
    from ..engine.kinematics import kinematics

    m = len(P)
    n = N_TURN
    h = 2.0 * math.pi / n
    parts = _psi_parts(machine, unit)
    k = kinematics(machine, np.arange(n) * h, params=P, inputs=inputs, omega=1.0,
                   on_failure="mask", **_selection(_psi_channels(parts)))
    V, S, _ = (np.degrees(x).reshape(m, n) for x in _psi(k, parts))
    feasible = k.feasible.reshape(m, n).all(axis=1)
    rows, vals, kinds = _local_extremes_rows(V, S, h)
    out = np.full(m, np.nan)
    got = []
    for j in range(m):
        sel = rows == j
        p = kinds[sel] * vals[sel] if sel.any() else np.abs(V[j, :1])
        got.append(p if family == "transmission_angle_deviation" else 90.0 - p)
        if feasible[j]:
            out[j] = np.max(p) if family == "transmission_angle_deviation" else 90.0 - np.max(p)
    if pieces is not None:
        pieces.extend(got)
    return out


def pressure_batch(machine: Machine, pair: str, P: np.ndarray, inputs=None,
                   pieces: list | None = None) -> np.ndarray:
    """The largest pressure angle (deg) of a cam contact at 1 deg steps, per design (one
    force-geometry evaluation each); NaN where a design does not assemble."""
    from ..engine.errors import SewmechError
    from ..sewing.transmission import pressure_angles

    phi = np.arange(N_TURN) * (2.0 * math.pi / N_TURN)
    out = np.full(len(P), np.nan)
    for j, row in enumerate(np.atleast_2d(P)):
        try:
            a = pressure_angles(machine, phi, inputs=inputs, params=row).angles.get(pair)
        except SewmechError:
            a = None
        if a is not None and np.isfinite(a).any():
            out[j] = float(np.nanmax(a))
            if pieces is not None:
                pieces.append(a[np.isfinite(a)])
        elif pieces is not None:
            pieces.append(np.zeros(0))
    return out


def event_batch(machine: Machine, channel: str, at: str, P: np.ndarray, inputs=None,
                phi_from: float = 0.0) -> np.ndarray:
    """A channel at an event for a batch of designs, values only: the event on the Hermite
    interpolant of :data:`N_TURN` angles, the channel read on its own; NaN where a design does
    not assemble or the event does not happen."""
    from ..engine._events import at_rows, crossing_rows, extreme_rows
    from ..engine.kinematics import kinematics

    kind, z, level = parse_event(at)
    m = len(P)
    n = N_TURN
    h = 2.0 * math.pi / n
    w = _w(machine)
    k = kinematics(machine, np.arange(n) * h, params=P, inputs=inputs, omega=1.0,
                   on_failure="mask",
                   **_selection([position_channel(channel), position_channel(z)]))
    Z, Z1, Z2 = (x.reshape(m, n) for x in _triple(k, z, w))
    if _kind(z) == "theta":
        Z = np.unwrap(Z, axis=1)
    rows = np.arange(m)
    if kind in ("max", "min"):
        phi, _ = extreme_rows(Z, Z1, Z2, h, 1 if kind == "max" else -1)
        x = phi / h
        idx = np.floor(x).astype(np.int64) % n
        t = x - np.floor(x)
        ok = np.ones(m, dtype=bool)
    else:
        ph, direction, tt = crossing_rows(Z - level, Z1, h)
        want = 1 if kind == "rising" else -1
        start = phi_from % (2.0 * math.pi)
        after = np.where(direction == want, np.mod(ph - start, 2.0 * math.pi), np.inf)
        idx = np.argmin(after, axis=1)
        ok = np.isfinite(after[rows, idx])
        t = np.where(ok, tt[rows, idx], 0.0)
    C, C1, _ = _triple(k, channel, w)
    C, C1 = C.reshape(m, n), C1.reshape(m, n)
    if _kind(channel) == "theta":
        C = np.unwrap(C, axis=1)
    val = at_rows(C, C1, idx, t, h)
    ok &= k.feasible.reshape(m, n).all(axis=1)
    return np.where(ok, val, np.nan)


def metric_value(machine: Machine, name: str, P, inputs=None) -> MetricValue:
    """A metric of this module (:func:`is_kinematic_family`) for one design, with its exact
    derivative (None for the cam pressure angle, value only)."""
    family, arg = split(name)
    if family in AGGREGATES:
        return aggregate_value(machine, family, arg, P, inputs)
    if family in TRANSMISSION:
        return transmission_value(machine, family, arg, P, inputs)
    pieces: list = []
    v = pressure_batch(machine, arg, np.atleast_2d(P), inputs, pieces)
    if not np.isfinite(v[0]):
        raise AnalysisError(f"machine '{machine.name}'", f"the pressure angle of {arg} cannot"
                            " be formed on this design (it does not assemble, or the follower"
                            " stands still)")
    return MetricValue(float(v[0]), None, "max", pieces[0], None,
                       np.full(len(pieces[0]), np.nan))


def metric_batch_values(machine: Machine, name: str, P: np.ndarray, inputs=None,
                        pieces: list | None = None) -> np.ndarray:
    """A metric of this module for a batch of designs (values only; NaN where a design does not
    assemble)."""
    family, arg = split(name)
    if family in AGGREGATES:
        return aggregate_batch(machine, family, arg, P, inputs, pieces)
    if family in TRANSMISSION:
        return transmission_batch(machine, family, arg, P, inputs, pieces)
    return pressure_batch(machine, arg, P, inputs, pieces)

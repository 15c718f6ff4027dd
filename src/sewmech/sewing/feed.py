"""The feed: feed-dog trajectory, stitch length, scale-plate marks, feed timing, sensitivity.

The feed dog's tooth tip (``[sewing] feed_dog``) moves in the plane of the machine frame; the
fabric moves with it only while the tip is above the throat plate (``plate_y``). So the stitch
length is the tip's horizontal travel between the moment it rises through the plate and the
moment it drops through it, positive in the ``forward`` direction. The lift is the tip's
highest point above the plate.

Every quantity comes from one batched kinematics call over a uniform grid of shaft angles and
any number of regulator settings (and designs); events between grid points are found on the
cubic Hermite interpolant built from the exact positions and the exact analytic rates (kinematics
at omega = 1 rad/s gives d/dphi), which is accurate to O(h^4) of the grid step h where the path
is smooth, but only to O(h^3) where a cam's arcs join (the path's third derivative jumps there:
up to 4e-5 mm at 1 deg on JB designs). So the dog's rise through the plate and its drop, which
make the stitch length, are then located by Newton's method on the exact kinematics, every
design and setting at once (:mod:`sewmech.sewing._locate`): exact to the loop units'
tolerance.

Angles returned to people are degrees (``*_deg``) in the machine's shaft-angle convention;
lengths mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..engine._events import at_rows as _at_rows
from ..engine._events import crossing_rows as _crossing_rows
from ..engine._events import extreme_rows as _extreme_rows
from ..engine.errors import AnalysisError, OptionError
from ..engine.evaluation import Evaluation, evaluation
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from ..engine.spec import SewingSpec
from .timing import Check, needle_windows

FEED_DOG_RISE_MM = (1.2, 1.5)  # [Sdelai-sam-1999]: Podolsk household machine, by fabric thickness
# the Singer 31-15 (3.6, [Navy-Singer-31-15]) .. a class-15 clone measured (4.2,
# [SewingMachineNut-2018])
MAX_STITCH_MM = (3.6, 4.2)


def _roles(machine: Machine) -> SewingSpec:
    s = machine.spec.sewing
    if s is None or s.feed_dog is None or s.regulator is None:
        raise ValueError(f"machine '{machine.name}' ({machine.file}): the feed analyses need"
                         " [sewing] feed_dog (the tooth-tip point) and regulator (the stitch"
                         " regulator input)")
    return s


#: the regulator's zero mark, deg: a regulator input is its setting from the zero mark (the slot
#: square to the fork: no feed; docs/notation.md). Its file default is the machine's working
#: setting instead, which the analyses default to
ZERO_MARK_DEG = 0.0


def regulator_range_deg(machine: Machine) -> tuple[float, float]:
    """(min, max) of the stitch regulator input from the machine file, degrees."""
    inp = machine.spec.inputs[_roles(machine).regulator]
    if inp.min_deg is None or inp.max_deg is None:
        raise ValueError(f"machine '{machine.name}': [inputs.{_roles(machine).regulator}] needs"
                         " min_deg and max_deg (the regulator's travel)")
    return inp.min_deg, inp.max_deg


# ---- one cycle per setting -------------------------------------------------------------------------


@dataclass(frozen=True)
class FeedCycles:
    """The feed dog over one revolution for a batch of regulator settings (and designs).

    Batch arrays have the shape of ``regulator_deg``; trajectories add the shaft-angle axis.

    Attributes
    ----------
    regulator_deg : ndarray
        Regulator setting, degrees.
    phi_deg : ndarray, (n_phi,)
        Shaft angles of the trajectories, degrees.
    x, y : ndarray, batch + (n_phi,)
        Tooth-tip position, mm (frame); ``y`` is the height above the throat plate.
    stitch_mm : ndarray
        Signed stitch length (+ forward), mm.
    lift_mm, drop_mm : ndarray
        Highest tip height above the plate, lowest (negative: below), mm.
    top_deg : ndarray
        Shaft angle of the top of lift.
    rise_deg, fall_deg : ndarray
        Shaft angles where the tip rises through and drops through the plate.
    stroke_mm : ndarray
        Horizontal peak-to-peak travel of the tip, mm.
    mid_feed_deg : ndarray
        Shaft angle where the tip passes the middle of its horizontal stroke while feeding (in
        the direction of the stitch); NaN without feed.
    feasible : ndarray of bool
        False where the mechanism could not be assembled for that setting (values NaN).
    """

    regulator_deg: np.ndarray
    phi_deg: np.ndarray
    x: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    stitch_mm: np.ndarray
    lift_mm: np.ndarray
    drop_mm: np.ndarray
    top_deg: np.ndarray
    rise_deg: np.ndarray
    fall_deg: np.ndarray
    stroke_mm: np.ndarray
    mid_feed_deg: np.ndarray
    feasible: np.ndarray

    def to_pandas(self):
        """One row per setting (flattened batch)."""
        import pandas as pd

        cols = ("regulator_deg", "stitch_mm", "lift_mm", "drop_mm", "top_deg", "rise_deg",
                "fall_deg", "stroke_mm", "mid_feed_deg", "feasible")
        return pd.DataFrame({c: np.asarray(getattr(self, c)).reshape(-1) for c in cols})


def feed_cycles(machine: Machine, regulator_deg: ArrayLike, *, params: ArrayLike | None = None,
                step_deg: float = 1.0, on_failure: str = "raise",
                exact: bool = True) -> FeedCycles:
    """Trajectory and feed figures of the dog's tooth tip for regulator settings (degrees).

    ``params`` (batch + (n_parameters,)) broadcasts against ``regulator_deg``; the grid of shaft
    angles starts at 0 with ``step_deg`` spacing (360 must be a multiple of it). ``exact``: the
    rise through the plate and the drop (``rise_deg``, ``fall_deg``) and so the stitch length
    are located by Newton's method on the exact kinematics from the interpolant's crossings
    (:func:`_polish`); False: read off the interpolant (up to about 4e-5 mm off at 1 deg where
    a cam's arcs join near a crossing; a little faster). The other figures are the
    interpolant's.
    """
    s = _roles(machine)
    n = round(360.0 / step_deg)
    if n < 36 or abs(n * step_deg - 360.0) > 1e-9:
        raise ValueError(f"step_deg must divide 360 into at least 36 steps, got {step_deg}")
    h = 2.0 * math.pi / n
    phi = np.arange(n) * h
    reg = np.asarray(regulator_deg, dtype=float)
    inputs = {s.regulator: np.radians(reg)}
    ev = Evaluation(machine, machine.defaults)
    unknowns = ev.unknown_selection([s.feed_dog])  # (the loops' unknowns: the polish's start)
    r = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0,
                   on_failure=on_failure, **unknowns)
    pm = r.point(s.feed_dog)
    batch = r.batch_shape
    fwd = 1.0 if s.forward == "+x" else -1.0
    X = pm.p[..., 0].reshape(-1, n)
    Y = (pm.p[..., 1] - s.plate_y).reshape(-1, n)
    VX = pm.v[..., 0].reshape(-1, n)
    VY = pm.v[..., 1].reshape(-1, n)
    AX = pm.a[..., 0].reshape(-1, n)
    AY = pm.a[..., 1].reshape(-1, n)
    ok = r.feasible.reshape(-1, n).all(axis=1)
    nan = np.full(X.shape[0], np.nan)
    out = {}
    if ok.any():
        out = _cycle_figures(X[ok], Y[ok], VX[ok], VY[ok], AX[ok], AY[ok], h, fwd)
        if exact:
            P = np.broadcast_to(machine.parameters(base=params, inputs=inputs),
                                batch + machine.defaults.shape).reshape(-1,
                                                                        machine.defaults.size)
            _polish(ev, s, r, P, np.nonzero(ok)[0], out, h, fwd)
    out = {k: _scatter(nan, ok, out.get(k)) for k in ("stitch_mm", "lift_mm", "drop_mm",
                                                       "top_deg", "rise_deg", "fall_deg",
                                                       "stroke_mm", "mid_feed_deg")}
    shape = batch
    return FeedCycles(
        regulator_deg=np.broadcast_to(reg, shape).copy(),
        phi_deg=np.degrees(phi),
        x=X.reshape(shape + (n,)),
        y=Y.reshape(shape + (n,)),
        feasible=ok.reshape(shape),
        **{k: v.reshape(shape) for k, v in out.items()},
    )


def _polish(ev: Evaluation, s: SewingSpec, r, P: np.ndarray, rows: np.ndarray, out: dict,
            h: float, fwd: float) -> None:
    """Locate the dog's rise through the plate and its drop by Newton's method on the exact
    kinematics (:class:`sewmech.sewing._locate.Locator`), from the interpolant's crossings, and
    take the stitch length from the tip's x there: exact to the loop units' tolerance where the
    interpolant's crossings are not (a cam's arcs joining near a crossing make the path's third
    derivative jump, and the interpolant's error there is of order h^3). ``rows``: the rows of ``P`` (the
    designs and settings, flat) that ``out`` holds, in order; a crossing not located keeps the
    interpolant's."""
    from ._locate import Locator

    has = np.isfinite(out["stitch_mm"])
    if not has.any():
        return
    sel = rows[has]
    m = ev.machine
    n = r.phi.shape[0]
    x, found = [], []
    for key, kind in (("rise_deg", "up"), ("fall_deg", "down")):
        start = np.radians(out[key][has])
        k = np.rint(start / h).astype(np.int64)
        d = start - k * h
        k %= n
        guess = P[sel][:, ev.init_params].copy()
        for c, (kd, i, _, _) in enumerate(m.unknowns):  # the grid's loop unknowns, carried
            names = m.link_names if kd == 0 else m.variable_names
            have = r.link_names if kd == 0 else r.variable_names
            if names[i] not in have:
                continue
            j = have.index(names[i])
            q, q1, q2 = ((r.theta, r.omega, r.epsilon) if kd == 0 else
                         (r.q, r.q_dot, r.q_ddot))
            q, q1, q2 = (a.reshape(-1, n, a.shape[-1])[sel, k, j] for a in (q, q1, q2))
            guess[:, c] = q + d * (q1 + 0.5 * d * q2)
        phi, f, at = Locator(ev, P[sel].copy()).locate(start, s.feed_dog, 1, s.plate_y, kind,
                                                       guess=guess)
        out[key][np.nonzero(has)[0][f]] = np.degrees(np.mod(phi[f], 2.0 * math.pi))
        x.append(at[:, 0])
        found.append(f)
    both = found[0] & found[1]
    idx = np.nonzero(has)[0][both]
    out["stitch_mm"][idx] = fwd * (x[1][both] - x[0][both])


def _scatter(base, mask, values):
    out = base.copy()
    if values is not None:
        out[mask] = values
    return out


def _cycle_figures(X, Y, VX, VY, AX, AY, h, fwd) -> dict:
    """The feed figures of rows of tooth-tip samples (m, n), all rows at once."""
    two_pi = 2.0 * math.pi
    m = X.shape[0]
    r = np.arange(m)
    top, lift = _extreme_rows(Y, VY, AY, h, +1)
    drop = _extreme_rows(Y, VY, AY, h, -1)[1]
    xmax = _extreme_rows(X, VX, AX, h, +1)[1]
    xmin = _extreme_rows(X, VX, AX, h, -1)[1]
    ph, dirn, t = _crossing_rows(Y, VY, h)
    # the window above the plate that contains the top of lift: the last rise before the top
    # and the first drop after it
    up_key = np.where(dirn > 0, (top[:, None] - ph) % two_pi, np.inf)
    dn_key = np.where(dirn < 0, (ph - top[:, None]) % two_pi, np.inf)
    has = np.isfinite(up_key).any(axis=1) & np.isfinite(dn_key).any(axis=1)
    ku = np.argmin(up_key, axis=1)
    kd = np.argmin(dn_key, axis=1)
    rise = np.where(has, ph[r, ku], np.nan)
    fall = np.where(has, ph[r, kd], np.nan)
    x_rise = _at_rows(X, VX, ku, t[r, ku], h)
    x_fall = _at_rows(X, VX, kd, t[r, kd], h)
    stitch = np.where(has, fwd * (x_fall - x_rise), np.nan)
    # mid-feed: the tip passes the middle of its stroke, moving with the stitch, while above
    pm, dm, _ = _crossing_rows(X - 0.5 * (xmax + xmin)[:, None], VX, h)
    want = (np.sign(stitch) * fwd)[:, None]
    since_rise = (pm - rise[:, None]) % two_pi
    inside = (dm == want) & (since_rise <= ((fall - rise) % two_pi)[:, None])
    key = np.where(inside, since_rise, np.inf)
    km = np.argmin(key, axis=1)
    mid = np.where(np.isfinite(key[r, km]) & (stitch != 0.0), pm[r, km], np.nan)
    return {"stitch_mm": stitch, "lift_mm": lift, "drop_mm": drop, "top_deg": np.degrees(top),
            "rise_deg": np.degrees(rise), "fall_deg": np.degrees(fall),
            "stroke_mm": xmax - xmin, "mid_feed_deg": np.degrees(mid)}


def stitch_length(machine: Machine, regulator_deg: float, *, params=None) -> float:
    """Signed stitch length (mm, + forward) at one regulator setting (degrees)."""
    return float(feed_cycles(machine, regulator_deg, params=params).stitch_mm)


def stitch_curve(machine: Machine, n: int = 61, *, params=None) -> FeedCycles:
    """Feed figures at ``n`` settings evenly over the regulator's travel (computed once per
    design: the report's feed section and its comparison read the same curve)."""
    memo = evaluation(machine, params).memo
    key = ("stitch_curve", int(n))
    if key not in memo:
        lo, hi = regulator_range_deg(machine)
        memo[key] = feed_cycles(machine, np.linspace(lo, hi, n), params=params)
    return memo[key]


def zero_mark(machine: Machine, *, params=None) -> float:
    """Regulator setting (degrees) where the stitch length is zero, to 1e-9 deg."""
    lo, hi = regulator_range_deg(machine)
    c = stitch_curve(machine, 21, params=params)
    sgn = np.sign(c.stitch_mm)
    k = np.nonzero(sgn[:-1] * sgn[1:] <= 0)[0]
    if k.size == 0:
        raise ValueError(f"machine '{machine.name}': the stitch length does not change sign over"
                         f" the regulator travel {lo:g}..{hi:g} deg")
    a, b = c.regulator_deg[k[0]], c.regulator_deg[k[0] + 1]
    from scipy.optimize import brentq

    return brentq(lambda g: stitch_length(machine, g, params=params), a, b, xtol=1e-9)


@dataclass(frozen=True)
class ScaleMark:
    """One mark of the stitch-length scale plate: stitch length (mm, - reverse), setting (deg)."""

    stitch_mm: float
    regulator_deg: float


def scale_marks(machine: Machine, step_mm: float = 0.5, *, params=None,
                curve: FeedCycles | None = None) -> list[ScaleMark]:
    """Regulator settings for every ``step_mm`` of stitch length, forward and reverse.

    The marks are solved on the stitch-length curve (secant iterations from its interpolation)
    to 1e-6 mm of stitch length; the curve must be monotonic over the regulator's travel.
    ``curve``: a :func:`stitch_curve` of the same machine and ``params`` already computed (any
    number of settings over the whole travel); default: one of 61 settings.
    """
    if not 0.001 <= step_mm <= 100.0:  # (a NaN fails too)
        raise OptionError("step_mm", f"must be a stitch-length step in 0.001 .. 100 mm, got"
                          f" {step_mm!r}", "Give e.g. 0.5")
    c = stitch_curve(machine, 61, params=params) if curve is None else curve
    st, rg = c.stitch_mm, c.regulator_deg
    travel = regulator_range_deg(machine)
    d = np.diff(st)
    if not (np.all(d > 0) or np.all(d < 0)):
        raise ValueError(f"machine '{machine.name}': the stitch length is not monotonic over the"
                         " regulator travel, so a scale cannot be made")
    order = np.argsort(st)
    st_s, rg_s = st[order], rg[order]
    lo = math.ceil(st_s[0] / step_mm - 1e-9)
    hi = math.floor(st_s[-1] / step_mm + 1e-9)
    targets = np.arange(lo, hi + 1) * step_mm
    g0 = np.interp(targets, st_s, rg_s)
    # the secant's second point 0.01 deg away, inside the travel (a mark at its end would
    # otherwise be evaluated beyond the regulator's range, which is refused)
    g1 = np.where(g0 + 0.01 <= travel[1], g0 + 0.01, g0 - 0.01)
    f0 = feed_cycles(machine, g0, params=params).stitch_mm - targets
    for _ in range(30):
        f1 = feed_cycles(machine, g1, params=params).stitch_mm - targets
        if np.all(np.abs(f1) < 1e-6):
            break
        den = np.where(f1 != f0, f1 - f0, 1.0)
        g0, g1, f0 = g1, np.clip(np.where(np.abs(f1) < 1e-6, g1, g1 - f1 * (g1 - g0) / den),
                                 *travel), f1
    return [ScaleMark(float(t), float(g)) for t, g in zip(targets, g1)]


# ---- relative position of the feed cam -------------------------------------------------------------


@dataclass(frozen=True)
class FeedTiming:
    """Feed-cam phase that puts the middle of the feed stroke at the target shaft angle.

    overrides: parameter values (internal units) for ``Machine.parameters``; phase_deg: the
    feed cam's phase on the upper shaft; cycle: the feed figures at the timing setting with it.
    """

    overrides: dict
    phase_deg: float
    cycle: FeedCycles


def set_feed_timing(machine: Machine, mid_feed_after_top_deg: float = 0.0, *,
                    regulator_deg: float | None = None, params=None) -> FeedTiming:
    """Phase the feed cam so that the dog is halfway through its feed stroke
    ``mid_feed_after_top_deg`` after its top of lift (at the longest forward stitch unless
    ``regulator_deg`` is given).

    With the feed cam turning with the shaft at ratio 1, a phase change shifts the horizontal
    motion along the shaft angle; the vertical motion depends on it only slightly (the feed bar
    slides over the lift roller), so the shift is repeated until the target holds to 1e-6 deg.
    The report's determination of the mechanisms' relative positions (各机构间相对位置的确定)
    for the feed.
    """
    s = _roles(machine)
    if s.feed_cam is None:
        raise ValueError(f"machine '{machine.name}': [sewing] feed_cam (the crank unit of the feed"
                         " cam) is not set")
    spec = next(u for u in machine.spec.units if u.name == s.feed_cam)
    if spec.ratio != 1.0 or spec.input != "shaft":
        raise ValueError(f"feed cam crank '{s.feed_cam}' must turn with the shaft at ratio 1")
    reg = regulator_range_deg(machine)[1] if regulator_deg is None else regulator_deg
    p = np.array(machine.defaults if params is None else params, dtype=float)
    i = machine.parameter_index(f"{s.feed_cam}.phase")
    for _ in range(20):
        c = feed_cycles(machine, reg, params=p)
        if not np.isfinite(c.mid_feed_deg):
            raise ValueError(f"no feed at regulator {reg:g} deg: choose a setting with a stitch")
        err = ((float(c.mid_feed_deg - c.top_deg) - mid_feed_after_top_deg + 180.0) % 360.0
               - 180.0)
        if abs(err) < 1e-6:
            break
        p[i] += math.radians(err)  # x(phi) ~ x0(phi + phase): a later mid-feed needs more phase
    else:
        raise AnalysisError(f"machine '{machine.name}' ({machine.file}) [sewing] feed_cam",
                            f"no phase of the feed cam puts the middle of the feed stroke"
                            f" {mid_feed_after_top_deg:g} deg after the top of lift at regulator"
                            f" {reg:g} deg: 20 steps left it {abs(err):.3g} deg off (the"
                            " middle of the stroke does not move with the cam's phase as a"
                            " shift of the shaft angle)", "Check the feed and lift cams'"
                            " dimensions against the machine's")
    return FeedTiming({f"{s.feed_cam}.phase": float(p[i])}, math.degrees(p[i]) % 360.0, c)


# ---- checks against the facts of the machine class ---------------------------------------------


def _overlap_deg(a0, a1, b0, b1) -> float:
    """Length (deg) of the overlap of two shaft-angle windows [a0, a1], [b0, b1] (may wrap)."""
    la = (a1 - a0) % 360.0
    lb = (b1 - b0) % 360.0
    b0 = a0 + (b0 - a0) % 360.0  # b's start at or after a's, then try b one turn earlier too
    return sum(max(0.0, min(a0 + la, s + lb) - max(a0, s)) for s in (b0, b0 - 360.0))


def check_feed(machine: Machine, params=None) -> list:
    """The feed checks (sources: docs/references.md) as :class:`sewmech.timing.Check` rows."""
    s = _roles(machine)
    lo, hi = regulator_range_deg(machine)
    c = feed_cycles(machine, [lo, ZERO_MARK_DEG, hi], params=params)
    w_in, w_below = needle_windows(machine, params)
    out = []
    a, b = FEED_DOG_RISE_MM
    lift = float(c.lift_mm[1])
    out.append(Check("feed dog above the plate at the top of lift (zero mark)", lift, "mm",
                     f"{a:g}-{b:g}", a <= lift <= b,
                     "[Sdelai-sam-1999] (Podolsk household machine)"))
    a, b = MAX_STITCH_MM
    for name, v in (("longest forward stitch", float(c.stitch_mm[2])),
                    ("longest reverse stitch", -float(c.stitch_mm[0]))):
        out.append(Check(name, v, "mm", f"{a:g}-{b:g}", a <= v <= b,
                         "[Navy-Singer-31-15], [SewingMachineNut-2018] (Singer 31-15;"
                         " class-15 machines measured)"))
    z = float(c.stitch_mm[1])
    out.append(Check("stitch at the regulator's zero mark", z, "mm", "|s| <= 0.01",
                     abs(z) <= 0.01, "[JB-kinematics] (no feed at the 0 mark)"))
    # the dog when the needle point reaches the plate, at the longest forward stitch
    phi_plate = math.radians(w_below.start_deg)
    r = kinematics(machine, np.array([phi_plate]), params=params,
                   inputs={s.regulator: math.radians(hi)}, points=[s.feed_dog])
    h = float(r.point(s.feed_dog).p[0, 1] - s.plate_y)
    out.append(Check("dog height when the needle point reaches the plate", h, "mm",
                     "<= 0 (level with or below the plate)", h <= 0.0,
                     "[NAVEDTRA-14218], [Juki-TL-2010Q], [Brother-S-7000DD]"))
    worst = max(_overlap_deg(float(c.rise_deg[k]), float(c.fall_deg[k]), w_in.start_deg,
                             w_in.end_deg) for k in range(3) if np.isfinite(c.rise_deg[k]))
    out.append(Check("overlap of 'needle in fabric' and 'dog above plate'", worst, "deg",
                     "0 (the dog feeds only while the needle is out)", worst == 0.0,
                     "[Juki-how-it-works], [SMI-feed-dog]"))
    return out


# ---- sensitivity of the feed to its structural parameters --------------------------------------


@dataclass(frozen=True)
class Sensitivity:
    """Feed figures with each structural parameter changed by -x %, 0, +x %.

    ``cycles`` has batch shape (n_parameters, 3): columns -x, 0, +x (the middle column is the
    machine as it is). ``table()`` gives the changes against it.
    """

    relative_change: float
    regulator_deg: float
    labels: tuple[str, ...]
    names: tuple[tuple[str, ...], ...]
    cycles: FeedCycles

    def table(self):
        """One row per parameter: changes of stitch length (mm), lift (mm) and feed timing
        (mid-feed shaft angle, deg) at -x % and +x %."""
        import pandas as pd

        c = self.cycles
        pct = 100.0 * self.relative_change
        rows = []
        for i, label in enumerate(self.labels):
            row = {"parameter": label, "names": " ".join(self.names[i])}
            for j, tag in ((0, f"-{pct:g}%"), (2, f"+{pct:g}%")):
                row[f"stitch change {tag} [mm]"] = c.stitch_mm[i, j] - c.stitch_mm[i, 1]
                row[f"lift change {tag} [mm]"] = c.lift_mm[i, j] - c.lift_mm[i, 1]
                row[f"timing change {tag} [deg]"] = ((c.mid_feed_deg[i, j] - c.mid_feed_deg[i, 1]
                                                      + 180.0) % 360.0 - 180.0)
            row["feasible"] = bool(c.feasible[i].all())
            rows.append(row)
        return pd.DataFrame(rows)


def _base_value(machine: Machine, name: str) -> float:
    cam, _, key = name.rpartition(".")
    if cam in machine.cam_designs and key in machine.cam_designs[cam]:
        return machine.cam_designs[cam][key]
    return float(machine.defaults[machine.parameter_index(name)])


def sensitivity(machine: Machine, relative_change: float = 0.05, *,
                parameters: dict[str, list[str]] | None = None,
                regulator_deg: float | None = None, step_deg: float = 1.0) -> Sensitivity:
    """Change each structural parameter of the feed by -x %, 0, +x % (one batch) and record
    the dog's trajectory, stitch length, lift and feed timing.

    parameters: label -> parameter names changed together (default: ``[sewing]
    feed_parameters`` of the machine file). regulator_deg: the setting (default: the longest
    forward stitch). Designs that cannot be assembled come back masked, not as errors.
    """
    if not 0.0 < relative_change < 1.0:
        raise ValueError(f"relative_change must be in (0, 1), got {relative_change}")
    s = _roles(machine)
    groups = dict(s.feed_parameters if parameters is None else parameters)
    if not groups:
        raise ValueError(f"machine '{machine.name}': no feed parameters to study; list them in"
                         " [sewing.feed_parameters] or pass parameters=")
    reg = regulator_range_deg(machine)[1] if regulator_deg is None else regulator_deg
    P = np.empty((len(groups), 3, machine.defaults.size))
    for i, names in enumerate(groups.values()):
        for j, f in enumerate((1.0 - relative_change, 1.0, 1.0 + relative_change)):
            P[i, j] = machine.parameters({n: _base_value(machine, n) * f for n in names})
    c = feed_cycles(machine, reg, params=P, step_deg=step_deg, on_failure="mask")
    return Sensitivity(relative_change, reg, tuple(groups), tuple(tuple(v) for v in
                                                                  groups.values()), c)

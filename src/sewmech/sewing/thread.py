"""The needle thread: its path through the guides, the take-up's supply.

A thread path is an ordered list of guides from the tension discs to the needle eye. Each guide
is a point (a hole or an eye: the thread passes through it) or a pin of radius r (the thread
wraps it, counter-clockwise or clockwise as seen from the hand-wheel end). Between guides the
thread runs straight, along the common tangent of the two guides' circles; on a pin it follows
the arc between its incoming and outgoing tangent points. Guides may move (the take-up eye, the
needle-bar thread guide, the needle eye): the path is evaluated from the kinematics at every
shaft angle, for one design or a batch.

Geometry. Give every guide a signed radius rho (+r: the thread turns left, counter-clockwise,
round it; -r: right; 0: a point). The thread leaves guide 1 towards guide 2 along the unit
vector u with tangent points t_k = c_k + rho_k R(u), R(u) the right normal of u. Requiring
t2 - t1 parallel to u gives, with d = c2 - c1, b = rho1 - rho2 and a = sqrt(|d|^2 - b^2):
u = (a d + b J d) / |d|^2 (J: rotation by +90 deg) and a straight length a. On a pin the thread
turns from u_in to u_out through the angle measured in its wrap direction, in [0, 2 pi).
A pin holds the thread on its given side at every angle (as a hook or an eye would); place the
guides so that the thread bends round each pin the same way all through the cycle (a wrap that
jumps towards 360 deg means it does not).

The take-up's supply is S(phi) = max L_tu - L_tu(phi), L_tu the length of the take-up section
of the path (from ``take_up[0]`` to ``take_up[1]``): the thread the take-up has released
towards the needle ([Krasowska-take-up], [US-10017890]). Lengths in mm, angles rad inside,
degrees at the edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..engine._events import crossing_rows as _crossing_rows
from ..engine.errors import AnalysisError, MachineFileError, OptionError
from ..engine.threadpath import path_length, path_length_gradient  # noqa: F401 (public here too)
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from . import timing as T
from .timing import Check


@dataclass(frozen=True)
class ThreadPath:
    """Thread lengths over the shaft cycle (batch + (n_phi,) arrays, mm).

    total: the whole path; take_up: its take-up section; supply: max(take_up) - take_up, the
    thread released towards the needle; below: the part after the take-up section (to the
    needle eye).
    """

    phi_deg: np.ndarray
    total: np.ndarray = field(repr=False)
    take_up: np.ndarray = field(repr=False)
    supply: np.ndarray = field(repr=False)
    below: np.ndarray = field(repr=False)

    @property
    def stroke(self) -> np.ndarray:
        """The take-up's thread stroke: peak-to-peak of its section, mm."""
        return np.ptp(self.take_up, axis=-1)


def _thread_spec(machine: Machine):
    t = machine.spec.thread
    if t is None:
        raise ValueError(f"machine '{machine.name}' ({machine.file}) has no [thread] table: list"
                         " the thread guides (docs/machine-files.md)")
    return t


def guide_radii(machine: Machine) -> np.ndarray:
    """Signed radii of the file's thread guides (mm; + counter-clockwise wrap)."""
    t = _thread_spec(machine)
    return np.array([g.radius * (1.0 if g.wrap == "ccw" else -1.0) for g in t.guides])


def thread_path(machine: Machine, phi: ArrayLike, *, params=None, inputs=None,
                on_failure: str = "raise") -> ThreadPath:
    """Lengths of the machine's thread path at shaft angles ``phi`` (rad) for one design or a
    batch (``params``). The supply is taken over the given angles: pass a full cycle.
    ``on_failure="mask"``: designs that cannot be assembled, or whose guides overlap, give NaN.
    """
    names = list(dict.fromkeys(g.point for g in _thread_spec(machine).guides))
    r = kinematics(machine, phi, params=params, inputs=inputs, points=names, links=[],
                   variables=[], on_failure=on_failure)
    return _path_of(machine, r, on_failure)


def _path_of(machine: Machine, r, on_failure: str = "raise") -> ThreadPath:
    """The thread path from a kinematics result that holds every guide point."""
    t = _thread_spec(machine)
    pos = np.stack([r.point(g.point).p for g in t.guides], axis=-2)  # batch+(n_phi, n_guide, 2)
    rho = guide_radii(machine)
    i0, i1 = t.take_up
    mode = "nan" if on_failure == "mask" else "raise"
    if mode == "raise":
        _refuse_overlap(machine, pos, rho, np.degrees(r.phi))
    total = path_length(pos, rho, on_overlap=mode)
    tu = path_length(pos[..., i0:i1 + 1, :], rho[i0:i1 + 1], on_overlap=mode)
    below = path_length(pos[..., i1:, :], rho[i1:], on_overlap=mode)
    return ThreadPath(np.degrees(r.phi), total, tu, tu.max(axis=-1, keepdims=True) - tu, below)


def _refuse_overlap(machine: Machine, pos: np.ndarray, rho: np.ndarray, phi_deg) -> None:
    """Two neighbouring guides with no common tangent at some angle (a guide inside the
    other's pin, or on it): a located error of the file's [thread] guides, naming the pair and
    the first such angle (it was the path's own "thread guides 0 and 1 overlap", without a
    file or a table, and only once an analysis read the thread)."""
    d = pos[..., 1:, :] - pos[..., :-1, :]
    b = rho[:-1] - rho[1:]
    bad = np.einsum("...i,...i->...", d, d) - b * b < 0.0  # batch + (n_phi, n_guide - 1)
    if not bad.any():
        return
    flat = bad.reshape(-1, bad.shape[-2], bad.shape[-1])
    _, j, k = (int(i) for i in np.argwhere(flat)[0])
    g = _thread_spec(machine).guides
    at = f" at phi = {float(np.ravel(phi_deg)[j]):g} deg" if np.size(phi_deg) > 1 else ""
    raise MachineFileError(machine.file, "thread", f"guides[{k}]", f"'{g[k].point}' and the next"
                           f" guide, '{g[k + 1].point}', overlap{at}: the thread has no common"
                           " tangent to run along from one to the other (they are closer than"
                           " the difference of their signed radii)", "Move the guides apart, or"
                           " give the pins smaller radii")


# ---- demand of the stitch-forming side, and the balance ------------------------------------------

CHECK_SPRING_STROKE_MM = 10.0  # [Juki-LK-1900B]: the check spring's stroke, 8-10 mm


def consumption_per_stitch(stitch_mm: ArrayLike, fabric_mm: ArrayLike,
                           thread_diameter_mm: ArrayLike = 0.0) -> dict[str, np.ndarray]:
    """Needle and bobbin thread per stitch of a balanced lockstitch (type 301), mm.

    Each thread runs one stitch length along its face of the fabric and half the thickness
    down (or up) to the interlacing at mid-thickness and back: l + t each ([Thread-consumption-301],
    the geometric form of the industry formula); a finite thread diameter d adds the bend of each
    thread round the other at the interlacing, pi d / 2 per thread (Malek et al., Autex 2020,
    [Malek-2020], in its simplest form). Also returned: the industry formula
    C = 2 + 2 T S (inches of thread per inch of seam, T thickness in inches, S stitches per inch)
    converted to mm per stitch, for comparison (with d = 0 it equals needle + bobbin).
    """
    l = np.asarray(stitch_mm, dtype=float)
    t = np.asarray(fabric_mm, dtype=float)
    d = np.asarray(thread_diameter_mm, dtype=float)
    if not (np.all(l > 0) and np.all(t >= 0) and np.all(d >= 0)
            and np.isfinite([l.max(), t.max(), d.max()]).all()):  # NaN fails too
        raise OptionError("stitch_mm", "stitch length must be > 0, fabric thickness and thread"
                          " diameter >= 0, all finite (mm)")
    each = l + t + 0.5 * math.pi * d
    inch = 25.4
    spi = inch / l
    industry = (2.0 + 2.0 * (t / inch) * spi) * inch / spi  # thread per inch x inches per stitch
    return {"needle": each, "bobbin": each.copy(), "total": 2.0 * each, "industry": industry}


def _taut_round_circle(A, C, R, B):
    """Shortest thread from A to B (..., 2) that may not enter the circle (C, R): straight if
    the segment clears it, else tangent + arc + tangent on the shorter side."""
    A, B = np.broadcast_arrays(np.asarray(A, float), np.asarray(B, float))
    C = np.broadcast_to(np.asarray(C, float), A.shape)
    ab = B - A
    t = np.clip(np.einsum("...i,...i->...", C - A, ab) / np.einsum("...i,...i->...", ab, ab),
                0.0, 1.0)
    gap = np.linalg.norm(A + t[..., None] * ab - C, axis=-1)
    straight = np.linalg.norm(ab, axis=-1)
    pts = np.stack([A, C, B], axis=-2)
    wrap = np.minimum(path_length(pts, np.array([0.0, R, 0.0])),
                      path_length(pts, np.array([0.0, -R, 0.0])))
    return np.where(gap >= R, straight, wrap)


@dataclass(frozen=True)
class ThreadBalance:
    """Supply, demand and overfeed of the needle thread over one cycle (mm, one design).

    Demand parts: ``bar`` the path from the end of the take-up section to the needle eye;
    ``penetration`` the leg from the eye back up to the fabric's top (0 while the eye is above
    it; the leg down to the eye is part of ``bar``); ``loop`` the growth of the loop the shuttle
    draws round the bobbin case, from seizure to cast-off. ``demand`` is their sum relative to
    its value at the take-up's top (the stitch is set there: no slack), ``overfeed`` = supply -
    demand: the slack thread the check spring or the loop takes.
    """

    phi_deg: np.ndarray
    supply: np.ndarray
    bar: np.ndarray
    penetration: np.ndarray
    loop: np.ndarray
    demand: np.ndarray
    overfeed: np.ndarray
    take_up_top_deg: float  # least supply: the take-up holds the most thread (stitch set)
    seizure_deg: float
    cast_off_deg: float
    loop_max_deg: float
    needle_entry_deg: float
    stitch_mm: float
    fabric_mm: float
    consumption_mm: float

    def _at(self, values, phi_deg):
        return float(np.interp(phi_deg % 360.0, self.phi_deg, values, period=360.0))

    @property
    def min_overfeed_while_loop_grows(self) -> float:
        """Least overfeed from seizure to the loop's largest size, mm (must be >= 0)."""
        a, b = self.seizure_deg, self.loop_max_deg
        inside = (self.phi_deg - a) % 360.0 <= (b - a) % 360.0
        return float(self.overfeed[inside].min())

    @property
    def overfeed_at_needle_entry(self) -> float:
        return self._at(self.overfeed, self.needle_entry_deg)

    @property
    def reserve_after_cast_off(self) -> float:
        """Overfeed once the loop is cast off: the slack the take-up still pulls in while
        rising to its top; it must cover the thread the stitch consumes (mm)."""
        return self._at(self.overfeed, self.cast_off_deg)

    def to_pandas(self):
        import pandas as pd

        return pd.DataFrame({k: getattr(self, k) for k in ("phi_deg", "supply", "bar",
                                                           "penetration", "loop", "demand",
                                                           "overfeed")})


def thread_balance(machine: Machine, *, stitch_mm: float = 2.5, fabric_mm: float | None = None,
                   step_deg: float = 0.5, params=None) -> ThreadBalance:
    """The thread balance of one cycle: the take-up's supply against the stitch's demand.

    Supply against demand ([Krasowska-take-up], [US-10017890]) with the machine's own
    geometry: the take-up section and the path to the needle eye from ``[thread]``, the eye
    and fabric from ``[sewing]``, loop seizure from the shuttle timing, and the loop drawn round
    a bobbin case of ``bobbin_case_radius`` about the shuttle axis until the shuttle has turned
    ``cast_off_deg`` past seizure.
    """
    return _balance(machine, stitch_mm, fabric_mm, step_deg, params)[0]


def _balance(machine: Machine, stitch_mm: float, fabric_mm: float | None, step_deg: float,
             params) -> tuple[ThreadBalance, dict]:
    """:func:`thread_balance` and what it was read from (the kinematics, the grid indices of
    its events, the loop's drawing mask): what the balance's derivatives need."""
    t = _thread_spec(machine)
    s = T.roles(machine)
    if t.bobbin_case_radius is None:
        raise ValueError(f"machine '{machine.name}': [thread] bobbin_case_radius is needed for"
                         " the loop demand")
    fabric = s.fabric_thickness if fabric_mm is None else float(fabric_mm)
    if not (0.0 < stitch_mm <= 100.0 and 0.0 <= fabric <= 100.0):  # (a NaN fails too)
        raise OptionError("stitch_mm" if not 0.0 < stitch_mm <= 100.0 else "fabric_mm",
                          f"stitch length {stitch_mm!r} mm and fabric thickness {fabric!r} mm"
                          " must be finite, the stitch in (0, 100] mm, the fabric in [0, 100]"
                          " mm")
    n = round(360.0 / step_deg)
    if n < 36 or abs(n * step_deg - 360.0) > 1e-9:
        raise ValueError(f"step_deg must divide 360 into at least 36 steps, got {step_deg}")
    h = 2.0 * math.pi / n
    phi = np.arange(n) * h
    sp = T._need(s.shuttle_point, "shuttle_point", machine)
    link = T._need(s.shuttle_link, "shuttle_link", machine)
    axis = T._shuttle_axis(machine)
    guides = [g.point for g in t.guides]
    pts = list(dict.fromkeys(guides + [s.needle_point, s.needle_eye, sp, axis]))
    # one pass at omega = 1 rad/s: velocities are d/dphi, for the events on the grid
    r = kinematics(machine, phi, params=params, points=pts, links=[link], variables=[],
                   omega=1.0)
    tp = _path_of(machine, r)
    eye = r.point(s.needle_eye).p
    pen = np.maximum(0.0, s.plate_y + fabric - eye[:, 1])
    # seizure: after the needle's bottom dead centre, the shuttle point first crosses the
    # needle line above its shaft axis (the definition of sewmech.timing.loop_lift)
    needle = r.point(s.needle_point)
    k_bdc = int(np.argmin(needle.p[:, 1]))
    x_line = needle.p[k_bdc, 0]
    spm = r.point(sp)
    above = spm.p[:, 1] > r.point(axis).p[:, 1]
    ph = _crossing_rows((spm.p[:, 0] - x_line)[None], spm.v[None, :, 0], h)[0][0]
    after_bdc = np.where(above & np.isfinite(ph), (ph - phi[k_bdc]) % (2 * math.pi), np.inf)
    if not np.isfinite(after_bdc).any():
        raise ValueError(f"machine '{machine.name}': the shuttle point never passes the needle"
                         " line above its axis")
    seize = float(ph[np.argmin(after_bdc)])
    k_s = int(math.ceil(seize / h - 1e-9)) % n  # first grid angle with the loop seized
    theta = np.unwrap(np.roll(r.link(link).theta, -k_s))
    turned = np.abs(theta - theta[0])  # shuttle turn since seizure
    drawing = np.roll(np.maximum.accumulate(turned) < math.radians(t.cast_off_deg), k_s)
    # the loop: from the needle hole in the plate round the bobbin case to the shuttle point
    hole = np.array([x_line, s.plate_y])
    legs = _taut_round_circle(hole, r.point(axis).p, t.bobbin_case_radius, spm.p)
    loop = np.where(drawing, 2.0 * (legs - legs[k_s]), 0.0)
    raw = tp.below + pen + loop
    k_top = int(np.argmin(tp.supply))
    demand = raw - raw[k_top]
    off = np.nonzero(~np.roll(drawing, -k_s))[0]
    k_c = (k_s + int(off[0])) % n if off.size else k_s  # first angle with the loop cast off
    k_m = (k_s + int(np.argmax(np.roll(loop, -k_s)[: max(1, (k_c - k_s) % n)]))) % n
    # needle entry: the needle point passes the fabric's top going down
    ph, d, _ = (a[0] for a in _crossing_rows((needle.p[:, 1] - (s.plate_y + fabric))[None],
                                              needle.v[None, :, 1], h))
    if not (d < 0).any():
        raise ValueError(f"machine '{machine.name}': the needle never enters the fabric")
    deg = 360.0 / n
    balance = ThreadBalance(np.arange(n) * deg, tp.supply, tp.below, pen, loop, demand,
                            tp.supply - demand, k_top * deg, math.degrees(seize), k_c * deg,
                            k_m * deg, math.degrees(float(ph[d < 0][0])), float(stitch_mm),
                            fabric, float(consumption_per_stitch(stitch_mm, fabric,
                                                                 t.thread_diameter)["needle"]))
    return balance, {"r": r, "h": h, "k_top": k_top, "k_s": k_s, "k_c": k_c, "k_m": k_m,
                     "k_bdc": k_bdc, "k_max": int(np.argmax(tp.take_up)), "drawing": drawing,
                     "hole": hole, "axis": axis, "shuttle_point": sp, "fabric": fabric,
                     "entry": float(ph[d < 0][0])}


def check_thread(machine: Machine, balance: ThreadBalance | None = None) -> list:
    """The thread-balance checks as :class:`sewmech.timing.Check` rows (their sources:
    docs/references.md)."""
    b = thread_balance(machine) if balance is None else balance
    out = []
    v = b.min_overfeed_while_loop_grows
    out.append(Check("least overfeed while the shuttle enlarges the loop", v, "mm",
                     ">= 0 (no thread pulled through the tension)", v >= 0.0,
                     "[US-10017890], [Krasowska-take-up] (the loop takes no more than the"
                     " take-up supplies)"))
    v = b.overfeed_at_needle_entry
    out.append(Check("overfeed when the needle enters the fabric", v, "mm",
                     f"0-{CHECK_SPRING_STROKE_MM:g} (the check spring takes it)",
                     0.0 <= v <= CHECK_SPRING_STROKE_MM,
                     "[Juki-LK-1900B] (check-spring stroke 8-10 mm)"))
    v = b.reserve_after_cast_off
    out.append(Check("take-up reserve once the loop is cast off", v, "mm",
                     f">= {b.consumption_mm:.2f} (the needle thread one stitch consumes)",
                     v >= b.consumption_mm, "[Thread-consumption-301] (stitch set:"
                     " l + t drawn per cycle)"))
    return out


# ---- the adjustable take-up ------------------------------------------------------------------------


@dataclass(frozen=True)
class TakeUpAdjustment:
    """Setting of one adjustable take-up dimension against fabric thickness.

    ``margin[i, j]`` (mm) is the smallest of the four slacks of the balance checks for thickness
    i at setting j: least overfeed while the loop grows, overfeed at needle entry, room left in
    the check spring, reserve after cast-off beyond the consumption; >= 0 means every check
    passes. ``best`` is the setting with the largest margin per thickness (NaN if none passes).
    """

    parameter: str
    thickness_mm: np.ndarray
    settings: np.ndarray
    margin: np.ndarray = field(repr=False)
    best: np.ndarray
    best_margin: np.ndarray

    def table(self):
        import pandas as pd

        return pd.DataFrame({"fabric_mm": self.thickness_mm,
                             f"recommended {self.parameter}": self.best,
                             "margin_mm": self.best_margin})


def adjust_take_up(machine: Machine, parameter: str, settings: ArrayLike, *,
                   thickness_mm: ArrayLike = np.arange(0.5, 6.01, 0.5), stitch_mm: float = 2.5,
                   step_deg: float = 0.5, params=None) -> TakeUpAdjustment:
    """For each fabric thickness, the setting of ``parameter`` (a take-up dimension, internal
    units) at which supply best matches demand: the largest margin to all the balance checks.

    The demand does not depend on the take-up and the supply does not depend on the fabric, so
    one batch of thread paths over the settings and one balance per thickness give the whole
    (thickness x setting) table.
    """
    svals = np.asarray(settings, dtype=float)
    tvals = np.asarray(thickness_mm, dtype=float)
    base = np.array(machine.defaults if params is None else params, dtype=float)
    P = machine.parameters({parameter: svals}, base=base)
    n = round(360.0 / step_deg)
    phi = np.arange(n) * (2.0 * math.pi / n)
    S = thread_path(machine, phi, params=P, on_failure="mask").supply  # (n_set, n)
    ok = np.isfinite(S).all(axis=-1)
    if not ok.any():
        raise AnalysisError(machine.file, f"the take-up cannot be assembled at any of the"
                            f" {svals.size} settings of '{parameter}' from {svals.min():g} to"
                            f" {svals.max():g}", "Give [thread.adjust] a range where it"
                            " assembles (sewmech check --set PARAM=VALUE tries one)")
    k_top = np.argmin(np.where(ok[:, None], S, np.inf), axis=-1)
    margin = np.full((tvals.size, svals.size), np.nan)
    for a, t in enumerate(tvals):
        b = thread_balance(machine, stitch_mm=stitch_mm, fabric_mm=t, step_deg=step_deg,
                           params=base)
        raw = b.bar + b.penetration + b.loop
        O = S - (raw[None, :] - raw[k_top][:, None])
        grow = (b.phi_deg - b.seizure_deg) % 360 <= (b.loop_max_deg - b.seizure_deg) % 360
        # at needle entry: linear between the grid angles, as ThreadBalance reads it
        x = b.needle_entry_deg / step_deg
        k0 = int(math.floor(x)) % n
        w = x - math.floor(x)
        o_e = (1.0 - w) * O[:, k0] + w * O[:, (k0 + 1) % n]
        k_c = int(round(b.cast_off_deg / step_deg)) % n
        m = np.minimum.reduce([O[:, grow].min(axis=-1), o_e, CHECK_SPRING_STROKE_MM - o_e,
                               O[:, k_c] - b.consumption_mm])
        margin[a] = np.where(ok, m, np.nan)
    filled = np.where(np.isfinite(margin), margin, -np.inf)
    j = np.argmax(filled, axis=-1)
    best_margin = filled[np.arange(tvals.size), j]
    best = np.where(best_margin >= 0.0, svals[j], np.nan)
    return TakeUpAdjustment(parameter, tvals, svals, margin, best,
                            np.where(np.isfinite(best_margin), best_margin, np.nan))

"""The feed metrics of many designs close to a nominal one: the tolerance Monte Carlo's batch.

A design made within its tolerances moves its events (the dog rising through the throat plate
and dropping through it again, the top of its lift, the needle point reaching the plate) by a
few degrees: the dog crosses the plate slowly. Instead of marching every design around the
whole turn and interpolating a grid, each design's events are located by Newton's method on
its exact kinematics, all designs at once:

- the start: the nominal event moved by the event's exact derivative times the design's
  deviation (:class:`sewmech.sewing.gradients.Gradient` ``events_d``; on JB1-3 within IT9 it
  misses by a tenth of a degree at most);
- the steps: :class:`sewmech.sewing._locate.Locator`, every design at its own shaft angle in
  one compiled call, moved by the root of the channel's second-order Taylor polynomial; two or
  three steps reach its ``STEP_TOL``, and the value read there is exact to round-off. For
  JB1-3's stitch length: 4 to 6 positions per design instead of a whole turn.

Two guards keep it honest:

- a design whose Newton steps do not settle (or cross the wrong way, or go beyond
  ``REACH`` from the start) is located again from the whole turn (:func:`whole_turn_values`:
  the events found on a 1 deg grid, then the same Newton steps), and counted;
- a sample of ``CHECK_DESIGNS`` designs is located from the whole turn as well and must agree
  to ``CHECK_MM``, and assemble all the way round; otherwise every design is (a nominal
  design whose event another part of the turn could take over, or designs that jam
  elsewhere in the turn, are caught there). The rest is not marched round: a design that
  jams away from its events while all of the sample assemble is counted as assembled (with
  1000 checked, a defect in 1 of 200 designs slips through once in 150 analyses).

Units: mm; angles rad inside, deg in the names that say so.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine._events import crossing_rows
from ..engine.evaluation import evaluation
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from ._locate import Locator
from .feed import _roles, feed_cycles
from .gradients import Gradient

#: designs located again from the whole turn to check the starts and that the designs
#: assemble all the way round, and the agreement asked (mm)
CHECK_DESIGNS = 1000
CHECK_MM = 1e-9
#: the whole turn's grid (deg): the events found on it start the same Newton steps
TURN_STEP_DEG = 5.0
#: the metrics located this way
WINDOWED = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


def _locate_metric(machine: Machine, metric: str, loc: Locator, starts: dict):
    """The metric from Newton's method started at ``starts`` (event -> (m,) rad): the values
    (NaN where a design was not located) and which designs were."""
    s = _roles(machine)
    if metric == "stitch_length":
        fwd = 1.0 if s.forward == "+x" else -1.0
        _, f1, x1 = loc.locate(starts["rise"], s.feed_dog, 1, s.plate_y, "up")
        _, f2, x2 = loc.locate(starts["fall"], s.feed_dog, 1, s.plate_y, "down")
        found = f1 & f2
        return np.where(found, fwd * (x2[:, 0] - x1[:, 0]), np.nan), found
    if metric == "feed_lift":
        _, found, y = loc.locate(starts["top"], s.feed_dog, 1, 0.0, "top")
        return np.where(found, y[:, 1] - s.plate_y, np.nan), found
    _, found, y = loc.locate(starts["needle_at_plate"], s.needle_point, 1, s.plate_y, "down",
                             read=s.feed_dog)
    return np.where(found, y[:, 1] - s.plate_y, np.nan), found


def _prepare(machine: Machine, regulator_deg: float, P: np.ndarray, base=None):
    """The designs at the setting (a private copy) and the nominal design's evaluation (the
    file's design, or ``base``)."""
    s = _roles(machine)
    reg = machine.parameter_index(f"input.{s.regulator}")
    P = np.array(P, dtype=float)
    P[:, reg] = math.radians(regulator_deg)
    base = np.array(machine.defaults if base is None else base, dtype=float)
    base[reg] = math.radians(regulator_deg)
    ev = evaluation(machine, base)
    return P, base, ev


def window_values(machine: Machine, metric: str, regulator_deg: float, P: np.ndarray,
                  nominal: Gradient, base=None) -> tuple[np.ndarray, np.ndarray]:
    """The feed metric ``metric`` (one of :data:`WINDOWED`) of the designs ``P`` (m,
    n_params; internal units) at a regulator setting (deg), each event located by Newton's
    method from the nominal event moved by its derivative (``nominal``: the metric's
    :class:`Gradient` at the file's design, or at ``base``, (n_params,)). Returns the values
    (mm; NaN where a design was not located) and which designs were located."""
    if metric not in WINDOWED:
        raise KeyError(f"{metric!r} is not located this way; those are {', '.join(WINDOWED)}")
    P, base, ev = _prepare(machine, regulator_deg, P, base)
    # (row by row, not P @ d: a matrix product's rounding depends on the batch's size, and a
    # design's answer must not depend on the others of its batch)
    shift = {k: ((P - base) * d).sum(axis=1) for k, d in nominal.events_d.items()}
    starts = {k: math.radians(nominal.events_deg[k]) + shift[k] for k in shift}
    return _locate_metric(machine, metric, Locator(ev, P), starts)


def whole_turn_values(machine: Machine, metric: str, regulator_deg: float,
                      P: np.ndarray, step_deg: float = TURN_STEP_DEG) -> np.ndarray:
    """The feed metric of the designs ``P`` with each design's events found on its whole turn
    (a ``step_deg`` grid, :func:`sewmech.sewing.feed.feed_cycles`) and located from there
    by the same Newton steps; NaN for a design that cannot be assembled somewhere in its turn
    or has no such event (an event the grid does not see: a dog above the plate for less than
    the grid's step has no stitch there)."""
    s = _roles(machine)
    m = P.shape[0]
    if metric == "dog_height_at_needle_plate":
        n = round(360.0 / step_deg)
        h = 2.0 * math.pi / n
        r = kinematics(machine, np.arange(n) * h, params=P, omega=1.0,
                       points=[s.needle_point], links=[], variables=[], on_failure="mask")
        pm = r.point(s.needle_point)
        ph, dirn, _ = crossing_rows(pm.p[..., 1].reshape(m, n) - s.plate_y,
                                    pm.v[..., 1].reshape(m, n), h)
        first = np.where(dirn < 0, ph, np.inf).min(axis=1)  # its crossing going down
        starts = {"needle_at_plate": np.where(np.isfinite(first), first, np.nan)}
    else:
        c = feed_cycles(machine, regulator_deg, params=P, step_deg=step_deg,
                        on_failure="mask", exact=False)  # (the steps below locate them)
        starts = {"rise": np.radians(c.rise_deg), "fall": np.radians(c.fall_deg),
                  "top": np.radians(c.top_deg)}
    Pp, _, ev = _prepare(machine, regulator_deg, P)
    bad = ~np.all([np.isfinite(v) for v in starts.values()], axis=0)
    starts = {k: np.where(bad, 0.0, v) for k, v in starts.items()}
    vals, _ = _locate_metric(machine, metric, Locator(ev, Pp), starts)
    return np.where(bad, np.nan, vals)


def sample_feed_values(machine: Machine, metric: str, regulator_deg: float, P: np.ndarray,
                       nominal: Gradient, *, seed: int = 0, check: np.ndarray | None = None,
                       base=None, fine_step_deg: float | None = None
                       ) -> tuple[np.ndarray, dict]:
    """:func:`window_values` with its two guards (the module's docstring): the values of the
    designs ``P`` (m, n_params) and what was done, ``{"located": designs located from their
    predicted events, "whole_turn": designs located from their whole turn, "checked":
    designs compared, "check_max_mm": their largest difference}``. NaN only for a design
    that cannot be assembled or has no such event. ``check``: the rows compared (default
    :data:`CHECK_DESIGNS` drawn with ``seed``); ``base``: the design ``nominal`` is of
    (default the file's). The checked designs and those not located are taken round their
    whole turns in one call (:data:`TURN_STEP_DEG`); ``fine_step_deg``: a finer grid for the
    designs not located whose turn showed no such event there (a dog above the plate for less
    than a step: the grid evaluation's 1 deg sees it), None: none."""
    vals, found = window_values(machine, metric, regulator_deg, P, nominal, base)
    m = P.shape[0]
    if check is None:
        rng = np.random.default_rng(seed)
        check = np.sort(rng.choice(m, size=min(CHECK_DESIGNS, m), replace=False))
    check = check[found[check]]
    turn = np.zeros(m, dtype=bool)
    turn[check] = True
    turn |= ~found
    rows = np.nonzero(turn)[0]
    ref = whole_turn_values(machine, metric, regulator_deg, P[rows]) \
        if rows.size else np.zeros(0)
    if fine_step_deg is not None:
        again = np.nonzero(np.isnan(ref) & ~found[rows])[0]
        if again.size:
            ref[again] = whole_turn_values(machine, metric, regulator_deg, P[rows[again]],
                                           fine_step_deg)
    at = np.searchsorted(rows, check)
    diff = np.abs(ref[at] - vals[check])
    agree = bool(np.all(diff <= CHECK_MM))  # (a NaN on either side disagrees)
    vals = vals.copy()
    if agree:
        redo = ~found
        vals[rows] = np.where(found[rows], vals[rows], ref)
    else:
        redo = np.ones(m, dtype=bool)
        vals = whole_turn_values(machine, metric, regulator_deg, P, fine_step_deg or
                                 TURN_STEP_DEG)
    worst = float(np.nanmax(diff)) if diff.size else 0.0
    return vals, {"located": int(m - redo.sum()), "whole_turn": int(redo.sum()),
                  "checked": int(check.size), "check_max_mm": worst}

"""Newton's method on the events of many designs at once, each at its own shaft angle: where a
point's coordinate crosses a level (going up or down) or has its maximum.

Each step evaluates every design at its own angle in one compiled call
(:meth:`sewmech.engine.evaluation.Evaluation.at_angles`) and moves it by the root of the
second-order Taylor polynomial of the channel (value, rate and acceleration per shaft angle are
exact); two or three steps reach :data:`STEP_TOL`, and the value read there by the same
polynomial is exact to round-off. Used by the tolerance Monte Carlo's and the sweeps' feed
metrics (:mod:`sewmech.sewing.samples`) and to polish the feed figures' crossings
(:func:`sewmech.sewing.feed.feed_cycles`).

Units: angles rad, lengths mm.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.evaluation import Evaluation

#: Newton's steps end when the last step is at most this (rad): the value read across it by the
#: Taylor polynomial is then off by its cubic term, of order STEP_TOL^3 (1e-18 mm); at most
#: MAX_STEPS evaluations
STEP_TOL = 1e-6
MAX_STEPS = 6
#: the farthest a design's event may be found from where its Newton steps start (rad)
REACH = math.radians(20.0)


def _step_to(y: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The step (rad) to where y + v d + a d^2 / 2 = 0, the root nearest 0 (the stable form of
    the quadratic's root; Newton's step where the quadratic has no root)."""
    disc = v * v - 2.0 * a * y
    with np.errstate(invalid="ignore", divide="ignore"):
        quad = -2.0 * y / (v + np.copysign(np.sqrt(np.maximum(disc, 0.0)), v))
        return np.where(disc >= 0.0, quad, -y / v)


def _taylor(p: np.ndarray, v: np.ndarray, a: np.ndarray, d: np.ndarray) -> np.ndarray:
    return p + d * (v + 0.5 * d * a)


class Locator:
    """Newton's method on every design's event at once. ``P`` (m, n_params) is a private
    copy whose crank phases and loop initial values each evaluation overwrites and this
    restores."""

    def __init__(self, ev: Evaluation, P: np.ndarray):
        self.ev = ev
        self.P = P
        self.cols = np.concatenate(ev._shaft_cranks[:1] + (ev.init_params,))
        self.keep = P[:, self.cols].copy()

    def _eval(self, rows: np.ndarray, phi: np.ndarray, points: list[str], guess):
        whole = rows.size == self.P.shape[0]
        P = self.P if whole else self.P[rows]
        try:
            r = self.ev.at_angles(P, phi, guess=guess, overwrite=True,
                                  **self.ev.unknown_selection(points))
        finally:
            if whole:
                self.P[:, self.cols] = self.keep
        return r

    def locate(self, start: np.ndarray, point: str, axis: int, level: float, kind: str,
               read: str | None = None, guess: np.ndarray | None = None):
        """Where ``point``'s coordinate ``axis`` crosses ``level`` going up (``kind`` "up")
        or down ("down"), or has its maximum ("top": its rate crosses 0 going down), starting
        from ``start`` (m,) (rad): the angles (m,), which designs were located, and ``read``'s
        (default ``point``'s) value of ``axis`` and of the other axis there, (m, 2).
        ``guess`` (m, n_unknowns): the loop units' unknowns at ``start`` (default: the
        evaluation's design's, carried from its grid: for designs close to it)."""
        m = start.size
        read = read or point
        points = [point] if read == point else [point, read]
        phi = start.copy()
        found = np.zeros(m, dtype=bool)
        out = np.full((m, 2), np.nan)
        todo = np.arange(m)
        for _ in range(MAX_STEPS):
            if not todo.size:
                break
            r = self._eval(todo, phi[todo], points, guess)
            pm, rm = r.point(point), r.point(read)
            if kind == "top":  # the rate's zero: y -> v, v -> a (Newton's step)
                f, df = pm.v[:, 0, axis], pm.a[:, 0, axis]
                with np.errstate(invalid="ignore", divide="ignore"):
                    step = -f / df
                right = df < 0.0
            else:
                f, df = pm.p[:, 0, axis] - level, pm.v[:, 0, axis]
                step = _step_to(f, df, pm.a[:, 0, axis])
                with np.errstate(invalid="ignore"):  # (an infinite step is not taken: ok below)
                    right = np.sign(df + pm.a[:, 0, axis] * step) == (1 if kind == "up" else -1)
            ok = r.feasible[:, 0] & np.isfinite(step) & right
            new = phi[todo] + np.where(ok, step, 0.0)
            ok &= np.abs(new - start[todo]) <= REACH
            done = ok & (np.abs(step) <= STEP_TOL)
            d = step[done]
            for c in range(2):
                out[todo[done], c] = _taylor(rm.p[done, 0, c], rm.v[done, 0, c],
                                             rm.a[done, 0, c], d)
            phi[todo] = new
            found[todo[done]] = True
            more = ok & ~done
            # the next start: each design's own solution carried along its step
            guess = self.ev.unknowns_of(r, np.where(ok, step, 0.0))[more]
            todo = todo[more]
        return phi, found, out

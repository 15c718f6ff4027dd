"""Events on a uniform periodic grid of shaft angles, located on the cubic Hermite interpolant
built from exact values and exact derivatives (kinematics at omega = 1 rad/s gives d/dphi):
accurate to O(h^4) of the grid step h. Shared by the feed and thread analyses.
"""

from __future__ import annotations

import math

import numpy as np


def herm(y0, y1, m0, m1, h, t):
    """Cubic Hermite interpolant on [0, 1] (slopes m per unit of the abscissa, step h)."""
    t2 = t * t
    t3 = t2 * t
    return ((2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * h * m0 + (-2 * t3 + 3 * t2) * y1
            + (t3 - t2) * h * m1)


#: up to this many intervals, :func:`herm_root` works on Python floats: the same operations in
#: the same order, so the same bits, without numpy's few microseconds per operation on tiny
#: arrays (an event of one cycle is one or two intervals: 8 events cost the page's turn 1.5 ms)
_FEW = 8


def herm_root(y0, y1, m0, m1, h):
    """Fraction t in [0, 1] where the Hermite interpolant crosses zero (y0, y1 of opposite sign
    or zero). Newton from the chord's root; any interval where Newton leaves [0, 1] or does not
    settle is bisected (52 halvings: machine precision of the interval)."""
    y0, y1, m0, m1 = (np.asarray(a, dtype=float) for a in (y0, y1, m0, m1))
    if y0.ndim == 1 and y0.size <= _FEW and y0.shape == y1.shape == m0.shape == m1.shape \
            and np.ndim(h) == 0:
        rows = list(zip(y0.tolist(), y1.tolist(), m0.tolist(), m1.tolist(), strict=True))
        if all(math.isfinite(v) for row in rows for v in row) and math.isfinite(float(h)):
            return np.array([_root_of_one(*row, float(h)) for row in rows], dtype=float)
    return _herm_root_arrays(y0, y1, m0, m1, h)


def _sign(x: float) -> float:
    """np.sign of a float."""
    return 1.0 if x > 0.0 else -1.0 if x < 0.0 else 0.0 if x == 0.0 else math.nan


def _root_of_one(y0: float, y1: float, m0: float, m1: float, h: float) -> float:
    """:func:`_herm_root_arrays` of one interval, on Python floats (finite inputs): each step
    the array path's, in its order."""
    den = y0 - y1
    t = min(max(y0 / den if den != 0.0 else 0.0, 0.0), 1.0)
    for _ in range(8):
        t2 = t * t
        f = herm(y0, y1, m0, m1, h, t)
        df = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * h * m0
              + (3 * t2 - 2 * t) * h * m1)
        step = f / df if df != 0.0 else 0.0
        t = t - step
    scale = max(abs(y0), abs(y1))
    if not (0.0 <= t <= 1.0) or not abs(herm(y0, y1, m0, m1, h, t)) <= 1e-12 * scale:
        lo, hi = 0.0, 1.0
        s0 = _sign(y0)
        for _ in range(52):
            mid = 0.5 * (lo + hi)
            if _sign(herm(y0, y1, m0, m1, h, mid)) == s0:
                lo = mid
            else:
                hi = mid
        t = 0.5 * (lo + hi)
    return 0.0 if y0 == 0.0 else t


def _herm_root_arrays(y0, y1, m0, m1, h):
    """:func:`herm_root` on arrays."""
    den = y0 - y1
    t = np.clip(np.divide(y0, den, out=np.zeros_like(y0), where=den != 0.0), 0.0, 1.0)
    for _ in range(8):
        t2 = t * t
        f = herm(y0, y1, m0, m1, h, t)
        df = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * h * m0
              + (3 * t2 - 2 * t) * h * m1)
        step = np.divide(f, df, out=np.zeros_like(f), where=df != 0.0)
        t = t - step
    scale = np.maximum(np.abs(y0), np.abs(y1))
    bad = ~((t >= 0.0) & (t <= 1.0)) | ~(np.abs(herm(y0, y1, m0, m1, h, t)) <= 1e-12 * scale)
    if bad.any():
        a, b, c, d = y0[bad], y1[bad], m0[bad], m1[bad]
        lo = np.zeros_like(a)
        hi = np.ones_like(a)
        s0 = np.sign(a)
        for _ in range(52):
            mid = 0.5 * (lo + hi)
            same = np.sign(herm(a, b, c, d, h, mid)) == s0
            lo = np.where(same, mid, lo)
            hi = np.where(same, hi, mid)
        t[bad] = 0.5 * (lo + hi)
    return np.where(y0 == 0.0, 0.0, t)


def crossing_rows(F, DF, h):
    """Zero crossings of periodic rows F (m, n) with slopes DF, as (m, n) arrays over the grid
    intervals: phase (rad, NaN where the interval holds no crossing), direction (+1 up, -1 down,
    0 none) and fraction t of the interval."""
    G = np.roll(F, -1, axis=-1)
    GD = np.roll(DF, -1, axis=-1)
    mask = ((F < 0) & (G >= 0)) | ((F > 0) & (G <= 0))
    t = np.zeros(F.shape)
    t[mask] = herm_root(F[mask], G[mask], DF[mask], GD[mask], h)
    k = np.arange(F.shape[-1])
    phase = np.where(mask, (k + t) * h, np.nan)
    direction = np.where(mask, np.where(F < 0, 1, -1), 0)
    return phase, direction, t


def at_rows(V, S, k, t, h):
    """Hermite values of periodic rows V (m, n) (slopes S) at interval k (m,), fraction t (m,)."""
    r = np.arange(V.shape[0])
    k1 = (k + 1) % V.shape[-1]
    return herm(V[r, k], V[r, k1], S[r, k], S[r, k1], h, t)


def extreme_rows(V, S, C, h, kind):
    """Global max (kind=+1) or min (-1) of each periodic row of V (m, n), refined on the
    Hermite interpolant of its slope S (curvature C) in the two intervals next to the best grid
    point: (phi rad, value), each (m,)."""
    m, n = V.shape
    r = np.arange(m)
    i = np.argmax(kind * V, axis=-1)
    phi = i * h
    best = V[r, i].copy()
    for k in ((i - 1) % n, i):
        k1 = (k + 1) % n
        s0, s1 = kind * S[r, k], kind * S[r, k1]
        ok = (s0 >= 0.0) & (s1 <= 0.0) & (s0 != s1)
        if not ok.any():
            continue
        t = np.zeros(m)
        t[ok] = herm_root(S[r, k][ok], S[r, k1][ok], C[r, k][ok], C[r, k1][ok], h)
        v = at_rows(V, S, k, t, h)
        better = ok & (kind * v >= kind * best)
        best = np.where(better, v, best)
        phi = np.where(better, (k + t) * h, phi)
    return phi, best

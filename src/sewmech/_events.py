"""Events on a uniform periodic grid of shaft angles, located on the cubic Hermite interpolant
built from exact values and exact derivatives (kinematics at omega = 1 rad/s gives d/dphi):
accurate to O(h^4) of the grid step h. Shared by the feed and thread analyses.
"""

from __future__ import annotations

import numpy as np


def herm(y0, y1, m0, m1, h, t):
    """Cubic Hermite interpolant on [0, 1] (slopes m per unit of the abscissa, step h)."""
    t2 = t * t
    t3 = t2 * t
    return ((2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * h * m0 + (-2 * t3 + 3 * t2) * y1
            + (t3 - t2) * h * m1)


def herm_root(y0, y1, m0, m1, h):
    """Fraction t in [0, 1] where the Hermite interpolant crosses zero (y0, y1 of opposite sign
    or zero). Newton from the chord's root; any interval where Newton leaves [0, 1] or does not
    settle is bisected (52 halvings: machine precision of the interval)."""
    y0, y1, m0, m1 = (np.asarray(a, dtype=float) for a in (y0, y1, m0, m1))
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


def crossings(f, df, h):
    """All zero crossings of periodic samples f (n,) with slopes df: (phi in rad from grid 0,
    direction +1 up / -1 down, interval index, fraction of the interval)."""
    g = np.roll(f, -1)
    gd = np.roll(df, -1)
    k = np.nonzero(((f < 0) & (g >= 0)) | ((f > 0) & (g <= 0)))[0]
    t = herm_root(f[k], g[k], df[k], gd[k], h)
    return (k + t) * h, np.where(f[k] < 0, 1, -1), k, t


def at(values, slopes, k, t, h):
    """Hermite value of periodic samples at interval k, fraction t."""
    k1 = (k + 1) % values.shape[0]
    return herm(values[k], values[k1], slopes[k], slopes[k1], h, t)


def extreme(values, slopes, curv, h, kind):
    """Global max (kind=+1) or min (-1) of periodic samples, refined where the slope changes
    sign next to the best grid point: (phi rad, value)."""
    i = int(np.argmax(kind * values))
    n = values.shape[0]
    best = (i * h, values[i])
    for k in ((i - 1) % n, i):
        k1 = (k + 1) % n
        s0, s1 = kind * slopes[k], kind * slopes[k1]
        if s0 >= 0.0 >= s1 and s0 != s1:
            t = float(herm_root(np.array([slopes[k]]), np.array([slopes[k1]]),
                                 np.array([curv[k]]), np.array([curv[k1]]), h)[0])
            v = float(at(values, slopes, np.array([k]), np.array([t]), h)[0])
            if kind * v >= kind * best[1]:
                best = ((k + t) * h, v)
    return best

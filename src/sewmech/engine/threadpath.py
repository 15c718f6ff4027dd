"""Lengths of a thread through moving guides (the geometry of sewmech.sewing.thread).

A thread path is an ordered list of guides. Each guide is a point (a hole or an eye: the thread
passes through it) or a pin of radius r (the thread wraps it, counter-clockwise or clockwise as
seen from the hand-wheel end). Give every guide a signed radius rho (+r: the thread turns left,
counter-clockwise, round it; -r: right; 0: a point). Between guides the thread runs straight,
along the common tangent of the two guides' circles; on a pin it follows the arc between its
incoming and outgoing tangent points. The engine reads it for the process loads' thread
channels (:mod:`sewmech.engine.loads`); the thread model of stitch formation
(:mod:`sewmech.sewing.thread`) builds on it. Lengths in mm.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike


def path_length(centres: ArrayLike, rho: ArrayLike, *, on_overlap: str = "raise") -> np.ndarray:
    """Length (mm) of a thread through guides with centres (..., n, 2) and signed radii (n,).

    The first and last guides must be points (rho = 0). Where two guides' circles overlap so
    that no common tangent exists: ValueError naming the pair (``on_overlap="raise"``) or NaN
    (``"nan"``, for sweeps over many designs).
    """
    c = np.asarray(centres, dtype=float)
    rho = np.asarray(rho, dtype=float)
    n = c.shape[-2]
    if rho.shape != (n,):
        raise ValueError(f"rho must have shape ({n},), got {rho.shape}")
    if rho[0] != 0.0 or rho[-1] != 0.0:
        raise ValueError("the thread path must start and end at a point guide (radius 0)")
    d = c[..., 1:, :] - c[..., :-1, :]
    dd = np.einsum("...i,...i->...", d, d)
    b = rho[:-1] - rho[1:]
    a2 = dd - b * b
    if on_overlap == "nan":
        a2 = np.where(a2 < 0.0, np.nan, a2)
    elif np.any(a2 < 0.0):
        k = int(np.nonzero(np.any(a2.reshape(-1, n - 1) < 0.0, axis=0))[0][0])
        raise ValueError(f"thread guides {k} and {k + 1} overlap: no common tangent (their"
                         " distance is less than the difference of their signed radii)")
    a = np.sqrt(a2)
    jd = np.stack([-d[..., 1], d[..., 0]], axis=-1)
    u = (a[..., None] * d + b[..., None] * jd) / dd[..., None]
    total = a.sum(axis=-1)
    pins = np.nonzero(rho[1:-1] != 0.0)[0] + 1
    if pins.size:
        u_in = u[..., pins - 1, :]
        u_out = u[..., pins, :]
        cross = u_in[..., 0] * u_out[..., 1] - u_in[..., 1] * u_out[..., 0]
        dot = np.einsum("...i,...i->...", u_in, u_out)
        turn = np.arctan2(cross, dot)  # left turn positive
        wrap = np.mod(np.sign(rho[pins]) * turn, 2.0 * math.pi)
        total = total + (np.abs(rho[pins]) * wrap).sum(axis=-1)
    return total


def path_length_gradient(centres: ArrayLike, rho: ArrayLike) -> np.ndarray:
    """d(path length)/d(each guide's centre) (..., n, 2) for the path of :func:`path_length`:
    the unit vector of the segment arriving at a guide minus that of the segment leaving it.
    On a pin the tangent points slide round it as it moves and the arc takes up exactly what
    the straight segments lose (the taut thread's length is stationary in them), so a pin
    counts like a point at its centre."""
    c = np.asarray(centres, dtype=float)
    rho = np.asarray(rho, dtype=float)
    d = c[..., 1:, :] - c[..., :-1, :]
    dd = np.einsum("...i,...i->...", d, d)
    b = rho[:-1] - rho[1:]
    a = np.sqrt(dd - b * b)
    jd = np.stack([-d[..., 1], d[..., 0]], axis=-1)
    u = (a[..., None] * d + b[..., None] * jd) / dd[..., None]
    g = np.zeros_like(c)
    g[..., :-1, :] -= u
    g[..., 1:, :] += u
    return g

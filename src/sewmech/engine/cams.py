"""Circular-arc cam profiles: the six-arc constant-width dwell cam of the feed fork.

A feed fork straddles its cam between two parallel faces a constant distance (the width W)
apart, so the cam must touch both faces in every position: a curve of constant width. The JB
feed cam is such a curve made of six circular arcs. sewmech builds it from its design values:

- ``width`` W: the gap between the fork's faces, mm;
- ``stroke`` S: the travel of the fork between its two dwells, mm;
- ``dwell`` delta: the cam rotation over which the fork rests at each end of its stroke, rad;
- ``orientation``: the normal direction (cam frame, rad) at the middle of the inner dwell.

Construction (cam frame, origin on the shaft axis). The arcs come in three opposite pairs with
common centres C0, C1, C2 and radii that add up to W, so the width is W in every direction:

- arc 0 (normals o +- delta/2) and arc 3 (opposite) are centred on the axis, radii (W - S)/2 and
  (W + S)/2: the support function is constant there, the fork dwells at both ends of its stroke;
- arcs 1, 2 (normals o + delta/2 .. o + pi/2 .. o + pi - delta/2) and their opposites 4, 5 carry
  the fork across. Tangent continuity at each joint puts the two centres on the common normal,
  C_{k+1} - C_k = (R_k - R_{k+1}) n(theta_{k+1}); closing the centre triangle gives
  R1 = (W - 2 k R0) / (2 (1 - k)), k = sin(delta/2), R2 = W - R1.

With delta -> 0 the cam becomes an eccentric of eccentricity S/2 (pure harmonic motion).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

#: design keys of a constant-width cam, in the order of :func:`constant_width_arcs`
CONSTANT_WIDTH_KEYS = ("width", "stroke", "dwell", "orientation")


def constant_width_arcs(width: ArrayLike, stroke: ArrayLike, dwell: ArrayLike,
                        orientation: ArrayLike = 0.0, *,
                        nan_invalid: bool = False) -> dict[str, np.ndarray]:
    """The six arcs of a constant-width dwell cam, for one design or a batch.

    Parameters
    ----------
    width, stroke : array_like
        Fork gap W and stroke S, mm (0 <= S < W).
    dwell : array_like
        Dwell of the fork at each end of its stroke, rad (0 <= dwell < pi).
    orientation : array_like
        Normal direction (cam frame) at the middle of the inner dwell, rad.

    Returns
    -------
    dict with ``cx``, ``cy``, ``radius`` (mm), ``normal_from``, ``normal_to`` (rad), each of
    shape ``batch + (6,)``: the arcs in counter-clockwise order of their normals, starting with
    the inner dwell arc.

    With ``nan_invalid`` the designs whose values give no convex cam get NaN arcs (the
    kinematics then marks them infeasible, naming the arc) instead of a ValueError for all.

    Raises
    ------
    ValueError
        When the values give no convex cam (a radius not positive) and not ``nan_invalid``:
        the message says which condition fails (:func:`constant_width_fault`).
    """
    W, S, d, o = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                      for x in (width, stroke, dwell, orientation)))
    bad = constant_width_fault(W, S, d)
    if bad is not None and not nan_invalid:
        raise ValueError(bad)
    k = np.sin(d / 2.0)
    R0 = (W - S) / 2.0
    R1 = (W - 2.0 * k * R0) / (2.0 * (1.0 - k))
    R2 = W - R1
    if nan_invalid:  # a batch: the designs that give no convex cam get NaN arcs
        none = ~_convex(W, S, d)
        R0, R1, R2 = (np.where(none, np.nan, R) for R in (R0, R1, R2))
    half = d / 2.0
    # boundaries of the arcs' normal ranges (relative to the orientation)
    bounds = np.stack([-half, half, np.full_like(d, math.pi / 2), math.pi - half, math.pi + half,
                       np.full_like(d, 1.5 * math.pi), 2.0 * math.pi - half], axis=-1) + o[..., None]
    radius = np.stack([R0, R1, R2, W - R0, W - R1, W - R2], axis=-1)
    n1 = np.stack([np.cos(bounds[..., 1]), np.sin(bounds[..., 1])], axis=-1)
    n2 = np.stack([np.cos(bounds[..., 2]), np.sin(bounds[..., 2])], axis=-1)
    c0 = np.zeros(W.shape + (2,))
    c1 = c0 + (R0 - R1)[..., None] * n1
    c2 = c1 + (R1 - R2)[..., None] * n2
    centres = np.stack([c0, c1, c2, c0, c1, c2], axis=-2)
    return {"cx": centres[..., 0], "cy": centres[..., 1], "radius": radius,
            "normal_from": bounds[..., :-1], "normal_to": bounds[..., 1:]}


def _convex(W, S, d) -> np.ndarray:
    """Where width W, stroke S (mm) and dwell d (rad) give a convex constant-width cam."""
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.sin(d / 2.0)
        R0 = (W - S) / 2.0
        R1 = (W - 2.0 * k * R0) / (2.0 * (1.0 - k))
        return (S >= 0) & (S < W) & (d >= 0) & (d < math.pi) & (R1 > 0.0) & (W - R1 > 0.0)


def constant_width_fault(width, stroke, dwell) -> str | None:
    """Why width, stroke (mm) and dwell (rad) give no convex constant-width cam (for the
    first design of a batch that does not), or None when every design does."""
    W, S, d = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (width, stroke, dwell)))
    ok = _convex(W, S, d)
    if ok.all():
        return None
    i = np.unravel_index(int(np.argmin(ok)), ok.shape) if ok.ndim else ()
    w, s, dd = float(W[i]), float(S[i]), float(d[i])
    at = f" (design {tuple(int(x) for x in i)})" if ok.ndim and ok.size > 1 else ""
    if not 0.0 <= s < w:
        return (f"a constant-width cam needs 0 <= stroke < width, got stroke {s:g} mm and width"
                f" {w:g} mm{at}")
    if not 0.0 <= dd < math.pi:
        return f"a constant-width cam needs 0 <= dwell < 180 deg, got {math.degrees(dd):g} deg{at}"
    return (f"no convex constant-width cam for width {w:g} mm, stroke {s:g} mm and dwell"
            f" {math.degrees(dd):g} deg{at}: reduce the dwell or the stroke, or widen the cam")


def support(arcs: dict[str, np.ndarray], normal: ArrayLike) -> np.ndarray:
    """Support function h(n) of an arc cam: the distance from the cam's axis to the tangent
    line whose outward normal is ``normal`` (cam frame, rad), mm.

    ``arcs`` as returned by :func:`constant_width_arcs` for one design (arrays of shape (n,)).
    """
    rho = np.asarray(normal, dtype=float)
    a0 = arcs["normal_from"]
    r = np.mod(rho[..., None] - a0, 2.0 * math.pi)
    inside = r < (arcs["normal_to"] - a0)
    k = np.argmax(inside, axis=-1)
    c, s = np.cos(rho), np.sin(rho)
    return arcs["cx"][k] * c + arcs["cy"][k] * s + arcs["radius"][k]

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
                        orientation: ArrayLike = 0.0) -> dict[str, np.ndarray]:
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

    Raises
    ------
    ValueError
        When the values give no convex cam (a radius not positive).
    """
    W, S, d, o = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                      for x in (width, stroke, dwell, orientation)))
    if np.any(S < 0) or np.any(S >= W):
        raise ValueError("a constant-width cam needs 0 <= stroke < width")
    if np.any(d < 0) or np.any(d >= math.pi):
        raise ValueError("a constant-width cam needs 0 <= dwell < 180 deg")
    k = np.sin(d / 2.0)
    R0 = (W - S) / 2.0
    R1 = (W - 2.0 * k * R0) / (2.0 * (1.0 - k))
    R2 = W - R1
    if np.any(R2 <= 0.0) or np.any(R1 <= 0.0):
        raise ValueError("no convex constant-width cam for these values: reduce the dwell or the"
                         " stroke, or widen the cam")
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

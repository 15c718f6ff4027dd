"""Trial-weight balancing's other solver: the correction that makes the largest residual
vibration over the places and speeds measured as small as it can be (min-max), with a weight
per place and a limit on each correction mass, as a linear programme.

With the influence coefficients A (rows x planes, :func:`sewmech.design.vibration
.influence_balance`'s), the residual of row i after adding the complex static moments U is
r_i = V0_i + sum_j A_ij U_j, and the problem is

    minimise  t  subject to  w_i |r_i| <= t  for every row,  |U_j| <= M_j  for every plane.

A modulus is not linear; each circle is replaced by a regular polygon of K sides
(``sides``), which makes the problem a linear programme in (Re U, Im U, t), solved by
scipy's HiGHS (:func:`scipy.optimize.linprog`):

- the residuals by the polygon circumscribed about the circle, Re(w_i r_i e^{-i theta_k}) <= t
  for theta_k = 2 pi k / K: every U that meets |w_i r_i| <= t meets these, and a U that meets
  them has |w_i r_i| <= t / cos(pi / K);
- the limits by the inscribed polygon, Re(U_j e^{-i theta_k}) <= M_j cos(pi / K): the answer
  keeps every limit exactly.

Without limits the answer's largest weighted residual (computed exactly afterwards) is within a
factor 1 / cos(pi / K) of the true min-max (K = 256: 7.5e-5 relative), and the programme's own
optimum is a lower bound. With limits a second programme, with the limits' circumscribed
polygon, gives the lower bound that no correction within the limits can beat; a limit that is
reached costs the answer at most w_i |A_ij| M_j (1 - cos(pi / K)) more. Either way the true
optimum lies between ``lower_bound`` and ``after_max``, both reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..engine.errors import AnalysisError, OptionError

#: sides of the polygons that stand for the circles (see the module's docstring)
SIDES = 256


@dataclass(frozen=True)
class MinmaxResult:
    """The min-max correction. correction_gcm, correction_angle_deg : per plane, g cm and deg
    (the trial angles' frame); coefficients : (rows, planes) influence coefficients; residual :
    (rows,) complex vibration predicted after, mm/s; weights : (rows,); before_max, after_max :
    the largest weighted vibration amplitude before and predicted after, mm/s; lower_bound :
    no correction within the limits makes it smaller, mm/s; before_rms, after_rms : RMS of the
    (unweighted) amplitudes, mm/s; limits_gcm : (planes,) or None; at_limit : (planes,) the
    planes whose correction is at its limit; sides : K; accuracy : 1 / cos(pi / K) - 1."""

    correction_gcm: np.ndarray
    correction_angle_deg: np.ndarray
    coefficients: np.ndarray
    residual: np.ndarray
    weights: np.ndarray
    before_max: float
    after_max: float
    lower_bound: float
    before_rms: float
    after_rms: float
    limits_gcm: np.ndarray | None
    at_limit: np.ndarray
    sides: int

    @property
    def accuracy(self) -> float:
        return 1.0 / math.cos(math.pi / self.sides) - 1.0

    def to_json(self, planes=None, places=None) -> dict:
        names = planes or [f"plane {j + 1}" for j in range(len(self.correction_gcm))]
        rows = places or [f"row {i + 1}" for i in range(len(self.residual))]
        return {"solver": "minmax",
                "corrections": {n: {"static_moment_gcm": float(s), "angle_deg": float(a),
                                    "at_limit": bool(lim)}
                                for n, s, a, lim in zip(names, self.correction_gcm,
                                                        self.correction_angle_deg,
                                                        self.at_limit, strict=True)},
                "before_max_mm_s": self.before_max, "after_max_mm_s": self.after_max,
                "lower_bound_mm_s": self.lower_bound,
                "before_rms_mm_s": self.before_rms, "after_rms_mm_s": self.after_rms,
                "residual_mm_s": {p: float(abs(r)) for p, r in zip(rows, self.residual,
                                                                    strict=True)},
                "weights": {p: float(w) for p, w in zip(rows, self.weights, strict=True)},
                "polygon_sides": self.sides, "relative_accuracy": self.accuracy}


def _rows(coef: np.ndarray, const: np.ndarray, angles: np.ndarray):
    """Re(c e^{-i theta}) for the affine complex c = const + coef @ (x + i y), as rows of
    (x, y) coefficients and constants, one per angle: (K*n, 2m) and (K*n,)."""
    rot = np.exp(-1j * angles)[:, None]  # (K, 1)
    c = coef[None, :, :] * rot[:, :, None]  # (K, n, m)
    a = np.concatenate([c.real, -c.imag], axis=-1).reshape(-1, 2 * coef.shape[1])
    b = (const[None, :] * rot).real.reshape(-1)
    return a, b


def _solve(A, V0, w, limits, K, inscribed: bool):
    from scipy.optimize import linprog

    n, m = A.shape
    ang = 2.0 * math.pi * np.arange(K) / K
    ra, rb = _rows(w[:, None] * A, w * V0, ang)
    # Re(...) <= t  ->  ra @ z - t <= -rb
    A_ub = [np.hstack([ra, -np.ones((ra.shape[0], 1))])]
    b_ub = [-rb]
    if limits is not None:
        la, lb = _rows(np.eye(m, dtype=complex), np.zeros(m, dtype=complex), ang)
        scale = math.cos(math.pi / K) if inscribed else 1.0
        lim = np.tile(limits, K) * scale
        keep = np.isfinite(lim)
        A_ub.append(np.hstack([la[keep], np.zeros((int(keep.sum()), 1))]))
        b_ub.append(lim[keep] - lb[keep])
    c = np.zeros(2 * m + 1)
    c[-1] = 1.0
    res = linprog(c, A_ub=np.vstack(A_ub), b_ub=np.concatenate(b_ub),
                  bounds=[(None, None)] * (2 * m) + [(0.0, None)], method="highs")
    if res.status != 0:
        raise AnalysisError("influence", f"the linear programme failed: {res.message}",
                            "This is a bug in sewmech: please report it with the file")
    z = res.x
    return z[:m] + 1j * z[m:2 * m], float(z[-1])


def influence_minmax(baseline: ArrayLike, trials: ArrayLike, trial_gcm: ArrayLike,
                     trial_angle_deg: ArrayLike, *, weights: ArrayLike | None = None,
                     limits_gcm: ArrayLike | None = None, sides: int = SIDES,
                     names: list[str] | None = None) -> MinmaxResult:
    """Correction masses that minimise the largest weighted residual vibration.

    baseline (rows,), trials (planes, rows), trial_gcm, trial_angle_deg (planes,) as
    :func:`sewmech.design.vibration.influence_balance`; weights (rows,) >= 0, default 1 (a
    place that matters more, or a speed the machine runs at most); limits_gcm (planes,) the
    most static moment each plane can take (inf: no limit), default none; sides: K of the
    polygons (module docstring), at least 8; names: the planes' names in messages."""
    from .vibration import influence_balance

    V0 = np.asarray(baseline, dtype=complex)
    lsq = influence_balance(baseline, trials, trial_gcm, trial_angle_deg, names)  # its checks
    A = lsq.coefficients
    n, m = A.shape
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise OptionError("--weight", "weights must be numbers >= 0, one a row, not all 0",
                          "Give e.g. --weight front-x@2000=2")
    lim = None
    if limits_gcm is not None:
        lim = np.asarray(limits_gcm, dtype=float)
        if lim.shape != (m,) or np.any(np.isnan(lim)) or np.any(lim < 0):
            raise OptionError("--max-gcm", "each plane's limit must be a static moment >= 0 g cm")
    if not (isinstance(sides, int) and 8 <= sides <= 100_000):
        raise OptionError("--sides", f"must be a whole number 8 .. 100000, got {sides!r}")
    U, lower = _solve(A, V0, w, lim, sides, inscribed=True)
    if lim is not None:  # the limits' circumscribed polygon: a bound no correction beats
        _, lower = _solve(A, V0, w, lim, sides, inscribed=False)
    res = V0 + A @ U
    amp = w * np.abs(res)
    at = (np.abs(U) >= lim * math.cos(math.pi / sides) * (1 - 1e-9)) if lim is not None else \
        np.zeros(m, dtype=bool)
    return MinmaxResult(np.abs(U), np.degrees(np.angle(U)), A, res, w,
                        float(np.max(w * np.abs(V0))), float(amp.max()), float(lower),
                        float(np.sqrt(np.mean(np.abs(V0) ** 2))),
                        float(np.sqrt(np.mean(np.abs(res) ** 2))), lim, at, sides)

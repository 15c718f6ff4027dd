"""The balancing criteria on the housing's predicted vibration (:func:`sewmech.design.balancing.
balance`, ``"vibration"`` and ``"equal-levels"``).

The wrench the mechanisms put on the housing is exactly linear in the counterweights' m, m u,
m v and m r^2 (the balancing basis), and the control point's velocity harmonics are linear in
the wrench's, so each design costs a few small complex products; only the RMS (a square root of
a sum of squares) is not linear.

- ``vibration``: the larger of the RMS velocities along x and y at the control point, minimised
  over the counterweights' static moments and angles (SLSQP on the epigraph form from several
  starts, within the counterweights' limits), polished by Nelder-Mead.
- ``equal-levels``: the balancing paper's experimental criterion [Sunkuev-balancing] predicted
  from the model: one counterweight's static moment along its present angle at which the x and
  y levels are equal (a scan and Brent's method; of several crossings the one of the lowest
  level). :func:`level_curves` gives v_x(S) and v_y(S), the curves the paper measures.

Units: static moments kg mm inside (g cm in results), velocities mm/s, levels dB re 5e-8 m/s.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.errors import OptionError
from ._minimax import _natural


def _direction(B) -> tuple[float, np.ndarray]:
    """The angle (rad) along which one counterweight's static moment is varied, and its unit
    vector: its present angle (the file's when it weighs nothing now)."""
    c = B.counterweights[0]
    x0, y0 = B.start[0]
    if math.hypot(x0, y0) > 0:
        beta = math.atan2(y0, x0)
    else:
        spec = B.machine.spec.counterweights[c.name]
        beta = math.radians(spec.angle_deg) if spec.by_moment else math.atan2(spec.at_mm[1],
                                                                              spec.at_mm[0])
    return beta, np.array([math.cos(beta), math.sin(beta)])


def _span(B) -> float:
    """How far along a counterweight's angle the scans go: its limit, else four times the
    machine's natural scale."""
    return float(B.s_max[0]) if math.isfinite(B.s_max[0]) else 4.0 * _natural(B)


def level_curves(B, n: int = 201) -> dict:
    """The control point's predicted RMS velocities along x and y (mm/s) against one
    counterweight's static moment along its present angle, from 0 to its limit (or four times
    the natural scale): ``S_gcm`` (n,), ``vx_mm_s``, ``vy_mm_s``, ``beta_deg``."""
    if len(B.counterweights) != 1:
        raise OptionError("--counterweight", "the level curves vary one counterweight;"
                          f" {len(B.counterweights)} are chosen", "Name one with"
                          " --counterweight NAME")
    beta, e = _direction(B)
    S = np.linspace(0.0, _span(B), n)
    v = B.velocities_at(S[:, None, None] * e)
    return {"S_gcm": S * 100.0, "vx_mm_s": v[:, 0], "vy_mm_s": v[:, 1],
            "beta_deg": math.degrees(beta)}


def solve_equal_levels(B) -> tuple[np.ndarray, str, str]:
    """One counterweight's static moment along its present angle where the control point's x
    and y levels are equal (see the module doc)."""
    from scipy.optimize import brentq

    if len(B.counterweights) != 1:
        raise OptionError("--counterweight", "equal-levels chooses the static moment of one"
                          f" counterweight; {len(B.counterweights)} are chosen", "Name one"
                          " with --counterweight NAME (its angle stays as the file gives it),"
                          " or choose vibration for several")
    beta, e = _direction(B)
    hi = _span(B)

    def diff(S):
        v = B.velocities_at((S * e)[None, :])
        return float(v[0] - v[1])

    grid = np.linspace(0.0, hi, 401)
    v = B.velocities_at(grid[:, None, None] * e)
    d = v[:, 0] - v[:, 1]
    roots = []
    for k in np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) <= 0)[0]:
        if d[k] == 0.0:
            roots.append(grid[k])
        elif d[k + 1] != 0.0:
            roots.append(brentq(diff, grid[k], grid[k + 1], xtol=1e-13 * hi, rtol=1e-13))
    where = f"along {math.degrees(beta):.6g} deg at control point '{B.control_name}'"
    if roots:
        def level(S):
            return float(B.velocities_at((S * e)[None, :]).max())

        best = min(roots, key=level)
        more = f" (the one of lowest level among {len(roots)})" if len(roots) > 1 else ""
        return (best * e)[None, :], "optimal", f"equal x and y vibration levels {where}{more}"
    k = int(np.argmin(np.abs(d)))
    limit = "max_static_moment_gcm" if math.isfinite(B.s_max[0]) else "the scanned range"
    return (grid[k] * e)[None, :], "infeasible", (f"the x and y levels are not equal anywhere"
                                                  f" {where} within {limit}")


def solve_vibration(B) -> tuple[np.ndarray, str, str]:
    """The counterweights' static moments and angles of least max(v_x, v_y) RMS at the control
    point (see the module doc)."""
    from scipy.optimize import minimize

    n = len(B.counterweights)
    scale = max(_natural(B), 1e-9)

    def worst(z):
        xy = (z * scale).reshape(n, 2)
        return float(B.velocities_at(xy[None])[0].max())

    limit = np.where(np.isfinite(B.s_max), B.s_max / scale, np.inf)
    cons = [{"type": "ineq", "fun": (lambda z, i=i: limit[i] ** 2 - z[2 * i] ** 2
                                     - z[2 * i + 1] ** 2)}
            for i in range(n) if np.isfinite(limit[i])]
    starts = [B.start.reshape(-1) / scale]
    rng = np.random.default_rng(0)
    for _ in range(6):
        r = rng.uniform(0.0, 1.0, n) * np.where(np.isfinite(limit), limit, 2.0)
        a = rng.uniform(-math.pi, math.pi, n)
        starts.append(np.stack([r * np.cos(a), r * np.sin(a)], axis=-1).reshape(-1))
    best = None
    for z0 in starts:
        # epigraph: minimise t with v_x <= t, v_y <= t
        t0 = worst(z0)

        def vel(zt):
            xy = (zt[:-1] * scale).reshape(n, 2)
            return B.velocities_at(xy[None])[0]

        c2 = [{"type": "ineq", "fun": (lambda zt: zt[-1] - vel(zt))}]
        for c in cons:
            c2 = c2 + [{"type": "ineq", "fun": (lambda zt, f=c["fun"]: f(zt[:-1]))}]
        res = minimize(lambda zt: zt[-1], np.append(z0, t0), method="SLSQP",
                       constraints=c2, options={"maxiter": 300, "ftol": 1e-12})
        z = res.x[:-1]
        if cons and any(c["fun"](z) < -1e-9 for c in cons):
            continue
        val = worst(z)
        if best is None or val < best[1]:
            best = (z, val)
    z, val = best
    # polish on the objective itself (the epigraph's corner is the objective's kink)
    if not cons:
        res = minimize(worst, z, method="Nelder-Mead",
                       options={"xatol": 1e-10, "fatol": 1e-12 * max(val, 1e-30),
                                "maxiter": 4000})
        if res.fun < val:
            z, val = res.x, float(res.fun)
    xy = (z * scale).reshape(n, 2)
    return xy, "optimal", (f"least larger RMS vibration velocity of x and y at control point"
                           f" '{B.control_name}': {val:.4g} mm/s")

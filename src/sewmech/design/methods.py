"""The JB kinematics report's optimisation methods, written out: the 0.618 (golden section)
search, cyclic coordinate search, Powell's conjugate directions, the interior penalty function
that turns a constrained problem into a sequence of unconstrained ones, and the two ways the
report weighs several sub-objectives (a weighted sum with automatic normalisation, and the
"weighted uniform convergence" form that minimises the largest normalised deviation).

Every method returns a :class:`scipy.optimize.OptimizeResult` (``x``, ``fun``, ``nfev``,
``nit``, ``status``, ``success``, ``message`` and ``history``: the best value after each
iteration), so that they and scipy's methods are used alike. They take no derivatives: the
report chose them because its objectives had none; sewmech's exact gradients serve scipy's
gradient methods instead.

Units: whatever the objective's variables are (sewmech's problems use internal units: mm, rad).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:  # (imported for the annotations only; see _result)
    from scipy.optimize import OptimizeResult

def _result(**fields):
    """A :class:`scipy.optimize.OptimizeResult` (imported here: scipy.optimize costs 0.3 s to
    import, which no command that does not optimise should pay)."""
    from scipy.optimize import OptimizeResult

    return OptimizeResult(**fields)


#: the golden section ratio (sqrt(5) - 1) / 2 = 0.618...
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def golden_trials(a: float, b: float, tol: float) -> int:
    """The report's estimate of the trial points the 0.618 method needs to shrink [a, b] to
    ``tol``: n >= lg(tol / (b - a)) / lg 0.618 + 1."""
    return math.ceil(math.log10(tol / (b - a)) / math.log10(GOLDEN) + 1.0)


def golden_section(f: Callable[[float], float], a: float, b: float, *, tol: float = 1e-8
                   ) -> OptimizeResult:
    """Minimise a function unimodal on [a, b] by the 0.618 method: two interior points at the
    golden ratio, the worse side cut off each step, one new evaluation per step, until the
    interval is shorter than ``tol``."""
    if not (math.isfinite(a) and math.isfinite(b) and b > a):
        raise ValueError(f"golden_section: need a < b, got [{a}, {b}]")
    if not tol > 0:
        raise ValueError(f"golden_section: tol must be > 0, got {tol}")
    x1 = b - GOLDEN * (b - a)
    x2 = a + GOLDEN * (b - a)
    f1, f2 = f(x1), f(x2)
    nfev, history = 2, []
    while b - a > tol:
        if f1 <= f2:  # the minimum is not in (x2, b]
            b, x2, f2 = x2, x1, f1
            x1 = b - GOLDEN * (b - a)
            f1 = f(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + GOLDEN * (b - a)
            f2 = f(x2)
        nfev += 1
        history.append(min(f1, f2))
    x, fx = (x1, f1) if f1 <= f2 else (x2, f2)
    return _result(x=np.array([x]), fun=fx, nfev=nfev, nit=len(history), status=0,
                          success=True, message=f"interval shorter than {tol:g}",
                          history=history)


def line_minimum(f: Callable[[np.ndarray], float], x: np.ndarray, d: np.ndarray, step: float,
                 tol: float) -> tuple[float, float, int]:
    """The step t minimising f(x + t d): bracketed by steps that grow by the golden ratio from
    ``step`` in the descending direction, then the 0.618 search to ``tol``. Returns (t,
    f(x + t d), evaluations). A direction along which f only rises returns t = 0."""
    f0 = f(x)
    n = 1
    fp = f(x + step * d)
    n += 1
    if fp > f0:  # try the other way
        fm = f(x - step * d)
        n += 1
        if fm >= f0:  # the minimum lies within one step of x
            r = golden_section(lambda t: f(x + t * d), -step, step, tol=tol)
            return float(r.x[0]), float(r.fun), n + r.nfev
        step = -step
        fp = fm
    lo, mid, fmid = 0.0, step, fp
    hi = step * (1.0 + 1.0 / GOLDEN)
    fhi = f(x + hi * d)
    n += 1
    for _ in range(200):
        if fhi > fmid or not math.isfinite(fhi):
            break
        lo, mid, fmid = mid, hi, fhi
        hi = mid + (mid - lo) / GOLDEN
        fhi = f(x + hi * d)
        n += 1
    a, b = sorted((lo, hi))
    r = golden_section(lambda t: f(x + t * d), a, b, tol=tol)
    t, ft = float(r.x[0]), float(r.fun)
    if ft > f0:
        return 0.0, f0, n + r.nfev
    return t, ft, n + r.nfev


def _counted(f):
    calls = [0]

    def g(x):
        calls[0] += 1
        v = float(f(np.asarray(x, dtype=float)))
        return v if math.isfinite(v) else math.inf

    return g, calls


def cyclic_coordinate(f: Callable[[np.ndarray], float], x0: ArrayLike, *,
                      step: float | ArrayLike = 0.1, tol: float = 1e-8, maxiter: int = 500
                      ) -> OptimizeResult:
    """Minimise along each coordinate in turn (a line search on each axis), round after round,
    each round ending with a line search along the round's whole move (the acceleration step
    that keeps the search from zig-zagging along a valley or a constraint's barrier at an angle
    to the axes), until a round improves f by less than ``tol`` (relative, with an absolute
    floor) and moves x by less than 1000 ``tol`` per unit of ``step``."""
    g, calls = _counted(f)
    x = np.array(x0, dtype=float)
    steps = np.broadcast_to(np.asarray(step, dtype=float), x.shape).copy()
    fx = g(x)
    history, status, it = [fx], 1, 0
    for it in range(1, maxiter + 1):
        f_start, x_start = fx, x.copy()
        for i in range(x.size):
            d = np.zeros(x.size)
            d[i] = 1.0
            t, ft, _ = line_minimum(g, x, d, steps[i], tol * steps[i])
            if ft < fx:
                x = x + t * d
                fx = ft
        move = x - x_start
        if np.any(move != 0.0):  # the acceleration step: on along the round's whole move
            t, ft, _ = line_minimum(g, x, move, 1.0, tol)
            if ft < fx:
                x = x + t * move
                fx = ft
        history.append(fx)
        if (f_start - fx <= tol * max(abs(fx), 1.0)
                and np.all(np.abs(x - x_start) <= tol * np.maximum(steps, 1e-300) * 1e3)):
            status = 0
            break
    return _result(x=x, fun=fx, nfev=calls[0], nit=it, status=status,
                          success=status == 0,
                          message="converged" if status == 0 else "maximum rounds reached",
                          history=history)


def powell(f: Callable[[np.ndarray], float], x0: ArrayLike, *, step: float | ArrayLike = 0.1,
           tol: float = 1e-8, maxiter: int = 500) -> OptimizeResult:
    """Powell's conjugate directions: line searches along n directions (at first the axes); the
    round's total move becomes a new direction in place of the one that helped most, unless
    that would make the set degenerate (Powell's test), so that on a quadratic the directions
    become conjugate and n rounds reach the minimum."""
    g, calls = _counted(f)
    x = np.array(x0, dtype=float)
    n = x.size
    scale = np.broadcast_to(np.asarray(step, dtype=float), x.shape).copy()
    D = np.diag(scale)  # directions as rows, each one step long
    fx = g(x)
    history, status, it = [fx], 1, 0
    for it in range(1, maxiter + 1):
        x_start, f_start = x.copy(), fx
        best_drop, best_k = 0.0, 0
        for k in range(n):
            t, ft, _ = line_minimum(g, x, D[k], 1.0, tol)
            if fx - ft > best_drop:  # the direction that helped most this round
                best_drop, best_k = fx - ft, k
            if ft < fx:
                x = x + t * D[k]
                fx = ft
        history.append(fx)
        if f_start - fx <= tol * max(abs(fx), 1.0) and np.all(
                np.abs(x - x_start) <= tol * 1e3 * np.maximum(scale, 1e-300)):
            status = 0
            break
        move = x - x_start
        f_ext = g(x + move)  # the point one round further
        # Powell's test: replace only if the extrapolated point is better and the drop along
        # the new direction is not dominated by the one direction that helped most
        if f_ext < f_start and 2.0 * (f_start - 2.0 * fx + f_ext) * (
                (f_start - fx - best_drop) ** 2) < best_drop * (f_start - f_ext) ** 2:
            t, ft, _ = line_minimum(g, x, move, 1.0, tol)
            if ft < fx:
                x = x + t * move
                fx = ft
            D = np.vstack([np.delete(D, best_k, axis=0), move])
    return _result(x=x, fun=fx, nfev=calls[0], nit=it, status=status,
                          success=status == 0,
                          message="converged" if status == 0 else "maximum rounds reached",
                          history=history)


def interior_penalty(f: Callable[[np.ndarray], float],
                     constraints: Callable[[np.ndarray], ArrayLike], x0: ArrayLike, *,
                     method: str = "powell", r0: float | None = None, c: float = 0.1,
                     tol: float = 1e-7, max_outer: int = 30, step: float | ArrayLike = 0.1
                     ) -> OptimizeResult:
    """Minimise f subject to g(x) >= 0 (every component) by the interior penalty function:
    minimise phi(x, r) = f(x) + r sum_j 1 / g_j(x) from a strictly feasible start, for
    r = r0, c r0, c^2 r0, ... (each minimisation by ``method``: "powell" or "cyclic", started
    where the last ended); outside the feasible region phi is infinite, so no search leaves it.
    Stops when r sum 1/g_j and the change of f are below ``tol`` (relative). ``constraints``
    returns the vector g(x); the result adds ``constr`` (g at the answer) and ``r`` (the last
    penalty factor)."""
    if method not in ("powell", "cyclic"):
        raise ValueError(f"interior_penalty: method must be 'powell' or 'cyclic', got {method!r}")
    x = np.array(x0, dtype=float)
    g0 = np.atleast_1d(np.asarray(constraints(x), dtype=float))
    if not np.all(g0 > 0):
        bad = int(np.argmin(g0))
        raise ValueError(f"interior_penalty: the start is not strictly feasible (constraint"
                         f" {bad} = {g0[bad]:g}); start inside every constraint")
    fcalls = [0]

    def barrier(xx):
        return float(np.sum(1.0 / np.atleast_1d(np.asarray(constraints(xx), dtype=float))))

    def phi_of(r):
        def phi(xx):
            gg = np.atleast_1d(np.asarray(constraints(xx), dtype=float))
            if not np.all(gg > 0):
                return math.inf
            fcalls[0] += 1
            return float(f(xx)) + r * float(np.sum(1.0 / gg))
        return phi

    f_x = float(f(x))
    r = r0 if r0 is not None else max(abs(f_x), 1.0) / max(barrier(x), 1e-300) * 0.1
    inner = powell if method == "powell" else cyclic_coordinate
    history, status, k = [f_x], 1, 0
    for k in range(1, max_outer + 1):
        res = inner(phi_of(r), x, step=step, tol=tol * 0.1)
        x = res.x
        f_new = float(f(x))
        pen = r * barrier(x)
        history.append(f_new)
        done = pen <= tol * max(abs(f_new), 1.0) and abs(f_new - f_x) <= tol * max(
            abs(f_new), 1.0)
        f_x = f_new
        if done:
            status = 0
            break
        r *= c
    gx = np.atleast_1d(np.asarray(constraints(x), dtype=float))
    return _result(x=x, fun=f_x, nfev=fcalls[0], nit=k, status=status,
                          success=status == 0 and bool(np.all(gx >= 0)),
                          message=("converged" if status == 0 else "maximum outer iterations"
                                   " reached") + f" ({method} inside, last r = {r:.3g})",
                          history=history, constr=gx, r=r)


def weighted_sum(objectives: Sequence[Callable[[np.ndarray], float]], weights: ArrayLike,
                 x0: ArrayLike) -> Callable[[np.ndarray], float]:
    """The report's weighted sum with automatic normalisation: sum_i w_i f_i(x) / |f_i(x0)|
    (a sub-objective that is 0 at the start is taken as it is), so that each weight means the
    same whatever the sub-objective's size."""
    w = np.asarray(weights, dtype=float)
    scale = np.array([abs(float(fi(np.asarray(x0, dtype=float)))) for fi in objectives])
    scale = np.where(scale > 0, scale, 1.0)
    if w.shape != scale.shape:
        raise ValueError(f"weighted_sum: {len(scale)} objectives and {w.size} weights")

    def total(x):
        return float(sum(wi * fi(x) / si for wi, fi, si in zip(w, objectives, scale)))

    return total


def weighted_uniform(objectives: Sequence[Callable[[np.ndarray], float]], weights: ArrayLike,
                     targets: ArrayLike, scales: ArrayLike) -> Callable[[np.ndarray], float]:
    """The report's "weighted uniform convergence": the largest weighted, normalised deviation
    max_i w_i |f_i(x) - t_i| / s_i, so that no sub-objective is left far behind the others."""
    w, t, s = (np.asarray(v, dtype=float) for v in (weights, targets, scales))
    if not (w.shape == t.shape == s.shape == (len(objectives),)):
        raise ValueError("weighted_uniform: one weight, target and scale per objective")
    if np.any(s <= 0):
        raise ValueError("weighted_uniform: every scale must be > 0")

    def worst(x):
        return float(max(wi * abs(fi(x) - ti) / si
                         for wi, fi, ti, si in zip(w, objectives, t, s)))

    return worst

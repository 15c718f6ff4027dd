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
           tol: float = 1e-8, maxiter: int = 500, directions: ArrayLike | None = None
           ) -> OptimizeResult:
    """Powell's conjugate directions: line searches along n directions (at first the axes),
    then along the round's total move, which becomes a new direction in place of the one that
    helped most unless that would make the set degenerate (Powell's test), so that on a
    quadratic the directions become conjugate and n rounds reach the minimum. A round is judged
    (the change of f below ``tol``, relative with an absolute floor, and the move below 1000
    ``tol`` per unit of ``step``) after the search along its move. ``directions`` (n, n rows)
    starts from a set of an earlier search (the result's ``directions``) instead of the
    axes."""
    g, calls = _counted(f)
    x = np.array(x0, dtype=float)
    n = x.size
    scale = np.broadcast_to(np.asarray(step, dtype=float), x.shape).copy()
    D = np.diag(scale) if directions is None else np.array(directions, dtype=float)
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
        move = x - x_start
        if np.any(move != 0.0):
            f_round = fx
            f_ext = g(x + move)  # the point one round further
            # the round's whole move is searched along before the round is judged: in a
            # narrow valley at an angle to the directions (an interior penalty's barrier, an
            # epigraph's kink) each direction gains almost nothing and the move is the valley
            t, ft, _ = line_minimum(g, x, move, 1.0, tol)
            if ft < fx:
                x = x + t * move
                fx = ft
            # Powell's test: the move replaces the direction that helped most only if the
            # extrapolated point is better and the drop along the move is not dominated by
            # that direction's (else the set would become degenerate)
            if f_ext < f_start and 2.0 * (f_start - 2.0 * f_round + f_ext) * (
                    (f_start - f_round - best_drop) ** 2) < best_drop * (f_start - f_ext) ** 2:
                D = np.vstack([np.delete(D, best_k, axis=0), move])
        history.append(fx)
        if f_start - fx <= tol * max(abs(fx), 1.0) and np.all(
                np.abs(x - x_start) <= tol * 1e3 * np.maximum(scale, 1e-300)):
            status = 0
            break
    return _result(x=x, fun=fx, nfev=calls[0], nit=it, status=status,
                          success=status == 0,
                          message="converged" if status == 0 else "maximum rounds reached",
                          history=history, directions=D)


def epigraph_value(q: np.ndarray, r: float) -> tuple[float, float]:
    """The epigraph variable t of max_i q_i under the interior penalty: t minimises
    t + r sum_i 1 / (t - q_i) over t > max q (one-dimensional and convex: Newton's method from
    max q + sqrt(r), where r sum 1 / (t - q)^2 >= 1, climbs to the root without overshooting).
    Returns (t, t + r sum 1 / (t - q)), the group's part of the penalty function; as r -> 0
    both tend to max q."""
    q = np.asarray(q, dtype=float)
    if q.size == 0:
        return -math.inf, 0.0
    if not np.all(np.isfinite(q)):
        return math.inf, math.inf
    top = float(q.max())
    if r <= 0.0:
        return top, top
    t = top + max(math.sqrt(r), 4.0 * np.finfo(float).eps * max(abs(top), 1.0))
    for _ in range(200):
        u = t - q
        g = r * float(np.sum(u ** -2)) - 1.0
        dg = -2.0 * r * float(np.sum(u ** -3))
        step = -g / dg
        nxt = t + step if t + step > top else 0.5 * (t + top)  # (never onto a q_i)
        if nxt == t or abs(nxt - t) <= 1e-15 * max(abs(t), 1.0):
            break
        t = nxt
    return t, t + r * float(np.sum(1.0 / (t - q)))


def interior_penalty(f: Callable[[np.ndarray], float],
                     constraints: Callable[[np.ndarray], ArrayLike], x0: ArrayLike, *,
                     method: str = "powell", r0: float | None = None, c: float = 0.1,
                     tol: float = 1e-7, max_outer: int = 30, step: float | ArrayLike = 0.1,
                     equalities: Callable[[np.ndarray], ArrayLike] | None = None,
                     epigraph: Callable[[np.ndarray], Sequence[ArrayLike]] | None = None,
                     equality_tol: float = 1e-6, phase_one: bool = False) -> OptimizeResult:
    """Minimise f(x) + sum_j max_i q_ji(x) subject to g(x) >= 0 (every component) and
    h(x) = 0 by the sequential unconstrained minimisation technique (SUMT) of the report's era:
    the mixed interior-exterior penalty function

        phi(x, r) = f(x) + sum_j T_j(x, r) + r sum_k 1 / g_k(x) + r^(-1/2) sum_l h_l(x)^2,

    minimised for r = r0, c r0, c^2 r0, ... (each by ``method``: "powell" or "cyclic", started
    where the last ended, after a line search along the last step: the extrapolation along the
    sequence of answers; Powell keeps its directions from one to the next). Outside g > 0 phi
    is infinite, so no search leaves the region; the
    equalities are pulled in from outside as r^(-1/2) grows. A max-type objective enters in its
    epigraph form: one more variable t_j per group with q_ji(x) <= t_j, barred as the
    constraints are, t_j + r sum_i 1 / (t_j - q_ji(x)); its own coordinate is minimised exactly
    at every x (:func:`epigraph_value`, ``T_j``), so the searches move on a smooth function
    where the maximum itself has a kink on which cyclic search and Powell stall.

    ``constraints`` returns the vector g(x), ``equalities`` h(x) (default none), ``epigraph``
    the groups [q_1(x), q_2(x), ...] (default none). A start that is not strictly inside
    g > 0 is refused unless ``phase_one``: then a first phase minimises the worst violation
    max_k -g_k(x) the same way (its epigraph form) until every g_k > 0, and the second starts
    there. Stops when the penalty terms, the change of the objective and the largest |h| are
    below ``tol`` (relative to the objective; |h| below ``equality_tol``). The result adds
    ``constr`` (g at the answer), ``eq`` (h), ``t`` (the epigraph variables), ``r`` (the last
    penalty factor) and ``phase_one`` (the first phase's result, or None)."""
    if method not in ("powell", "cyclic"):
        raise ValueError(f"interior_penalty: method must be 'powell' or 'cyclic', got {method!r}")
    x = np.array(x0, dtype=float)

    def g_of(xx):
        return np.atleast_1d(np.asarray(constraints(xx), dtype=float))

    def h_of(xx):
        return np.zeros(0) if equalities is None else \
            np.atleast_1d(np.asarray(equalities(xx), dtype=float))

    def groups_of(xx):
        return [] if epigraph is None else [np.atleast_1d(np.asarray(q, dtype=float))
                                            for q in epigraph(xx)]

    g0 = g_of(x)
    first = None
    if not np.all(g0 > 0):
        bad = int(np.argmin(g0))
        if not phase_one:
            raise ValueError(f"interior_penalty: the start is not strictly feasible (constraint"
                             f" {bad} = {g0[bad]:g}); start inside every constraint")
        first = _phase_one(g_of, x, method=method, tol=tol, max_outer=max_outer, step=step)
        if not np.all(g_of(first.x) > 0):
            return _result(x=first.x, fun=math.inf, nfev=first.nfev, nit=0, status=2,
                           success=False, message="the first phase found no design strictly"
                           f" inside every constraint (the worst violation is {first.fun:.3g})",
                           history=[], constr=g_of(first.x), eq=h_of(first.x), t=[], r=0.0,
                           phase_one=first)
        x = np.array(first.x, dtype=float)
    fcalls = [0]

    def objective(xx):  # the problem's own: f + sum of the groups' maxima
        return float(f(xx)) + sum(float(q.max()) for q in groups_of(xx) if q.size)

    def barrier(xx):
        return float(np.sum(1.0 / g_of(xx)))

    def phi_of(r):
        def phi(xx):
            gg = g_of(xx)
            if not np.all(gg > 0):
                return math.inf
            fcalls[0] += 1
            total = float(f(xx)) + r * float(np.sum(1.0 / gg))
            for q in groups_of(xx):
                total += epigraph_value(q, r)[1]
            hh = h_of(xx)
            if hh.size:
                total += float(np.sum(hh * hh)) / math.sqrt(r)
            return total
        return phi

    f_x = objective(x)
    if r0 is None:
        r0 = max(abs(f_x), 1.0) / max(barrier(x), 1e-300) * 0.1 if g0.size else \
            max(abs(f_x), 1.0) * 0.1
    r = r0
    history, status, k = [f_x], 1, 0
    directions, last = None, None
    for k in range(1, max_outer + 1):
        phi = phi_of(r)
        if last is not None and np.any(x != last):
            # the extrapolation of the penalty methods: the answers x(r) of the sequence run
            # toward the optimum, so the next one is searched for along the last step first
            # (in a valley of the kink or the barrier no single direction of the inner search
            # follows them)
            t, _, _ = line_minimum(phi, x, x - last, 1.0, tol * 0.1)
            x_from = x + t * (x - last)
        else:
            x_from = x
        last = x
        if method == "powell":  # (its directions carried from one minimisation to the next)
            res = powell(phi, x_from, step=step, tol=tol * 0.1, directions=directions)
            directions = res.directions
        else:
            res = cyclic_coordinate(phi, x_from, step=step, tol=tol * 0.1)
        x = res.x
        f_new = objective(x)
        gg = g_of(x)
        pen = r * float(np.sum(1.0 / gg)) if gg.size else 0.0
        pen += sum(epigraph_value(q, r)[1] - float(q.max()) for q in groups_of(x) if q.size)
        hh = h_of(x)
        history.append(f_new)
        size = max(abs(f_new), 1.0)
        done = (pen <= tol * size and abs(f_new - f_x) <= tol * size
                and (hh.size == 0 or float(np.max(np.abs(hh))) <= equality_tol))
        f_x = f_new
        if done:
            status = 0
            break
        r *= c
    gx = g_of(x)
    hx = h_of(x)
    ts = [epigraph_value(q, r)[0] for q in groups_of(x)]
    met = bool(np.all(gx >= 0)) and (hx.size == 0 or float(np.max(np.abs(hx))) <= equality_tol)
    return _result(x=x, fun=f_x, nfev=fcalls[0] + (first.nfev if first else 0), nit=k,
                   status=status, success=status == 0 and met,
                   message=("converged" if status == 0 else "maximum outer iterations"
                            " reached") + f" ({method} inside, last r = {r:.3g})",
                   history=history, constr=gx, eq=hx, t=ts, r=r, phase_one=first)


#: how far inside every constraint (in the constraints' units) the first phase looks for a start
PHASE_ONE_DEPTH = 0.01


def _phase_one(g_of, x0: np.ndarray, *, method: str, tol: float, max_outer: int, step
               ) -> OptimizeResult:
    """The first phase: minimise the worst violation max_k -g_k(x) (its epigraph form, no
    constraints) until a design strictly inside every constraint is found: at least
    :data:`PHASE_ONE_DEPTH` inside each, where the phase's objective stops falling (each
    violation is taken no lower than that floor). ``fun`` is the worst violation at the answer (< 0: strictly
    inside)."""
    inner = powell if method == "powell" else cyclic_coordinate
    x = np.array(x0, dtype=float)
    calls = [0]

    def phi_of(r):
        def phi(xx):
            calls[0] += 1
            return epigraph_value(np.maximum(-g_of(xx), -PHASE_ONE_DEPTH), r)[1]
        return phi

    worst = float(np.max(-g_of(x)))
    r = max(abs(worst), 1.0) * 0.1
    k = 0
    for k in range(1, max_outer + 1):
        x = inner(phi_of(r), x, step=step, tol=tol * 0.1).x
        worst = float(np.max(-g_of(x)))
        if worst < 0:
            break
        r *= 0.1
    return _result(x=x, fun=worst, nfev=calls[0], nit=k, status=0 if worst < 0 else 1,
                   success=worst < 0, message="a design strictly inside every constraint"
                   if worst < 0 else "no design strictly inside every constraint found",
                   history=[])


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
        return float(sum(wi * fi(x) / si for wi, fi, si in zip(w, objectives, scale, strict=True)))

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
                         for wi, fi, ti, si in zip(w, objectives, t, s, strict=True)))

    return worst

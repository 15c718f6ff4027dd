"""Solving a design problem (:class:`sewmech.design.problem.Problem`): the JB kinematics
report's methods (the 0.618 search, cyclic coordinate search and Powell's directions inside the
interior penalty, :mod:`sewmech.design.methods`), scipy's SLSQP with the metrics' exact
derivatives and the assembly margin as a constraint, differential evolution with a population
per batch call, and pymoo's NSGA-II for the Pareto front between an objective's parts.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.errors import OptionError, SewmechError
from .evaluate import ASSEMBLY_CLEARANCE_MM
from .problem import Problem, batch_values

METHODS = ("golden", "cyclic", "powell", "slsqp", "de", "nsga2")
#: the largest random seed (numpy's and scipy's generators take 0 .. 2**32 - 1 everywhere)
MAX_SEED = 2**32 - 1


def check_seed(seed, option: str = "--seed") -> int:
    """``seed`` if it is a whole number in 0 .. :data:`MAX_SEED`, else an OptionError."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) \
            or not 0 <= seed <= MAX_SEED:
        raise OptionError(option, f"must be a whole number in 0 .. {MAX_SEED}, got {seed!r}",
                          f"Give e.g. {option} 0")
    return int(seed)


def optimize(problem: Problem, method: str = "powell", *, tol: float = 1e-7, seed: int = 0):
    """Solve ``problem`` by ``method`` (:data:`METHODS`): golden (one variable, bounds only),
    cyclic or powell (the JB report's interior penalty over the constraints and the bounds,
    variables scaled to their ranges), slsqp (scipy, with the metrics' exact gradients), de
    (scipy's differential evolution, a whole population per batch call, ``seed``), nsga2
    (pymoo's NSGA-II over the objective's parts as separate objectives, a whole population per
    batch call; the compromise nearest the ideal point is the answer, the front in ``front``).
    Returns an OptimizeResult with x (file units), fun, objective_start, constraints (name ->
    value, satisfied), status ("success" when converged with every constraint met, else
    "failed"), n_evaluations, history; ``fun`` and ``objective_start`` are infinite where the
    objective is not defined (the design does not assemble over the whole turn, or a metric
    cannot be formed on it), and ``fun_note`` and ``objective_start_note`` then say why in
    words (else None)."""
    from scipy.optimize import OptimizeResult

    from .methods import golden_section, interior_penalty

    if method not in METHODS:
        raise OptionError("--method", f"unknown method {method!r}",
                          f"Choose one of {', '.join(METHODS)}")
    check_seed(seed)
    lo, hi = problem.lower, problem.upper
    span = hi - lo

    def to_x(u):
        return lo + np.asarray(u, dtype=float) * span

    def f_of(x):  # a design that does not assemble over the whole turn is infinitely bad
        try:
            if not problem.design_ok(x):
                return math.inf
            return problem.objective(x)[0]
        except SewmechError:
            return math.inf

    def fv_of(x):  # the same from values only (the derivative-free searches)
        try:
            f, _, ok = problem.value(x)
        except SewmechError:
            return math.inf
        return f if ok and math.isfinite(f) else math.inf

    converged = True
    message = ""
    history: list[float] = []
    if method == "golden":
        if len(problem.names) != 1 or problem.spec.constraints:
            raise OptionError("--method", "golden searches one variable within its bounds,"
                              " without constraints", "Use powell, cyclic or slsqp")
        r = golden_section(lambda t: fv_of(np.array([t])), lo[0], hi[0], tol=tol * span[0])
        x, history, message = np.array(r.x), r.history, r.message
    elif method in ("cyclic", "powell"):
        def g_all(u):
            try:
                _, g, ok = problem.value(to_x(u))
            except SewmechError:
                return np.array([-1.0])
            if not (ok and np.all(np.isfinite(g))):
                return np.array([-1.0])
            return np.concatenate([g, u, 1.0 - u])

        u0 = (problem.start - lo) / span
        if not np.all(g_all(u0) > 0):
            raise OptionError(problem.where, "the start is not strictly inside every constraint"
                              " and bound, which the interior penalty needs",
                              "Give a start (variables' start) that meets every constraint")
        r = interior_penalty(lambda u: fv_of(to_x(u)), g_all, u0, method=method, tol=tol)
        x, history, message, converged = to_x(r.x), r.history, r.message, r.status == 0
    elif method == "nsga2":
        x, history, message, converged, front = _nsga2(problem, seed)
    elif method == "de":
        x, history, message, converged = _differential_evolution(problem, seed, tol)
        # polished like scipy's own polish, but with the constraints and exact gradients
        xp, ok_p = _slsqp(problem, x, lo, hi, tol, [])
        if ok_p and f_of(xp) <= f_of(x) and all(
                c["satisfied"] for c in problem.report(xp).values()):
            x = xp
            message += "; polished by SLSQP"
    else:
        x, converged = _slsqp(problem, problem.start, lo, hi, tol, history)
        message = "SLSQP " + ("converged" if converged else "did not converge")
    x = np.clip(x, lo, hi)
    # the answer and the start are judged by the exact proof of assembly (the constraints'
    # report), not by the searches' clearance of ASSEMBLY_CLEARANCE_MM on a grid: SLSQP stops
    # on its margin constraint to within its tolerance (2e-10 mm inside the clearance), and
    # the answer, proved to assemble, was called undefined while its own table said it
    # assembles
    report = problem.report(x)
    fx = _answer_value(problem, x, report)
    start_report = problem.report(problem.start)
    f0 = _answer_value(problem, problem.start, start_report)
    ok = converged and math.isfinite(fx) and all(c["satisfied"] for c in report.values())
    res = OptimizeResult(x=x, fun=fx, objective_start=f0, constraints=report,
                         status="success" if ok else "failed", success=ok, message=message,
                         n_evaluations=problem.evaluations, history=history, method=method,
                         fun_note=None if math.isfinite(fx) else
                         undefined_objective(problem, x, report),
                         objective_start_note=None if math.isfinite(f0) else
                         undefined_objective(problem, problem.start, start_report))
    if method == "nsga2":
        res.front = front
    return res


def _assembles(report: dict) -> bool:
    return bool(report["assembles over the whole turn"]["satisfied"])


def _answer_value(problem: Problem, x: np.ndarray, report: dict) -> float:
    """The objective at a design the searches return (or start from): defined where the
    design is proved to assemble over the whole turn (``report``: :meth:`Problem.report`) and
    every metric can be formed, else infinite."""
    if not _assembles(report):
        return math.inf
    try:
        return float(problem.objective(x)[0])
    except SewmechError:
        return math.inf


def undefined_objective(problem: Problem, x: np.ndarray, report: dict | None = None) -> str:
    """Why the objective is not defined at the design x (file units), in words; ``report``:
    :meth:`Problem.report` of x (computed if not given), whose exact proof says whether x
    assembles."""
    report = problem.report(x) if report is None else report
    if not _assembles(report):
        failures = report["assembles over the whole turn"]["failures"]
        return ("not defined: the design does not assemble over the whole turn (proved at both"
                " ends of every setting input" + (f": {failures[0]}" if failures else "")
                + ")")
    try:
        problem.objective(x)
    except SewmechError as exc:
        return f"not defined: a metric cannot be formed on the design ({exc.message})"
    return "not defined: a metric of the objective is not a finite number on the design"


def _slsqp(problem: Problem, x0, lo, hi, tol: float, history: list) -> tuple[np.ndarray, bool]:
    """SLSQP from x0 with the metrics' exact gradients, the bounds and the constraints."""
    from scipy.optimize import minimize

    def guarded(x):  # the constraints where the design can be evaluated, else all unmet
        try:
            return problem.constraints(x)[:2]
        except SewmechError:
            k = sum((c.min is not None) + (c.max is not None) for c in problem.spec.constraints)
            return -np.ones(k), np.zeros((k, len(x)))

    # every closed-form unit kept ASSEMBLY_CLEARANCE_MM from failing to assemble anywhere in
    # the turn (a machine of loop units alone has no margin to hold)
    from ..engine.margins import conditions

    cons = [] if not conditions(problem.machine, problem.params(x0)) else [
        {"type": "ineq",
         "fun": lambda x: np.array([problem.assembly_margin(x)[0] - ASSEMBLY_CLEARANCE_MM]),
         "jac": lambda x: problem.assembly_margin(x)[1][None, :]}]
    if problem.spec.constraints:
        cons.append({"type": "ineq", "fun": lambda x: guarded(x)[0],
                     "jac": lambda x: guarded(x)[1]})

    def fg(x):
        try:
            return problem.objective(x)
        except SewmechError:
            return math.inf, np.zeros(len(x))

    if problem.spec.objective.form == "weighted_uniform":
        return _slsqp_uniform(problem, x0, lo, hi, tol, history, cons)
    r = minimize(fg, x0, jac=True, method="SLSQP", bounds=list(zip(lo, hi)), constraints=cons,
                 options={"ftol": tol * 1e-2, "maxiter": 300},
                 callback=lambda xk: history.append(fg(xk)[0]))
    return np.array(r.x), bool(r.success)


def _slsqp_uniform(problem: Problem, x0, lo, hi, tol: float, history: list, cons: list
                   ) -> tuple[np.ndarray, bool]:
    """The weighted uniform form (a maximum, not smooth where two parts are equal) as SLSQP's
    smooth epigraph problem: minimise t over (x, t) subject to
    t >= +-w_i (f_i(x) - t_i) / s_i for every part, besides the problem's constraints."""
    from scipy.optimize import minimize

    parts = problem.spec.objective.parts
    scales = problem._part_scales()
    n = len(x0)

    def part_rows(z):
        x = z[:n]
        g, J = [], []
        for p, sc in zip(parts, scales):
            v, d = problem.metric(p, x)
            for sign in (1.0, -1.0):
                g.append(z[n] - sign * p.weight * (v - p.target) / sc)
                J.append(np.concatenate([-sign * p.weight * d / sc, [1.0]]))
        return np.array(g), np.array(J)

    zcons = [{"type": "ineq", "fun": lambda z: part_rows(z)[0],
              "jac": lambda z: part_rows(z)[1]}]
    for c in cons:
        zcons.append({"type": "ineq", "fun": (lambda z, c=c: c["fun"](z[:n])),
                      "jac": (lambda z, c=c: np.hstack([c["jac"](z[:n]),
                                                        np.zeros((len(c["fun"](z[:n])), 1))]))})
    t0 = problem.objective(np.asarray(x0, dtype=float))[0]
    r = minimize(lambda z: (z[n], np.concatenate([np.zeros(n), [1.0]])),
                 np.concatenate([x0, [t0]]), jac=True, method="SLSQP",
                 bounds=list(zip(lo, hi)) + [(0.0, None)], constraints=zcons,
                 options={"ftol": tol * 1e-2, "maxiter": 300},
                 callback=lambda zk: history.append(float(zk[n])))
    return np.array(r.x[:n]), bool(r.success)


def _penalised(problem: Problem, X: np.ndarray) -> np.ndarray:
    """The objective of a batch of designs, a design that violates a constraint valued
    1e6 (1 + its violations in units of their bounds' sizes), one that does not assemble 1e12:
    the population never holds a NaN."""
    f, g, ok = problem.batch(X)
    # Deb's rule: any design that meets every constraint beats any that does not, and of two
    # that do not, the one that violates less wins
    viol = np.sum(np.maximum(0.0, -g) / problem.constraint_scales(), axis=1)
    f = np.where(viol > 0, 1e6 * (1.0 + viol), f)
    return np.where(ok & np.isfinite(f) & np.isfinite(viol), f, 1e12)


def _differential_evolution(problem: Problem, seed: int, tol: float):
    """scipy's differential evolution over the variables' box, each generation one batch call
    (``vectorized``), the constraints as penalties; polished by nothing (the caller reports
    the answer's constraints exactly)."""
    from scipy.optimize import differential_evolution

    history: list[float] = []
    n = len(problem.names)

    def f(Xt):  # scipy passes (n_variables, population)
        vals = _penalised(problem, Xt.T)
        problem.evaluations += Xt.shape[1]
        history.append(float(np.min(vals)))
        return vals

    r = differential_evolution(f, list(zip(problem.lower, problem.upper)), seed=seed,
                               vectorized=True, updating="deferred", tol=1e-8,
                               popsize=max(8, 4 * n), maxiter=300, polish=False,
                               x0=problem.start)
    return np.array(r.x), history, str(r.message), bool(r.success)


def _part_values(problem: Problem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each objective part as its own objective (to minimise: the normalised deviation from a
    target, or -+ the normalised value), the constraints as g <= 0 (pymoo's sign), and which
    designs assemble, for a batch of designs."""
    vals, ok = batch_values(problem, X)
    spec = problem.spec
    F = []
    for p, sc in zip(spec.objective.parts, problem._part_scales()):
        v = vals[(p.metric, p.regulator_deg, p.phi_deg)]
        if p.sense == "target":
            F.append(np.abs(v - p.target) / sc)
        else:
            F.append((1.0 if p.sense == "min" else -1.0) * v / sc)
    G = []
    for c in spec.constraints:
        v = vals[(c.metric, c.regulator_deg, c.phi_deg)]
        if c.min is not None:
            G.append((c.min - v) / max(abs(c.min), 1.0))
        if c.max is not None:
            G.append((v - c.max) / max(abs(c.max), 1.0))
    F = np.column_stack(F)
    G = np.column_stack(G) if G else np.zeros((len(X), 0))
    # a design that does not assemble: every objective and constraint very bad, never NaN
    F = np.where(ok[:, None] & np.isfinite(F), F, 1e12)
    G = np.where(ok[:, None] & np.isfinite(G), G, 1e12)
    return F, G, ok


def _nsga2(problem: Problem, seed: int):
    """pymoo's NSGA-II over the parts of the objective, each generation one batch call; the
    answer is the front's design nearest the ideal point in objectives scaled to the front's
    ranges. Returns (x, history, message, converged, front)."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem as PymooProblem
    from pymoo.optimize import minimize as pymoo_minimize

    parts = problem.spec.objective.parts
    if len(parts) < 2:
        raise OptionError("--method", "nsga2 needs at least two objective parts (it finds the"
                          " front between them)", "Use slsqp or de for one objective")
    n_con = sum((c.min is not None) + (c.max is not None) for c in problem.spec.constraints)
    history: list[float] = []

    class Wrapped(PymooProblem):
        def __init__(self):
            super().__init__(n_var=len(problem.names), n_obj=len(parts), n_ieq_constr=n_con,
                             xl=problem.lower, xu=problem.upper)

        def _evaluate(self, X, out, *args, **kwargs):
            F, G, _ = _part_values(problem, X)
            problem.evaluations += len(X)
            out["F"] = F
            if n_con:
                out["G"] = G
            history.append(float(np.min(F.sum(axis=1))))

    pop = max(24, 12 * len(problem.names))
    r = pymoo_minimize(Wrapped(), NSGA2(pop_size=pop), ("n_gen", 60), seed=seed, verbose=False)
    if r.X is None:
        return (problem.start.copy(), history,
                "NSGA-II found no design that meets every constraint", False,
                {"x": [], "f": [], "parts": [p.metric for p in parts]})
    X = np.atleast_2d(r.X)
    F = np.atleast_2d(r.F)
    lo, hi = F.min(axis=0), F.max(axis=0)
    z = (F - lo) / np.where(hi > lo, hi - lo, 1.0)
    k = int(np.argmin(np.linalg.norm(z, axis=1)))
    front = {"x": X.tolist(), "f": F.tolist(), "parts": [p.metric for p in parts],
             "compromise": k}
    message = f"NSGA-II, {len(X)} designs on the front; the compromise nearest the ideal point"
    return X[k], history, message, True, front

"""Solving a design problem (:class:`sewmech.design.problem.Problem`): the JB kinematics
report's methods (the 0.618 search, cyclic coordinate search and Powell's directions inside the
classical SUMT penalty, :mod:`sewmech.design.methods`), scipy's SLSQP with the metrics' exact
derivatives and the assembly margin as a constraint, differential evolution with a population
per batch call, and pymoo's NSGA-II for the Pareto front between an objective's parts.

Every method solves the problem in its epigraph form (:class:`~sewmech.design.problem.
FormPoint`): a max-type objective (a largest value over the turn to minimise, the weighted
uniform form) as an extra variable t with every piece q_i <= t, a bound on a max-type metric
once per piece, so that no method stops on the kink of a maximum. Equalities enter SLSQP as
equalities, the penalty methods through the mixed interior-exterior penalty, the population
methods within :data:`POPULATION_EQUALITY_TOL`. A start that is not strictly inside the
constraints is moved inside by a first phase.

No answer is called a success before an optimality check that can fail (:func:`check_answer`):
a local polish from the answer (SLSQP with the exact derivatives, or Powell with the penalty
where a metric is value-only) must not lower the objective by more than ``check_tol``
(relative); the KKT residual of the exact derivatives is reported beside it. Otherwise the
status says what is wrong (:data:`STATUSES`).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.errors import OptionError, SewmechError
from .evaluate import ASSEMBLY_CLEARANCE_MM
from .problem import EQUALITY_TOL, FormPoint, Problem, batch_values

METHODS = ("golden", "cyclic", "powell", "slsqp", "de", "nsga2")
#: the largest random seed (numpy's and scipy's generators take 0 .. 2**32 - 1 everywhere)
MAX_SEED = 2**32 - 1
#: what a result's status says
STATUSES = {
    "success": "converged, every constraint met, a local polish from the answer does not"
               " lower the objective by more than the check's tolerance, and (with exact"
               " derivatives) the KKT residual is within its tolerance",
    "not_optimal": "every constraint met, but a local polish from the answer lowers the"
                   " objective by more than the check's tolerance, or (with exact"
                   " derivatives) the KKT residual is above its tolerance: not shown a local"
                   " optimum",
    "infeasible": "the answer does not meet every constraint (or does not assemble over the"
                  " whole turn)",
    "failed": "no answer: the objective is not defined at the method's design, or the first"
              " phase found no design strictly inside the constraints",
}
#: the optimality check: a polish may lower the objective by at most this (relative to
#: max(1, |objective|)) for the answer to count as a local optimum
CHECK_TOL = 1e-6
#: the optimality check with exact derivatives: the KKT residual (:func:`kkt_residual`) may be
#: at most this for the answer to count as a local optimum. It catches a search that stopped
#: where it started, its polish stopping there too (0.94 on the JB1-3 bearings problem), not
#: an answer within the objective's tolerance on a flat valley (cyclic search 0.01 mm along the
#: transmission-angle problem's kink, where the objective is 1e-6 from its least: 1.7e-3)
KKT_TOL = 5e-2
#: how close (relative to max(1, |value|)) differential evolution and NSGA-II take an equality
#: to be met: a population cannot hit a curve; their best member is then polished onto it
POPULATION_EQUALITY_TOL = 1e-3


def check_seed(seed, option: str = "--seed") -> int:
    """``seed`` if it is a whole number in 0 .. :data:`MAX_SEED`, else an OptionError."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) \
            or not 0 <= seed <= MAX_SEED:
        raise OptionError(option, f"must be a whole number in 0 .. {MAX_SEED}, got {seed!r}",
                          f"Give e.g. {option} 0")
    return int(seed)


def optimize(problem: Problem, method: str = "powell", *, tol: float = 1e-7, seed: int = 0,
             check_tol: float = CHECK_TOL):
    """Solve ``problem`` by ``method`` (:data:`METHODS`): golden (one variable, bounds only),
    cyclic or powell (the JB report's methods inside the SUMT penalty over the constraints and
    the bounds, variables scaled to their ranges, the epigraph form of a max-type objective),
    slsqp (scipy, with the metrics' exact gradients, in the epigraph form), de (scipy's
    differential evolution, a whole population per batch call, ``seed``, polished), nsga2
    (pymoo's NSGA-II over the objective's parts as separate objectives, a whole population per
    batch call; the compromise nearest the ideal point is the answer, the front in ``front``,
    the best feasible member by the objective, polished, in ``best``).

    Returns an OptimizeResult with x (file units), fun, objective_start, constraints (name ->
    value, satisfied), status (:data:`STATUSES`), success, message, check (the optimality
    check: ``how``, ``improvement``, ``tolerance``, ``passed``, ``kkt_residual``,
    ``evaluations``), n_evaluations (the method's designs, the check's not counted), history;
    ``fun`` and ``objective_start`` are infinite where the objective is not defined (the design
    does not assemble over the whole turn, or a metric cannot be formed on it), and ``fun_note``
    and ``objective_start_note`` then say why in words (else None)."""
    from scipy.optimize import OptimizeResult

    from .methods import golden_section

    if method not in METHODS:
        raise OptionError("--method", f"unknown method {method!r}",
                          f"Choose one of {', '.join(METHODS)}")
    check_seed(seed)
    lo, hi = problem.lower, problem.upper
    span = hi - lo
    if method == "slsqp":
        _require_gradients(problem, "slsqp")

    def fv_of(x):  # values only (the derivative-free searches)
        try:
            f, _, ok = problem.value(x)
        except SewmechError:
            return math.inf
        return f if ok and math.isfinite(f) else math.inf

    converged = True
    message = ""
    history: list[float] = []
    extra: dict = {}
    if method == "golden":
        if len(problem.names) != 1 or problem.spec.constraints:
            raise OptionError("--method", "golden searches one variable within its bounds,"
                              " without constraints", "Use powell, cyclic or slsqp")
        r = golden_section(lambda t: fv_of(np.array([t])), lo[0], hi[0], tol=tol * span[0])
        x, history, message = np.array(r.x), r.history, r.message
    elif method in ("cyclic", "powell"):
        r = _penalty(problem, method, problem.start, tol)
        x, history, converged = r.x_design, r.history, r.status == 0
        message = r.message
        if r.phase_one is not None:
            message += ("; the start was not strictly inside every constraint and bound: a"
                        " first phase moved it inside")
        if r.status == 2:
            extra["no_answer"] = r.message
    elif method == "nsga2":
        x, history, message, converged, front, best = _nsga2(problem, seed, tol, check_tol)
        extra["front"], extra["best"] = front, best
    elif method == "de":
        x, history, message, converged = _differential_evolution(problem, seed, tol)
        xp, how = _polish(problem, x, tol)
        if xp is not None and _feasible(problem, xp) and (
                not _feasible(problem, x)
                or objective_of(problem, xp) <= objective_of(problem, x)):
            x = xp
            message += f"; polished by {how}"
    else:
        x, converged = _slsqp(problem, problem.start, tol, history)
        message = "SLSQP " + ("converged" if converged else "did not converge")
    x = np.clip(x, lo, hi)
    n_method = problem.evaluations
    # the answer and the start are judged by the exact proof of assembly (the constraints'
    # report), not by the searches' clearance of ASSEMBLY_CLEARANCE_MM on a grid: SLSQP stops
    # on its margin constraint to within its tolerance (2e-10 mm inside the clearance), and
    # the answer, proved to assemble, was called undefined while its own table said it
    # assembles
    report = problem.report(x)
    fx = objective_of(problem, x, report)
    start_report = problem.report(problem.start)
    f0 = objective_of(problem, problem.start, start_report)
    feasible = all(c["satisfied"] for c in report.values())
    check = None
    if method == "nsga2":  # the compromise is a member of the front (an equality met within
        # the population's tolerance), not the objective's optimum: the status is that of the
        # best feasible member, polished and checked
        best = extra["best"]
        status = "infeasible" if best is None else best["status"]
        check = None if best is None else best["check"]
    elif "no_answer" in extra or not math.isfinite(fx):
        status = "failed"
    elif not feasible:
        status = "infeasible"
    else:
        check = check_answer(problem, x, tol=tol, check_tol=check_tol)
        status = "success" if check["passed"] else "not_optimal"
    if status == "success" and not converged:
        message += " (its own stopping rule not met; the check finds no better design nearby)"
    if status == "not_optimal":
        if check["improvement"] > check["tolerance"]:
            message += (f"; not a local optimum: {check['how']} lowered the objective by"
                        f" {check['improvement']:.3g} (more than {check['tolerance']:.3g})")
        else:
            message += (f"; not shown a local optimum: its KKT residual from the exact"
                        f" derivatives is {check['kkt_residual']:.3g} (more than"
                        f" {check['kkt_tolerance']:.3g}), and {check['how']} did not move it")
        if method == "nsga2":
            message += " at the best feasible member"
    res = OptimizeResult(x=x, fun=fx, objective_start=f0, constraints=report, status=status,
                         success=status == "success", message=message, check=check,
                         n_evaluations=n_method, history=history, method=method,
                         fun_note=None if math.isfinite(fx) else
                         undefined_objective(problem, x, report),
                         objective_start_note=None if math.isfinite(f0) else
                         undefined_objective(problem, problem.start, start_report))
    if method == "nsga2":
        res.front, res.best = extra["front"], extra["best"]
    return res


def _require_gradients(problem: Problem, method: str) -> None:
    if not problem.has_gradients:
        raise OptionError("--method", f"{method} needs every metric's exact derivative;"
                          f" {', '.join(problem.value_only_metrics())} has none yet (value"
                          " only)", "Use powell, cyclic, de or golden, which compare values")


def objective_of(problem: Problem, x: np.ndarray, report: dict | None = None) -> float:
    """The objective at x from the exactly located metrics; infinite where it is not defined
    (the design does not assemble over the whole turn, or a metric cannot be formed). Whether
    x assembles: ``report``'s exact proof (:meth:`Problem.report`) where given, else the
    searches' clearance on a grid and, where that refuses x (an answer on the assembly
    margin), the exact proof."""
    try:
        ok = _assembles(report) if report is not None else (
            problem.design_ok(x) or _assembles(problem.report(x)))
        if not ok:
            return math.inf
        v = problem.form(x).objective
    except SewmechError:
        return math.inf
    return v if math.isfinite(v) else math.inf


def _feasible(problem: Problem, x: np.ndarray) -> bool:
    return all(c["satisfied"] for c in problem.report(x).values())


def _assembles(report: dict) -> bool:
    return bool(report["assembles over the whole turn"]["satisfied"])


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


# ---- the penalty methods ---------------------------------------------------------------------
def _penalty(problem: Problem, method: str, x0: np.ndarray, tol: float, step: float = 0.1,
             max_outer: int = 30):
    """Cyclic search or Powell inside the SUMT penalty (:func:`~sewmech.design.methods.
    interior_penalty`) over the variables scaled to their ranges: the problem's inequalities
    and bounds barred from inside, its equalities pulled in from outside, a max-type
    objective's groups in the epigraph form, the values alone (:meth:`Problem.form_values`);
    a start outside the constraints moved inside by the first phase. Adds ``x_design`` (file
    units) to the result."""
    from .methods import interior_penalty

    lo, hi = problem.lower, problem.upper
    span = hi - lo

    def to_x(u):
        return lo + np.asarray(u, dtype=float) * span

    def fp(u):
        return problem.form_values(to_x(u))

    def f(u):
        p = fp(u)
        return p.smooth if p.ok else math.inf

    def g(u):
        p = fp(u)
        if not (p.ok and np.all(np.isfinite(p.g))):
            return np.array([-1.0])
        return np.concatenate([p.g, u, 1.0 - u])

    def h(u):
        p = fp(u)
        return p.h if p.ok else np.full(n_eq, math.inf)

    def groups(u):
        p = fp(u)
        return p.groups if p.ok else [np.array([math.inf])] * n_groups

    u0 = (np.asarray(x0, dtype=float) - lo) / span
    start = problem.form_values(np.asarray(x0, dtype=float))
    n_eq = sum(c.equality is not None for c in problem.spec.constraints)
    n_groups = len(start.groups) if start.ok else 0
    r = interior_penalty(f, g, u0, method=method, tol=tol, step=step, max_outer=max_outer,
                         equalities=h if n_eq else None,
                         epigraph=groups if n_groups else None,
                         equality_tol=0.5 * EQUALITY_TOL, phase_one=True)
    r.x_design = to_x(r.x)
    return r


# ---- SLSQP in the epigraph form --------------------------------------------------------------
def _match(ref_tag: np.ndarray, tag: np.ndarray) -> np.ndarray:
    """For each reference piece (source, angle) the index of the current piece it continues
    (-1: none): the same source, the nearest angle (or the same place in order where angles
    are not known)."""
    out = np.full(len(ref_tag), -1, dtype=np.int64)
    for k, (src, phi) in enumerate(ref_tag):
        cand = np.flatnonzero(tag[:, 0] == src) if len(tag) else np.zeros(0, dtype=np.int64)
        if not len(cand):
            continue
        if math.isnan(phi) or np.isnan(tag[cand, 1]).any():
            order = int(np.sum(ref_tag[:k, 0] == src))
            out[k] = cand[min(order, len(cand) - 1)]
        else:
            dist = np.abs(np.mod(tag[cand, 1] - phi + math.pi, 2.0 * math.pi) - math.pi)
            out[k] = cand[int(np.argmin(dist))]
    return out


def _tracked(problem: Problem, ref: FormPoint, x: np.ndarray):
    """The form at x with its pieces continued from the reference's (fixed sizes, as SLSQP
    needs): (smooth, smooth_d, [(q, dq) per group], g, dg, h, dh), or None where the form is
    not defined."""
    try:
        p = problem.form(x)
    except SewmechError:
        return None
    if not p.ok:
        return None
    n = len(x)
    groups = []
    for j, rt in enumerate(ref.groups_tag):
        idx = _match(rt, p.groups_tag[j])
        q = np.where(idx >= 0, p.groups[j][np.maximum(idx, 0)], -1e300)
        dq = np.where((idx >= 0)[:, None], p.groups_d[j][np.maximum(idx, 0)], 0.0)
        groups.append((q, dq))
    idx = _match(ref.g_tag, p.g_tag)
    g = np.where(idx >= 0, p.g[np.maximum(idx, 0)] if len(p.g) else 0.0, 1e300)
    dg = np.where((idx >= 0)[:, None], p.g_d[np.maximum(idx, 0)] if len(p.g) else 0.0, 0.0)
    return p.smooth, p.smooth_d, groups, g, dg.reshape(len(g), n), p.h, p.h_d


def _slsqp(problem: Problem, x0, tol: float, history: list, maxiter: int = 300
           ) -> tuple[np.ndarray, bool]:
    """SLSQP from x0 on the epigraph form with the metrics' exact gradients, the bounds, the
    constraints (a max-type bound once per piece) and the assembly margin; the pieces are
    continued from the start's (by their shaft angles), and where the answer has a piece the
    start did not (a new local extreme above the epigraph variable), SLSQP starts again from
    the answer with it (at most four rounds)."""
    from ..engine.margins import conditions

    x = np.clip(np.asarray(x0, dtype=float), problem.lower, problem.upper)
    margin = bool(conditions(problem.machine, problem.params(x)))
    ok = False
    for _ in range(4):
        ref = problem.form(x)
        if not ref.ok:
            return x, False
        x, ok, missed = _slsqp_round(problem, ref, x, tol, history, maxiter, margin)
        if not missed:
            break
    return x, ok


def _slsqp_round(problem: Problem, ref: FormPoint, x: np.ndarray, tol: float, history: list,
                 maxiter: int, margin: bool) -> tuple[np.ndarray, bool, bool]:
    """One SLSQP run of :func:`_slsqp` with the pieces of ``ref`` (the form at x): (answer,
    SLSQP's success, whether the answer has a piece or a bound that the run left out)."""
    from scipy.optimize import minimize

    lo, hi = problem.lower, problem.upper
    n = len(x)
    G = len(ref.groups)
    sizes = [len(q) for q in ref.groups]
    n_g, n_h = len(ref.g), len(ref.h)
    n_in = sum(sizes) + n_g
    last: dict = {}

    def at(z):
        key = z.tobytes()
        if key not in last:
            last.clear()
            last[key] = _tracked(problem, ref, z[:n])
        return last[key]

    def fun(z):
        t = at(z)
        if t is None:
            return math.inf, np.zeros(n + G)
        return t[0] + float(np.sum(z[n:])), np.concatenate([t[1], np.ones(G)])

    def ineq(z):
        t = at(z)
        if t is None:
            return -np.ones(n_in)
        return np.concatenate([*(z[n + j] - q for j, (q, _) in enumerate(t[2])), t[3]])

    def ineq_jac(z):
        t = at(z)
        J = np.zeros((n_in, n + G))
        if t is None:
            return J
        r0 = 0
        for j, (_, dq) in enumerate(t[2]):
            J[r0:r0 + len(dq), :n] = -dq
            J[r0:r0 + len(dq), n + j] = 1.0
            r0 += len(dq)
        J[r0:, :n] = t[4]
        return J

    def eq(z):
        t = at(z)
        return np.full(n_h, 1.0) if t is None else t[5]

    def eq_jac(z):
        t = at(z)
        J = np.zeros((n_h, n + G))
        if t is not None:
            J[:, :n] = t[6]
        return J

    def margin_fun(z):
        return np.array([problem.assembly_margin(z[:n])[0] - ASSEMBLY_CLEARANCE_MM])

    def margin_jac(z):
        return np.concatenate([problem.assembly_margin(z[:n])[1], np.zeros(G)])[None, :]

    cons = []
    if n_in:
        cons.append({"type": "ineq", "fun": ineq, "jac": ineq_jac})
    if n_h:
        cons.append({"type": "eq", "fun": eq, "jac": eq_jac})
    if margin:
        cons.append({"type": "ineq", "fun": margin_fun, "jac": margin_jac})
    z0 = np.concatenate([x, [float(q.max()) for q in ref.groups]])
    r = minimize(fun, z0, jac=True, method="SLSQP",
                 bounds=list(zip(lo, hi, strict=True)) + [(None, None)] * G,
                 constraints=cons, options={"ftol": tol * 1e-2, "maxiter": maxiter},
                 callback=lambda zk: history.append(float(fun(zk)[0])))
    x_new = np.clip(np.array(r.x[:n]), lo, hi)
    new = problem.form(x_new)
    # every piece of the answer within its group's epigraph variable and every inequality met:
    # no local extreme the start lacked was left out
    size = max(1.0, abs(new.objective)) if new.ok else 1.0
    missed = new.ok and bool(
        [len(q) for q in new.groups] != sizes or len(new.g) != n_g
        or any(float(q.max()) > float(r.x[n + j]) + 1e-7 * size
               for j, q in enumerate(new.groups) if len(q))
        or (len(new.g) and float(new.g.min()) < -1e-9))
    return x_new, bool(r.success), missed


# ---- the optimality check --------------------------------------------------------------------
def _polish(problem: Problem, x: np.ndarray, tol: float) -> tuple[np.ndarray | None, str]:
    """A local polish from x: SLSQP on the epigraph form with the exact derivatives, or, where
    a metric is value-only, Powell inside the penalty with small steps (1e-3 of each range)."""
    try:
        if problem.has_gradients:
            xp, _ = _slsqp(problem, x, tol, [], maxiter=100)
            return xp, "SLSQP from the answer (exact derivatives)"
        r = _penalty(problem, "powell", x, tol, step=1e-3, max_outer=20)
        return (r.x_design if r.status != 2 else None,
                "Powell with the penalty from the answer (a metric is value-only)")
    except SewmechError:
        return None, "a polish from the answer"


def check_answer(problem: Problem, x: np.ndarray, *, tol: float = 1e-7,
                 check_tol: float = CHECK_TOL) -> dict:
    """The optimality check of an answer x that meets every constraint: a local polish from it
    (:func:`_polish`) may lower the objective by at most ``check_tol`` max(1, |f|) at a design
    that meets every constraint too; the KKT residual of the epigraph form from the exact
    derivatives (where every metric has them) is reported beside it. Returns ``how``,
    ``objective``, ``polished_objective``, ``improvement``, ``tolerance``, ``passed``,
    ``kkt_residual`` (None without exact derivatives) and ``evaluations`` (the check's
    designs)."""
    before = problem.evaluations
    f0 = objective_of(problem, x)
    xp, how = _polish(problem, x, tol)
    fp = objective_of(problem, xp) if xp is not None else math.inf
    gain = f0 - fp if (xp is not None and math.isfinite(fp) and _feasible(problem, xp)) \
        else 0.0
    limit = check_tol * max(1.0, abs(f0))
    kkt = kkt_residual(problem, x) if problem.has_gradients else None
    return {"how": how, "objective": f0, "polished_objective": fp if math.isfinite(fp) else
            None, "polished_x": None if xp is None else [float(v) for v in xp],
            "improvement": max(gain, 0.0), "tolerance": limit,
            "passed": gain <= limit and (kkt is None or kkt <= KKT_TOL),
            "kkt_residual": kkt, "kkt_tolerance": KKT_TOL if kkt is not None else None,
            "evaluations": problem.evaluations - before}


def kkt_residual(problem: Problem, x: np.ndarray, active_tol: float = 1e-6) -> float | None:
    """The KKT residual of the epigraph form at x (t at each group's maximum) from the exact
    derivatives: the larger of the stationarity residual, the least || grad F - sum lambda_a
    grad c_a || over multipliers >= 0 of the active inequalities (pieces within ``active_tol``
    of their group's maximum, constraints within it of 0, the variables' bounds, the assembly
    margin) and free ones of the equalities, relative to max(1, ||grad F||) in the variables
    scaled to their ranges, and how far the active set is from holding with equality (the
    active pieces' distance below their maximum, |h|, the active constraints' values; each
    relative to max(1, its size)). None where the form is not defined."""
    from scipy.optimize import nnls

    from ..engine.margins import conditions

    p = problem.form(x)
    if not p.ok:
        return None
    n = len(x)
    span = problem.upper - problem.lower
    G = len(p.groups)
    grad = np.concatenate([p.smooth_d * span, np.ones(G)])
    cols, free = [], []
    gap = [float(np.max(np.abs(p.h)))] if len(p.h) else [0.0]
    for j, (q, dq) in enumerate(zip(p.groups, p.groups_d, strict=True)):
        top = max(1.0, abs(float(q.max())))
        for i in np.flatnonzero(q >= q.max() - active_tol * top):
            c = np.zeros(n + G)
            c[:n] = -dq[i] * span
            c[n + j] = 1.0
            cols.append(c)
            gap.append(float(q.max() - q[i]) / top)
    for i in np.flatnonzero(p.g <= active_tol):
        cols.append(np.concatenate([p.g_d[i] * span, np.zeros(G)]))
        gap.append(abs(float(p.g[i])))
    for i in range(len(p.h)):
        free.append(np.concatenate([p.h_d[i] * span, np.zeros(G)]))
    u = (np.asarray(x, dtype=float) - problem.lower) / span
    for i in range(n):
        for side, at in ((1.0, u[i] <= active_tol), (-1.0, u[i] >= 1.0 - active_tol)):
            if at:
                c = np.zeros(n + G)
                c[i] = side
                cols.append(c)
    if conditions(problem.machine, problem.params(x)):
        v, d = problem.assembly_margin(x)
        if v - ASSEMBLY_CLEARANCE_MM <= active_tol * 10.0:
            cols.append(np.concatenate([d * span, np.zeros(G)]))
    A = np.array(cols + free + [-c for c in free]).T.reshape(n + G, -1)
    if not np.all(np.isfinite(A)) or not np.all(np.isfinite(grad)):
        return None
    if A.shape[1] == 0:
        res = float(np.linalg.norm(grad))
    else:
        res = float(nnls(A, grad, maxiter=50 * A.shape[1])[1])
    return max(res / max(1.0, float(np.linalg.norm(grad))), max(gap))


# ---- the population methods ------------------------------------------------------------------
def _violations(problem: Problem, g: np.ndarray) -> np.ndarray:
    """Each design's constraint violation in units of its bounds' sizes, an equality met within
    :data:`POPULATION_EQUALITY_TOL` counted as met: (m,)."""
    scales = problem.constraint_scales()
    v = np.maximum(0.0, -g) / scales
    col = 0
    for c in problem.spec.constraints:
        k = len(c.bounds)
        if c.equality is not None:  # its two rows: |value - b| within the band
            v[:, col:col + k] = np.maximum(0.0, v[:, col:col + k] - POPULATION_EQUALITY_TOL)
        col += k
    return np.sum(v, axis=1)


def _penalised(problem: Problem, X: np.ndarray) -> np.ndarray:
    """The objective of a batch of designs, a design that violates a constraint valued
    1e6 (1 + its violations in units of their bounds' sizes), one that does not assemble 1e12:
    the population never holds a NaN."""
    f, g, ok = problem.batch(X)
    # Deb's rule: any design that meets every constraint beats any that does not, and of two
    # that do not, the one that violates less wins
    viol = _violations(problem, g)
    f = np.where(viol > 0, 1e6 * (1.0 + viol), f)
    return np.where(ok & np.isfinite(f) & np.isfinite(viol), f, 1e12)


def _differential_evolution(problem: Problem, seed: int, tol: float):
    """scipy's differential evolution over the variables' box, each generation one batch call
    (``vectorized``), the constraints by Deb's rule (an equality within
    :data:`POPULATION_EQUALITY_TOL`); polished by the caller."""
    from scipy.optimize import differential_evolution

    history: list[float] = []
    n = len(problem.names)

    def f(Xt):  # scipy passes (n_variables, population)
        vals = _penalised(problem, Xt.T)
        problem.evaluations += Xt.shape[1]
        history.append(float(np.min(vals)))
        return vals

    r = differential_evolution(f, list(zip(problem.lower, problem.upper, strict=True)),
                               seed=seed, vectorized=True, updating="deferred", tol=1e-8,
                               popsize=max(8, 4 * n), maxiter=300, polish=False,
                               x0=problem.start)
    return np.array(r.x), history, str(r.message), bool(r.success)


def _part_values(problem: Problem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each objective part as its own objective (to minimise: the normalised deviation from a
    target, or -+ the normalised value), the constraints as g <= 0 (pymoo's sign; an equality
    as |value - b| / size - :data:`POPULATION_EQUALITY_TOL` <= 0), and which designs assemble,
    for a batch of designs."""
    from ._models import ref_key

    vals, ok = batch_values(problem, X)
    spec = problem.spec
    F = []
    for p, sc in zip(spec.objective.parts, problem._part_scales(), strict=True):
        v = vals[ref_key(p)]
        if p.sense == "target":
            F.append(np.abs(v - p.target) / sc)
        else:
            F.append((1.0 if p.sense == "min" else -1.0) * v / sc)
    G = []
    for c in spec.constraints:
        v = vals[ref_key(c)]
        eq = c.equality
        if eq is not None:
            G.append(np.abs(v - eq) / max(abs(eq), 1.0) - POPULATION_EQUALITY_TOL)
            continue
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


def _nsga2(problem: Problem, seed: int, tol: float, check_tol: float):
    """pymoo's NSGA-II over the parts of the objective, each generation one batch call; the
    answer is the front's design nearest the ideal point in objectives scaled to the front's
    ranges; beside it the best member of the final population that meets every constraint (an
    equality within :data:`POPULATION_EQUALITY_TOL`) by the problem's own objective, polished
    and checked (:func:`check_answer`). Returns (x, history, message, converged, front,
    best)."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem as PymooProblem
    from pymoo.optimize import minimize as pymoo_minimize

    parts = problem.spec.objective.parts
    if len(parts) < 2:
        raise OptionError("--method", "nsga2 needs at least two objective parts (it finds the"
                          " front between them)", "Use slsqp or de for one objective")
    n_con = sum(1 if c.equality is not None else len(c.bounds)
                for c in problem.spec.constraints)
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
    empty = {"x": [], "f": [], "parts": [p.metric for p in parts],
             "equality_tolerance": POPULATION_EQUALITY_TOL}
    if r.X is None:
        return (problem.start.copy(), history,
                "NSGA-II found no design that meets every constraint (an equality within"
                f" {POPULATION_EQUALITY_TOL:g} of its size)", False, empty, None)
    X = np.atleast_2d(r.X)
    F = np.atleast_2d(r.F)
    lo, hi = F.min(axis=0), F.max(axis=0)
    z = (F - lo) / np.where(hi > lo, hi - lo, 1.0)
    k = int(np.argmin(np.linalg.norm(z, axis=1)))
    front = {**empty, "x": X.tolist(), "f": F.tolist(), "compromise": k}
    best = _best_member(problem, np.atleast_2d(r.pop.get("X")), tol, check_tol)
    message = f"NSGA-II, {len(X)} designs on the front; the compromise nearest the ideal point"
    if best is not None:
        message += (f"; the best feasible member by the objective {best['member_objective']:.6g}"
                    f", polished {best['objective']:.6g} ({best['status']})")
        front["best_member"] = best["member_x"]
    return X[k], history, message, True, front, best


def _best_member(problem: Problem, X: np.ndarray, tol: float, check_tol: float
                 ) -> dict | None:
    """The member of a population that meets every constraint (an equality within
    :data:`POPULATION_EQUALITY_TOL`) with the least objective, polished and checked."""
    f, g, ok = problem.batch(X)
    good = ok & np.isfinite(f) & (_violations(problem, g) == 0)
    if not good.any():
        return None
    k = int(np.argmin(np.where(good, f, np.inf)))
    x = X[k]
    xp, how = _polish(problem, x, tol)
    answer = x
    if xp is not None and _feasible(problem, xp) and (
            not _feasible(problem, x) or objective_of(problem, xp) <= objective_of(problem, x)):
        answer = np.clip(xp, problem.lower, problem.upper)
    feasible = _feasible(problem, answer)
    check = check_answer(problem, answer, tol=tol, check_tol=check_tol) if feasible else None
    status = "infeasible" if not feasible else ("success" if check["passed"] else
                                                "not_optimal")
    return {"member_x": [float(v) for v in x], "member_objective": float(f[k]),
            "x": [float(v) for v in answer], "objective": objective_of(problem, answer),
            "polished_by": how, "status": status, "check": check,
            "constraints": problem.report(answer)}

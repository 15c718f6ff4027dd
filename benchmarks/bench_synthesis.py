"""Benchmark: four-bar path synthesis, sewmech against pylinkage's particle swarm (issue 18).

The job: the benchmark four-bar (``fourbar-benchmark``: A = (0, 0), D = (38, 0), coupler point
P at (30, 10) mm in the coupler frame) with unknown crank, coupler and rocker lengths AB, BC,
CD (bounds 10-20, 30-50, 25-45 mm) whose coupler point must pass through 12 given points at
the crank angles 0, 30, ..., 330 deg (timed path generation). The points are those of a
hidden design, AB = 13.5, BC = 42, CD = 33 mm, so the best objective is 0. Objective: the mean
squared distance of P from its 12 points, mm^2; a design that does not assemble costs 1e9.

Contenders, run in alternation (``_timing.interleave``) so that a slow phase of the shared
machine does not decide the verdict:

1. pylinkage 1.3.0: ``particle_swarm_optimization`` (its local-best swarm, 100 particles, 200
   iterations), each particle evaluated by its own ``Linkage`` API (``set_constraints``,
   ``set_coords``, ``step`` over the 12 angles);
2. sewmech, the same swarm algorithm (pylinkage's ``_local_best_pso``, the same settings) with
   every particle of an iteration evaluated in one batch ``kinematics`` call;
3. sewmech's own way: the same job as a design problem (24 target parts, the weighted sum of
   squares) by SLSQP with the exact derivatives, from the machine's lengths.

Reported: each one's time and objective; the time sewmech's runs take to reach the objective
pylinkage's swarm ends with (goal: 10x faster). The swarms draw from unseeded generators (as
pylinkage's does), so each round is a new draw; medians over the rounds. Writes
``benchmarks/results/synthesis.json``; a missed target prints MISSED and exits 0.

Then classical synthesis and the CAD files (issue 33; :func:`classical`, written to
``benchmarks/results/synthesis-classical.json``), each timed alone (best and median of 7 after
a warm-up) and checked while it is timed:

- Freudenstein three points (x^1.5 on 1..4, input 60..150 deg, output 90..160 deg, AD 100 mm):
  sewmech's whole ``synthesize_function`` (the branch and Grashof checks and the structural
  error on 721 points) against pylinkage 1.3.0's ``function_generation`` on the same angle
  pairs; the two answers' lengths must agree (two implementations of the same equations);
- Burmester's curves of four poses (720 values of beta2) and the whole ``synthesize_motion``
  (every pair of the dyads built and checked for defects);
- timed path generation on this job's 12 points: the exact three-point start and SLSQP over
  every dimension (``synthesize_path``), its rms distance;
- the embroidery take-up by the paper's method (``synthesize_take_up``);
- JB1-3's drawing: the geometry, the DXF written by ezdxf, read back and audited; the SVG;
- ``influence-balance --solver minmax`` on the example file (two linear programmes of 256-gons)
  against the least-squares solver.

Run: ``.venv/bin/python benchmarks/bench_synthesis.py`` (``make bench`` installs pylinkage).
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import Own, figure, interleave, write_results  # noqa: E402 (benchmarks/ is the script's directory)

import sewmech

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "synthesis.json"
HIDDEN = (13.5, 42.0, 33.0)  # AB, BC, CD, mm
LO, HI = np.array([10.0, 30.0, 25.0]), np.array([20.0, 50.0, 45.0])
AD = 38.0
P_LOCAL = (30.0, 10.0)
ANGLES_DEG = np.arange(0.0, 360.0, 30.0)
PARTICLES, ITERATIONS = 100, 200
TARGET_RATIO = 10.0
INFEASIBLE = 1e9
PL_FUNCTION = "pylinkage function_generation (3 points)"


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results
    (synthesis.json)."""
    rows, pl = out["rows"], out["rows"]["pylinkage"]
    smaller = all(r["objective"] <= out["pylinkage_objective"]
                  for r in rows["sewmech slsqp"]["runs"])
    anchor = "pylinkage 1.3 particle swarm"
    return [
        figure("four-bar path synthesis, 12 points, SLSQP with exact derivatives",
               rows["sewmech slsqp"]["seconds_median"], "s", anchor=anchor,
               anchor_value=pl["seconds_median"], ratio=out["ratio_slsqp"],
               target=out["target_ratio"], op=">=", on="ratio",
               condition=("a smaller objective than pylinkage's", smaller)),
        figure("four-bar path synthesis, 12 points, the same swarm with batch evaluation",
               rows["sewmech swarm"]["seconds_median"], "s", anchor=anchor,
               anchor_value=pl["seconds_median"], ratio=out["ratio_swarm"]),
    ]


def current_figures_classical(out: dict) -> list[dict]:
    """The rows of the table of current figures from synthesis-classical.json (information:
    no targets)."""
    if PL_FUNCTION not in out:
        return []
    pl = out[PL_FUNCTION]["seconds_best"] * 1e6
    anchor = "pylinkage 1.3 function_generation (the lengths alone)"
    alone = out["sewmech Freudenstein's K and the lengths alone"]["seconds_best"] * 1e6
    whole = out["sewmech synthesize_function (3 points, checks, 721-point error)"][
        "seconds_best"] * 1e6
    return [figure("Freudenstein function generation, 3 points, the lengths alone", alone, "us",
                   anchor=anchor, anchor_value=pl, ratio=pl / alone),
            figure("Freudenstein function generation, 3 points, with the checks and the"
                   " 721-point error", whole, "us", anchor=anchor, anchor_value=pl,
                   ratio=whole / pl, ratio_kind="time")]
NAMES = ("B.u", "dyad.length1", "dyad.length2")


def targets(m) -> np.ndarray:
    """P at the 12 angles for the hidden design (sewmech; checked against pylinkage below)."""
    P = m.parameters(dict(zip(NAMES, HIDDEN)))
    r = sewmech.kinematics(m, np.radians(ANGLES_DEG), params=P, points=["P"], links=[],
                           variables=[])
    return r.point("P").p.copy()


class Clocked:
    """A batch objective that remembers when its best value first fell to ``goal``."""

    def __init__(self, fn, goal: float):
        self.fn, self.goal, self.t0, self.reached = fn, goal, time.perf_counter(), None

    def __call__(self, X):
        c = self.fn(X)
        if self.reached is None and np.min(c) <= self.goal:
            self.reached = time.perf_counter() - self.t0
        return c


def sewmech_cost(m, T):
    phi = np.radians(ANGLES_DEG)
    plan_names = list(NAMES)

    def cost(X):  # (particles, 3) -> (particles,)
        P = m.parameters(dict(zip(plan_names, X.T)))
        r = sewmech.kinematics(m, phi, params=P, points=["P"], links=[], variables=[],
                               on_failure="mask")
        d2 = np.sum((r.point("P").p - T) ** 2, axis=-1).mean(axis=-1)
        return np.where(r.feasible.all(axis=-1) & np.isfinite(d2), d2, INFEASIBLE)

    return cost


def build_pylinkage():
    from pylinkage.actuators import Crank
    from pylinkage.components import Ground
    from pylinkage.dyads import FixedDyad, RRRDyad
    from pylinkage.simulation import Linkage

    step = math.radians(30.0)
    A = Ground(0.0, 0.0, name="A")
    D = Ground(AD, 0.0, name="D")
    # the crank advances before a step is recorded: start one step back, so step k is at 30 k
    B = Crank(anchor=A, radius=15.0, angular_velocity=step, initial_angle=-step, name="B")
    C = RRRDyad(B.output, D, distance1=40.0, distance2=35.0, x=16.0, y=40.0, name="C")
    P = FixedDyad(B.output, C, distance=math.hypot(*P_LOCAL),
                  angle=math.atan2(P_LOCAL[1], P_LOCAL[0]), name="P")
    return Linkage([A, D, B, C, P], name="synthesis")


def pylinkage_eval(T):
    """pylinkage's evaluation of one particle: its constraints set, the start coordinates
    restored, the 12 steps walked; an unbuildable design costs INFEASIBLE."""
    from pylinkage.exceptions import UnbuildableError

    base_p = [math.hypot(*P_LOCAL), math.atan2(P_LOCAL[1], P_LOCAL[0])]

    def eval_func(linkage, dims, pos):
        linkage.set_constraints([dims[0], dims[1], dims[2], *base_p])
        linkage.set_coords(pos)
        try:
            loci = [step[4] for step in linkage.step(iterations=len(ANGLES_DEG))]
        except UnbuildableError:
            return INFEASIBLE
        d2 = np.sum((np.array(loci, dtype=float) - T) ** 2, axis=1).mean()
        return float(d2) if math.isfinite(d2) else INFEASIBLE

    return eval_func


def problem_file(T, root: Path) -> Path:
    parts = "".join(
        f'\n[[objective.parts]]\nmetric = "p_P_{c}"\nphi_deg = {a:g}\ntarget = {float(T[k, i])!r}\n'
        f"scale = 1.0\n"
        for k, a in enumerate(ANGLES_DEG) for i, c in enumerate("xy"))
    variables = "".join(
        f'\n[[variables]]\nparameter = "{n}"\nlower = {lo:g}\nupper = {hi:g}\n'
        for n, lo, hi in zip(NAMES, LO, HI))
    path = root / "synthesis.toml"
    path.write_text(f'[problem]\nname = "four-bar path synthesis"\nmachine ='
                    f' "fourbar-benchmark"\n{variables}\n[objective]\nform = "weighted_sum"'
                    f"\n{parts}", encoding="utf-8")
    return path


def classical() -> dict:
    """Classical synthesis, the CAD files and the min-max balancing, timed and checked."""
    from _timing import best

    from sewmech.design import burmester as BU
    from sewmech.design import synthesis as SY
    from sewmech.design.take_up_synthesis import synthesize_take_up

    out: dict = {}

    def row(name, fn, repeat=7, **extra):
        b, med = best(fn, repeat=repeat)
        out[name] = {"seconds_best": b, "seconds_median": med, **extra}
        print(f"  {name:58s} {med * 1e3:10.2f} ms (best {b * 1e3:.2f})"
              + "".join(f"; {k} {v:.3g}" if isinstance(v, float) else f"; {k} {v}"
                        for k, v in extra.items()))

    print("classical synthesis and CAD files (median of 7 after a warm-up):")
    args = ("x**1.5", (1.0, 4.0), (60.0, 150.0), (90.0, 160.0))
    r = SY.synthesize_function(*args)
    pairs = list(zip(np.radians(r.theta2_deg), np.radians(r.theta4_deg), strict=True))
    try:
        from pylinkage.synthesis.function_generation import function_generation

        pl = function_generation(pairs, ground_length=100.0, require_grashof=False)
        s = pl.raw_solutions[0]
        gap = max(abs(s.crank_length - r.fourbar.a), abs(s.coupler_length - r.fourbar.b),
                  abs(s.rocker_length - r.fourbar.c))
        row(PL_FUNCTION,
            lambda: function_generation(pairs, ground_length=100.0, require_grashof=False),
            lengths_gap_mm=gap)
        assert gap < 1e-9, f"the two Freudenstein answers differ by {gap} mm"
    except ImportError:
        print("  (pylinkage is not installed: `make bench` installs it)")
    row("sewmech synthesize_function (3 points, checks, 721-point error)",
        lambda: SY.synthesize_function(*args), max_error_deg=r.max_error_deg)
    row("sewmech Freudenstein's K and the lengths alone",
        lambda: SY.lengths_from_k(SY.freudenstein_k(*zip(*pairs, strict=True))[0], 100.0))
    poses = [[0.0, 0.0, 0.0], [20.0, 5.0, 20.0], [35.0, 15.0, 45.0], [45.0, 30.0, 70.0]]
    P = np.array(poses)
    P[:, 2] = np.radians(P[:, 2])
    c = BU.burmester_curves(P, 720)
    row("sewmech Burmester curves, 4 poses (720 beta2)", lambda: BU.burmester_curves(P, 720),
        dyads=len(c.beta2), worst_circle_mm=float(c.residual.max()))
    m = BU.synthesize_motion(poses)
    row("sewmech synthesize_motion, 4 poses (every pair checked)",
        lambda: BU.synthesize_motion(poses), repeat=3, pairs=m.candidates[0],
        free_of_defects=m.candidates[1])
    mach = sewmech.load_machine("fourbar-benchmark")
    T = targets(mach)
    ps = BU.synthesize_path(T, ANGLES_DEG)
    row("sewmech synthesize_path, 12 points (start + SLSQP)",
        lambda: BU.synthesize_path(T, ANGLES_DEG), repeat=3, start_rms_mm=ps.start_rms_mm,
        answer_rms_mm=ps.answer_rms_mm, designs=int(ps.result.n_evaluations))
    row("sewmech path_start alone (the 9^4 free choices scanned)",
        lambda: BU.path_start(T, ANGLES_DEG), repeat=3)
    tu = synthesize_take_up()
    row("sewmech synthesize_take_up (the paper's case)", synthesize_take_up, repeat=3,
        bc=tu.bc, cd=tu.cd, ad=tu.ad)
    import ezdxf

    from sewmech.app.drawing.cad import machine_drawing
    from sewmech.app.files.cad import svg_text, write_dxf

    jb = sewmech.load_machine("jb1-3")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "jb1-3.dxf"
        d = machine_drawing(jb, phi_deg=30.0)
        row("JB1-3 drawing's geometry (machine_drawing)",
            lambda: machine_drawing(jb, phi_deg=30.0), entities=len(d.entities))
        row("JB1-3 DXF written (ezdxf)", lambda: write_dxf(d, path))
        row("JB1-3 DXF read back and audited (ezdxf)",
            lambda: ezdxf.readfile(path).audit(), bytes=path.stat().st_size)
        row("JB1-3 SVG text", lambda: svg_text(d))
    from sewmech.design.minmax_balance import influence_minmax
    from sewmech.design.vibration import influence_balance, phasor

    rows = [ln.split(",") for ln in (HERE.parent / "examples" / "measurements"
                                     / "trial-runs.csv").read_text().splitlines()
            if ln and not ln.startswith(("#", "run"))]
    places = list(dict.fromkeys(r_[1] for r_ in rows))
    tab = {(r_[0], r_[1]): phasor(float(r_[2]), float(r_[3])) for r_ in rows}
    V0 = np.array([tab["0", p] for p in places])
    Vt = np.array([[tab[k, p] for p in places] for k in ("1", "2")])
    mm = influence_minmax(V0, Vt, [30.0, 30.0], [0.0, 90.0])
    row("influence-balance least squares (example file)",
        lambda: influence_balance(V0, Vt, [30.0, 30.0], [0.0, 90.0]))
    row("influence-balance minmax LP, K = 256 (example file)",
        lambda: influence_minmax(V0, Vt, [30.0, 30.0], [0.0, 90.0]),
        after_max_mm_s=mm.after_max)
    row("influence-balance minmax LP with a limit (two LPs)",
        lambda: influence_minmax(V0, Vt, [30.0, 30.0], [0.0, 90.0],
                                 limits_gcm=[40.0, np.inf]))
    return out


def main() -> int:
    classic = classical()
    RESULTS.parent.mkdir(exist_ok=True)
    write_results(RESULTS.parent / "synthesis-classical.json", classic,
                  current_figures_classical(classic))
    try:
        from pylinkage.optimization import particle_swarm_optimization
        from pylinkage.optimization.particle_swarm import _local_best_pso
    except ImportError:
        print("pylinkage is not installed: `make bench` installs it")
        return 0
    from sewmech.design.optimize import optimize
    from sewmech.design.problem import Problem, load_problem

    m = sewmech.load_machine("fourbar-benchmark")
    T = targets(m)
    cost = sewmech_cost(m, T)
    lk = build_pylinkage()
    ev = pylinkage_eval(T)
    # the two engines agree on the hidden design's points (an independent check of the job)
    assert ev(lk, list(HIDDEN), tuple(lk.get_coords())) < 1e-18, "pylinkage disagrees"
    assert cost(np.array([HIDDEN]))[0] < 1e-24
    pos0 = tuple(lk.get_coords())
    runs = {"pylinkage": [], "sewmech swarm": [], "sewmech slsqp": []}

    def pl_swarm():
        lk.set_coords(pos0)
        t0 = time.perf_counter()
        ens = particle_swarm_optimization(ev, lk, dimensions=3, n_particles=PARTICLES,
                                          iterations=ITERATIONS, bounds=(LO, HI),
                                          order_relation=min, verbose=False)
        dt = time.perf_counter() - t0
        runs["pylinkage"].append({"seconds": dt, "objective": float(ens.scores["score"][0])})
        return Own(dt)

    def sew_swarm():
        goal = runs["pylinkage"][-1]["objective"] if runs["pylinkage"] else 0.0
        f = Clocked(cost, goal)
        t0 = time.perf_counter()
        best, _ = _local_best_pso(f, 3, (LO, HI), n_particles=PARTICLES, iterations=ITERATIONS,
                                  verbose=False)
        dt = time.perf_counter() - t0
        runs["sewmech swarm"].append({"seconds": dt, "objective": float(best),
                                      "to_goal": f.reached})
        return Own(dt)

    with tempfile.TemporaryDirectory() as tmp:
        spec, pm = load_problem(problem_file(T, Path(tmp)))

        def sew_slsqp():
            p = Problem(spec, pm)
            t0 = time.perf_counter()
            r = optimize(p, "slsqp", tol=1e-12)
            dt = time.perf_counter() - t0
            runs["sewmech slsqp"].append({"seconds": dt, "objective": float(r.fun) / 12.0,
                                          "designs": int(r.n_evaluations),
                                          "x": [float(v) for v in r.x]})
            return Own(dt)

        t = interleave({"pylinkage": pl_swarm, "sewmech swarm": sew_swarm,
                        "sewmech slsqp": sew_slsqp}, rounds=3)
    for v in runs.values():
        del v[0]  # the warm-up
    pl_obj = statistics.median(r["objective"] for r in runs["pylinkage"])
    to_goal = [r["to_goal"] for r in runs["sewmech swarm"] if r["to_goal"] is not None]
    rows = {name: {"seconds_median": t.median(name), "seconds_best": t.best(name),
                   "objective_median_mm2": statistics.median(r["objective"] for r in rs),
                   "runs": rs} for name, rs in runs.items()}
    ratio_swarm = t.ratio("pylinkage", "sewmech swarm")
    ratio_slsqp = t.ratio("pylinkage", "sewmech slsqp")
    print(f"four-bar path synthesis: 3 lengths, 12 points, {PARTICLES} particles x {ITERATIONS}"
          " iterations for the swarms")
    print(f"{'contender':16s} {'median s':>9s} {'objective mm^2 (median)':>24s}")
    for name, r in rows.items():
        print(f"{name:16s} {r['seconds_median']:9.3f} {r['objective_median_mm2']:24.3e}")
    print(f"sewmech swarm reached the objective pylinkage's swarm ended with (each round's"
          f" own) in {len(to_goal)} of {len(runs['sewmech swarm'])} rounds, after"
          f" {statistics.median(to_goal) if to_goal else float('nan'):.3f} s (median)")
    slsqp_ok = all(r["objective"] <= pl_obj for r in runs["sewmech slsqp"])
    verdict = "met" if ratio_slsqp >= TARGET_RATIO and slsqp_ok else "MISSED"
    print(f"pylinkage's swarm / sewmech's swarm: {ratio_swarm:.1f}x (same algorithm, batch"
          f" evaluation); / sewmech SLSQP to a smaller objective: {ratio_slsqp:.1f}x;"
          f" target {TARGET_RATIO:g}x: {verdict}")
    RESULTS.parent.mkdir(exist_ok=True)
    out = {"rows": rows, "ratio_swarm": ratio_swarm, "ratio_slsqp": ratio_slsqp,
           "pylinkage_objective": pl_obj, "swarm_to_goal_s": to_goal,
           "target_ratio": TARGET_RATIO, "verdict": verdict}
    write_results(RESULTS, out, current_figures(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: design problems (issue 18).

Targets (issue 18): the feed-lift problem by Powell with the interior penalty at most 2 s warm.
Measured, each once after a warm-up of the metrics: the four-bar swing problem by every method
(time, designs evaluated, the crank length against the closed form), and the shipped JB1-3
problems by SLSQP (exact gradients) and by Powell with the interior penalty (the JB report's
method). Prints a table and writes ``benchmarks/results/optimize.json``; a missed target
prints MISSED and exits 0. (Powell on the feed-lift problem takes minutes: the run is long.)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from _timing import figure, write_results  # noqa: E402
from test_problem import closed_form_crank  # noqa: E402

from sewmech.design.optimize import optimize  # noqa: E402
from sewmech.design.problem import Problem, load_problem  # noqa: E402

PROBLEMS = HERE.parent / "examples" / "problems"
RESULTS = HERE / "results" / "optimize.json"
TARGET_FEED_LIFT_POWELL_S = 2.0


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    powell = [r for r in out["rows"] if r["problem"] == "JB1-3 feed lift"
              and r["method"] == "powell"][-1]
    return [figure("JB1-3 feed-lift problem by Powell with the penalty", powell["seconds"], "s",
                   target=TARGET_FEED_LIFT_POWELL_S)]


def run(path: Path, method: str) -> dict:
    spec, m = load_problem(path)
    Problem(spec, m).objective(Problem(spec, m).start)  # warm the metrics' plans
    p = Problem(spec, m)
    t0 = time.perf_counter()
    r = optimize(p, method)
    dt = time.perf_counter() - t0
    return {"problem": spec.problem.name, "method": method, "seconds": dt,
            "designs": int(r.n_evaluations), "status": r.status, "objective": float(r.fun),
            "x": [float(v) for v in r.x]}


def main():
    rows = []
    a_star = closed_form_crank(0.9)
    for method in ("golden", "slsqp", "powell", "cyclic", "de"):
        row = run(PROBLEMS / "fourbar-swing.toml", method)
        row["error_mm"] = abs(row["x"][0] - a_star)
        rows.append(row)
    for name in ("feed-lift.toml", "jb13-toward-jb82.toml", "take-up.toml"):
        rows.append(run(PROBLEMS / name, "slsqp"))
    powell = run(PROBLEMS / "feed-lift.toml", "powell")
    rows.append(powell)
    print(f"{'problem':28s} {'method':8s} {'seconds':>9s} {'designs':>8s}  status   objective")
    for r in rows:
        extra = f"  crank off the closed form by {r['error_mm']:.1e} mm" if "error_mm" in r \
            else ""
        print(f"{r['problem']:28s} {r['method']:8s} {r['seconds']:9.2f} {r['designs']:8d}"
              f"  {r['status']:8s} {r['objective']:.6g}{extra}")
    verdict = "met" if powell["seconds"] <= TARGET_FEED_LIFT_POWELL_S else "MISSED"
    print(f"target: the feed-lift problem by Powell with the penalty at most"
          f" {TARGET_FEED_LIFT_POWELL_S:g} s: {powell['seconds']:.1f} s, {verdict}")
    out = {"rows": rows, "verdict": verdict}
    write_results(RESULTS, out, current_figures(out))


if __name__ == "__main__":
    main()

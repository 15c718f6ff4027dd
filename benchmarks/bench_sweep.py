"""Benchmark: design sweeps (issues 20 and 34).

The shipped sweep's designs (examples/sweeps/jb-feed.toml: six feed dimensions, four feed
metrics at the regulator's settings, the whole-turn assembly at both regulator ends, peak
torque and shaking force), its first ``DESIGNS`` designs (a Sobol sequence's prefix: the same
designs the full sweep starts with), in chunks of ``CHUNK`` (the command's default; until
2026-11-27 this ran 640 designs in chunks of 80, where a chunk's fixed costs weigh more):

- in this process (``--workers 0``: the kernels on every core through threads), and on a Dask
  LocalCluster of 1 and of 2 worker processes (one thread each), timed in interleaved rounds
  (benchmarks/_timing.py), each into a fresh directory (writing Parquet included); the
  clusters are started before the rounds (their start-up is printed apart);
- the target (issue 20): Dask's overhead at 2 workers at most 10 % against in-process on 2
  cores, i.e. the 2-worker time at most 1.10 x the in-process time;
- designs per second per core (issue 34 item 1, target 1000): the 1-worker LocalCluster,
  beside a 1-worker LocalCluster that evaluates as sewmech did before issue 34 (the assembly
  on the whole 1 deg grid, every feed metric on its 1 deg turn: :func:`grid_evaluation`), in
  the same interleaved rounds; and a design's time by part (assembly, feed metrics, force
  analysis) both ways, in this process on one thread, over the first ``PART_DESIGNS`` designs;
- the shipped 100,000-design sweep's time, estimated from the in-process rate (``--full`` runs
  the whole sweep through the command line instead).

Prints a table and writes ``benchmarks/results/sweep.json``; a missed target prints MISSED and
exits 0.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _timing import figure, interleave, table, write_results

SHIPPED = HERE.parent / "examples" / "sweeps" / "jb-feed.toml"
RESULTS = HERE / "results" / "sweep.json"
DESIGNS = 1000
#: the chunk ``sewmech sweep`` takes by default (sewmech.app.sweep_run.DEFAULT_CHUNK): the
#: shipped sweep as it runs (four chunks: two for each of 2 workers)
CHUNK = 250
ROUNDS = 3
TARGET_OVERHEAD = 0.10
TARGET_PER_CORE = 1000.0  # designs/s per core on the shipped sweep (issue 34)


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    c = out["contenders"]
    return [
        figure(f"shipped JB feed sweep, {out['designs']} designs on a LocalCluster of 2 workers"
               " (Dask's overhead)", c["LocalCluster, 2 workers"]["median_s"], "s",
               anchor="the same designs in-process, 2 cores",
               anchor_value=c["in-process"]["median_s"], ratio=out["overhead_ratio_2_workers"],
               ratio_kind="time", target=1.0 + TARGET_OVERHEAD, on="ratio"),
        figure("shipped JB feed sweep, designs per second per core (1 worker)",
               out["per_core_designs_per_s"], "designs/s", target=TARGET_PER_CORE, op=">=",
               anchor="the same worker evaluating on the 1 deg grid (before issue 34)",
               anchor_value=out.get("per_core_grid_designs_per_s"),
               ratio=out.get("located_over_grid")),
    ]


#: the contender that evaluates as sewmech did before issue 34 item 1
GRID = "LocalCluster, 1 worker, 1 deg grid (before)"
#: designs of the per-part timing
PART_DESIGNS = 1000


def grid_evaluation() -> None:
    """Make this process evaluate sweeps as before issue 34 item 1: the assembly on the whole
    1 deg grid, every feed metric on its 1 deg turn (the same batch calls as the design
    problems' grid evaluation)."""
    from sewmech.design import evaluate, sweep

    def on_grid(machine, P, *, counts=None):
        ok = evaluate.assembles_on_grid(machine, P)
        if counts is not None:
            counts.whole_grid += len(ok)
        return ok

    evaluate.assembles_batch = on_grid
    sweep._located = lambda sweep_, o: False


def time_parts() -> dict:
    """A design's time by part (ms), located and on the grid, in this process on one thread:
    the assembly, the feed metrics together, the force analysis."""
    from sewmech.design import evaluate
    from sewmech.design import sweep as sw
    from sewmech.design._dynamic_metrics import is_dynamic
    from sewmech.design.sweep_file import load_sweep
    from sewmech.engine import _threads

    n = PART_DESIGNS
    full = load_sweep(SHIPPED)  # (its first designs: the same sample as the part file's)
    P = sw.params_of(full, sw.sample(full, 0, n))
    kin = [o for o in full.spec.outputs if not is_dynamic(o.metric)]
    out = {"assembly": {}, "feed metrics": {}, "force analysis": {}}
    was = _threads._THREADS
    _threads.set_threads(1)
    try:
        for rnd in range(2):  # (the first round warms up)
            t0 = time.perf_counter()
            ok = evaluate.assembles_batch(full.machine, P)
            t1 = time.perf_counter()
            evaluate.assembles_on_grid(full.machine, P)
            t2 = time.perf_counter()
            counts = dict.fromkeys(sw.COUNTS, 0)
            for o in kin:
                sw._feed_values(full, o, P, ok, 0, counts)
            t3 = time.perf_counter()
            evaluate.metric_batch(full.machine, kin, P, ok)
            t4 = time.perf_counter()
            sw._dynamics(full, P, ok)
            t5 = time.perf_counter()
            if rnd:
                ms = 1e3 / n
                out["assembly"] = {"located": (t1 - t0) * ms, "grid": (t2 - t1) * ms}
                out["feed metrics"] = {"located": (t3 - t2) * ms, "grid": (t4 - t3) * ms}
                out["force analysis"] = {"located": (t5 - t4) * ms, "grid": (t5 - t4) * ms}
    finally:
        _threads.set_threads(was)
    out["total"] = {k: sum(v[k] for v in list(out.values())) for k in ("located", "grid")}
    return out


def main():
    from distributed import Client

    from sewmech.app.sweep_run import local_cluster, run_sweep
    from sewmech.design.sweep_file import load_sweep

    tmp = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    try:
        text = SHIPPED.read_text(encoding="utf-8")
        assert "designs = 100000" in text
        part = tmp / "jb-feed-part.toml"
        part.write_text(text.replace("designs = 100000", f"designs = {DESIGNS}"),
                        encoding="utf-8")
        sweep = load_sweep(part)
        runs = [0]

        def fresh() -> Path:
            runs[0] += 1
            return tmp / f"out-{runs[0]}"

        starts = {}
        clusters = {}
        for n in (1, 2, "grid"):
            t0 = time.perf_counter()
            cluster = local_cluster(1 if n == "grid" else n)
            client = Client(cluster)
            client.wait_for_workers(1 if n == "grid" else n)
            starts[n] = time.perf_counter() - t0
            clusters[n] = (cluster, client)
        clusters["grid"][1].run(grid_evaluation)  # that worker evaluates as before issue 34

        def here():
            run_sweep(sweep, fresh(), workers=0, chunk=CHUNK)

        def on(n):
            return lambda: run_sweep(sweep, fresh(), chunk=CHUNK, client=clusters[n][1])

        contenders = {"in-process": here, "LocalCluster, 1 worker": on(1),
                      "LocalCluster, 2 workers": on(2), GRID: on("grid")}
        t = interleave(contenders, rounds=ROUNDS)
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
        rows = []
        result = {"designs": DESIGNS, "chunk": CHUNK, "rounds": ROUNDS, "cores": os.cpu_count(),
                  "cluster_start_s": starts, "contenders": {}}
        for name in contenders:
            best, med = t.best(name), t.median(name)
            rows.append((name, f"{best:.2f}", f"{med:.2f}", f"{DESIGNS / med:.1f}"))
            result["contenders"][name] = {"best_s": best, "median_s": med,
                                          "designs_per_s": DESIGNS / med,
                                          "rounds_s": t.rounds[name]}
        print(f"the shipped sweep's first {DESIGNS} designs in chunks of {CHUNK},"
              f" {ROUNDS} interleaved rounds, {os.cpu_count()} cores")
        print(table(rows, ("contender", "best s", "median s", "designs/s (median)")))
        print(f"cluster start-up: 1 worker {starts[1]:.1f} s, 2 workers {starts[2]:.1f} s"
              " (not in the times above)")
        starts = {str(k): v for k, v in starts.items()}
        result["cluster_start_s"] = starts
        ratio = t.ratio("LocalCluster, 2 workers", "in-process")
        lo, hi = t.ratio_range("LocalCluster, 2 workers", "in-process")
        speedup = t.ratio("LocalCluster, 1 worker", "LocalCluster, 2 workers")
        verdict = "met" if ratio <= 1.0 + TARGET_OVERHEAD else "MISSED"
        print(f"Dask at 2 workers / in-process: {ratio:.3f} (rounds {lo:.3f} .. {hi:.3f}),"
              f" overhead {100 * (ratio - 1):+.1f} %; target <= {100 * TARGET_OVERHEAD:.0f} %:"
              f" {verdict}")
        print(f"2 workers against 1: {speedup:.2f} x")
        rate = DESIGNS / t.median("in-process")
        per_core = DESIGNS / t.median("LocalCluster, 1 worker")
        before = DESIGNS / t.median(GRID)
        gain = t.ratio(GRID, "LocalCluster, 1 worker")
        glo, ghi = t.ratio_range(GRID, "LocalCluster, 1 worker")
        print(f"per core (1 worker): {per_core:.1f} designs/s located, {before:.1f} on the"
              f" 1 deg grid as before: {gain:.2f} x (rounds {glo:.2f} .. {ghi:.2f}); target"
              f" >= {TARGET_PER_CORE:.0f} designs/s:"
              f" {'met' if per_core >= TARGET_PER_CORE else 'MISSED'}")
        parts = time_parts()
        print("where a design's time goes (this process, one thread, ms a design):")
        print(table([(k, f"{v['located']:.3f}", f"{v['grid']:.3f}") for k, v in parts.items()],
                    ("part", "located", "1 deg grid (before)")))
        estimate = 100_000 / rate
        print(f"the shipped 100,000-design sweep in this process: about {estimate / 60:.0f} min"
              f" at {rate:.1f} designs/s (estimated from the rate above, not run whole);"
              f" per core (1 worker): {per_core:.1f} designs/s")
        result.update({"overhead_ratio_2_workers": ratio, "overhead_range": [lo, hi],
                       "speedup_2_over_1": speedup, "verdict": verdict,
                       "per_core_designs_per_s": per_core,
                       "per_core_grid_designs_per_s": before, "located_over_grid": gain,
                       "parts_ms_per_design": parts,
                       "full_sweep_estimate_s": estimate})
        if "--full" in sys.argv:
            out = tmp / "full"
            t0 = time.perf_counter()
            subprocess.run([str(Path(sys.executable).parent / "sewmech"), "sweep",
                            str(SHIPPED), "--out", str(out)], check=True)
            result["full_sweep_s"] = time.perf_counter() - t0
            print(f"the shipped 100,000-design sweep, run whole: {result['full_sweep_s']:.0f} s")
        write_results(RESULTS, result, current_figures(result))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

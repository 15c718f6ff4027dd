"""The install's compile (issue 34 item 3): CPU seconds (user + sys of the child) of
``python -m sewmech.engine.warm``, which ``make demo`` and ``make test`` run, from an empty
numba cache (a fresh NUMBA_CACHE_DIR each run, so that nobody's cache is read or touched).

    python benchmarks/bench_compile.py [--runs 3] [--all]

CPU time rather than wall time: the machine is shared and its wall time varies with the load,
while a compile's CPU seconds do not much (the system part, LLVM's page faults, varies by a
few seconds). The former code's figures (every kernel, some twice) were measured on commit
bbd3833 and are kept in the results file as they were recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _timing import figure, write_results  # noqa: E402

RESULTS = HERE / "results" / "compile.json"
TARGET_S = 30.0


def one_run(all_kernels: bool) -> dict:
    """One compile from an empty cache: CPU seconds of the child, its wall time, the load."""
    with tempfile.TemporaryDirectory(prefix="sewmech-numba-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cmd = [sys.executable, "-m", "sewmech.engine.warm"] + (["--all"] if all_kernels else [])
        load = os.getloadavg()[0]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    user, sys_ = after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime
    return {"cpu_s": round(user + sys_, 1), "user_s": round(user, 2), "sys_s": round(sys_, 2),
            "wall_s": round(wall, 1), "load": f"{load:.1f} -> {os.getloadavg()[0]:.1f}"}


def current_figures(out: dict) -> list[dict]:
    """The row of the table of current figures (BENCHMARKS.md) from this script's results."""
    before = statistics.median(r["cpu_s"] for r in out["before"]["runs"])
    after = statistics.median(r["cpu_s"] for r in out["after_install"]["runs"])
    return [figure("the install's compile from an empty numba cache, CPU (user + sys),"
                   f" median of {len(out['after_install']['runs'])}", after, "s",
                   target=TARGET_S, anchor="the former install (every kernel, some twice)",
                   anchor_value=before, ratio=before / after, ratio_kind="faster")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="compiles from an empty cache")
    ap.add_argument("--all", action="store_true", help="also time `warm --all` (every kernel)")
    args = ap.parse_args()
    out = json.loads(RESULTS.read_text(encoding="utf-8"))
    for key in ("figures", "date", "commit", "load_1min", "stamped_from"):
        out.pop(key, None)
    runs = []
    for k in range(args.runs):
        r = one_run(False)
        runs.append(r)
        print(f"install's compile, run {k + 1}: {r['cpu_s']:.1f} s CPU (user {r['user_s']:.1f},"
              f" sys {r['sys_s']:.1f}), {r['wall_s']:.0f} s wall, load {r['load']}")
    out["after_install"] = {**out.get("after_install", {}), "runs": runs,
                            "command": "python -m sewmech.engine.warm"}
    if args.all:
        r = one_run(True)
        print(f"every kernel (warm --all): {r['cpu_s']:.1f} s CPU")
        out["after_all"] = {**out.get("after_all", {}), "runs": [r]}
    rows = current_figures(out)
    r = rows[0]
    print(f"median {r['figure']:.1f} s CPU against {r['anchor_figure']:.1f} s before"
          f" ({r['ratio']:.2f}x faster); target <= {TARGET_S:g} s: "
          + ("met" if r["met"] else "MISSED"))
    write_results(RESULTS, out, rows, indent=2)


if __name__ == "__main__":
    main()

"""Run every ``benchmarks/bench_*.py`` in turn (same interpreter, one subprocess each).

Exits non-zero if any script fails (non-zero exit status). A missed performance target is not a
failure: the scripts print MISSED for it and exit 0. Each script writes its results file in
``benchmarks/results/``; ``make bench`` then prints the table of current figures from them and
rewrites it in BENCHMARKS.md (``benchmarks/table.py --write``).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    scripts = sorted(HERE.glob("bench_*.py"))
    if not scripts:
        print("no benchmarks/bench_*.py scripts found")
        return 1
    failed = []
    for script in scripts:
        print(f"=== {script.name} " + "=" * max(0, 70 - len(script.name)), flush=True)
        t0 = time.perf_counter()
        rc = subprocess.run([sys.executable, str(script)], cwd=HERE.parent).returncode
        dt = time.perf_counter() - t0
        print(f"=== {script.name}: {'ok' if rc == 0 else f'FAILED (exit {rc})'} in {dt:.1f} s\n",
              flush=True)
        if rc != 0:
            failed.append(script.name)
    if failed:
        print(f"{len(failed)} of {len(scripts)} benchmark(s) failed: {', '.join(failed)}")
        return 1
    print(f"all {len(scripts)} benchmark(s) ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())

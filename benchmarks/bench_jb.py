"""Benchmark: kinematics of the whole JB1-3 machine, and batches of feed-mechanism designs.

Targets (issue 3):

1. whole-machine kinematics (every mechanism: every point's position, velocity and
   acceleration, every link's angle and rates, every joint variable) at 72 positions (5 deg),
   one design: at most 5 ms;
2. the feed mechanism at 360 positions (1 deg) for 1,000 designs: at most 2 s. The designs
   scale the feed cam stroke, the block's place on the fork, the fork arm and the lift
   eccentricity by independent uniform factors in [0.97, 1.03] (``default_rng(2026)``) at the
   longest forward stitch; outputs: the dog tooth tip (p, v, a): every unit it depends on is
   solved (the needle bar and take-up are not). Also the full feed figures (stitch, lift,
   timing per design) from ``feed_cycles``;
3. the needle-thread balance (``thread_balance``: supply, demand, overfeed, events) of JB1-3
   at 360 positions: at most 5 ms (issue 4).

The 1982 program needed over ten minutes for the 72 positions of its force analysis (the JB
dynamics report); kinematics is the first half of that job.

Best of several repeats after a warm-up. Prints a table and writes
``benchmarks/results/jb.json``. Exits 0 when a target is missed (reported as MISSED).
"""

from __future__ import annotations

import math
import os
import platform
from pathlib import Path

import numpy as np
from _timing import best, figure, write_results  # noqa: E402 (benchmarks/ is the script's directory)
from sewmech.feed import feed_cycles
from sewmech.thread import thread_balance

import sewmech
from sewmech.engine._threads import n_threads

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "jb.json"
N_DESIGN = 1000
SEED = 2026
TARGET_MACHINE_72_MS = 5.0
TARGET_FEED_BATCH_S = 2.0
TARGET_THREAD_MS = 5.0


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    return [figure(f"JB1-3 {name}", row["best"], row["unit"], target=row["target"])
            for name, row in out.items()
            if isinstance(row, dict) and row.get("target") is not None]


def main():
    m = sewmech.load_machine("jb1-3")
    phi72 = np.radians(np.arange(0.0, 360.0, 5.0))
    whole = best(lambda: sewmech.kinematics(m, phi72), repeat=30)

    rng = np.random.default_rng(SEED)
    names = {"feed_cam.stroke": 7.0, "feed_fork.slot.2.length": 125.0}
    f = rng.uniform(0.97, 1.03, size=(N_DESIGN, 4))
    over = {n: v * f[:, i] for i, (n, v) in enumerate(names.items())}
    for n in ("feed_fork.cam.2.length", "feed_fork.slot.1.length", "feed_fork.pin.u"):
        over[n] = 16.0 * f[:, 2]  # one physical arm length in three terms
    over["lift_cam.arc0.cx"] = 1.3 * f[:, 3]
    params = m.parameters(over, inputs={"regulator": np.full(N_DESIGN, math.radians(30.0))})
    phi360 = np.radians(np.arange(360.0))
    feed = best(lambda: sewmech.kinematics(m, phi360, params=params, points=["feed_dog.tip"],
                                           links=[], variables=[], on_failure="mask"), repeat=3)
    r = sewmech.kinematics(m, phi360, params=params, points=["feed_dog.tip"], links=[],
                           variables=[], on_failure="mask")
    cycles = best(lambda: feed_cycles(m, 30.0, params=params, on_failure="mask"), repeat=3)
    c = feed_cycles(m, 30.0, params=params, on_failure="mask")

    thread = best(lambda: thread_balance(m, step_deg=1.0), repeat=30)
    rows = [
        ("whole machine, 72 positions", whole[0] * 1e3, whole[1] * 1e3, "ms",
         TARGET_MACHINE_72_MS),
        ("thread balance, 360 positions", thread[0] * 1e3, thread[1] * 1e3, "ms",
         TARGET_THREAD_MS),
        (f"feed, {N_DESIGN} designs x 360 positions", feed[0], feed[1], "s", TARGET_FEED_BATCH_S),
        (f"feed figures (stitch, lift, timing), {N_DESIGN} designs", cycles[0], cycles[1], "s",
         None),
    ]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus,"
          f" kernel threads {n_threads()}")
    print(f"{'job':48s} {'best':>10s} {'median':>10s}  target")
    out = {}
    for name, b, med, unit, target in rows:
        verdict = "" if target is None else (
            f"<= {target:g} {unit}: {'met' if b <= target else 'MISSED'}")
        print(f"{name:48s} {b:10.4g} {med:10.4g} {unit}  {verdict}")
        out[name] = {"best": b, "median": med, "unit": unit, "target": target}
    ok = int(r.feasible.all(axis=-1).sum())
    print(f"feasible designs: {ok} of {N_DESIGN}; stitch over the batch"
          f" {np.nanmin(c.stitch_mm):.3f}..{np.nanmax(c.stitch_mm):.3f} mm, lift"
          f" {np.nanmin(c.lift_mm):.3f}..{np.nanmax(c.lift_mm):.3f} mm")
    out["feasible designs"] = ok
    write_results(RESULTS, out, current_figures(out), indent=2)


if __name__ == "__main__":
    main()

"""Benchmark: exact derivatives of the inverse dynamics by the design (issue 32, part 2).

Target: the derivatives of every pair force, the driving torque, the shaking force and moment
and the bearing reactions of JB1-3 (friction, springs, loads and its counterweight as
shipped) by all of its parameters, at 72 positions (5 deg), in at most 4x the cost of one
inverse dynamics of the same job (``inverse_dynamics``). Printed beside it: the cost of central
finite differences of the same derivatives (two inverse dynamics per parameter), and the
largest difference between the two on a few parameters.

Interleaved rounds after a warm-up (``_timing.interleave``). Prints a table and writes
``benchmarks/results/dynamic-gradient.json``. Exits 0 when the target is missed (reported as
MISSED).
"""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import numpy as np
from _timing import interleave, table

import sewmech
from sewmech.engine.dynamic_sensitivity import dynamics_sensitivities
from sewmech.engine.dynamics import inverse_dynamics

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "dynamic-gradient.json"
TARGET_RATIO = 4.0


def main():
    m = sewmech.load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    n_p = len(m.parameter_names)
    t = interleave({"inverse dynamics": lambda: inverse_dynamics(m, phi),
                    "exact gradient": lambda: dynamics_sensitivities(m, phi)}, rounds=7)
    ratio = t.ratio("exact gradient", "inverse dynamics")
    lo, hi = t.ratio_range("exact gradient", "inverse dynamics")
    fd_cost = 2 * n_p * t.median("inverse dynamics")
    ds = dynamics_sensitivities(m, phi)
    worst = 0.0
    for name in ("needle_bar.length", "take_up.length1", "Lp.x", "feed_cam.arc0.radius"):
        j = m.parameter_names.index(name)
        h = 1e-5 * max(1.0, abs(m.defaults[j]))
        Pp, Pm = m.defaults.copy(), m.defaults.copy()
        Pp[j] += h
        Pm[j] -= h
        rp, rm = inverse_dynamics(m, phi, params=Pp), inverse_dynamics(m, phi, params=Pm)
        same = np.all((rp.load_on == ds.result.load_on) & (rm.load_on == ds.result.load_on),
                      axis=-1)
        fd = (rp.unknowns - rm.unknowns)[same] / (2 * h)
        worst = max(worst, float(np.abs(fd - ds.dX[same, :, j]).max() / np.abs(fd).max()))
    ok = ratio <= TARGET_RATIO
    rows = [("inverse dynamics, one design, 72 positions",
             f"{t.best('inverse dynamics') * 1e3:.2f} ms",
             f"{t.median('inverse dynamics') * 1e3:.2f} ms", ""),
            (f"exact derivatives by all {n_p} parameters",
             f"{t.best('exact gradient') * 1e3:.1f} ms",
             f"{t.median('exact gradient') * 1e3:.1f} ms",
             f"{ratio:.1f}x ({lo:.1f}..{hi:.1f}) target <= {TARGET_RATIO:g}x:"
             f" {'met' if ok else 'MISSED'}"),
            (f"central differences, 2 x {n_p} inverse dynamics (estimate)", "",
             f"{fd_cost * 1e3:.0f} ms",
             f"{fd_cost / t.median('exact gradient'):.1f}x the exact gradient's time")]
    print(table(rows, ("job", "best", "median", "ratio")))
    print(f"exact against central differences (h = 1e-5, 4 parameters): largest relative"
          f" difference {worst:.2g} (the differences' own truncation and round-off)")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps({
        "machine": platform.machine(), "cpus": os.cpu_count(), "parameters": n_p,
        "inverse_dynamics_s": t.best("inverse dynamics"),
        "exact_gradient_s": t.best("exact gradient"), "ratio": ratio,
        "target_ratio": TARGET_RATIO, "met": ok, "finite_differences_s": fd_cost,
        "agreement": worst}, indent=1))


if __name__ == "__main__":
    main()

"""Benchmark: the housing's vibration (issue 31).

Target: the vibration of 1,000 designs of JB1-3 in one call (``housing_vibration``: their
inverse dynamics over a turn, the wrench on the housing, one complex 6 x 6 solve per harmonic
for every design, the control point's velocities and levels) at most 2x their inverse dynamics
alone (``inverse_dynamics`` on the same grid). The designs differ in the needle-bar link's
length; the grid is the JB dynamics report's 5 deg (harmonics up to 36). The part the housing
adds (excitation and response from a dynamics result) is timed alone too, and the one-design
call for scale. Also checks the batch against one design at a time.

Interleaved rounds after a warm-up (``_timing.interleave``). Prints a table and writes
``benchmarks/results/vibration.json``. Exits 0 when the target is missed (reported as MISSED).
"""

from __future__ import annotations

import json
import math
import os
import platform
from pathlib import Path

import numpy as np
from _timing import interleave, table

import sewmech
from sewmech.dynamics import inverse_dynamics
from sewmech.engine.housing import Housing, excitation, housing_vibration, vibration

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "vibration.json"
TARGET_RATIO = 2.0
N_DESIGNS = 1000
STEP_DEG = 5.0


def main():
    m = sewmech.load_machine("jb1-3")
    lengths = np.linspace(42.0, 46.0, N_DESIGNS)
    P = m.parameters({"needle_bar.length": lengths})
    phi = np.arange(0.0, 360.0, STEP_DEG) * math.pi / 180.0
    h = Housing.of(m)
    r = inverse_dynamics(m, phi, params=P)
    rpm = float(r.kin.omega_shaft.reshape(-1)[0] * 30.0 / math.pi)
    t = interleave({
        "inverse dynamics": lambda: inverse_dynamics(m, phi, params=P),
        "vibration": lambda: housing_vibration(m, STEP_DEG, params=P),
        "housing part": lambda: vibration(h, excitation(m, h, r), rpm),
    }, rounds=3)
    one = interleave({"one design": lambda: housing_vibration(m, STEP_DEG)}, rounds=5,
                     number=5)
    ratio = t.ratio("vibration", "inverse dynamics")
    lo, hi = t.ratio_range("vibration", "inverse dynamics")
    # the batch's answer is each design's own
    v = housing_vibration(m, STEP_DEG, params=P)
    diffs = []
    for k in (0, N_DESIGNS // 2, N_DESIGNS - 1):
        vk = housing_vibration(m, STEP_DEG, params=m.parameters(
            {"needle_bar.length": lengths[k]}))
        diffs.append(float(np.abs(v.rms_velocity[k] - vk.rms_velocity).max()
                           / np.abs(vk.rms_velocity).max()))
    ok = ratio <= TARGET_RATIO
    rows = [
        (f"inverse dynamics, {N_DESIGNS} designs x {len(phi)} positions",
         f"{t.best('inverse dynamics'):.3f} s", f"{t.median('inverse dynamics'):.3f} s", ""),
        (f"vibration, {N_DESIGNS} designs (incl. their inverse dynamics)",
         f"{t.best('vibration'):.3f} s", f"{t.median('vibration'):.3f} s",
         f"{ratio:.2f}x ({lo:.2f}..{hi:.2f}) target <= {TARGET_RATIO:g}x:"
         f" {'met' if ok else 'MISSED'}"),
        ("  the housing's part alone (excitation, 36 harmonics' solves)",
         f"{t.best('housing part'):.3f} s", f"{t.median('housing part'):.3f} s", ""),
        ("vibration, one design", f"{one.best('one design') * 1e3:.1f} ms",
         f"{one.median('one design') * 1e3:.1f} ms", ""),
    ]
    print(table(rows, ("job", "best", "median", "ratio")))
    print(f"batch against one design at a time: largest relative difference {max(diffs):.2g}")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps({
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "inverse_dynamics_s": t.best("inverse dynamics"),
        "vibration_s": t.best("vibration"), "housing_part_s": t.best("housing part"),
        "one_design_s": one.best("one design"), "ratio": ratio, "target_ratio": TARGET_RATIO,
        "met": ok, "batch_vs_single": max(diffs)}, indent=1))


if __name__ == "__main__":
    main()

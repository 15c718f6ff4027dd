"""Benchmark: balancing (issue 16).

Target: each criterion on JB1-3 with two counterweights at most 50 ms warm.

JB1-3 with two counterweights on its upper shaft (front and rear of the arm, as the report's
whole-machine balancing would place them), at the file's speed over one turn. Timed, best and
median of several repeats after a warm-up:

- the balancing basis (one batch of 1 + 4 x 2 designs through the dynamics), built once per
  machine, speed and grid;
- each criterion's solve from that basis, including the re-evaluation of the file's and the
  chosen counterweights on the whole machine (one batch of two designs): this is what the
  target counts, since the basis is shared by every criterion, the report, the front and a
  designer's repeated questions;
- the whole ``balance()`` call (basis included), once per criterion.

Both grids: 1 deg (360 positions, the default) and 5 deg (72 positions, the JB dynamics
report's grid). The peer: the same peak-force problem solved by brute force, scipy's
Nelder-Mead on the whole machine's dynamics (one dynamics evaluation per trial design), with
the value each reaches. Prints a table and writes ``benchmarks/results/balance.json``; a missed
target prints MISSED and exits 0.
"""

from __future__ import annotations

import platform
from importlib import resources
from pathlib import Path

import numpy as np
from _timing import best, figure, write_results

import sewmech
from sewmech.design.balancing import CRITERIA, balance, balance_basis, figures

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "balance.json"
TARGET_MS = 50.0


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    rows = [figure("JB1-3 balancing, each criterion from the basis, 1 deg grid (the slowest)",
                   out["slowest_solve_ms"], "ms", target=out["target_ms"])]
    peer = out["grids"]["1"].get("peer_peak")
    if peer is not None:
        rows.append(figure("JB1-3 balancing, peak force, 1 deg grid", peer["sewmech_ms"], "ms",
                           anchor="Nelder-Mead on the whole machine's dynamics",
                           anchor_value=peer["nelder_mead_s"] * 1e3,
                           ratio=peer["nelder_mead_s"] * 1e3 / peer["sewmech_ms"]))
    return rows

EXTRA = """
[counterweights.front_cw]
link = "needle_crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = 18.0
z_mm = 40.0
[counterweights.rear_cw]
link = "needle_crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = 18.0
z_mm = 292.0
"""


def machine() -> sewmech.Machine:
    text = resources.files("sewmech.data.machines").joinpath("jb1-3.toml").read_text("utf-8")
    return sewmech.machine_from_toml(text + EXTRA)


def nelder_mead_peak(B) -> tuple[float, int]:
    """Brute force: Nelder-Mead on the whole machine's peak shaking force; (value, n evals)."""
    from scipy.optimize import minimize

    r = minimize(lambda z: float(figures(B.evaluate(z.reshape(2, 2)))["peak_force_N"]),
                 np.zeros(4) + 0.1, method="Nelder-Mead",
                 options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 4000})
    return float(r.fun), int(r.nfev)


def main():
    m = machine()
    names = ["front_cw", "rear_cw"]
    rows, out = [], {"machine": "jb1-3 + front_cw, rear_cw", "host": platform.node(),
                     "target_ms": TARGET_MS, "grids": {}}
    worst = 0.0
    for step in (1.0, 5.0):
        B = balance_basis(m, names, step_deg=step)
        t_basis, t_basis_med = best(lambda: balance_basis(m, names, step_deg=step), repeat=5)
        grid = {"basis_ms": t_basis * 1e3, "basis_median_ms": t_basis_med * 1e3,
                "criteria": {}}
        for crit in CRITERIA:
            cws = ["front_cw"] if crit == "delta-q" else names
            Bc = balance_basis(m, cws, step_deg=step) if crit == "delta-q" else B
            res = balance(m, crit, cws, basis=Bc)
            t, t_med = best(lambda: balance(m, crit, cws, basis=Bc), repeat=5)
            t_full, _ = best(lambda: balance(m, crit, cws, step_deg=step), repeat=3)
            grid["criteria"][crit] = {"solve_ms": t * 1e3, "solve_median_ms": t_med * 1e3,
                                      "whole_call_ms": t_full * 1e3, "status": res.status,
                                      "basis_error": res.basis_error}
            rows.append((step, crit, t * 1e3, t_med * 1e3, t_full * 1e3, res.status))
            if step == 1.0:
                worst = max(worst, t * 1e3)
        nm_value, nm_evals = nelder_mead_peak(B)
        t_nm, _ = best(lambda: nelder_mead_peak(B), repeat=1)
        ours = balance(m, "peak", names, basis=B).after["peak_force_N"]
        grid["peer_peak"] = {"nelder_mead_s": t_nm, "evaluations": nm_evals,
                             "nelder_mead_N": nm_value, "sewmech_N": float(ours),
                             "sewmech_ms": grid["criteria"]["peak"]["solve_ms"]}
        out["grids"][f"{step:g}"] = grid
        print(f"grid {step:g} deg ({int(360 / step)} positions): basis {t_basis * 1e3:.1f} ms"
              f" (median {t_basis_med * 1e3:.1f})")
        print(f"  peer, peak force: Nelder-Mead on the whole machine {t_nm:.2f} s"
              f" ({nm_evals} dynamics evaluations) reaches {nm_value:.6f} N; sewmech"
              f" {grid['criteria']['peak']['solve_ms']:.1f} ms reaches {ours:.6f} N"
              f" ({t_nm / (grid['criteria']['peak']['solve_ms'] * 1e-3):.0f} x faster)")
    print(f"\n{'grid':>5} {'criterion':>10} {'solve ms':>9} {'median':>8} {'whole call ms':>14}"
          f"  status")
    for step, crit, t, tm, tf, st in rows:
        print(f"{step:5g} {crit:>10} {t:9.1f} {tm:8.1f} {tf:14.1f}  {st}")
    verdict = "met" if worst <= TARGET_MS else "MISSED"
    print(f"\ntarget: each criterion from the basis at most {TARGET_MS:g} ms warm (1 deg grid):"
          f" slowest {worst:.1f} ms, {verdict}")
    out["slowest_solve_ms"] = worst
    out["verdict"] = verdict
    write_results(RESULTS, out, current_figures(out))


if __name__ == "__main__":
    main()

"""Benchmark: sewmech's general kinematics engine vs pylinkage 1.3.0 (numba) on a four-bar.

The job (the shipped machine file ``fourbar-benchmark``): a crank-rocker with A = (0, 0),
D = (38, 0), AB = 15, BC = 40, CD = 35 mm and a coupler point P at (30, 10) mm in the coupler
frame (x along B->C, y to its left); 360 crank angles 0..359 deg; a batch of 1,000 designs whose
lengths AB, BC, CD and AD are each scaled by an independent uniform factor in [0.97, 1.03]
(``np.random.default_rng(12345)``). P's local coordinates are NOT scaled.

Measured in one run (best of several repeats after a warm-up):

1. batch, 1000 designs x 360 angles: sewmech (positions, velocities and accelerations of C and
   P, the job's outputs; every point and link as information) vs pylinkage's fastest batch path
   (positions only);
2. one revolution of one design: sewmech's prepared path (``KinematicsPlan``, what a loop over
   designs uses) against pylinkage's fastest (its bare numba ``solver.simulate`` on prepared
   arrays); the one-off ``kinematics()`` call is printed too;
3. the first call in a fresh process (import + first ``kinematics``), run twice: the second run
   is reported against the target because numba compiles once and caches on disk;
4. accuracy of C and P against a closed form written here in plain numpy.

Prints a table and writes ``benchmarks/results/fourbar.json``. Exits 0 when the targets are
missed (they are reported as MISSED); exits non-zero only if something actually breaks.
Run: ``.venv/bin/python benchmarks/bench_fourbar.py`` (``make bench`` installs pylinkage).
"""

from __future__ import annotations

import importlib.metadata
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _timing import best as _best  # noqa: E402 (benchmarks/ is the script's directory)
from _timing import figure, interleave, write_results

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "fourbar.json"

# ---- the job -----------------------------------------------------------------------------------
AB0, BC0, CD0, AD0 = 15.0, 40.0, 35.0, 38.0
P_LOCAL = (30.0, 10.0)  # coupler frame: x along B->C, y to its left; not scaled
N_DESIGN = 1000
SEED = 12345
PHI = np.radians(np.arange(360.0))
STEP = math.tau / 360.0  # 1 deg

# ---- targets -------------------------------------------------------------------------------------
TARGET_BATCH_RATIO = 3.0   # pylinkage batch time / sewmech batch time
TARGET_SINGLE_RATIO = 2.0  # pylinkage one revolution / sewmech one revolution
TARGET_FIRST_CALL_S = 1.0  # import sewmech .. first kinematics(m, phi), fresh process
TARGET_ONE_OFF_S = 50e-6  # one-off kinematics() of one design, one revolution (issue 15)
REPEAT = 7


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    sew, pl, ratios = out["sewmech"], out["pylinkage"], out["ratios"]
    first = out["first_call"]
    job = f"four-bar, {out['job']['n_designs']} designs x {out['job']['n_phi']} positions"
    rows = []
    if pl is not None:
        rows += [
            figure(f"{job}, p+v+a of C and P", sew["batch_s"] * 1e3, "ms",
                   anchor=f"pylinkage {pl['version']} (numba) {ratios['batch_pylinkage_api']},"
                   " positions only",
                   anchor_value=min(pl["batch_ensemble_s"], pl["batch_raw_simulate_loop_s"]) * 1e3,
                   ratio=ratios["batch"], target=TARGET_BATCH_RATIO, op=">=", on="ratio"),
            figure("four-bar, one revolution (360 positions), KinematicsPlan, p+v+a of C and P",
                   sew["single_plan_s"] * 1e6, "us",
                   anchor=f"pylinkage {pl['version']} (numba) {ratios['single_pylinkage_api']},"
                   " positions only",
                   anchor_value=min(pl["single_step_fast_s"], pl["single_raw_simulate_s"]) * 1e6,
                   ratio=ratios["single"], target=TARGET_SINGLE_RATIO, op=">=", on="ratio"),
        ]
    rows.append(figure("four-bar, one revolution, one-off kinematics() call",
                       sew["single_s"] * 1e6, "us", target=TARGET_ONE_OFF_S * 1e6))
    ours = first["sewmech_runs"][1]["first_call_s"]
    theirs = first["pylinkage_runs"][1]["first_call_s"] if first["pylinkage_runs"] else None
    rows.append(figure("import sewmech and the first kinematics in a fresh process (numba cache"
                       " warm)", ours, "s",
                       anchor=None if theirs is None else "pylinkage import and first step_fast",
                       anchor_value=theirs, ratio=None if theirs is None else ours / theirs,
                       ratio_kind="time", target=TARGET_FIRST_CALL_S, op="<"))
    return rows


def best(fn, number: int, repeat: int = REPEAT) -> float:
    """Best time per call, seconds (the shared harness's)."""
    return _best(fn, repeat=repeat, number=number)[0]


def design_lengths():
    rng = np.random.default_rng(SEED)
    f = rng.uniform(0.97, 1.03, size=(N_DESIGN, 4))
    return AB0 * f[:, 0], BC0 * f[:, 1], CD0 * f[:, 2], AD0 * f[:, 3]


# ---- closed form (plain numpy) -----------------------------------------------------------------------
def closed_form(ab, bc, cd, ad, phi):
    """B, C (upper assembly: C to the left of the directed line B->D) and P, broadcast.

    Returns arrays of shape broadcast(ab..., phi) + (2,); NaN where the dyad cannot close.
    """
    ab, bc, cd, ad, phi = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                                for x in (ab, bc, cd, ad, phi)))
    bx, by = ab * np.cos(phi), ab * np.sin(phi)
    dx, dy = ad - bx, -by
    L = np.hypot(dx, dy)
    ux, uy = dx / L, dy / L
    along = (bc**2 - cd**2 + L**2) / (2.0 * L)
    with np.errstate(invalid="ignore"):
        h = np.sqrt(bc**2 - along**2)
    cx = bx + along * ux - h * uy   # left normal of (ux, uy) is (-uy, ux)
    cy = by + along * uy + h * ux
    ex, ey = (cx - bx) / bc, (cy - by) / bc  # unit x of the coupler frame (|C-B| = BC)
    px = bx + P_LOCAL[0] * ex - P_LOCAL[1] * ey
    py = by + P_LOCAL[0] * ey + P_LOCAL[1] * ex
    st = lambda x, y: np.stack([x, y], axis=-1)  # noqa: E731
    return st(bx, by), st(cx, cy), st(px, py)


# ---- sewmech -------------------------------------------------------------------------------------------
def run_sewmech(ab, bc, cd, ad):
    import sewmech

    m = sewmech.load_machine("fourbar-benchmark")
    params = m.parameters({"B.u": ab, "dyad.length1": bc, "dyad.length2": cd, "D.x": ad})

    job = {"points": ["C", "P"], "links": []}  # the job's outputs: p, v, a of C and P

    def batch():
        return sewmech.kinematics(m, PHI, params=params, on_failure="mask", **job)

    def batch_all():
        return sewmech.kinematics(m, PHI, params=params, on_failure="mask")

    def single():
        return sewmech.kinematics(m, PHI, **job)

    def single_all():
        return sewmech.kinematics(m, PHI)

    # the prepared path for repeated evaluation (optimisation loops): argument checks, march,
    # trigonometry of the angles and output arrays are done once, each call is one kernel call
    plan = sewmech.KinematicsPlan(m, PHI, **job)
    plan_batch = sewmech.KinematicsPlan(m, PHI, on_failure="mask", **job)

    def single_plan():
        return plan()

    def batch_plan():
        return plan_batch(params)

    t_batch = best(batch, number=1)
    t_batch_plan = best(batch_plan, number=1)
    t_batch_all = best(batch_all, number=1)
    t_single = best(single, number=200)
    t_single_plan = best(single_plan, number=2000)
    t_single_all = best(single_all, number=200)
    assert np.array_equal(single_plan().p, single().p)

    r = batch()
    r1 = single()
    feas = r.feasible
    _, C_ref, P_ref = closed_form(ab[:, None], bc[:, None], cd[:, None], ad[:, None], PHI[None, :])
    _, C1_ref, P1_ref = closed_form(AB0, BC0, CD0, AD0, PHI)
    err = lambda x, ref, mask=None: float(np.max(np.abs(x - ref)[mask] if mask is not None  # noqa: E731
                                                  else np.abs(x - ref)))
    out = {
        "version": getattr(sewmech, "__version__", None),
        "batch_s": t_batch,
        "batch_plan_s": t_batch_plan,
        "batch_all_outputs_s": t_batch_all,
        "single_s": t_single,
        "single_plan_s": t_single_plan,
        "single_all_outputs_s": t_single_all,
        "batch_shape_C_p": list(r.point("C").p.shape),
        "batch_outputs": "p, v, a of C and P (the job); *_all_outputs_s: every point and link",
        "n_infeasible": int((~feas).sum()),
        "n_positions": int(feas.size),
        "max_err_C_batch_mm": err(r.point("C").p, C_ref, feas),
        "max_err_P_batch_mm": err(r.point("P").p, P_ref, feas),
        "max_err_C_single_mm": err(r1.point("C").p, C1_ref),
        "max_err_P_single_mm": err(r1.point("P").p, P1_ref),
        "_C_v": r.point("C").v,  # for an informational cross-check with pylinkage (not in JSON)
        "_rpm": m.rpm,
        "_fns": {"batch": batch, "single_plan": single_plan},
    }
    return out


# ---- pylinkage ----------------------------------------------------------------------------------------
def pylinkage_available():
    try:
        import pylinkage  # noqa: F401
    except ImportError:
        return False
    return True


def build_pylinkage(ab, bc, cd, ad):
    """One design as a pylinkage Linkage: Ground A, D; Crank B; RRRDyad C; FixedDyad P.

    simulate() advances the crank *before* recording a step, so the crank starts at -1 deg and
    row k of the trajectory is at k deg. C's initial position is the upper assembly at -1 deg:
    the RRR solver keeps the intersection nearest to the previous position (hysteresis), so this
    seeds the branch.
    """
    from pylinkage.actuators import Crank
    from pylinkage.components import Ground
    from pylinkage.dyads import FixedDyad, RRRDyad
    from pylinkage.simulation import Linkage

    _, c0, _ = closed_form(ab, bc, cd, ad, -STEP)
    A = Ground(0.0, 0.0, name="A")
    D = Ground(float(ad), 0.0, name="D")
    B = Crank(anchor=A, radius=float(ab), angular_velocity=STEP, initial_angle=-STEP, name="B")
    C = RRRDyad(B.output, D, distance1=float(bc), distance2=float(cd),
                x=float(c0[0]), y=float(c0[1]), name="C")
    P = FixedDyad(B.output, C, distance=math.hypot(*P_LOCAL),
                  angle=math.atan2(P_LOCAL[1], P_LOCAL[0]), name="P")
    return Linkage([A, D, B, C, P], name="fourbar-benchmark")


JOINTS = ("A", "D", "B", "C", "P")


def run_pylinkage(ab, bc, cd, ad, rpm, sew_C_v):
    import pylinkage
    from pylinkage.population import Ensemble
    from pylinkage.solver import simulate, simulate_with_kinematics

    # -- one revolution of one design
    lk = build_pylinkage(AB0, BC0, CD0, AD0)
    lk.compile()
    sd = lk._solver_data  # the SolverData that step_fast itself builds (Linkage.compile())
    pos0 = sd.positions.copy()
    struct = (sd.joint_types, sd.parent_indices, sd.constraint_offsets, sd.solve_order)

    def single_step_fast():
        return lk.step_fast(iterations=360)  # 360 steps = one turn: state returns to start

    def single_raw():
        return simulate(pos0.copy(), sd.constraints, *struct, 360, 1.0)

    t_step_fast = best(single_step_fast, number=100)
    t_raw_single = best(single_raw, number=100)
    traj1 = single_raw()

    # -- batch: Ensemble of the 1000 designs (one topology; dims and start positions vary)
    dims = np.column_stack([ab, bc, cd, np.full(N_DESIGN, math.hypot(*P_LOCAL)),
                            np.full(N_DESIGN, math.atan2(P_LOCAL[1], P_LOCAL[0]))])
    assert len(lk.get_constraints()) == dims.shape[1], lk.get_constraints()
    B0, C0, P0 = closed_form(ab, bc, cd, ad, -STEP)
    pos = np.zeros((N_DESIGN, len(JOINTS), 2))
    pos[:, 1, 0] = ad
    pos[:, 2] = B0
    pos[:, 3] = C0
    pos[:, 4] = P0
    ens = Ensemble(lk, dims, pos)

    def batch_ensemble():
        return ens.simulate(iterations=360, store=False)

    cons_base = sd.constraints.copy()  # [AB, angle rate, BC, CD, |P|, angle(P)]
    rows = np.column_stack([ab, np.full(N_DESIGN, STEP), bc, cd,
                            np.full(N_DESIGN, cons_base[4]), np.full(N_DESIGN, cons_base[5])])

    def batch_raw():
        out = np.empty((N_DESIGN, 360, len(JOINTS), 2))
        for i in range(N_DESIGN):
            out[i] = simulate(pos[i].copy(), rows[i], *struct, 360, 1.0)
        return out

    omega = np.array([rpm * math.tau / 60.0])
    alpha = np.zeros(1)
    crank_idx = np.array([2], dtype=np.int32)

    def batch_kin():  # like-for-like (positions + velocities + accelerations), information only
        out = np.empty((3, N_DESIGN, 360, len(JOINTS), 2))
        for i in range(N_DESIGN):
            p, v, a = simulate_with_kinematics(
                pos[i].copy(), np.zeros((len(JOINTS), 2)), np.zeros((len(JOINTS), 2)),
                rows[i], *struct, omega, alpha, crank_idx, 360, 1.0)
            out[0, i], out[1, i], out[2, i] = p, v, a
        return out

    t_ens = best(batch_ensemble, number=1)
    t_raw = best(batch_raw, number=1)
    t_kin = best(batch_kin, number=1)
    tr = batch_ensemble()
    assert np.array_equal(tr, batch_raw(), equal_nan=True)
    kin = batch_kin()

    # -- accuracy of C (and P) against the closed form
    _, C_ref, P_ref = closed_form(ab[:, None], bc[:, None], cd[:, None], ad[:, None], PHI[None, :])
    _, C1_ref, _ = closed_form(AB0, BC0, CD0, AD0, PHI)
    Cb = tr[:, :, 3]
    nan = np.isnan(Cb).any(axis=-1)
    dC = np.abs(Cb - C_ref).max(axis=-1)
    other_branch = (dC > 1e-6) & ~nan  # a clear departure from the upper assembly
    ok = ~nan
    v_diff = np.abs(kin[1][:, :, 3] - sew_C_v)
    return {
        "version": getattr(pylinkage, "__version__", None) or importlib.metadata.version("pylinkage"),
        "single_step_fast_s": t_step_fast,
        "single_raw_simulate_s": t_raw_single,
        "batch_ensemble_s": t_ens,
        "batch_raw_simulate_loop_s": t_raw,
        "batch_with_kinematics_s": t_kin,
        "n_nan_positions": int(nan.sum()),
        "n_designs_other_branch": int(other_branch.any(axis=1).sum()),
        "max_err_C_batch_mm": float(dC[ok].max()),
        "max_err_P_batch_mm": float(np.abs(tr[:, :, 4] - P_ref).max(axis=-1)[ok].max()),
        "max_err_C_single_mm": float(np.abs(traj1[:, 3] - C1_ref).max()),
        "max_rel_diff_C_velocity_vs_sewmech": float(np.nanmax(v_diff)
                                                    / np.nanmax(np.abs(sew_C_v))),
        "_fns": {"batch_ensemble": batch_ensemble, "batch_raw": batch_raw,
                 "single_step_fast": single_step_fast, "single_raw": single_raw},
    }


# ---- first call in a fresh process -------------------------------------------------------------------
FIRST_CALL_CODE = r"""
import time
t0 = time.perf_counter()
import sewmech
t1 = time.perf_counter()
import numpy as np
m = sewmech.load_machine("fourbar-benchmark")
r = sewmech.kinematics(m, np.radians(np.arange(360.0)))
t2 = time.perf_counter()
assert r.point("P").p.shape == (360, 2)
import json
print(json.dumps({"import_s": t1 - t0, "first_call_s": t2 - t0}))
"""

FIRST_CALL_CODE_PYLINKAGE = r"""
import time, math
t0 = time.perf_counter()
from pylinkage.actuators import Crank
from pylinkage.components import Ground
from pylinkage.dyads import FixedDyad, RRRDyad
from pylinkage.simulation import Linkage
t1 = time.perf_counter()
A = Ground(0.0, 0.0); D = Ground(38.0, 0.0)
B = Crank(anchor=A, radius=15.0, angular_velocity=math.tau / 360)
C = RRRDyad(B.output, D, distance1=40.0, distance2=35.0)
P = FixedDyad(B.output, C, distance=math.hypot(30, 10), angle=math.atan2(10, 30))
tr = Linkage([A, D, B, C, P]).step_fast(iterations=360)
t2 = time.perf_counter()
import json
print(json.dumps({"import_s": t1 - t0, "first_call_s": t2 - t0}))
"""


def fresh_process(code: str) -> dict:
    t0 = time.perf_counter()
    cp = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                        cwd=HERE.parent)
    wall = time.perf_counter() - t0
    if cp.returncode != 0:
        raise RuntimeError(f"fresh-process run failed:\n{cp.stderr}")
    d = json.loads(cp.stdout.strip().splitlines()[-1])
    d["process_wall_s"] = wall
    return d


# ---- report ---------------------------------------------------------------------------------------------
def fmt_t(s: float | None) -> str:
    if s is None:
        return "-"
    if s >= 1.0:
        return f"{s:.3f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.2f} ms"
    return f"{s * 1e6:.1f} us"


def status(ok: bool | None) -> str:
    return "n/a" if ok is None else ("PASS" if ok else "MISSED")


def main() -> int:
    ab, bc, cd, ad = design_lengths()
    have_pl = pylinkage_available()

    sew = run_sewmech(ab, bc, cd, ad)
    sew_C_v = sew.pop("_C_v")
    rpm = sew.pop("_rpm")
    pl = run_pylinkage(ab, bc, cd, ad, rpm, sew_C_v) if have_pl else None

    first = [fresh_process(FIRST_CALL_CODE) for _ in range(2)]
    pl_first = [fresh_process(FIRST_CALL_CODE_PYLINKAGE) for _ in range(2)] if have_pl else None

    rows = []  # (section, figure, value, target, status)

    def add(section, name, value, target="", ok=None):
        rows.append((section, name, value, target, status(ok) if target else ""))

    ratios = {}
    sew_fns = sew.pop("_fns")
    if pl is not None:
        pl_fns = pl.pop("_fns")
        pl_batch = min(pl["batch_ensemble_s"], pl["batch_raw_simulate_loop_s"])
        pl_batch_api = ("Ensemble.simulate" if pl["batch_ensemble_s"] <= pl["batch_raw_simulate_loop_s"]
                        else "solver.simulate loop")
        pl_single = min(pl["single_step_fast_s"], pl["single_raw_simulate_s"])
        pl_single_api = ("Linkage.step_fast" if pl["single_step_fast_s"] <= pl["single_raw_simulate_s"]
                         else "solver.simulate")
        # the verdicts: sewmech and pylinkage's fastest path timed in alternation, the ratio
        # taken within each round (a slow phase of the shared machine hits both)
        fast_batch = pl_fns["batch_ensemble" if pl_batch_api == "Ensemble.simulate"
                            else "batch_raw"]
        fast_single = pl_fns["single_step_fast" if pl_single_api == "Linkage.step_fast"
                             else "single_raw"]
        tb = interleave({"sewmech": sew_fns["batch"], "pylinkage": fast_batch}, rounds=REPEAT)
        ts = interleave({"sewmech": sew_fns["single_plan"], "pylinkage": fast_single},
                        rounds=REPEAT, number=200)
        ratios = {
            "batch": tb.ratio("pylinkage", "sewmech"),
            "batch_range_over_rounds": tb.ratio_range("pylinkage", "sewmech"),
            "single_range_over_rounds": ts.ratio_range("pylinkage", "sewmech"),
            "batch_vs_Ensemble_simulate": pl["batch_ensemble_s"] / sew["batch_s"],
            "batch_like_for_like_pva": pl["batch_with_kinematics_s"] / sew["batch_s"],
            "single": ts.ratio("pylinkage", "sewmech"),
            "single_kinematics_call": pl_single / sew["single_s"],
            "single_vs_step_fast": pl["single_step_fast_s"] / sew["single_plan_s"],
            "batch_pylinkage_api": pl_batch_api,
            "single_pylinkage_api": pl_single_api,
        }

    S1 = "1 batch 1000x360"
    add(S1, "sewmech kinematics(params, mask) p+v+a of C, P", fmt_t(sew["batch_s"]))
    add(S1, "sewmech KinematicsPlan(params) same job (info)", fmt_t(sew["batch_plan_s"]))
    add(S1, "sewmech same, every point and link (info)", fmt_t(sew["batch_all_outputs_s"]))
    if pl is not None:
        add(S1, "pylinkage Ensemble.simulate (p only)", fmt_t(pl["batch_ensemble_s"]))
        add(S1, "pylinkage solver.simulate loop (p only)", fmt_t(pl["batch_raw_simulate_loop_s"]))
        add(S1, "pylinkage simulate_with_kinematics loop (p+v+a, info)",
            fmt_t(pl["batch_with_kinematics_s"]))
        lo, hi = ratios["batch_range_over_rounds"]
        add(S1, f"ratio pylinkage fastest ({ratios['batch_pylinkage_api']}) / sewmech,"
            f" interleaved (rounds {lo:.2f}-{hi:.2f}x)",
            f"{ratios['batch']:.2f}x", f">= {TARGET_BATCH_RATIO:g}",
            ratios["batch"] >= TARGET_BATCH_RATIO)
        add(S1, "ratio pylinkage p+v+a / sewmech p+v+a (info)",
            f"{ratios['batch_like_for_like_pva']:.2f}x")
    add(S1, "sewmech infeasible positions", f"{sew['n_infeasible']} / {sew['n_positions']}")
    if pl is not None:
        add(S1, "pylinkage NaN positions", f"{pl['n_nan_positions']} / {sew['n_positions']}")

    S2 = "2 one revolution"
    add(S2, "sewmech KinematicsPlan() p+v+a of C, P (prepared)", fmt_t(sew["single_plan_s"]))
    add(S2, "sewmech kinematics(m, phi) same (one-off call)", fmt_t(sew["single_s"]),
        f"<= {TARGET_ONE_OFF_S * 1e6:g} us", sew["single_s"] <= TARGET_ONE_OFF_S)
    add(S2, "sewmech kinematics(m, phi), every point and link (info)",
        fmt_t(sew["single_all_outputs_s"]))
    if pl is not None:
        add(S2, "pylinkage Linkage.step_fast(360) (p only)", fmt_t(pl["single_step_fast_s"]))
        add(S2, "pylinkage solver.simulate(...) (p only)", fmt_t(pl["single_raw_simulate_s"]))
        lo, hi = ratios["single_range_over_rounds"]
        add(S2, f"ratio pylinkage fastest ({ratios['single_pylinkage_api']}) / sewmech plan,"
            f" interleaved (rounds {lo:.2f}-{hi:.2f}x)",
            f"{ratios['single']:.2f}x", f">= {TARGET_SINGLE_RATIO:g}",
            ratios["single"] >= TARGET_SINGLE_RATIO)
        add(S2, "ratio pylinkage fastest / sewmech kinematics() (info)",
            f"{ratios['single_kinematics_call']:.2f}x")
        add(S2, "ratio pylinkage step_fast / sewmech plan (info)",
            f"{ratios['single_vs_step_fast']:.2f}x")

    S3 = "3 fresh process"
    add(S3, "sewmech import (run 2)", fmt_t(first[1]["import_s"]))
    add(S3, "sewmech import -> first kinematics (run 2, numba cache warm)",
        fmt_t(first[1]["first_call_s"]), f"< {TARGET_FIRST_CALL_S:g} s",
        first[1]["first_call_s"] < TARGET_FIRST_CALL_S)
    add(S3, "  same, run 1 (may include numba compilation)", fmt_t(first[0]["first_call_s"]))
    add(S3, "  whole subprocess wall clock incl. interpreter (run 2)",
        fmt_t(first[1]["process_wall_s"]))
    if pl_first is not None:
        add(S3, "pylinkage import -> first step_fast (run 2, info)",
            fmt_t(pl_first[1]["first_call_s"]))

    S4 = "4 accuracy vs closed form"
    add(S4, "sewmech max |C error| batch (feasible)", f"{sew['max_err_C_batch_mm']:.2e} mm")
    add(S4, "sewmech max |P error| batch (feasible)", f"{sew['max_err_P_batch_mm']:.2e} mm")
    add(S4, "sewmech max |C error| single", f"{sew['max_err_C_single_mm']:.2e} mm")
    add(S4, "sewmech max |P error| single", f"{sew['max_err_P_single_mm']:.2e} mm")
    if pl is not None:
        add(S4, "pylinkage max |C error| batch", f"{pl['max_err_C_batch_mm']:.2e} mm")
        add(S4, "pylinkage max |P error| batch (info)", f"{pl['max_err_P_batch_mm']:.2e} mm")
        add(S4, "pylinkage max |C error| single", f"{pl['max_err_C_single_mm']:.2e} mm")
        add(S4, "pylinkage designs on the other branch", f"{pl['n_designs_other_branch']}")
        add(S4, "pylinkage vs sewmech C velocity, max rel. diff (info)",
            f"{pl['max_rel_diff_C_velocity_vs_sewmech']:.2e}")

    print("Four-bar benchmark: sewmech vs pylinkage"
          + ("" if pl is not None else " (pylinkage NOT installed: sewmech side only;"
             " `make bench` installs pylinkage[numba]==1.3.0)"))
    print(f"  python {platform.python_version()}, numpy {np.__version__}, "
          f"{os.cpu_count()} CPU(s), best of {REPEAT} repeats after a warm-up")
    w1 = max(len(r[1]) for r in rows)
    w2 = max(len(r[2]) for r in rows)
    w3 = max(len(r[3]) for r in rows)
    section = None
    for sec, name, value, target, st in rows:
        if sec != section:
            print(f"\n[{sec}]")
            section = sec
        print(f"  {name:<{w1}}  {value:>{w2}}  {target:<{w3}}  {st}")
    print()

    try:
        import numba
        numba_v = numba.__version__
    except ImportError:
        numba_v = None
    payload = {
        "job": {"A": [0, 0], "D": [AD0, 0], "AB": AB0, "BC": BC0, "CD": CD0,
                "P_local": list(P_LOCAL), "n_phi": len(PHI), "n_designs": N_DESIGN,
                "scale": [0.97, 1.03], "seed": SEED},
        "environment": {"python": platform.python_version(), "numpy": np.__version__,
                        "numba": numba_v, "platform": platform.platform(),
                        "cpu_count": os.cpu_count(), "repeats": REPEAT},
        "targets": {"batch_ratio": TARGET_BATCH_RATIO, "single_ratio": TARGET_SINGLE_RATIO,
                    "first_call_s": TARGET_FIRST_CALL_S},
        "sewmech": sew,
        "pylinkage": pl,
        "ratios": ratios,
        "first_call": {"sewmech_runs": first, "pylinkage_runs": pl_first,
                       "reported": "run 2 (numba compiles once and caches on disk)"},
        "status": {
            "batch_ratio": status(None if pl is None else ratios["batch"] >= TARGET_BATCH_RATIO),
            "single_ratio": status(None if pl is None
                                   else ratios["single"] >= TARGET_SINGLE_RATIO),
            "first_call": status(first[1]["first_call_s"] < TARGET_FIRST_CALL_S),
        },
        "table": [dict(zip(("section", "figure", "value", "target", "status"), r)) for r in rows],
    }
    write_results(RESULTS, payload, current_figures(payload), indent=2)
    print(f"written {RESULTS.relative_to(HERE.parent)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

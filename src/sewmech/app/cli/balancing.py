"""The balancing commands of the ``sewmech`` command line: ``balance`` (choose counterweights
on a machine), ``trial-balance`` (the crossing of measured vibration velocities) and
``influence-balance`` (correction masses from trial runs). Registered on the shared app of
:mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import math
from enum import Enum
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import AnalysisError, OptionError
from ..display import is_round_off, number
from .common import (
    DEFAULT_MACHINE,
    SET_HELP,
    _bounded,
    _choice,
    _load,
    _phi_grid,
    _rpm,
    choices_metavar,
    command,
    console,
    print_json,
)


class Criterion(str, Enum):
    delta_q = "delta-q"
    peak = "peak"
    rms = "rms"
    moment = "moment"
    bearings = "bearings"
    torque = "torque"
    weighted = "weighted"
    vibration = "vibration"
    equal_levels = "equal-levels"


#: the largest --weight (weights are relative; each part is divided by its value before)
MAX_WEIGHT = 1e6


def _weights(items: list[str] | None) -> dict[str, float] | None:
    """--weight PART=W options -> {part: weight}."""
    if not items:
        return None
    out = {}
    for item in items:
        name, eq, text = (x.strip() for x in item.partition("="))
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not eq or not name:
            raise OptionError("--weight", f"{item!r} is not PART=WEIGHT",
                              "Write e.g. --weight peak_force_N=2")
        if not 0.0 <= value <= MAX_WEIGHT:  # (a NaN fails too)
            raise OptionError("--weight", f"{item!r}: the weight must be a number in 0 .."
                              f" {MAX_WEIGHT:g} (weights are relative)",
                              "Write e.g. --weight peak_force_N=2")
        if name in out:
            raise OptionError("--weight", f"{item!r}: '{name}' is given twice", "Give it once")
        out[name] = value
    return out


def _figure_rows(res, after: str = "after") -> Table:
    from ..report.balancing import FIGURE_LABELS

    table = Table(title=f"balancing figures at {res.rpm:g} rpm (computed on the whole machine)")
    for col in ("figure", "unit", "before", after, "change"):
        table.add_column(escape(col), justify="left" if col in ("figure", "unit") else "right")
    for k, (label, unit) in FIGURE_LABELS.items():
        b, a = res.before[k], res.after[k]
        if b is None:
            continue
        # a figure the counterweights cancel is round-off of what it was: shown as 0
        if unit.startswith("dB"):  # a level changes by a difference of levels
            change = f"{a - b:+.1f} dB"
        else:
            change = f"{100.0 * (a - b) / b:+.1f} %" if not is_round_off(b, res.before[
                "peak_force_N"] if unit == "N" else b) else ""
        table.add_row(label, unit, number(b, scale=b), number(a, scale=b), change)
    return table


def _cw_table(res) -> Table:
    table = Table(title=f"counterweights ({res.criterion}): {res.status}")
    for col in ("counterweight", "link", "S before [g cm]", "S [g cm]", "angle [deg]",
                "mass [g]", "radius [mm]"):
        table.add_column(escape(col), justify="left" if col in ("counterweight", "link")
                         else "right")
    for name, c in res.counterweights.items():
        b = res.counterweights_before[name]
        table.add_row(name, c["link"], f"{b['static_moment_gcm']:.4g}",
                      f"{c['static_moment_gcm']:.4g}", f"{c['angle_deg']:.4g}",
                      f"{c['mass_g']:.4g}", f"{c['radius_mm']:.4g}")
    return table


@command("balance")
def balance_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    criterion: str = typer.Option(Criterion.delta_q.value, metavar=choices_metavar(Criterion),
                                  help="what to minimise: delta-q (the balancing paper's equal"
                                  " peaks of Qx and Qy, one counterweight), peak or rms shaking"
                                  " force, moment (peak shaking moment about the upper shaft),"
                                  " bearings (larger peak reaction of the upper shaft's"
                                  " bearings), torque (fluctuation), weighted, vibration"
                                  " (least larger x or y level at a control point of the"
                                  " housing) or equal-levels (the paper's bench criterion"
                                  " predicted: x and y levels equal; one counterweight)"),
    counterweights: list[str] = typer.Option(None, "--counterweight", help="a counterweight"
                                             " of the file to choose; repeatable (default:"
                                             " all; delta-q: the one on the upper shaft)"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    step_deg: float = typer.Option(1.0, help="shaft-angle step over the turn, deg"),
    moment_point: str = typer.Option(None, "--moment-point-mm", help="the point X,Y (mm, machine"
                                     " frame) the shaking moment is taken about (default: the"
                                     " upper shaft's axis)"),
    weights: list[str] = typer.Option(None, "--weight", help="weighted criterion: PART=W for"
                                      " peak_force_N, rms_force_N, peak_moment_Nm,"
                                      " bearings_peak_N, torque_fluctuation_Nm (default 1"
                                      " each, each part divided by its value before)"),
    control_point: str = typer.Option(None, "--control-point", help="vibration and"
                                      " equal-levels: the housing's control point judged"
                                      " (default: its first)"),
    as_json: bool = typer.Option(False, "--json", help="print the result as JSON"),
    out: Path = typer.Option(None, help="also write the balancing figures (PNG, SVG, CSV),"
                             " every criterion's answer (CSV) and the result (JSON) here"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Choose counterweights: static moment and angle of each, with the machine's balancing
    figures before and after."""
    from ...design.balancing import balance, paper_workflow, shaft_counterweight

    criterion = Criterion(_choice("--criterion", criterion, Criterion, "peak"))
    _bounded("--step-deg", step_deg, 0.1, 30.0, "deg", "1")
    _phi_grid(step_deg)  # it divides 360
    m = _load(machine, sets)
    rpm = _rpm(rpm)
    w = _weights(weights)
    if w is not None and criterion is not Criterion.weighted:
        raise OptionError("--weight", "only the weighted criterion reads weights",
                          "Add --criterion weighted or leave --weight out")
    names = counterweights or None
    if control_point is not None and criterion not in (Criterion.vibration,
                                                       Criterion.equal_levels):
        raise OptionError("--control-point", "only the vibration criteria judge at a control"
                          " point", "Add --criterion vibration or equal-levels, or leave it"
                          " out")
    if criterion in (Criterion.vibration, Criterion.equal_levels) and m.spec.housing is None:
        raise OptionError("--criterion", f"{criterion.value} needs the machine's housing;"
                          f" {m.name} has no [housing] table", "Add [housing] to the machine"
                          " file (docs/vibration.md) or choose another criterion")
    if criterion in (Criterion.delta_q, Criterion.equal_levels) and not names \
            and len(m.counterweights) > 1:
        shaft = shaft_counterweight(m)
        names = [shaft] if shaft else None
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="balance")
    point = _point(moment_point)
    res = balance(m, criterion.value, names, rpm=rpm, step_deg=step_deg, weights=w,
                  moment_point=point, control_point=control_point)
    data = {"machine": m.name, **res.to_json()}
    if criterion is Criterion.delta_q:
        chosen = next(iter(res.counterweights))
        link = next(c.link for c in m.counterweights if c.name == chosen)
        if link in _shaft_cranks(m):
            paper = paper_workflow(m, chosen, rpm=rpm, step_deg=step_deg, result=res)
            data["paper"] = {k: v for k, v in paper.items() if k != "result"}
        else:  # S_1 is the shaft's crank's: of a coupler it was called "the shaft's crank"
            data["paper_note"] = (f"the balancing paper's method (S_1, S_add, the built"
                                  f" counterweight) is for a counterweight on a crank that"
                                  f" turns with the upper shaft; '{chosen}' is on"
                                  f" '{link}'")
    if out is not None:
        _write_balance(m, out, res, data, names, rpm, point)
    if as_json:
        print_json(data)
        return
    if res.proposed:
        console.print(_cw_table(res))
        console.print(escape(res.message))
        console.print(_figure_rows(res))
    else:
        alt = res.alternative
        console.print(f"[bold]{res.criterion}: {res.status}[/]")
        console.print(escape(res.message))
        console.print(_cw_table(alt))
        console.print(_figure_rows(alt, f"with --criterion {alt.criterion}"))
        again = [f"--set {x}" for x in sets or ()] + ([f"--rpm {rpm:g}"] if rpm else [])
        least = ("the least vibration" if alt.criterion == "vibration" else
                 "the least peak shaking force")
        console.print(escape(" ".join([f"{least}: sewmech balance"
                                       f" {machine} --criterion {alt.criterion}"
                                       f" --counterweight {next(iter(alt.counterweights))}",
                                       *again])))
    if "paper" in data:
        for line in paper_lines(data["paper"]):
            console.print(escape(line))
    elif "paper_note" in data:
        console.print(escape(f"note: {data['paper_note']}"), highlight=False)
    agree = ("it agrees to round-off" if is_round_off(res.basis_error,
                                                        res.before["peak_force_N"])
             else f"largest difference {res.basis_error:.2g} (N, N m)")
    console.print(f"basis checked on the whole machine: {agree}")
    if out is not None:
        console.print(f"written: figures, {m.name}-balance.json and"
                      f" {m.name}-balance-criteria.csv in {out}")


def _shaft_cranks(m) -> set[str]:
    """The links that turn with the upper shaft at its speed (the paper's S_1 is of one)."""
    return {u.link or u.name for u in m.spec.units
            if u.type == "crank" and u.input == "shaft" and u.ratio == 1.0}


def paper_lines(p: dict) -> list[str]:
    """The balancing paper's method as the command prints it: S_1, S_add, S_opt, and the
    built counterweight's recipe, or why there is none."""
    lines = []
    if p["s_add_gcm"] is None:
        lines.append(f"the balancing paper's method: S_1 {p['s1_gcm']:.4g} g cm (the shaft's"
                     " crank, all its solids); no S_add (Delta-Q has no root)")
    else:
        lines.append(f"the balancing paper's method: S_1 {p['s1_gcm']:.4g} g cm (the shaft's"
                     f" crank, all its solids), S_add {p['s_add_gcm']:.4g} g cm, S_opt ="
                     f" |S_1 + S_add| {p['s_opt_gcm']:.4g} g cm (the crank's net static moment"
                     " with the extra counterweight)")
    b = p.get("build")
    if b:
        ins, blk = b["insert"], b["block"]
        lines.append(
            f"built {b['factor']:g} x: {b['s_built_gcm']:.4g} g cm, a steel cup"
            f" {blk['diameter_mm']:.3g} mm across and {blk['length_mm']:.3g} mm long, its axis"
            f" parallel to the shaft at {blk['radius_mm']:.3g} mm ({blk['steel_g']:.3g} g of"
            f" steel, clamped on the {b['bore_mm']:.3g} mm shaft), with a lead insert"
            f" {ins['diameter_mm']:.3g} mm across and {ins['depth_mm']:.3g} mm deep"
            f" ({ins['mass_g']:.3g} g of lead; walls at least {b['wall_mm']:g} mm: its edge"
            f" {b['hole_edge_mm']:.3g} mm from the shaft's axis, {b['clearance_mm']:.3g} mm of"
            " steel to the shaft), which drilled out takes it back to S_add")
        if b.get("factor_note"):
            lines.append(f"  margin {b['factor_note']}")
    elif p.get("build_refused"):
        lines.append(f"no recipe for the built counterweight: {p['build_refused']}")
    return lines


def _point(text: str | None) -> tuple[float, float] | None:
    """--moment-point-mm X,Y -> (x, y) mm."""
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise OptionError("--moment-point-mm", f"{text!r} is not X,Y in mm",
                          "Write e.g. --moment-point-mm 0,-80") from None
    if not (math.isfinite(x) and math.isfinite(y) and abs(x) <= 1e6 and abs(y) <= 1e6):
        raise OptionError("--moment-point-mm", f"{text!r}: give finite coordinates in mm")
    return x, y


def _write_balance(m, out: Path, res, data: dict, names, rpm, point) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from ..drawing.figures import Figures
    from ..files.io import atomic_write, dump_json
    from ..files.outdir import output_dir
    from ..report.balancing import balancing_section, results_frame

    with output_dir(out, command="balance", machine=m.name) as root:
        figs = Figures(root, m.name)
        sec = balancing_section(figs, m, criterion=res.criterion, counterweights=names,
                                rpm=rpm, weights=res.weights or None, moment_point=point)
        figs.blocks  # every figure written
        with atomic_write(root / f"{m.name}-balance-criteria.csv") as fh:
            results_frame(sec["results"]).to_csv(fh, index=False, float_format="%.10g")
        with atomic_write(root / f"{m.name}-balance.json") as fh:
            dump_json(data, fh, indent=1)


@command("trial-balance")
def trial_balance_cmd(
    file: Path = typer.Argument(..., help="CSV with columns s_add_gcm, vx_mm_s, vy_mm_s: the"
                                " extra counterweight's static moment (g cm) and the vibration"
                                " velocity of the control point on x and y (mm/s); repeats"
                                " allowed"),
    as_json: bool = typer.Option(False, "--json", help="print the result as JSON"),
    out: Path = typer.Option(None, help="also write the plot (PNG, SVG) and the fit (CSV)"),
    calibrate: str = typer.Option(None, "--calibrate", metavar="MACHINE", help="also fit"
                                  " MACHINE's housing (its mounts' stiffness and damping) to"
                                  " the measurements: the fitted values with their"
                                  " uncertainty and the calibrated model's crossing beside the"
                                  " model's and Delta-Q's (needs [housing])"),
    fit_angle: bool = typer.Option(False, "--fit-angle", help="with --calibrate: fit the extra"
                                   " counterweight's angle too"),
    counterweight: str = typer.Option(None, "--counterweight", help="with --calibrate: the"
                                      " counterweight the measurements varied (default: the"
                                      " one on the upper shaft's crank)"),
    control_point: str = typer.Option(None, "--control-point", help="with --calibrate: the"
                                      " housing's control point measured (default: its"
                                      " first)"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """The static moment where the measured x and y vibration velocities are equal, with its
    95 % interval (the balancing paper's correction from measurements); with --calibrate, the
    machine's housing fitted to them (why the model and the bench disagree)."""
    from ...design.vibration import STATIC_MOMENT_RANGE_GCM, VELOCITY_RANGE_MM_S, crossing
    from ..files.io import read_csv_columns

    if calibrate is None:
        for opt, given in (("--fit-angle", fit_angle), ("--counterweight", counterweight),
                           ("--control-point", control_point), ("--set", sets)):
            if given:
                raise OptionError(opt, "it only applies to a calibration",
                                  "Add --calibrate MACHINE or leave it out")
    cols = read_csv_columns(file, ["s_add_gcm", "vx_mm_s", "vy_mm_s"],
                            ranges={"s_add_gcm": (*STATIC_MOMENT_RANGE_GCM, "g cm"),
                                    "vx_mm_s": (*VELOCITY_RANGE_MM_S, "mm/s"),
                                    "vy_mm_s": (*VELOCITY_RANGE_MM_S, "mm/s")})
    cal = None
    if calibrate is not None:
        cal = _calibration(calibrate, sets, file, cols, fit_angle, counterweight,
                           control_point)
    try:
        c = crossing(cols["s_add_gcm"], cols["vx_mm_s"], cols["vy_mm_s"], where=str(file))
    except AnalysisError:
        if cal is None:
            raise
        c = None  # the lines do not cross; the calibration still says what the model does
    data = c.to_json() if c is not None else {}
    if cal is not None:
        data["calibration"] = cal.to_json()
    if out is not None:
        _write_trial(out, file, cols, c, cal)
    if as_json:
        print_json(data)
        return
    if c is None:
        console.print(escape(f"no crossing of the measured lines ({cal.message})"))
    else:
        _print_crossing(c)
    if cal is not None:
        _print_calibration(cal)
    if out is not None:
        console.print(f"written: plot and fit in {out}")


def _calibration(machine: str, sets, file: Path, cols: dict, fit_angle: bool,
                 counterweight: str | None, control_point: str | None):
    """trial-balance --calibrate: the machine's housing fitted to the measurements."""
    from ...design.calibration import calibrate

    m = _load(machine, sets)
    if counterweight is not None and counterweight not in m.spec.counterweights:
        raise OptionError("--counterweight", f"'{counterweight}' is not a counterweight of"
                          f" {m.name}", "Choose one of: " + ", ".join(m.spec.counterweights))
    try:
        return calibrate(m, cols["s_add_gcm"], cols["vx_mm_s"], cols["vy_mm_s"],
                         counterweight=counterweight, control_point=control_point,
                         fit_angle=fit_angle, where=str(file))
    except AnalysisError as exc:
        if exc.where == (m.file or m.name):
            raise OptionError("--calibrate", f"{m.name}: {exc.message}", exc.hint) from None
        raise


def _print_calibration(cal) -> None:
    t = Table(title=f"{cal.machine}'s housing fitted to the bench (control point"
              f" '{cal.control_point}', counterweight '{cal.counterweight}')")
    t.add_column("fitted value", justify="left")
    t.add_column("value", justify="right")
    t.add_column("standard deviation", justify="right")
    for name, v in cal.values.items():
        t.add_row(name, f"{v:.4g}", f"{cal.std[name]:.3g}")
    console.print(t)

    def g(x):
        return "none" if x is None else f"{x:.4g} g cm"

    console.print(escape(f"RMS error of the model {cal.before_rms_log_error:.3g} -> calibrated"
                         f" {cal.rms_log_error:.3g} (of log velocity: 0.1 is about 10 %)"))
    console.print(escape(f"crossing (x and y equal): measured lines {g(cal.measured_crossing_gcm)},"
                         f" calibrated model {g(cal.crossing_gcm)}, model as the file has it"
                         f" {g(cal.model_crossing_gcm)}; Delta-Q = 0 at {g(cal.delta_q_gcm)}"),
                  highlight=False)
    style = "" if cal.status == "fitted" else "[yellow]"
    console.print(f"{style}{cal.status}[/]: {escape(cal.message)}" if style else
                  f"{cal.status}: {escape(cal.message)}")


def _print_crossing(c) -> None:
    lo, hi = c.ci95_gcm
    console.print(f"crossing: S_add = [bold]{c.s_add_gcm:.4g} g cm[/] (95 % interval {lo:.4g}"
                  f" .. {hi:.4g} g cm) from {c.n_points} measurements")
    change = (f"{c.level_change_db:+.2f} dB" if c.level_change_db is not None else
              f"undefined ({c.level_change_note.removeprefix('not defined: ')})")
    console.print(escape(f"velocity there {c.v_at_crossing_mm_s:.4g} mm/s on each axis; level"
                         f" change against S_add = {c.s_lowest_gcm:g} g cm: {change}"),
                  highlight=False)


def _write_trial(out: Path, file: Path, cols: dict, c, cal=None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    from ..drawing.figures import save_figure
    from ..files.io import atomic_write, dump_json
    from ..files.outdir import output_dir

    s = cols["s_add_gcm"]
    grid = np.linspace(s.min(), s.max(), 200)
    with output_dir(out, command="trial-balance") as root:
        if c is not None:
            fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
            ax.plot(s, cols["vx_mm_s"], "o", color="C0", ms=4, label="x measured")
            ax.plot(s, cols["vy_mm_s"], "s", color="C1", ms=4, label="y measured")
            ax.plot(grid, c.fit_x[0] + c.fit_x[1] * grid, color="C0")
            ax.plot(grid, c.fit_y[0] + c.fit_y[1] * grid, color="C1")
            ax.axvspan(*c.ci95_gcm, color="0.85", label="95 % interval")
            ax.axvline(c.s_add_gcm, color="k", ls="--",
                       label=f"crossing {c.s_add_gcm:.4g} g cm")
            ax.set_xlabel("static moment of the extra counterweight S_add [g cm]")
            ax.set_ylabel("vibration velocity [mm/s]")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            ax.set_title(f"{file.name}: vibration velocity of the control point")
            save_figure(fig, root, "trial-balance")
            with atomic_write(root / "trial-balance.csv") as fh:
                pd.DataFrame({"s_add_gcm": grid,
                              "vx_fit_mm_s": c.fit_x[0] + c.fit_x[1] * grid,
                              "vy_fit_mm_s": c.fit_y[0] + c.fit_y[1] * grid}).to_csv(
                    fh, index=False, float_format="%.10g")
        if cal is not None:
            _calibration_figure(root, file, cal)
            cv = cal.curves
            with atomic_write(root / "trial-balance-calibration.csv") as fh:
                pd.DataFrame({"s_add_gcm": cv["S_gcm"],
                              "vx_model_mm_s": cv["model"][:, 0],
                              "vy_model_mm_s": cv["model"][:, 1],
                              "vx_calibrated_mm_s": cv["calibrated"][:, 0],
                              "vy_calibrated_mm_s": cv["calibrated"][:, 1]}).to_csv(
                    fh, index=False, float_format="%.10g")
        with atomic_write(root / "trial-balance.json") as fh:
            data = c.to_json() if c is not None else {}
            if cal is not None:
                data["calibration"] = cal.to_json()
            dump_json(data, fh, indent=1)


def _calibration_figure(root: Path, file: Path, cal) -> None:
    """The measured velocities with the model's curves as the file has it (dashed) and
    calibrated (solid), each crossing marked: the paper's measured figure with the model
    beside it."""
    import matplotlib.pyplot as plt

    from ..drawing.figures import save_figure

    cv = cal.curves
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    for k, (axis, mark) in enumerate((("x", "o"), ("y", "s"))):
        ax.plot(cv["measured_S_gcm"], cv["measured"][:, k], mark, color=f"C{k}", ms=4,
                label=f"{axis} measured")
        ax.plot(cv["S_gcm"], cv["model"][:, k], "--", color=f"C{k}", lw=1,
                label=f"{axis} model (the file's mounts)")
        ax.plot(cv["S_gcm"], cv["calibrated"][:, k], "-", color=f"C{k}",
                label=f"{axis} calibrated")
    for value, style, what in ((cal.measured_crossing_gcm, ":", "measured lines"),
                               (cal.crossing_gcm, "-", "calibrated model"),
                               (cal.model_crossing_gcm, "--", "model"),
                               (cal.delta_q_gcm, "-.", "Delta-Q = 0")):
        if value is not None:
            ax.axvline(value, color="k", ls=style, lw=0.9, label=f"{what}: {value:.4g} g cm")
    ax.set_xlabel("static moment of the extra counterweight S_add [g cm]")
    ax.set_ylabel(f"vibration velocity at '{cal.control_point}' [mm/s RMS]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"{file.name}: the housing's model fitted to the bench ({cal.status})")
    save_figure(fig, root, "trial-balance-calibration")


@command("influence-balance")
def influence_balance_cmd(
    file: Path = typer.Argument(..., help="CSV with columns run, place, amplitude_mm_s,"
                                " phase_deg, trial_gcm, trial_angle_deg: run 0 without trial"
                                " masses, then one run per correction plane with its trial"
                                " mass (static moment g cm > 0, angle deg); a place is a sensor"
                                " and speed (any label), measured in every run; amplitudes"
                                " are magnitudes (>= 0), phases as below"),
    phase_lag: bool = typer.Option(False, "--phase-lag", help="the phases are lags, counted"
                                   " against the sense of trial_angle_deg (most vibration"
                                   " analysers with a shaft mark): each is read as -phase_deg"),
    as_json: bool = typer.Option(False, "--json", help="print the result as JSON"),
    solver: str = typer.Option("lsq", metavar="[lsq|minmax]", help="lsq: least squares over"
                               " the readings; minmax: the smallest largest (weighted)"
                               " residual, a linear programme (docs/balancing.md)"),
    weight: list[str] = typer.Option(None, "--weight", help="minmax: PLACE=W, the weight of a"
                                     " place's residual (default 1); repeatable"),
    max_gcm: list[str] = typer.Option(None, "--max-gcm", help="minmax: RUN=S, the most static"
                                      " moment the plane of trial run RUN can take, g cm;"
                                      " repeatable"),
):
    """Correction masses for a built machine from trial runs (influence coefficients, least
    squares over the places and speeds measured).

    Phases: phase_deg is the angle of the once-per-turn vibration against the mark on the
    shaft, counted in the same sense as trial_angle_deg (it grows when a trial mass is turned
    forward); give --phase-lag for an instrument that counts it against that sense. The
    corrections' angles come out in the frame of the trial angles."""
    from ...design.vibration import (
        ANGLE_RANGE_DEG,
        STATIC_MOMENT_RANGE_GCM,
        VELOCITY_RANGE_MM_S,
        _count,
        influence_balance,
        phasor,
    )
    from ...engine.errors import AnalysisError
    from ..files.io import read_csv_columns

    cols = read_csv_columns(file, ["amplitude_mm_s", "phase_deg", "trial_gcm",
                                   "trial_angle_deg"], ["run", "place"],
                            nonnegative={"amplitude_mm_s": "An amplitude is a magnitude: give"
                                         " it >= 0 and add 180 deg to its phase_deg instead",
                                         "trial_gcm": "A trial mass's static moment is a"
                                         " magnitude: give it > 0 and add 180 deg to its"
                                         " trial_angle_deg instead"},
                            ranges={"amplitude_mm_s": (*VELOCITY_RANGE_MM_S, "mm/s"),
                                    "phase_deg": (*ANGLE_RANGE_DEG, "deg"),
                                    "trial_gcm": (*STATIC_MOMENT_RANGE_GCM, "g cm"),
                                    "trial_angle_deg": (*ANGLE_RANGE_DEG, "deg")},
                            labels={"run": ("0|[1-9][0-9]*", "a run number", "Label the runs 0"
                                            " (no trial mass),"
                                            " 1, 2, ... (one run per correction plane)")})
    runs = list(dict.fromkeys(cols["run"]))
    places = list(dict.fromkeys(cols["place"]))
    if "0" not in runs or len(runs) < 2:
        raise AnalysisError(str(file), f"runs {', '.join(runs)}: need run 0 (no trial mass)"
                            " and one run per correction plane", "Label the runs 0, 1, 2, ...")
    sign = -1.0 if phase_lag else 1.0
    table: dict = {}
    trial: dict = {}
    for r, p, a, ph, s, ang in zip(cols["run"], cols["place"], cols["amplitude_mm_s"],
                                   cols["phase_deg"], cols["trial_gcm"],
                                   cols["trial_angle_deg"]):
        if (r, p) in table:
            raise AnalysisError(str(file), f"run {r} measures place {p} twice",
                                "One line per run and place")
        table[r, p] = phasor(a, sign * ph)
        if r != "0":
            if r in trial and trial[r] != (s, ang):
                raise AnalysisError(str(file), f"run {r} gives two different trial masses",
                                    "One trial mass per run")
            if s == 0.0:
                raise AnalysisError(str(file), f"run {r}: its trial mass has trial_gcm = 0",
                                    "Give the static moment of the trial mass added in this"
                                    " run (> 0 g cm)")
            trial[r] = (s, ang)
    missing = [f"run {r} place {p}" for r in runs for p in places if (r, p) not in table]
    if missing:
        raise AnalysisError(str(file), f"not measured: {', '.join(missing[:5])}",
                            "Measure every place in every run")
    planes = [r for r in runs if r != "0"]
    V0 = np.array([table["0", p] for p in places])
    Vt = np.array([[table[r, p] for p in places] for r in planes])
    solver = _choice("--solver", solver, ("lsq", "minmax"))
    if solver == "minmax":
        return _minmax(file, V0, Vt, planes, places, trial, weight, max_gcm, phase_lag, as_json)
    if weight or max_gcm:
        raise OptionError("--weight" if weight else "--max-gcm", "is for --solver minmax",
                          "Give --solver minmax, or leave it out")
    try:
        res = influence_balance(V0, Vt, [trial[r][0] for r in planes],
                                [trial[r][1] for r in planes], [f"run {r}" for r in planes])
    except AnalysisError as exc:
        raise AnalysisError(str(file), exc.message, exc.hint) from None
    data = {**res.to_json([f"run {r}" for r in planes]), "n_places": len(places),
            "phase": "lag" if phase_lag else "same sense as trial_angle_deg"}
    if as_json:
        print_json(data)
        return
    t = Table(title=f"correction masses from {_count(len(places), 'place')} and"
                    f" {_count(len(planes), 'trial run')}")
    for col in ("plane (trial run)", "static moment [g cm]", "angle [deg]"):
        t.add_column(escape(col))
    for name, v in data["corrections"].items():
        t.add_row(name, f"{v['static_moment_gcm']:.4g}", f"{v['angle_deg']:.4g}")
    console.print(t)
    if res.cancelled is not None:
        console.print(escape(f"vibration RMS over the places {res.before:.4g} -> 0 mm/s"
                             f" predicted: {res.cancelled}"))
    else:
        db = res.level_change_db
        console.print(f"vibration RMS over the places {res.before:.4g} -> {res.after:.4g} mm/s"
                      " predicted" + (f" ({db:+.2f} dB)" if db is not None else ""))


def _named_values(option: str, items: list[str] | None, names: list[str], what: str,
                  example: str) -> dict[str, float]:
    """NAME=VALUE options (names from ``names``) -> {name: value >= 0}."""
    out: dict[str, float] = {}
    for item in items or ():
        name, eq, text = (x.strip() for x in item.partition("="))
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not eq or not name:
            raise OptionError(option, f"{item!r} is not {what}=VALUE", f"Write e.g. {option}"
                              f" {example}")
        if name not in names:
            import difflib

            near = difflib.get_close_matches(name, names, n=1)
            raise OptionError(option, f"{item!r}: the file has no {what.lower()} '{name}'",
                              f"Did you mean {near[0]}?" if near else
                              f"The file's: {', '.join(names)}")
        if not (value >= 0 and not math.isnan(value)):
            raise OptionError(option, f"{item!r}: the value must be a number >= 0")
        if name in out:
            raise OptionError(option, f"{item!r}: '{name}' is given twice", "Give it once")
        out[name] = value
    return out


def _minmax(file, V0, Vt, planes, places, trial, weight, max_gcm, phase_lag, as_json):
    """influence-balance --solver minmax (sewmech.design.minmax_balance)."""
    from ...design.minmax_balance import influence_minmax
    from ...design.vibration import _count
    from ...engine.errors import AnalysisError

    w = _named_values("--weight", weight, places, "PLACE", f"{places[0]}=2")
    lim = _named_values("--max-gcm", max_gcm, planes, "RUN", f"{planes[0]}=40")
    weights = np.array([w.get(p, 1.0) for p in places])
    limits = np.array([lim.get(r, np.inf) for r in planes]) if lim else None
    try:
        res = influence_minmax(V0, Vt, [trial[r][0] for r in planes],
                               [trial[r][1] for r in planes], weights=weights,
                               limits_gcm=limits, names=[f"run {r}" for r in planes])
    except AnalysisError as exc:
        raise AnalysisError(str(file), exc.message, exc.hint) from None
    data = {**res.to_json([f"run {r}" for r in planes], places), "n_places": len(places),
            "phase": "lag" if phase_lag else "same sense as trial_angle_deg"}
    if as_json:
        print_json(data)
        return
    t = Table(title=f"min-max correction masses from {_count(len(places), 'place')} and"
                    f" {_count(len(planes), 'trial run')}")
    for col in ("plane (trial run)", "static moment [g cm]", "angle [deg]", "limit [g cm]"):
        t.add_column(escape(col))
    for (name, v), r in zip(data["corrections"].items(), planes, strict=True):
        t.add_row(name, f"{v['static_moment_gcm']:.4g}", f"{v['angle_deg']:.4g}",
                  (f"{lim[r]:g}" + (" (reached)" if v["at_limit"] else "")) if r in lim
                  else "none")
    console.print(t)
    console.print(f"largest weighted vibration over the places {res.before_max:.4g} ->"
                  f" {res.after_max:.4g} mm/s predicted (no correction within the limits"
                  f" gets below {res.lower_bound:.4g} mm/s); RMS {res.before_rms:.4g} ->"
                  f" {res.after_rms:.4g} mm/s", highlight=False)
    console.print(escape(f"(circles as {res.sides}-gons: the answer is within"
                         f" {100 * res.accuracy:.2g} % of the true min-max)"), highlight=False)


@command("level-change")
def level_change_cmd(
    before: float = typer.Argument(..., help="vibration velocity before, mm/s"),
    after: float = typer.Argument(..., help="vibration velocity after, mm/s"),
    as_json: bool = typer.Option(False, "--json", help="print the result as JSON"),
):
    """The change in vibration velocity level (dB) between two measurements, and each level
    against 5e-8 m/s."""
    from ...design.vibration import LEVEL_RANGE_MM_S, V_REF_MM_S, level_change_db, level_db

    lo, hi = LEVEL_RANGE_MM_S
    for name, v in (("BEFORE", before), ("AFTER", after)):
        if not lo <= v <= hi:  # (a NaN fails too)
            raise OptionError(name, f"must be a vibration velocity in {lo:g} .. {hi:g} mm/s,"
                              f" got {v:g}", "Give the velocity measured (RMS or peak), mm/s;"
                              " a level in dB needs a velocity > 0")
    data = {"before_db": float(level_db(before)), "after_db": float(level_db(after)),
            "level_change_db": level_change_db(before, after), "reference_mm_s": V_REF_MM_S}
    if as_json:
        print_json(data)
        return
    console.print(f"{before:g} mm/s -> {after:g} mm/s: {data['before_db']:.1f} dB ->"
                  f" {data['after_db']:.1f} dB (re 5e-8 m/s), change"
                  f" [bold]{data['level_change_db']:+.2f} dB[/]")

"""The ``sewmech`` command line (typer + rich)."""

from __future__ import annotations

import json
import math
import sys
from enum import Enum
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .errors import SewmechError
from .machine import Machine, load_machine, shipped_machines

DEFAULT_MACHINE = "jb1-3"

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="sewmech: kinematics of sewing-machine mechanisms (mm, s, rad inside; "
                       "degrees at the edges).")
console = Console()
err_console = Console(stderr=True)


class Format(str, Enum):
    csv = "csv"
    json = "json"


def _fail(exc: Exception) -> None:
    err_console.print(f"[bold red]error:[/] {escape(str(exc))}", markup=True, highlight=False,
                      soft_wrap=True)
    raise typer.Exit(code=2)


def _load(machine: str) -> Machine:
    try:
        return load_machine(machine)
    except SewmechError as exc:
        _fail(exc)


def _phi_grid(machine: Machine, step_deg: float) -> np.ndarray:
    if not (0 < step_deg <= 90):
        _fail(ValueError(f"--step-deg must be in (0, 90], got {step_deg}"))
    n = int(round(360.0 / step_deg))
    if not math.isclose(n * step_deg, 360.0, rel_tol=1e-9):
        _fail(ValueError(f"--step-deg {step_deg} does not divide 360"))
    return np.radians(np.arange(n) * step_deg)


def _settings(m: Machine, inputs: list[str] | None) -> dict[str, float]:
    """--input NAME=DEG options -> {name: rad}."""
    settings = {}
    for item in inputs or ():
        name, _, value = item.partition("=")
        if name not in m.spec.inputs:
            _fail(ValueError(f"--input {item!r}: machine '{m.name}' has no input '{name}'"
                             f" (inputs: {', '.join(m.spec.inputs) or 'none'})"))
        try:
            settings[name] = math.radians(float(value))
        except ValueError:
            _fail(ValueError(f"--input {item!r}: expected NAME=DEGREES"))
    return settings


@app.command("machines")
def machines_cmd():
    """List the machine files shipped with sewmech."""
    table = Table(title="shipped machines")
    for col in ("name", "title", "units", "file"):
        table.add_column(col)
    for name, path in sorted(shipped_machines().items()):
        m = load_machine(path)
        table.add_row(name, m.spec.machine.title, str(len(m.unit_names)), str(path))
    console.print(table)


@app.command("check")
def check_cmd(file: Path = typer.Argument(..., help="machine file (TOML) or shipped name"),
              step_deg: float = typer.Option(5.0, help="angle step of the assembly check, deg")):
    """Validate a machine file and assemble it over one revolution."""
    from .kinematics import kinematics

    m = _load(str(file))
    try:
        res = kinematics(m, _phi_grid(m, step_deg))
    except SewmechError as exc:
        _fail(exc)
    table = Table(title=f"{m.name}: valid", show_header=False)
    table.add_row("file", m.file)
    table.add_row("angle convention", f"phi = {m.spec.convention.reference_phi_deg:g} deg: "
                  f"{m.spec.convention.reference_event}")
    table.add_row("points / links / variables", f"{len(m.point_names)} / "
                  f"{len(m.link_names) - 1} / {len(m.variable_names)}")
    table.add_row("units", ", ".join(f"{n} ({t})" for n, t in zip(m.unit_names, m.unit_types)))
    table.add_row("branches", ", ".join(f"{k}: {v:+d}" for k, v in m.branches.items()) or "-")
    table.add_row("parameters", str(len(m.parameter_names)))
    table.add_row("assembles", f"at all {res.phi.size} positions (step {step_deg:g} deg)")
    from .dynamics import force_system

    table.add_row("force analysis", escape(force_system(m)))
    console.print(table)


def _summary(res) -> Table:
    table = Table(title=f"{res.machine}: kinematics over {res.phi.size} positions "
                        f"({res.omega_shaft[0] * 60 / (2 * math.pi):g} rpm)")
    for col in ("channel", "unit", "min", "max", "max |rate|", "max |accel|"):
        table.add_column(col, justify="right" if col not in ("channel", "unit") else "left")
    for pt in res.point_names:
        m = res.point(pt)
        for c, ax in (("x", 0), ("y", 1)):
            if np.ptp(m.p[:, ax]) < 1e-12:
                continue
            table.add_row(f"{pt}.{c}", "mm, mm/s, mm/s^2", f"{m.p[:, ax].min():.4f}",
                          f"{m.p[:, ax].max():.4f}", f"{np.abs(m.v[:, ax]).max():.4g}",
                          f"{np.abs(m.a[:, ax]).max():.4g}")
    for lk in res.link_names:
        if lk == "frame":
            continue
        m = res.link(lk)
        th = np.degrees(np.unwrap(m.theta))
        table.add_row(f"theta {lk}", "deg, rad/s, rad/s^2", f"{th.min():.3f}", f"{th.max():.3f}",
                      f"{np.abs(m.omega).max():.4g}", f"{np.abs(m.epsilon).max():.4g}")
    return table


@app.command("kinematics")
def kinematics_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    step_deg: float = typer.Option(5.0, help="shaft-angle step, deg"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    out: Path = typer.Option(None, help="write the channels into this directory"),
    format: Format = typer.Option(Format.csv, "--format", help="file format with --out"),
    as_json: bool = typer.Option(False, "--json", help="print every channel as JSON to stdout"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=20; repeatable (default: the file's)"),
):
    """Positions, velocities and accelerations of every point, link and joint variable."""
    from .io import kinematics_to_dict, write_kinematics_csv, write_kinematics_json
    from .kinematics import kinematics

    m = _load(machine)
    settings = _settings(m, inputs)
    try:
        res = kinematics(m, _phi_grid(m, step_deg), rpm=rpm, inputs=settings or None)
    except SewmechError as exc:
        _fail(exc)
    if as_json:
        json.dump(kinematics_to_dict(res), sys.stdout)
        sys.stdout.write("\n")
        return
    console.print(_summary(res))
    if out is not None:
        path = out / f"{m.name}-kinematics.{format.value}"
        (write_kinematics_csv if format is Format.csv else write_kinematics_json)(res, path)
        console.print(f"written: {path}")


@app.command("dynamics")
def dynamics_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    step_deg: float = typer.Option(5.0, help="shaft-angle step, deg (5: the report's 72"
                                   " positions)"),
    as_json: bool = typer.Option(False, "--json", help="print the per-position figures as JSON"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the file's)"),
    loads: Path = typer.Option(None, help="a load file ([[loads]] tables) that replaces the"
                               " machine file's loads"),
    no_loads: bool = typer.Option(False, "--no-loads", help="no process loads (no-load run)"),
    gravity: bool = typer.Option(True, "--gravity/--no-gravity", help="weights of the links"),
    out: Path = typer.Option(None, help="also write the per-position table and the pair"
                             " forces (CSV) and the dynamics figures (PNG, SVG, CSV) here"),
):
    """Inverse dynamics: driving torque, pair forces, shaking force and moment, energies,
    upper-shaft bearing reactions."""
    from .dynamics import inverse_dynamics
    from .io import dynamics_to_dict, write_dynamics_csv
    from .spec import load_load_file

    m = _load(machine)
    settings = _settings(m, inputs)
    try:
        load_specs = [] if no_loads else (load_load_file(loads) if loads is not None else None)
        if load_specs:
            m.check_loads(load_specs, str(loads))
        res = inverse_dynamics(m, _phi_grid(m, step_deg), rpm=rpm, inputs=settings or None,
                               gravity=gravity, loads=load_specs)
        data = dynamics_to_dict(res)
    except (SewmechError, ValueError) as exc:
        _fail(exc)
    if as_json:
        json.dump(data, sys.stdout)
        sys.stdout.write("\n")
        return
    console.print(_dynamics_summary(res, data))
    console.print(_pair_table(res))
    if out is not None:
        for path in write_dynamics_csv(res, out):
            console.print(f"written: {path}")
        if m.spec.sewing is not None:
            _dynamics_figures(m, out, settings, rpm, load_specs, gravity)


def _dynamics_figures(m, out, settings, rpm, load_specs, gravity):
    """The report's dynamics figures for the CLI's settings, written into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    from rich.progress import Progress

    from .report import _Figures
    from .report_dynamics import dynamics_section

    out.mkdir(parents=True, exist_ok=True)
    figs = _Figures(out, m.name)
    with Progress(console=console, transient=True) as progress:
        progress.add_task("dynamics figures", total=None)
        try:
            # the command's settings (the file's defaults unless --input), as its tables
            inputs = {n: math.radians(i.default_deg) for n, i in m.spec.inputs.items()}
            key = dynamics_section(figs, m, inputs={**inputs, **settings}, rpm=rpm,
                                   loads=load_specs, gravity=gravity)
        except (SewmechError, ValueError) as exc:
            _fail(exc)
    from .io import atomic_write

    path = out / f"{m.name}-dynamics-key-figures.csv"
    with atomic_write(path) as fh:
        key.to_csv(fh, index=False, float_format="%.10g")
    console.print(f"written: {path} and {len(figs.blocks)} figures (PNG, SVG, CSV) in {out}")


def _dynamics_summary(res, data) -> Table:
    rows = data["positions"]
    rpm = res.kin.omega_shaft[0] * 60 / (2 * math.pi)
    table = Table(title=f"{res.machine.name}: inverse dynamics over {len(rows)} positions"
                        f" ({rpm:g} rpm, gravity {'on' if res.gravity else 'off'},"
                        f" loads: {', '.join(res.load_names) or 'none'})")
    for col in ("quantity", "unit", "min", "max", "at phi, deg (max |.|)"):
        table.add_column(col, justify="left" if col in ("quantity", "unit") else "right")
    phi = res.phi_deg

    def add(label, unit, values):
        values = np.asarray(values, dtype=float)
        if values.ndim == 2:
            values = np.linalg.norm(values, axis=-1)
            label = f"|{label}|"
        k = int(np.nanargmax(np.abs(values)))
        table.add_row(label, unit, f"{np.nanmin(values):.4g}", f"{np.nanmax(values):.4g}",
                      f"{phi[k]:g}")

    add("input torque", "N m", [r["input_torque_Nm"] for r in rows])
    add("input power", "W", [r["input_power_W"] for r in rows])
    add("kinetic energy", "J", [r["kinetic_energy_J"] for r in rows])
    add("reduced inertia J(phi)", "kg m^2", [r["reduced_inertia_kgm2"] for r in rows])
    add("shaking force", "N", [r["shaking_force_N"] for r in rows])
    add("shaking moment", "N m", [r["shaking_moment_Nm"] for r in rows])
    if rows and rows[0]["bearing_front_N"] is not None:
        add("front bearing", "N", [r["bearing_front_N"] for r in rows])
        add("rear bearing", "N", [r["bearing_rear_N"] for r in rows])
    for name, values in res.setting_torques.items():
        add(f"torque holding '{name}'", "N m", values * 1e-3)
    return table


def _pair_table(res) -> Table:
    table = Table(title="pairs: largest force (N) or driving torque (N m) over the cycle")
    for col in ("pair", "kind", "links (action of first on second)", "max", "at phi, deg"):
        table.add_column(col, justify="right" if col in ("max", "at phi, deg") else "left")
    for pair in res.pairs:
        mag = res.magnitude(pair.name) * (1e-3 if pair.kind == "driver" else 1.0)
        k = int(np.nanargmax(mag))
        table.add_row(pair.name, pair.kind, " -> ".join(pair.links), f"{mag[k]:.4g}",
                      f"{res.phi_deg[k]:g}")
    return table


@app.command("feed")
def feed_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="machine name or TOML file"),
    step_mm: float = typer.Option(0.5, help="stitch-length step of the scale marks, mm"),
    as_json: bool = typer.Option(False, "--json", help="print the figures as JSON to stdout"),
):
    """Stitch length, lift and timing of the feed dog; scale-plate marks; feed-cam phase."""
    from . import feed as FD

    m = _load(machine)
    try:
        lo, hi = FD.regulator_range_deg(m)
        zero = m.spec.inputs[m.spec.sewing.regulator].default_deg
        cyc = FD.feed_cycles(m, [lo, zero, hi]).to_pandas()
        marks = FD.scale_marks(m, step_mm)
        timing = FD.set_feed_timing(m, 0.0) if m.spec.sewing.feed_cam else None
    except (SewmechError, ValueError) as exc:
        _fail(exc)
    phase_now = next((u.phase_deg for u in m.spec.units if timing and
                      u.name == m.spec.sewing.feed_cam), None)
    if as_json:
        rows = cyc.astype(object).where(cyc.notna(), None)  # JSON has no NaN: null
        json.dump({"machine": m.name, "settings": rows.to_dict(orient="records"),
                   "scale_marks": [{"stitch_mm": k.stitch_mm, "regulator_deg": k.regulator_deg}
                                   for k in marks],
                   "feed_cam_phase_deg": phase_now,
                   "feed_cam_phase_for_mid_feed_at_top_deg":
                       timing.phase_deg if timing else None}, sys.stdout)
        sys.stdout.write("\n")
        return
    table = Table(title=f"{m.name}: feed dog (angles in deg of shaft, lengths mm)")
    cols = ("regulator_deg", "stitch_mm", "lift_mm", "rise_deg", "top_deg", "mid_feed_deg",
            "fall_deg")
    for c in cols:
        table.add_column(c, justify="right")
    for row in cyc.itertuples():
        table.add_row(*(f"{getattr(row, c):.4g}" for c in cols))
    console.print(table)
    mt = Table(title=f"scale-plate marks every {step_mm:g} mm")
    mt.add_column("stitch [mm]", justify="right")
    mt.add_column("regulator [deg]", justify="right")
    for k in marks:
        mt.add_row(f"{k.stitch_mm:+.2f}", f"{k.regulator_deg:+.4f}")
    console.print(mt)
    if timing is not None:
        console.print(f"feed cam phase: {phase_now:g} deg in the file; {timing.phase_deg:.4f}"
                      " deg puts the middle of the feed stroke at the top of lift")


@app.command("embroidery-take-up")
def embroidery_cmd(
    alpha_deg: float = typer.Option(10.0, help="frame line AD from +x, degrees"),
    beta_deg: float = typer.Option(35.0, help="DE from DC (clockwise), degrees"),
    points: int = typer.Option(12, help="equally spaced positions from phi = 0"),
    machine: str = typer.Option("embroidery-131", help="machine name or TOML file"),
    as_json: bool = typer.Option(False, "--json", help='print {"phi_deg": [...], "L_mm": [...]}'),
    out: Path = typer.Option(None, help="without --json: also save the figure (PNG) here"),
):
    """Thread drawn L(phi) = l_max - l by the embroidery take-up for one (alpha, beta)."""
    from . import embroidery as EM

    if points < 2:
        _fail(ValueError(f"--points must be at least 2, got {points}"))
    m = _load(machine)
    try:
        phi, L = EM.thread_drawn(m, alpha_deg, beta_deg, n_points=points)
    except (SewmechError, ValueError, KeyError) as exc:
        _fail(exc)
    if not np.isfinite(L).all():
        _fail(ValueError(f"the take-up cannot be assembled at alpha = {alpha_deg:g} deg,"
                         f" beta = {beta_deg:g} deg"))
    if as_json:
        json.dump({"phi_deg": phi.tolist(), "L_mm": L.tolist()}, sys.stdout)
        sys.stdout.write("\n")
        return
    table = Table(title=f"{m.name}: thread drawn, alpha {alpha_deg:g} deg, beta {beta_deg:g} deg")
    table.add_column("phi [deg]", justify="right")
    table.add_column("L [mm]", justify="right")
    for a, b in zip(phi, L):
        table.add_row(f"{a:g}", f"{b:.2f}")
    console.print(table)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fphi, fL = EM.thread_drawn(m, alpha_deg, beta_deg, n_points=360)
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(fphi, fL, lw=1.6)
    ax.plot(phi, L, "o", ms=4)
    ax.set_xlabel("phi [deg] (0: needle top dead centre)")
    ax.set_ylabel("thread drawn L [mm]")
    ax.set_title(f"{m.name}: alpha {alpha_deg:g} deg, beta {beta_deg:g} deg")
    ax.grid(True, alpha=0.3)
    from .io import atomic_write

    path = (out or Path("out")) / f"{m.name}-L-a{alpha_deg:g}-b{beta_deg:g}.png"
    with atomic_write(path, "wb", encoding=None) as fh:
        fig.savefig(fh, format="png", dpi=120)
    plt.close(fig)
    console.print(f"figure: {path}")


@app.command("report")
def report_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="machine name or TOML file"),
    out: Path = typer.Option(Path("out/report"), help="output directory (replaced as a whole)"),
    step_deg: float = typer.Option(1.0, help="shaft-angle step of the diagrams, degrees"),
    compare: list[str] = typer.Option(None, help="machine (name or file) to compare side by"
                                      " side; repeatable (default: the file's [machine] variants)"),
):
    """The main job: DIR/index.html with checks, timing, feed, figures (PNG, SVG), tables (CSV)."""
    import pandas as pd
    from rich.progress import Progress

    from .report import write_report

    m = _load(machine)
    _phi_grid(m, step_deg)  # validates the step
    variants = [_load(v) for v in (compare or m.spec.machine.variants)]
    s = m.spec.sewing
    steps = ["kinematics", "timing checks", "figures"]
    if s is not None and s.feed_dog and s.regulator:
        steps += ["feed trajectories", "stitch curve", "sensitivity"]
    if m.spec.thread is not None and m.spec.thread.bobbin_case_radius:
        steps.append("thread")
    if m.spec.masses:
        steps.append("dynamics")
    if variants:
        steps.append("comparison")
    steps += ["tables", "page"]
    with Progress(console=console, transient=True) as progress:
        task = progress.add_task(f"report {m.name}", total=len(steps))
        try:
            index = write_report(m, out, step_deg=step_deg, variants=variants,
                                 advance=lambda name: progress.update(task, advance=1,
                                                                      description=name))
        except (SewmechError, ValueError) as exc:
            _fail(exc)
    table = Table(title=f"{m.name}: checks")
    for col in ("check", "value", "expected", "result"):
        table.add_column(col)
    for c in pd.read_csv(index.parent / f"{m.name}-checks.csv").itertuples():
        table.add_row(c.check, f"{c.value:.4g} {c.unit}", c.expected,
                      "[green]pass[/]" if c.result == "pass" else "[red]FAIL[/]")
    console.print(table)
    console.print(f"[bold]report:[/] {index.resolve()}")
    console.print(f"  figures (PNG, SVG) and tables (CSV) in {index.parent.resolve()}")


@app.command("demo")
def demo_cmd(out: Path = typer.Option(Path("out/demo"), help="output directory")):
    """Same as `sewmech report jb1-3 --out DIR` (the main job on the default machine)."""
    report_cmd(DEFAULT_MACHINE, out, 1.0, None)


def main():  # pragma: no cover - entry point
    app()

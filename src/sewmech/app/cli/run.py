"""The ``sewmech run`` command: the machine run in time with its motor (start-up from rest, the
steady state, the stop; docs/running.md). Registered on the shared app of
:mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import OptionError
from .common import DEFAULT_MACHINE, SET_HELP, _load, _rpm, _settings, command, console, print_json


def _step(step_deg: float) -> float:
    n = round(360.0 / step_deg) if 0.1 <= step_deg <= 10.0 else 0
    if not (n and math.isclose(n * step_deg, 360.0, rel_tol=1e-9)):
        raise OptionError("--step-deg", f"must divide 360 and be in 0.1 .. 10 deg, got"
                          f" {step_deg:g}", "Give e.g. --step-deg 1 (the default) or 0.5")
    return step_deg


@command("run")
def run_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    rpm: float = typer.Option(None, help="working speed, rev/min: the speed the start-up is"
                              " timed to and a servo's command (default: the file's)"),
    motor: Path = typer.Option(None, help="a motor file (TOML, with its motor table as a machine"
                               " file has it; docs/running.md) instead of the machine file's"
                               " motor"),
    time_s: float = typer.Option(None, "--time-s", help="run the motor this long, s, instead"
                                 " of until the steady state"),
    no_stop: bool = typer.Option(False, "--no-stop", help="end with the steady state (no"
                                 " stop)"),
    phi_deg: float = typer.Option(None, "--phi-deg", help="the shaft's angle at rest before"
                                  " the start, deg (default: the convention's reference"
                                  " angle, e.g. the needle at its top)"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the file's)"),
    loads: Path = typer.Option(None, help="a load file (TOML, its loads as a machine file has"
                               " them) that replaces the machine file's loads"),
    no_loads: bool = typer.Option(False, "--no-loads", help="no process loads (no-load run)"),
    gravity: bool = typer.Option(True, "--gravity/--no-gravity", help="weights of the links"),
    step_deg: float = typer.Option(1.0, help="shaft-angle grid of the force analysis' tables,"
                                   " deg"),
    as_json: bool = typer.Option(False, "--json", help="print the run as JSON (time_s,"
                                 " omega_rad_s, ..., time_to_speed_s, delta_run,"
                                 " delta_energy)"),
    out: Path = typer.Option(None, help="also write the run (CSV) and its figures (PNG, SVG,"
                             " CSV) here"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """The machine run in time: start-up from rest with its motor, the steady state, the stop;
    the time to reach the working speed and the speed fluctuation against the energy method."""
    from ...engine.motor import load_motor_file
    from ...engine.running import machine_motor, run
    from ...engine.spec import load_load_file

    m = _load(machine, sets)
    settings = _settings(m, inputs)
    rpm = _rpm(rpm)
    step_deg = _step(step_deg)
    if time_s is not None and not 1e-3 <= time_s <= 1e4:  # (a NaN fails too)
        raise OptionError("--time-s", f"must be in 0.001 .. 10000 s, got {time_s:g}",
                          "Give e.g. --time-s 2, or leave it out to run to the steady state")
    if phi_deg is not None and not abs(phi_deg) <= 1e6:
        raise OptionError("--phi-deg", f"must be a finite angle in deg, got {phi_deg}")
    if no_loads and loads is not None:
        raise OptionError("--no-loads", f"and --loads {loads} contradict each other (no process"
                          " loads, and the loads of a file)", "Give one of them")
    load_specs = [] if no_loads else (load_load_file(loads) if loads is not None else None)
    if load_specs:
        m.check_loads(load_specs, str(loads))
    mo = load_motor_file(motor) if motor is not None else machine_motor(m)
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="run")
    r = run(m, motor=mo, rpm=rpm, inputs=settings or None, loads=load_specs, gravity=gravity,
            run_time=time_s, stop=not no_stop, step_deg=step_deg,
            phi0=None if phi_deg is None else math.radians(phi_deg))
    if as_json:
        print_json(run_to_dict(r))
        return
    console.print(_summary(r))
    if out is not None:
        n_figs = _write(r, out, settings, load_specs, gravity)
        console.print(f"written: {out / f'{m.name}-run.csv'},"
                      f" {out / f'{m.name}-run-key-figures.csv'} and {n_figs} figures (PNG,"
                      f" SVG, CSV) in {out}")


def run_to_dict(r) -> dict:
    """The run as JSON: SI units named in the keys."""
    s = r.steady
    return {
        "machine": r.machine.name,
        "motor": r.motor.to_json(),
        "rpm": r.rpm,
        "phi0_deg": math.degrees(r.phi0),
        "time_s": r.time.tolist(),
        "phi_rad": r.phi.tolist(),
        "omega_rad_s": r.omega.tolist(),
        "motor_speed_rad_s": r.motor_speed.tolist(),
        "motor_torque_Nm": (r.motor_torque * 1e-3).tolist(),
        "motor_power_W": (r.motor_power * 1e-3).tolist(),
        "belt_torque_Nm": (r.belt_torque * 1e-3).tolist(),
        "stopping": (r.phase == 1).tolist(),
        "time_to_speed_s": r.time_to_speed,
        "steady": {"t_start_s": s.t_start, "t_end_s": s.t_end, "mean_rpm": s.mean_rpm,
                   "settled": s.settled, "turn_change": s.change if math.isfinite(s.change)
                   else None},
        "delta_run": s.delta,
        "delta_energy": r.delta_energy if r.energy is not None else None,
        "stop_start_s": r.stop_start if bool((r.phase == 1).any()) else None,
        "time_to_stop_s": r.time_to_stop,
        "events": [{"time_s": t, "what": what} for t, what in r.events],
        "tables": {"step_deg": r.tables.step_deg, "top_rpm": r.tables.w_top * 30 / math.pi,
                   "max_acceleration_rad_s2": r.tables.e_max,
                   "friction_with_acceleration": r.tables.friction,
                   "positions": r.tables.positions},
        "steps": r.steps,
    }


def _summary(r) -> Table:
    s = r.steady
    table = Table(title=f"{r.machine.name}: the run in time with its {r.motor.describe()}")
    for col in ("quantity", "value", "unit"):
        table.add_column(col, justify="left" if col != "value" else "right")

    def row(q, v, unit, fmt=".4g"):
        table.add_row(q, "none" if v is None else format(v, fmt), unit)

    row("working speed", r.rpm, "rpm", "g")
    row("time to reach it (from rest)", r.time_to_speed, "s")
    row("steady speed (mean over the last turn)", s.mean_rpm, "rpm", ".6g")
    if not s.settled:
        row("  not settled: the last turn's change", s.change, "1", ".2g")
    row("speed fluctuation, run in time (delta_run)", s.delta, "1")
    if r.energy is not None:
        row("speed fluctuation, energy method (delta_energy)", r.delta_energy, "1")
        row("  delta_run / delta_energy - 1", s.delta / r.delta_energy - 1.0, "1", ".3g")
    row("largest motor torque", float(np.abs(r.motor_torque).max()) * 1e-3, "N m")
    row("largest motor power", float(np.abs(r.motor_power).max()) * 1e-3, "W")
    from ..report.running import _steady_power

    row("mean motor power, steady turn", _steady_power(r) * 1e-3, "W")
    if bool((r.phase == 1).any()):
        if r.time_to_stop is not None:
            row("time to stop (below 1 % of the working speed)", r.time_to_stop, "s")
        else:
            row("the stop: not below 1 % of the working speed after (nothing takes the"
                " energy out)", float(r.time[-1] - r.stop_start), "s")
    for t, what in r.events:
        table.add_row(escape(what), format(t, ".4g"), "s")
    return table


def _write(r, out: Path, settings, load_specs, gravity) -> int:
    """The run's CSV and figures, written into ``out``; returns how many figures."""
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from ..drawing.figures import Figures, figure_pool
    from ..files.io import atomic_write
    from ..files.outdir import output_dir
    from ..report.running import running_section

    m = r.machine
    pool = figure_pool()
    try:
        with output_dir(out, command="run") as root:
            figs = Figures(root, m.name, pool)
            key = running_section(figs, m, result=r)["table"]
            _ = figs.blocks  # every figure written
            table = pd.DataFrame({
                "time_s": r.time, "phi_rad": r.phi, "omega_rad_s": r.omega,
                "shaft_rpm": r.rpm_curve, "epsilon_rad_s2": r.epsilon,
                "motor_rpm": r.motor_speed * 30 / math.pi,
                "motor_torque_Nm": r.motor_torque * 1e-3,
                "motor_power_W": r.motor_power * 1e-3, "belt_torque_Nm": r.belt_torque * 1e-3,
                "stopping": r.phase == 1})
            with atomic_write(root / f"{m.name}-run.csv") as fh:
                table.to_csv(fh, index=False, float_format="%.10g")
            with atomic_write(root / f"{m.name}-run-key-figures.csv") as fh:
                key.to_csv(fh, index=False, float_format="%.10g")
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    return figs.figure_count

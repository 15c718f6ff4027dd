"""The analysis commands of the ``sewmech`` command line: ``machines``, ``check``,
``kinematics``, ``dynamics``, ``feed``, ``embroidery-take-up``, ``report`` and ``demo``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import AnalysisError, OptionError, SewmechError
from ...engine.machine import Machine, file_value, load_machine, shipped_machines
from ..display import is_round_off, number
from .common import (DEFAULT_MACHINE, SET_HELP, Format, _bounded, _load, _phi, _phi_grid, _rpm,
                     _settings, command, console, print_json, process_ends, refuse_unused)


@command("machines")
def machines_cmd():
    """List the machine files shipped with sewmech."""
    table = Table(title="shipped machines")
    for col in ("name", "title", "units", "file"):  # a path is never cut: in a narrow
        table.add_column(col, overflow="fold")       # terminal it goes on to the next line
    for name, path in sorted(shipped_machines().items()):
        m = load_machine(path)
        table.add_row(name, m.spec.machine.title, str(len(m.unit_names)), str(path))
    console.print(table)


@command("check")
def check_cmd(
    file: str = typer.Argument(..., help="machine file (TOML) or shipped name"),
    step_deg: float = typer.Option(5.0, help="grid of the assembly check, deg (assembly between"
                                   " the grid points is proved too)"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
    list_parameters: bool = typer.Option(False, "--parameters", help="also list every"
                                         " parameter: name, value, unit, where in the file"),
):
    """Validate a machine file, prove that it assembles over the whole turn (at every setting
    limit) and check its angle convention."""
    from ...engine.assembly import prove_assembly
    from ...engine.dynamics import force_system
    from ...engine.errors import format_ranges
    from ...engine.extremes import require_reference
    from ...engine.kinematics import kinematics

    m = _load(file, sets)
    phi = _phi_grid(step_deg)
    kinematics(m, phi)  # a failure at a grid point: the located error, with branch hints
    settings = [("", None, None)]  # (label, inputs, params): the default and every limit
    for name, spec in m.spec.inputs.items():
        for label, deg in (("min", spec.min_deg), ("max", spec.max_deg)):
            if deg is not None and deg != spec.default_deg:
                settings.append((f"{name} = {deg:g} deg ({label})",
                                 {name: math.radians(deg)}, None))
    adj = m.spec.thread.adjust if m.spec.thread is not None else None
    if adj is not None:  # the take-up's adjustable dimension, at both ends of its range
        for label, value in (("[thread.adjust] min", adj.min), ("[thread.adjust] max", adj.max)):
            settings.append((f"{adj.parameter} = {value:g} ({label})", None,
                             m.parameters({adj.parameter: value})))
    proofs = []
    for label, inputs, params in settings:
        proof = prove_assembly(m, inputs=inputs, params=params, step_deg=step_deg)
        if not proof.ok:
            f = proof.failures[0]
            at = f" at {label}" if label else ""
            more = f" ({len(proof.failures) - 1} more)" if len(proof.failures) > 1 else ""
            span = format_ranges([(round(f.from_deg, 4), round(f.to_deg, 4))])
            raise SewmechError(m.file, f"cannot be assembled over the whole turn{at}: unit"
                               f" '{f.unit}' fails over phi {span} deg: {f.reason}{more}",
                               "Change the unit's lengths or the positions of the points it"
                               " joins; the margin says by how much")
        proofs.append((label, proof))
    ref = require_reference(m)
    _variants(m, None)  # the file's variants: each a machine the report can compare
    if m.spec.sewing is not None:  # the throat plate and the fabric within the needle's
        from ...sewing.timing import needle_windows  # reach, as the report needs them

        needle_windows(m)
    if m.spec.thread is not None:  # a thread path whose guides never overlap over the turn
        from ...sewing.thread import thread_path

        thread_path(m, phi)
    conv = m.spec.convention
    table = Table(title=f"{m.name}: valid", show_header=False)
    table.add_row("file", m.file)
    if m.changes:
        table.add_row("changed by --set", ", ".join(f"{k} = {v:g}" for k, v in m.changes.items()))
    table.add_row("angle convention", escape(f"phi = {conv.reference_phi_deg:g} deg:"
                                             f" {conv.reference_event} ({ref.text})"))
    table.add_row("points / links / variables", f"{len(m.point_names)} / "
                  f"{len(m.link_names) - 1} / {len(m.variable_names)}")
    table.add_row("units", ", ".join(f"{n} ({t})" for n, t in zip(m.unit_names, m.unit_types)))
    table.add_row("branches", ", ".join(f"{k}: {v:+d}" for k, v in m.branches.items()) or "-")
    table.add_row("parameters", str(len(m.parameter_names)))
    first = proofs[0][1]
    span = ("the whole turn" if first.turns == 1 else
            f"{first.turns} turns (the machine's cycle)")
    text = f"over {span}, proved (grid of the margins' minima: {step_deg:g} deg)"
    if not first.periodic:
        text += ("; the cranks' ratios do not repeat within 100 turns, so only the first turn"
                 " is proved")
    if len(proofs) > 1:
        text += " at the working setting and at " + ", ".join(lb for lb, _ in proofs[1:])
    if proofs[0][1].loop_steps:
        from ...engine.assembly import LOOP_STEP_DEG

        text += (f"; loop units ({', '.join(proofs[0][1].loop_units)}) continued in"
                 f" {LOOP_STEP_DEG:g} deg steps without a branch jump")
    table.add_row("assembles", escape(text))
    table.add_row("force analysis", escape(force_system(m)))
    console.print(table)
    console.print(_margin_table(m, proofs))
    from ...sewing.checks import check_contacts

    contacts = check_contacts(m)  # at the working speed and setting
    if contacts:
        ct = Table(title=f"{m.name}: one-sided contacts at the working speed and setting")
        for col in ("check", "least force, N", "expected", "passes"):
            ct.add_column(col, justify="right" if col == "least force, N" else "left")
        for c in contacts:
            ct.add_row(escape(c.name), f"{c.value:.4g}", escape(c.expected),
                       "yes" if c.passed else "[bold red]no[/]")
        console.print(ct)
    if list_parameters:
        _print_parameters(m)


def _margin_table(m: Machine, proofs) -> Table:
    """The smallest assembly margin of every closed-form unit over the turn and settings."""
    table = Table(title=f"{m.name}: assembly margins", caption="how far each unit is from"
                  " failing to assemble: the smallest over the turn and the settings")
    for col in ("unit", "condition", "margin [mm]", "at phi [deg]", "setting"):  # (escaped:
        # rich would take [mm] for a style)
        table.add_column(escape(col), justify="right" if col.startswith(("margin", "at"))
                         else "left")
    worst: dict[str, tuple] = {}
    for label, proof in proofs:
        for g in proof.margins:
            if g.unit not in worst or g.value_mm < worst[g.unit][0].value_mm:
                worst[g.unit] = (g, label or "default")
    for g, label in worst.values():
        table.add_row(g.unit, escape(g.condition), f"{g.value_mm:.4g}", f"{g.phi_deg:.4g}",
                      escape(label))
    return table


def _print_parameters(m: Machine) -> None:
    """Every parameter, one per line (names are never wrapped, so they can be copied)."""
    rows = []
    for name, value, unit in zip(m.parameter_names, m.defaults, m.parameter_units):
        loc = m.parameter_location(name)
        where = f"[{loc[0]}] {loc[1]}" if loc else "(built from the cam's constant_width)"
        x, shown_unit = file_value(value, unit)
        rows.append((name, f"{x:.6g}", shown_unit, where))
    w = [max(len(r[k]) for r in rows) for k in range(3)]
    console.print(f"{m.name}: parameters (names for --set and Machine.parameters; values as in"
                  " the file)", highlight=False)
    for name, shown, unit, where in rows:
        console.print(escape(f"  {name:<{w[0]}}  {shown:>{w[1]}} {unit:<{w[2]}}  {where}"),
                      highlight=False, soft_wrap=True)


def _channels(res):
    """Every channel of a kinematics result as (label, unit, x, rate, accel, scale, size): the
    values in the unit shown (``scale`` converts from the internal one) and ``size``, the size
    of the quantity in internal units, below whose round-off a value reads 0 (mm: the largest
    distance of any point from the origin; rad: a turn)."""
    w = float(np.max(np.abs(res.omega_shaft))) if res.phi.size else 0.0
    pts = [res.point(pt).p for pt in res.point_names]
    length = max([float(np.nanmax(np.abs(p))) for p in pts if p.size] + [1.0])
    turn = 2.0 * math.pi
    out = []
    for pt in res.point_names:
        m = res.point(pt)
        for c, ax in (("x", 0), ("y", 1)):
            out.append((f"{pt}.{c}", "mm", m.p[:, ax], m.v[:, ax], m.a[:, ax], 1.0, length))
    for lk in res.link_names:
        if lk == "frame":
            continue
        m = res.link(lk)
        th = np.unwrap(m.theta)
        th -= turn * np.round(th[0] / turn)  # start in (-180, 180] deg
        out.append((f"theta {lk}", "deg", th, m.omega, m.epsilon, 180.0 / math.pi, turn))
    for var in res.variable_names:
        m = res.variable(var)
        rad = m.unit == "rad"
        out.append((f"q {var}", "deg" if rad else m.unit, m.q, m.q_dot, m.q_ddot,
                    180.0 / math.pi if rad else 1.0, turn if rad else length))
    return out, w


def _summary(res) -> Table:
    """A whole turn: each channel's least and greatest value and its largest rate and
    acceleration; a channel is called constant only when it neither moves nor has a rate or an
    acceleration (each at the round-off of its size, :mod:`sewmech.app.display`)."""
    rpm = res.omega_shaft[0] * 60 / (2 * math.pi) if res.phi.size else 0.0
    table = Table(title=f"{res.machine}: kinematics over {res.phi.size} positions ({rpm:g} rpm)",
                  caption="rate: unit/s, accel: unit/s^2; link angles are unwrapped"
                          " (continuous over the turn, so they may pass 360 deg)")
    for col in ("channel", "unit", "min", "max", "max |rate|", "max |accel|"):
        table.add_column(col, justify="right" if col not in ("channel", "unit") else "left",
                         overflow="fold")  # long names wrap instead of being cut
    if not res.phi.size:
        return table
    channels, w = _channels(res)
    for label, unit, x, dx, ddx, scale, size in channels:
        rate, acc = float(np.abs(dx).max()), float(np.abs(ddx).max())
        if (is_round_off(float(np.ptp(x)), size) and is_round_off(rate, size * w)
                and is_round_off(acc, size * w * w)):
            table.add_row(label, unit, number(x[0] * scale, size * scale, 7), "(constant)",
                          "0", "0")
            continue
        table.add_row(label, unit, number(x.min() * scale, size * scale, 7),
                      number(x.max() * scale, size * scale, 7),
                      number(rate * scale, size * w * scale), number(acc * scale,
                                                                     size * w * w * scale))
    return table


def _values(res) -> Table:
    """At the shaft angles asked for (--phi-deg): each channel's value, rate and acceleration
    at each angle, one row an angle."""
    rpm = res.omega_shaft[0] * 60 / (2 * math.pi) if res.phi.size else 0.0
    phi_deg = np.degrees(res.phi)
    at = ", ".join(f"{p:g}" for p in phi_deg)
    table = Table(title=f"{res.machine}: kinematics at phi = {at} deg ({rpm:g} rpm)",
                  caption="value: unit, rate: unit/s, accel: unit/s^2; link angles in"
                          " (-180, 180] deg")
    for col in ("channel", "unit", "phi, deg", "value", "rate", "accel"):
        table.add_column(col, justify="right" if col not in ("channel", "unit") else "left",
                         overflow="fold")
    if not res.phi.size:
        return table
    channels, w = _channels(res)
    several = res.phi.size > 1
    for label, unit, x, dx, ddx, scale, size in channels:
        if unit == "deg" and label.startswith("theta "):
            x = np.angle(np.exp(1j * x))  # each angle on its own, not unwrapped across them
            x = np.where(x <= -math.pi, x + 2.0 * math.pi, x)
        for k in range(res.phi.size):
            table.add_row(label if k == 0 else "", unit if k == 0 else "", f"{phi_deg[k]:g}",
                          number(x[k] * scale, size * scale, 7),
                          number(dx[k] * scale, size * w * scale),
                          number(ddx[k] * scale, size * w * w * scale),
                          end_section=several and k == res.phi.size - 1)
    return table


@command("kinematics")
def kinematics_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    step_deg: float = typer.Option(5.0, help="shaft-angle step, deg"),
    phi_deg: list[float] = typer.Option(None, "--phi-deg", help="only at these shaft angles,"
                                        " deg; repeatable: each channel's value, rate and"
                                        " acceleration at each (default: a turn in --step-deg"
                                        " steps, summarised)"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    out: Path = typer.Option(None, help="write the channels into this directory"),
    format: Format = typer.Option(Format.csv, "--format", help="file format with --out"),
    as_json: bool = typer.Option(False, "--json", help="print every channel as JSON to stdout"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=20; repeatable (default: the file's)"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Positions, velocities and accelerations of every point, link and joint variable."""
    from ...engine.kinematics import kinematics
    from ..files.io import kinematics_to_dict, write_kinematics_csv, write_kinematics_json
    from ..files.outdir import output_dir

    if out is None:
        refuse_unused("format", "--format", "is the format of the file --out writes, and no"
                      " --out is given: nothing would be written", "Give --out DIR, or leave"
                      " --format out")
    m = _load(machine, sets)
    settings = _settings(m, inputs)
    phi = _phi(step_deg, phi_deg)
    rpm = _rpm(rpm)
    if out is not None:
        with output_dir(out, command="kinematics", machine=m.name) as root:
            res = kinematics(m, phi, rpm=rpm, inputs=settings or None)
            path = root / f"{m.name}-kinematics.{format.value}"
            (write_kinematics_csv if format is Format.csv else write_kinematics_json)(res, path)
    else:
        res = kinematics(m, phi, rpm=rpm, inputs=settings or None)
    if as_json:
        print_json(kinematics_to_dict(res))
        return
    console.print(_summary(res) if not phi_deg else _values(res))
    if out is not None:
        console.print(f"written: {out / f'{m.name}-kinematics.{format.value}'}")


@command("dynamics")
def dynamics_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    step_deg: float = typer.Option(5.0, help="shaft-angle step, deg (5: the report's 72"
                                   " positions)"),
    phi_deg: list[float] = typer.Option(None, "--phi-deg", help="only at these shaft angles,"
                                        " deg; repeatable (default: a turn in --step-deg steps)"),
    as_json: bool = typer.Option(False, "--json", help="print the per-position figures as JSON"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the file's)"),
    loads: Path = typer.Option(None, help="a load file ([[loads]] tables) that replaces the"
                               " machine file's loads"),
    no_loads: bool = typer.Option(False, "--no-loads", help="no process loads (no-load run)"),
    gravity: bool = typer.Option(True, "--gravity/--no-gravity", help="weights of the links"),
    out: Path = typer.Option(None, help="also write the per-position table and the pair"
                             " forces (CSV) and the dynamics figures (PNG, SVG, CSV) here"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Inverse dynamics: driving torque, pair forces, shaking force and moment, energies,
    upper-shaft bearing reactions."""
    from ...engine.contacts import contact_margins
    from ...engine.dynamics import inverse_dynamics
    from ...engine.spec import load_load_file
    from ..files.io import dynamics_to_dict, write_dynamics_csv
    from ..files.outdir import output_dir

    m = _load(machine, sets)
    settings = _settings(m, inputs)
    phi = _phi(step_deg, phi_deg)
    rpm = _rpm(rpm)
    if no_loads and loads is not None:
        raise OptionError("--no-loads", f"and --loads {loads} contradict each other (no process"
                          " loads, and the loads of a file)", "Give one of them")
    load_specs = [] if no_loads else (load_load_file(loads) if loads is not None else None)
    if load_specs:
        m.check_loads(load_specs, str(loads))
    has_loads = bool(m.spec.loads if load_specs is None else load_specs)
    if not m.spec.masses and not has_loads:
        raise AnalysisError(m.file, "the machine has no [masses] tables and no loads: every"
                            " force would be zero", "Add [masses.LINK] tables (docs/machine-"
                            "files.md) or a load file (--loads); `sewmech kinematics` needs"
                            " neither")
    res = inverse_dynamics(m, phi, rpm=rpm, inputs=settings or None, gravity=gravity,
                           loads=load_specs)
    contacts = contact_margins(m, rpm=rpm, inputs=settings or None, loads=load_specs,
                               gravity=gravity)
    data = dynamics_to_dict(res, contacts)
    if as_json:
        print_json(data)
        return
    if not m.spec.masses:
        console.print("[yellow]note:[/] " + escape("the machine has no [masses] tables: no"
                                                   " inertia forces or weights, only the loads"))
    console.print(_dynamics_summary(res, data))
    console.print(_pair_table(res))
    if contacts:
        console.print(_contact_table(contacts))
    drive = data["load_dissipation_W"]
    if drive is not None and drive < -1e-6 * float(np.abs(res.input_power).max()) * 1e-3:
        console.print("[yellow]note:[/] " + escape(
            f"the process loads put {-drive:.4g} W into the machine over the turn: a process"
            " resists the machine, so their windows or conditions do not follow it. Give them"
            " conditions (`when`, docs/dynamics.md) that hold while their process acts"))
    if out is not None:
        with output_dir(out, command="dynamics", machine=m.name) as root:
            written = write_dynamics_csv(res, root)
            n_figs = 0
            if m.spec.sewing is not None:
                n_figs = _dynamics_figures(m, root, settings, rpm, load_specs, gravity)
        for path in written:
            console.print(f"written: {out / path.name}")
        if n_figs:
            console.print(f"written: {out / f'{m.name}-dynamics-key-figures.csv'} and {n_figs}"
                          f" figures (PNG, SVG, CSV) in {out}")


def _dynamics_figures(m, out, settings, rpm, load_specs, gravity) -> int:
    """The report's dynamics figures for the CLI's settings, written into ``out``; returns
    how many figures."""
    import matplotlib

    matplotlib.use("Agg")
    from rich.progress import Progress

    from ..drawing.figures import Figures, figure_pool
    from ..files.io import atomic_write
    from ..report.dynamics import dynamics_section

    pool = figure_pool()
    try:
        figs = Figures(out, m.name, pool)
        with Progress(console=console, transient=True,
                      disable=not console.is_terminal) as progress:
            progress.add_task("dynamics figures", total=None)
            # the command's settings (the file's defaults unless --input), as its tables
            inputs = {n: math.radians(i.default_deg) for n, i in m.spec.inputs.items()}
            key = dynamics_section(figs, m, inputs={**inputs, **settings}, rpm=rpm,
                                   loads=load_specs, gravity=gravity)
            figs.blocks  # every figure written
        with atomic_write(out / f"{m.name}-dynamics-key-figures.csv") as fh:
            key.to_csv(fh, index=False, float_format="%.10g")
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    return figs.figure_count


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
    if res.friction is not None:
        add("friction loss", "W", res.friction_power * 1e-3)
    if res.springs is not None and res.springs.names:
        for j, name in enumerate(res.springs.names):
            torsion = j >= res.springs.n_translational
            add(f"spring '{name}'", "N m" if torsion else "N",
                res.springs.force[..., j] * (1e-3 if torsion else 1.0))
    if data["mean_input_power_W"] is not None:
        table.add_section()
        for key, label in (("mean_input_power_W", "mean input power (over the turn)"),
                           ("friction_loss_W", "friction loss (mean)"),
                           ("damping_loss_W", "dampers' loss (mean)"),
                           ("load_dissipation_W", "loads' dissipation (mean)")):
            table.add_row(label, "W", f"{data[key]:.4g}", "", "")
    return table


def _contact_table(contacts) -> Table:
    table = Table(title="one-sided contacts: least force over the turn at this speed, and the"
                        " speed above which each opens")
    for col in ("contact", "least force, N", "at phi, deg", "margin, N", "holds",
                "opens above, rpm"):
        table.add_column(col, justify="left" if col == "contact" else "right")
    for c in contacts:
        table.add_row(c.name, f"{c.least_force_N:.4g}", f"{c.at_phi_deg:.1f}",
                      f"{c.margin_N:g}", "yes" if c.ok else "[bold red]no[/]",
                      "never (below 100 x this speed)" if c.opens_above_rpm is None
                      else f"{c.opens_above_rpm:.0f}")
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


#: why a figure of the feed table is not defined at a setting (it is NaN there)
FEED_UNDEFINED = {
    "mid_feed_deg": "the dog does not pass the middle of its stroke while above the plate and"
                    " moving with the stitch (no feed at this setting, as at the zero mark)",
    "rise_deg": "the dog's tip never rises through the throat plate at this setting",
    "fall_deg": "the dog's tip never drops through the throat plate at this setting",
    "stitch_mm": "the dog's tip never rises through the throat plate at this setting",
}


@command("feed")
def feed_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="machine name or TOML file"),
    step_mm: float = typer.Option(0.5, help="stitch-length step of the scale marks, mm"),
    as_json: bool = typer.Option(False, "--json", help="print the figures as JSON to stdout"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Stitch length, lift and timing of the feed dog; scale-plate marks; feed-cam phase."""
    from ...sewing import feed as FD

    _bounded("--step-mm", step_mm, 0.01, 10.0, "mm", "0.5")
    m = _load(machine, sets)
    lo, hi = FD.regulator_range_deg(m)
    cyc = FD.feed_cycles(m, [lo, FD.ZERO_MARK_DEG, hi]).to_pandas()  # reverse, zero, forward
    marks = FD.scale_marks(m, step_mm)
    timing, timing_note = None, None
    if m.spec.sewing.feed_cam:
        try:
            timing = FD.set_feed_timing(m, 0.0)
        except AnalysisError as exc:  # the figures above stand; the phase is not defined
            timing_note = f"not defined: {exc.message}"
    phase_now = next((u.phase_deg for u in m.spec.units
                      if m.spec.sewing.feed_cam and u.name == m.spec.sewing.feed_cam), None)
    if as_json:
        rows = cyc.astype(object).where(cyc.notna(), None).to_dict(orient="records")
        for row in rows:  # JSON has no NaN: null, and why beside it
            for key in list(row):
                if row[key] is None and key in FEED_UNDEFINED:
                    row[f"{key}_note"] = "not defined: " + FEED_UNDEFINED[key]
        data = {"machine": m.name, "settings": rows,
                "scale_marks": [{"stitch_mm": k.stitch_mm,
                                 "regulator_deg": k.regulator_deg} for k in marks],
                "feed_cam_phase_deg": phase_now,
                "feed_cam_phase_for_mid_feed_at_top_deg": timing.phase_deg if timing else None}
        if timing_note is not None:
            data["feed_cam_phase_for_mid_feed_at_top_deg_note"] = timing_note
        print_json(data)
        return
    table = Table(title=f"{m.name}: feed dog (angles in deg of shaft, lengths mm)")
    cols = ("regulator_deg", "stitch_mm", "lift_mm", "rise_deg", "top_deg", "mid_feed_deg",
            "fall_deg")
    for c in cols:
        table.add_column(c, justify="right")
    undefined = {}
    for row in cyc.itertuples():
        cells = []
        for c in cols:
            x = getattr(row, c)
            if math.isnan(x):
                undefined.setdefault(c, []).append(f"{row.regulator_deg:g}")
            cells.append("undefined" if math.isnan(x) else f"{x:.4g}")
        table.add_row(*cells)
    console.print(table)
    for c, settings in undefined.items():
        console.print(escape(f"  {c} undefined at regulator {', '.join(settings)} deg:"
                             f" {FEED_UNDEFINED.get(c, 'it cannot be formed there')}"),
                      highlight=False)
    mt = Table(title=f"scale-plate marks every {step_mm:g} mm")
    mt.add_column(escape("stitch [mm]"), justify="right")
    mt.add_column(escape("regulator [deg]"), justify="right")
    for k in marks:
        mt.add_row(f"{k.stitch_mm:+.2f}", f"{k.regulator_deg:+.4f}")
    console.print(mt)
    if timing is not None:
        console.print(f"feed cam phase: {phase_now:g} deg in the file; {timing.phase_deg:.4f}"
                      " deg puts the middle of the feed stroke at the top of lift")
    elif timing_note is not None:
        console.print(escape(f"feed cam phase: {phase_now:g} deg in the file; the phase that"
                             " puts the middle of the feed stroke at the top of lift is"
                             f" undefined ({timing_note.removeprefix('not defined: ')})"),
                      highlight=False)


@command("embroidery-take-up")
def embroidery_cmd(
    alpha_deg: float = typer.Option(10.0, help="frame line AD from +x, degrees"),
    beta_deg: float = typer.Option(35.0, help="DE from DC (clockwise), degrees"),
    points: int = typer.Option(12, help="equally spaced positions from phi = 0 (2 .. 3600)"),
    machine: str = typer.Option("embroidery-131", help="machine name or TOML file"),
    as_json: bool = typer.Option(False, "--json", help='print {"phi_deg": [...], "L_mm": [...]}'),
    out: Path = typer.Option(None, help="without --json: also save the figure (PNG) in this"
                             " directory"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Thread drawn L(phi) = l_max - l by the embroidery take-up for one (alpha, beta)."""
    from ...sewing import embroidery as EM

    if as_json and out is not None:
        raise OptionError("--out", f"{out} and --json contradict each other (the figure is"
                          " drawn for the table; --json prints the numbers and writes"
                          " nothing)", "Give one of them")
    _bounded("--alpha-deg", alpha_deg, -360.0, 360.0, "deg", "10")
    _bounded("--beta-deg", beta_deg, -360.0, 360.0, "deg", "35")
    _bounded("--points", points, 2, 3600, "positions", "12")
    m = _load(machine, sets)
    phi, L = EM.thread_drawn(m, alpha_deg, beta_deg, n_points=points)
    if not np.isfinite(L).all():
        raise OptionError("--alpha-deg/--beta-deg", f"the take-up of {m.file} cannot be"
                          f" assembled at alpha = {alpha_deg:g} deg, beta = {beta_deg:g} deg",
                          "The paper's study uses alpha 5 .. 30 deg and beta 33 .. 35 deg")
    if as_json:
        print_json({"phi_deg": phi.tolist(), "L_mm": L.tolist()})
        return
    table = Table(title=f"{m.name}: thread drawn, alpha {alpha_deg:g} deg, beta {beta_deg:g} deg")
    table.add_column(escape("phi [deg]"), justify="right")
    table.add_column(escape("L [mm]"), justify="right")
    for a, b in zip(phi, L):
        table.add_row(f"{a:g}", f"{b:.2f}")
    console.print(table)
    if out is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..files.io import atomic_write
    from ..files.outdir import output_dir

    fphi, fL = EM.thread_drawn(m, alpha_deg, beta_deg, n_points=360)
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(fphi, fL, lw=1.6)
    ax.plot(phi, L, "o", ms=4)
    ax.set_xlabel("phi [deg] (0: needle top dead centre)")
    ax.set_ylabel("thread drawn L [mm]")
    ax.set_title(f"{m.name}: alpha {alpha_deg:g} deg, beta {beta_deg:g} deg")
    ax.grid(True, alpha=0.3)
    name = f"{m.name}-L-a{alpha_deg:g}-b{beta_deg:g}.png"
    try:
        with output_dir(out, command=f"embroidery {name}") as root:
            with atomic_write(root / name, "wb", encoding=None) as fh:
                fig.savefig(fh, format="png", dpi=120)
    finally:
        plt.close(fig)
    console.print(f"figure: {out / name}")


@command("report")
def report_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="machine name or TOML file"),
    out: Path = typer.Option(Path("out/report"), help="output directory: new, empty, or one"
                             " that sewmech wrote (its files are replaced, no other file is"
                             " touched)"),
    step_deg: float = typer.Option(1.0, help="shaft-angle step of the diagrams, degrees"),
    compare: list[str] = typer.Option(None, help="machine (name or file) to compare side by"
                                      " side; repeatable (default: the file's [machine] variants)"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """The main job: DIR/index.html with checks, timing, feed, figures (PNG, SVG), tables (CSV)."""
    import pandas as pd
    from rich.progress import Progress

    from ...sewing.timing import roles
    from ..display import number_in
    from ..files.outdir import preflight
    from ..report import write_report

    _phi_grid(step_deg, min_step=0.1)  # validates the step
    m = _load(machine, sets)
    roles(m)  # the machine's [sewing] roles, which the report reads
    variants = _variants(m, compare)
    preflight(out, command="report")
    s = m.spec.sewing
    steps = ["kinematics", "timing checks", "figures"]
    if s is not None and s.feed_dog and s.regulator:
        steps += ["feed trajectories", "stitch curve", "sensitivity"]
    if m.spec.thread is not None and m.spec.thread.bobbin_case_radius:
        steps.append("thread")
    if m.spec.masses:
        steps.append("dynamics")
    if m.counterweights:
        steps.append("balancing")
    if s is not None and s.feed_dog and s.regulator:
        steps.append("accuracy")
    if variants:
        steps.append("comparison")
    steps += ["tables", "page"]
    if process_ends():
        _keep_freed_memory()
    with Progress(console=console, transient=True,
                  disable=not console.is_terminal) as progress:
        task = progress.add_task(f"report {m.name}", total=len(steps))
        index = write_report(m, out, step_deg=step_deg, variants=variants,
                             advance=lambda name: progress.update(task, advance=1,
                                                                  description=name),
                             collect_garbage=not process_ends())
    table = Table(title=f"{m.name}: checks")
    for col in ("check", "value", "expected", "result"):
        table.add_column(col)
    for c in pd.read_csv(index.parent / f"{m.name}-checks.csv").itertuples():
        table.add_row(c.check, f"{number_in(c.value, c.unit, digits=4)} {c.unit}", c.expected,
                      "[green]pass[/]" if c.result == "pass" else "[red]FAIL[/]")
    console.print(table)
    console.print(f"[bold]report:[/] {index.resolve()}")
    console.print(f"  figures (PNG, SVG) and tables (CSV) in {index.parent.resolve()}")


@command("demo")
def demo_cmd(out: Path = typer.Option(Path("out/demo"), help="output directory (as for"
                                      " report)"),
             sets: list[str] = typer.Option(None, "--set", help=SET_HELP)):
    """Same as `sewmech report jb1-3 --out DIR` (the main job on the default machine)."""
    report_cmd.__wrapped__(DEFAULT_MACHINE, out, 1.0, None, sets)


def _variants(m: Machine, compare: list[str] | None) -> list[Machine]:
    """The machines a report compares with ``m``: --compare's (a shipped name or a file, as
    every machine argument), else the file's ``[machine] variants`` (a file named relative to
    the machine file, else a shipped name). Each is loaded and its ``[sewing]`` roles (which
    the comparison reads) checked where it is named; comparing the machine with itself, or
    with one machine twice, is refused."""
    from ...sewing.timing import roles

    if compare:
        named = [(f"--compare {c}", c, c) for c in compare]
    else:
        base = Path(m.file).parent
        named = []
        for i, v in enumerate(m.spec.machine.variants):
            where = f"{m.file}: [machine] variants[{i}]"
            beside = base / Path(v).expanduser()
            if not beside.is_file() and v not in shipped_machines():
                raise SewmechError(where, f"{v}: no such file ({beside}) and no shipped machine"
                                   " of that name", "Give a shipped machine's name ("
                                   + ", ".join(sorted(shipped_machines())) + ") or a machine"
                                   " file (a path relative to this file)")
            named.append((where, v, beside if beside.is_file() else v))
    out: list[Machine] = []
    seen = {str(Path(m.file).resolve()): "the machine reported"} if not m.changes else {}
    for where, name, source in named:
        try:
            v = load_machine(source)
        except SewmechError as exc:
            hint = ("Give a shipped machine's name or a machine file" +
                    ("" if compare else " (a path relative to this file)"))
            raise SewmechError(where, str(exc).rstrip("."), hint) from None
        try:
            roles(v)
        except ValueError as exc:  # (its text says what to add)
            raise SewmechError(where, f"cannot be compared: {exc}") from None
        key = str(Path(v.file).resolve())
        if key in seen:
            raise SewmechError(where, f"{name!r} is {seen[key]} again ({v.file}): the"
                               " comparison would show one machine twice", "Compare with"
                               " another machine, or with a --set variant of this one")
        seen[key] = f"the machine of {where}"
        out.append(v)
    return out


def _keep_freed_memory() -> None:
    """In a ``sewmech report`` process (glibc's malloc): large blocks stay in the heap when
    freed. Not for the long-running commands (``serve``, sweeps): a process that lives on
    would keep what it freed.

    By default glibc gives the top of its heap back to the system whenever more than 128 KiB
    there is free, and maps blocks above its mmap threshold (128 KiB at first) on their own;
    the memory is then taken back page by page, each page zeroed on its first touch. A
    report allocates and frees renderer buffers and arrays of megabytes all the time: 617
    `brk` calls and 174,000 minor page faults. Blocks up to 32 MiB now come from the heap,
    and up to 1 GiB freed at its top is kept: 214 `brk` calls, 129,000 page faults, 0.96x
    the report's CPU, 0.8x its system time, the same peak memory.
    Elsewhere (another C library) nothing changes."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_top_pad, m_mmap_threshold = -1, -2, -3  # glibc's malloc.h
    mallopt(m_mmap_threshold, 32 << 20)
    mallopt(m_trim_threshold, 1 << 30)
    mallopt(m_top_pad, 16 << 20)

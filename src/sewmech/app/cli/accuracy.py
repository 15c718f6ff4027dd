"""The accuracy commands of the ``sewmech`` command line: ``sensitivity`` (exact derivatives of
an output by every parameter) and ``tolerance`` (worst case, RSS, Monte Carlo, contributions,
allocation). Registered on the shared app of :mod:`sewmech.app.cli.common`
when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import OptionError
from ..display import is_round_off, number
from .common import (DEFAULT_MACHINE, SET_HELP, _load, _settings, command, console,
                     print_json, refuse_unused)


#: the sewing metrics ``--output`` accepts besides the position channels (the keys of
#: :data:`sewmech.sewing.gradients.METRICS`)
METRICS = ("stitch_length", "feed_lift", "dog_height_at_needle_plate", "needle_top_deg",
           "take_up_lag_deg", "needle_descent_at_take_up_top", "loop_lift", "shuttle_swing_deg")
#: the metrics read at a stitch-regulator setting (the others at the working setting)
FEED_METRICS = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


#: what --output takes besides the sewing metrics and the channels (docs/design.md)
FAMILY_HELP = (" or a metric over the turn: min:, max:, range:, mean:, rms:CHANNEL,"
               " transmission_angle_min:UNIT, transmission_angle_deviation:UNIT (deg), or a"
               " force metric (peak_torque, rms_torque N m, peak_force:PAIR,"
               " peak_bearing_reaction, peak_shaking_force N, peak_shaking_moment N m, at the"
               " file's speed on a 2 deg grid)")
#: --at: a channel read at an event
AT_HELP = ("read the channel at an event instead of --phi-deg: max:CHANNEL, min:CHANNEL,"
           " rising:CHANNEL=LEVEL or falling:CHANNEL=LEVEL (a position channel; a crossing"
           " the first at or after --phi-deg)")


def _refuse_phi_for_a_metric(output: str, at: str | None = None) -> None:
    """--phi-deg places a position channel (or where a crossing is looked for from); a metric
    is read at its own events or over the whole turn."""
    from ...design.tolerances import is_family_metric

    if output in METRICS or (at is None and is_family_metric(output)):
        refuse_unused("phi_deg", "--phi-deg", f"is the shaft angle of a position channel, and"
                      f" {output} is a metric read at its own events or over the whole turn:"
                      " the angle would be ignored", "Leave --phi-deg out, or give a channel"
                      " such as p_needle.point_y")
    if at is not None and output in METRICS:
        raise OptionError("--at", f"{output} is a metric read at its own events: only a"
                          " channel is read at an event", "Leave --at out, or give a channel")


def _family_setting(m, settings: dict) -> float | None:
    """The stitch-regulator setting (deg) a metric over the turn or at an event is read at,
    from --input: only the regulator may be given (None: the working setting)."""
    s = m.spec.sewing
    regulator = s.regulator if s is not None else None
    other = [k for k in settings if k != regulator]
    if other:
        raise OptionError("--input", f"a metric over the turn or at an event is read at the"
                          f" working setting or at a stitch-regulator setting; '{other[0]}'"
                          " would be ignored", "Leave --input out, or give only the"
                          " regulator" + (f" ({regulator})" if regulator else ""))
    return math.degrees(settings[regulator]) if regulator in settings else None


def _metric(m, name: str, settings: dict) -> tuple[float, np.ndarray, str, dict]:
    """A sewing metric's value, derivatives, unit and event angles (deg)."""
    from ...sewing.gradients import METRICS as FUNCTIONS
    from ...sewing.gradients import require_a_stitch
    from ...sewing.timing import roles

    s = roles(m)
    feed = name in ("stitch_length", "feed_lift", "dog_height_at_needle_plate")
    if feed and (s.regulator is None or s.feed_dog is None):
        raise OptionError("--output", f"machine '{m.name}' has no feed dog and regulator in its"
                          f" [sewing] table: no {name.replace('_', ' ')}",
                          "Choose a position channel")
    if not feed:
        g = FUNCTIONS[name](m, None)
        return g.value, g.d_dparam, g.unit, dict(g.events_deg)
    reg = settings.get(s.regulator)
    deg = m.spec.inputs[s.regulator].default_deg if reg is None else math.degrees(reg)
    g = FUNCTIONS[name](m, deg)
    require_a_stitch(m, name, g.value, deg, **_setting_option(m, reg is None, "--input",
                                                              f"--input {s.regulator}={{deg:g}}"))
    return g.value, g.d_dparam, g.unit, {**g.events_deg, "regulator": deg}


def _setting_option(m, default: bool, option: str, give: str) -> dict:
    """Which option a refused regulator setting came from, and the setting to suggest: a
    ``--set input.REGULATOR=...`` when the option was not given and --set changed it (the
    error blamed --input, which was not given), else ``option``."""
    s = m.spec.sewing
    key = f"input.{s.regulator}"
    if not (default and key in m.changes):
        return {"option": option, "give": give}
    from ...engine.machine import load_machine

    return {"option": "--set", "give": f"--set {key}={{deg:g}}deg",
            "working_deg": load_machine(m.file).spec.inputs[s.regulator].default_deg}


@command("sensitivity")
def sensitivity_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    output: str = typer.Option(..., help="a channel: p_POINT_x, p_POINT_y, theta_LINK, q_VAR,"
                               " the rates v_POINT_x, omega_LINK, qd_VAR or the accelerations"
                               " a_POINT_x, epsilon_LINK, qdd_VAR (as `sewmech kinematics"
                               " --json` names them), or a"
                               " metric: stitch_length, feed_lift, dog_height_at_needle_plate"
                               " (at --input regulator=DEG, default the file's setting),"
                               " needle_top_deg, take_up_lag_deg,"
                               " needle_descent_at_take_up_top, loop_lift, shuttle_swing_deg,"
                               + FAMILY_HELP),
    phi_deg: float = typer.Option(0.0, "--phi-deg", help="shaft angle, deg (position"
                                  " channels)"),
    at: str = typer.Option(None, "--at", help=AT_HELP),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the machine's"
                                     " working setting)"),
    top: int = typer.Option(15, help="rows of the table: the parameters whose tolerance moves"
                            " the output most"),
    tolerances: Path = typer.Option(None, help="tolerance file (TOML, docs/accuracy.md) whose"
                                    " tolerances rank the parameters; default: IT9 on every"
                                    " length, +-0.05 deg on every angle"),
    as_json: bool = typer.Option(False, "--json", help="print output, phi_deg, value, unit,"
                                 " d_dparam (parameter -> derivative, internal units),"
                                 " tolerances and effects as JSON"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Exact derivatives of one output by every parameter of the machine, at one shaft angle
    (units: the output's per the parameter's, mm and rad), ranked by what each parameter's
    tolerance moves the output by (derivative x tolerance), so that lengths and angles compare."""
    from ...design.tolerance_file import RANKING_ANGLE_DEG, load_tolerance_file, ranking_tolerances
    from ...engine.sensitivity import sensitivities

    if not (math.isfinite(phi_deg) and abs(phi_deg) <= 1e6):
        raise OptionError("--phi-deg", f"must be a finite angle in deg, got {phi_deg}")
    if top < 1:
        raise OptionError("--top", f"must be at least 1, got {top}")
    _refuse_phi_for_a_metric(output, at)
    m = _load(machine, sets)
    settings = _settings(m, inputs)
    if settings and output in METRICS and output not in FEED_METRICS:
        raise OptionError("--input", f"{output} is read at the machine's working setting: the"
                          f" setting {', '.join(inputs)} would be ignored", "Leave --input out"
                          " (it sets " + ", ".join(FEED_METRICS) + " and the position channels)")
    tol = ranking_tolerances(m, load_tolerance_file(tolerances) if tolerances else None,
                             str(tolerances or "tolerances"))
    ranked_by = (f"the tolerances of {tolerances}" if tolerances else
                 f"IT9 on lengths, +-{RANKING_ANGLE_DEG:g} deg on angles")
    names = m.parameter_names
    from ...design.tolerances import is_family_metric, metric_gradient

    if at is not None or is_family_metric(output):
        value, d, unit = metric_gradient(m, output, regulator_deg=_family_setting(m, settings),
                                         phi_deg=phi_deg, at=at)
        where = f"at {at}" + (f" (from phi = {phi_deg:g} deg)" if phi_deg else "") \
            if at is not None else "over the turn"
        data = {"output": output, "phi_deg": phi_deg if at is not None else None, "at": at}
    elif output in METRICS:
        value, d, unit, events = _metric(m, output, settings)
        where = "at " + ", ".join(f"{k} {v:.6g} deg" for k, v in events.items())
        data = {"output": output, "phi_deg": None, "events_deg": events}
    else:
        try:
            S = sensitivities(m, np.radians([phi_deg]), inputs=settings or None,
                              rates=output.split("_")[0] in ("v", "omega", "qd", "a", "epsilon",
                                                             "qdd"), outputs=[output])
            value, d, unit = S.channel(output)
        except KeyError as exc:
            raise OptionError("--output", exc.args[0], "Give e.g. p_needle.point_y,"
                              " theta_take_up_lever or a metric: " + ", ".join(METRICS)) from None
        value, d = float(value[0]), d[0]
        where = f"at phi = {phi_deg:g} deg"
        data = {"output": output, "phi_deg": phi_deg}
    effect = d * tol
    data.update({"value": float(value), "unit": unit,
                 "d_dparam": {n: float(x) for n, x in zip(names, d)},
                 "parameter_units": dict(zip(names, m.parameter_units)),
                 "ranked_by": ranked_by,
                 "tolerances": {n: float(t) for n, t in zip(names, tol) if t > 0},
                 "effects": {n: float(e) for n, e, t in zip(names, effect, tol) if t > 0}})
    if as_json:
        print_json(data)
        return
    out_scale, per_unit = _scales(m, unit)
    moves = np.array([not is_round_off(x, out_scale / per_unit(u))
                      for x, u in zip(d, m.parameter_units)])
    table = Table(title=f"{m.name}: d {output} / d parameter {where} ({output} ="
                        f" {value:.6g} {unit}), ranked by what each tolerance moves it by",
                  caption=f"effect: derivative x tolerance ({ranked_by}), {unit}")
    for col in ("parameter", "tolerance", "effect", "derivative", "unit"):
        table.add_column(col, justify="left" if col in ("parameter", "unit") else "right")
    made = np.flatnonzero((tol > 0) & moves)
    for j in made[np.argsort(-np.abs(effect[made]), kind="stable")][:top]:
        u = m.parameter_units[j]
        t = f"+-{math.degrees(tol[j]):.3g} deg" if u == "rad" else f"+-{tol[j]:.3g} {u}"
        table.add_row(names[j], t, number(effect[j]), number(d[j], digits=6),
                      escape(f"{unit} per {u}"))
    console.print(table)
    exact = [j for j in np.flatnonzero(tol == 0) if moves[j]]
    if exact:
        console.print(escape("not toleranced (setting inputs, speed ratios, counterweights, or"
                             " held exact): " + ", ".join(
                                 f"{names[j]} {number(d[j], digits=6)} {unit} per"
                                 f" {m.parameter_units[j]}" for j in exact)), highlight=False)
    console.print(f"{len(names)} parameters; {int(np.sum(~moves))} do not move {output} {where}",
                  highlight=False)


def _scales(m, unit: str):
    """The size of an output in ``unit`` (below whose round-off a value is 0) and, per unit of
    a parameter, the size that parameter's unit stands for: lengths the machine's size (its
    largest length), angles one radian. A derivative's round-off is that of the output's size
    over the parameter's."""
    size = max([abs(float(v)) for v, u in zip(m.defaults, m.parameter_units) if u == "mm"]
               + [1.0])
    base, _, per = unit.partition("/")
    out = {"mm": size, "rad": 2.0 * math.pi, "deg": 360.0}.get(base, 1.0)
    w = m.spec.speed.rpm * 2.0 * math.pi / 60.0
    out *= {"": 1.0, "s": w, "s^2": w * w}.get(per, 1.0)
    return out, (lambda u: size if u == "mm" else 1.0)


@command("tolerance")
def tolerance_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    output: str = typer.Option(..., help="a metric (stitch_length, feed_lift,"
                               " dog_height_at_needle_plate) or a position channel (p_POINT_y,"
                               " theta_LINK, q_VAR at --phi-deg or --at)," + FAMILY_HELP),
    tolerances: Path = typer.Option(None, help="tolerance file (TOML, docs/accuracy.md);"
                                    " default: IT9 on every length, angles exact"),
    samples: int = typer.Option(10_000, help="Monte Carlo designs (one batch call)"),
    seed: int = typer.Option(0, help="random seed of the Monte Carlo"),
    band: float = typer.Option(None, help="allocate: the widest tolerances (least cost) that"
                               " keep the output within +-BAND (its unit)"),
    regulator_deg: float = typer.Option(None, "--regulator-deg", help="stitch regulator"
                                        " setting, deg (default: the machine's working"
                                        " setting)"),
    phi_deg: float = typer.Option(0.0, "--phi-deg", help="shaft angle of a position channel,"
                                  " deg"),
    at: str = typer.Option(None, "--at", help=AT_HELP),
    top: int = typer.Option(12, help="rows of the contributions table"),
    as_json: bool = typer.Option(False, "--json", help="print worst_case, rss, monte_carlo,"
                                 " contributions (and allocation) as JSON"),
    out: Path = typer.Option(None, help="also write the distribution and Pareto charts"
                             " (PNG, SVG, CSV) and the result (JSON) here"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """How far an output strays when every dimension is made within its tolerance: worst
    case, RSS, Monte Carlo, each dimension's share, and allocation to a band."""
    from rich.progress import Progress

    from ...design.tolerance_file import load_tolerance_file
    from ...design.tolerances import tolerance_analysis

    if not (math.isfinite(phi_deg) and abs(phi_deg) <= 1e6):
        raise OptionError("--phi-deg", f"must be a finite angle in deg, got {phi_deg}")
    if top < 1:
        raise OptionError("--top", f"must be at least 1, got {top}")
    _refuse_phi_for_a_metric(output, at)
    m = _load(machine, sets)
    if regulator_deg is not None:
        regulator = m.spec.sewing.regulator if m.spec.sewing is not None else None
        if regulator is None:
            raise OptionError("--regulator-deg", f"machine '{m.name}' has no stitch regulator"
                              " ([sewing] regulator): the setting would be ignored",
                              "Leave --regulator-deg out")
        if output in METRICS and output not in FEED_METRICS:
            raise OptionError("--regulator-deg", f"{output} is read at the machine's working"
                              " setting: the setting would be ignored", "Leave --regulator-deg"
                              " out (it sets " + ", ".join(FEED_METRICS) + " and the position"
                              " channels)")
        _settings(m, [f"{regulator}={regulator_deg}"])
    spec = load_tolerance_file(tolerances) if tolerances is not None else None
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="tolerance")
    with Progress(console=console, transient=True,
                  disable=not console.is_terminal) as progress:
        progress.add_task(f"tolerance analysis of {output} ({samples} designs)", total=None)
        how = (_setting_option(m, regulator_deg is None, "--regulator-deg",
                               "--regulator-deg {deg:g}")
               if m.spec.sewing is not None and m.spec.sewing.regulator else {})
        res = tolerance_analysis(m, output, spec, regulator_deg=regulator_deg, phi_deg=phi_deg,
                                 samples=samples, seed=seed, band=band, at=at,
                                 where=str(tolerances or "tolerances"),
                                 **{"option": "--regulator-deg",
                                    "give": "--regulator-deg {deg:g}", **how})
    data = {"machine": m.name, **res.to_json()}
    if out is not None:
        _write_tolerance(m, out, res, data)
    if as_json:
        print_json(data)
        return
    mc = res.monte_carlo
    u = res.unit
    console.print(f"{m.name}: {output} = {res.value:.6g} {u}; {len(res.names)} toleranced"
                  f" dimensions ({res.distribution})")
    console.print(f"  worst case +-{res.worst_case:.4g} {u}, RSS +-{res.rss:.4g} {u}")
    if mc["std"] is None:
        console.print(escape(f"  Monte Carlo ({mc['n']} designs): undefined ({mc['note']})"),
                      highlight=False)
    else:
        console.print(f"  Monte Carlo ({mc['n']} designs): std {mc['std']:.4g} {u} (RSS /"
                      f" {res.sigma_divisor[1]} = {res.sigma:.4g} {u} to first order,"
                      f" {res.distribution} dimensions), p99 of |deviation| {mc['p99']:.4g}"
                      f" {u}, range {mc['min']:.4g} .. {mc['max']:.4g}")
    how = mc.get("evaluation", {})
    if "located" in how:
        console.print(f"    events located on each design ({how['located']} from their"
                      f" predicted angles, {how['whole_turn']} from their whole turn;"
                      f" {how['checked']} checked on the whole turn, within"
                      f" {how['check_max_mm']:.1g} mm)")
    if mc["assembled"] < mc["n"]:
        console.print(f"    {mc['n'] - mc['assembled']} designs not counted: they cannot be"
                      " assembled, or the metric's event cannot be located on them")
    table = Table(title="contributions (share of the RSS variance)")
    for col in ("parameter", "tolerance", "derivative", "share"):
        table.add_column(col, justify="left" if col == "parameter" else "right")
    idx = {n: j for j, n in enumerate(res.names)}
    for name, share in list(res.contributions.items())[:top]:
        j = idx[name]
        tu = "deg" if res.units[j] == "rad" else res.units[j]
        tv = math.degrees(res.tolerance[j]) if res.units[j] == "rad" else res.tolerance[j]
        table.add_row(name, f"+-{tv:.4g} {tu}", f"{res.derivative[j]:.4g}",
                      f"{100 * share:.1f} %")
    console.print(table)
    if res.allocation is not None:
        t = Table(title=f"allocated to +-{band:g} {u} ({res.allocation_rule}), tightest first")
        for col in ("parameter", "tolerance"):
            t.add_column(col)
        for name, tol in sorted(res.allocation.items(), key=lambda x: x[1])[:top]:
            unit = m.parameter_units[m.parameter_names.index(name)]
            shown = f"+-{math.degrees(tol):.4g} deg" if unit == "rad" else \
                f"+-{tol:.4g} {unit}"
            t.add_row(name, shown)
        console.print(t)
    if out is not None:
        console.print(f"written: charts and {m.name}-tolerance.json in {out}")


def _write_tolerance(m, out: Path, res, data: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    from ..drawing.figures import save_figure
    from ..files.io import atomic_write, dump_json
    from ..files.outdir import output_dir

    u = res.unit
    with output_dir(out, command="tolerance", machine=m.name) as root:
        stem = f"{m.name}-tolerance-{res.metric}"
        fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
        ax.hist(res.deviations, bins=80, density=True, color="C0", alpha=0.6,
                label=f"Monte Carlo, {res.monte_carlo['n']} designs")
        sigma = res.sigma
        x = np.linspace(-res.worst_case, res.worst_case, 400)
        ax.plot(x, np.exp(-0.5 * (x / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi)), "k-",
                lw=1.2, label=f"normal, sigma from the RSS ({sigma:.3g} {u})")
        for v, ls, lab in ((res.worst_case, ":", "worst case"), (res.rss, "--", "RSS")):
            ax.axvline(v, color="C3", ls=ls, lw=1.0, label=f"{lab} +-{v:.3g} {u}")
            ax.axvline(-v, color="C3", ls=ls, lw=1.0)
        ax.set_xlabel(f"deviation of {res.metric} from its nominal {res.value:.5g} [{u}]")
        ax.set_ylabel("density")
        ax.legend(fontsize=7)
        ax.set_title(f"{m.name}: {res.metric} with every dimension within its tolerance")
        save_figure(fig, root, stem + "-distribution")
        names = list(res.contributions)[:15]
        shares = np.array([res.contributions[n] for n in names])
        fig, ax = plt.subplots(figsize=(8, 0.35 * len(names) + 1.5), constrained_layout=True)
        ax.barh(range(len(names))[::-1], 100 * shares, color="C0")
        ax.set_yticks(range(len(names))[::-1], names, fontsize=8)
        ax2 = ax.twiny()
        ax2.plot(100 * np.cumsum(shares), range(len(names))[::-1], "C3o-", ms=3)
        ax2.set_xlim(0, 100)
        ax2.set_xlabel("cumulative share [%]", color="C3")
        ax.set_xlabel("share of the RSS variance [%]")
        ax.set_title(f"{m.name}: what makes {res.metric} stray", fontsize=10)
        save_figure(fig, root, stem + "-pareto")
        with atomic_write(root / f"{stem}-contributions.csv") as fh:
            pd.DataFrame({"parameter": list(res.contributions),
                          "share": list(res.contributions.values())}).to_csv(
                fh, index=False, float_format="%.10g")
        with atomic_write(root / f"{m.name}-tolerance.json") as fh:
            dump_json(data, fh, indent=1)

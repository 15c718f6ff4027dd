"""The accuracy commands of the ``sewmech`` command line: ``sensitivity`` (exact derivatives of
an output by every parameter). Registered on the shared app of :mod:`sewmech.app.cli_common`
when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..engine.errors import OptionError
from .cli_common import DEFAULT_MACHINE, SET_HELP, _load, _settings, command, console


#: the sewing metrics ``--output`` accepts besides the position channels (the keys of
#: :data:`sewmech.sewing.gradients.METRICS`)
METRICS = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


def _metric(m, name: str, settings: dict) -> tuple[float, np.ndarray, str, dict]:
    """A sewing metric's value, derivatives, unit and event angles (deg)."""
    from ..sewing.gradients import METRICS as FUNCTIONS
    from ..sewing.timing import roles

    s = roles(m)
    if s.regulator is None or s.feed_dog is None:
        raise OptionError("--output", f"machine '{m.name}' has no feed dog and regulator in its"
                          f" [sewing] table: no {name.replace('_', ' ')}",
                          "Choose a position channel")
    reg = settings.get(s.regulator)
    deg = m.spec.inputs[s.regulator].default_deg if reg is None else math.degrees(reg)
    g = FUNCTIONS[name](m, deg)
    return g.value, g.d_dparam, g.unit, {**g.events_deg, "regulator": deg}


@command("sensitivity")
def sensitivity_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    output: str = typer.Option(..., help="a position channel: p_POINT_x, p_POINT_y, theta_LINK"
                               " or q_VAR (as `sewmech kinematics --json` names them), or a"
                               " metric: stitch_length, feed_lift, dog_height_at_needle_plate"
                               " (at --input regulator=DEG, default the file's setting)"),
    phi_deg: float = typer.Option(0.0, "--phi-deg", help="shaft angle, deg (position"
                                  " channels)"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the file's)"),
    top: int = typer.Option(15, help="rows of the table: the largest derivatives"),
    as_json: bool = typer.Option(False, "--json", help="print output, phi_deg, value, unit and"
                                 " d_dparam (parameter -> derivative, internal units) as JSON"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """Exact derivatives of one output by every parameter of the machine, at one shaft angle
    (units: the output's per the parameter's, mm and rad)."""
    from ..engine.sensitivity import sensitivities

    if not (math.isfinite(phi_deg) and abs(phi_deg) <= 1e6):
        raise OptionError("--phi-deg", f"must be a finite angle in deg, got {phi_deg}")
    if top < 1:
        raise OptionError("--top", f"must be at least 1, got {top}")
    m = _load(machine, sets)
    settings = _settings(m, inputs)
    names = m.parameter_names
    if output in METRICS:
        value, d, unit, events = _metric(m, output, settings)
        at = "at " + ", ".join(f"{k} {v:.6g} deg" for k, v in events.items())
        data = {"output": output, "phi_deg": None, "events_deg": events}
    else:
        try:
            S = sensitivities(m, np.radians([phi_deg]), inputs=settings or None)
            value, d, unit = S.channel(output)
        except KeyError as exc:
            raise OptionError("--output", exc.args[0], "Give e.g. p_needle.point_y,"
                              " theta_take_up_lever or a metric: " + ", ".join(METRICS)) from None
        value, d = float(value[0]), d[0]
        at = f"at phi = {phi_deg:g} deg"
        data = {"output": output, "phi_deg": phi_deg}
    data.update({"value": float(value), "unit": unit,
                 "d_dparam": {n: float(x) for n, x in zip(names, d)},
                 "parameter_units": dict(zip(names, m.parameter_units))})
    if as_json:
        json.dump(data, sys.stdout)
        sys.stdout.write("\n")
        return
    table = Table(title=f"{m.name}: d {output} / d parameter {at} ({output} ="
                        f" {value:.6g} {unit})")
    for col in ("parameter", "derivative", "unit"):
        table.add_column(col, justify="right" if col == "derivative" else "left")
    order = np.argsort(-np.abs(d))[:top]
    for j in order:
        table.add_row(names[j], f"{d[j]:.6g}", escape(f"{unit} per {m.parameter_units[j]}"))
    console.print(table)
    zero = int(np.sum(d == 0.0))
    console.print(f"{len(names)} parameters; {zero} do not move {output} {at}")

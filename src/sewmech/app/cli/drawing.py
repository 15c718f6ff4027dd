"""The drawing command of the ``sewmech`` command line: ``export`` (a machine as a workshop
drawing, DXF or SVG; docs/synthesis.md, "CAD files"). Registered on the shared app of
:mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import math
from pathlib import Path

import typer
from rich.markup import escape

from ...engine.errors import OptionError
from .common import SET_HELP, _choice, _load, _settings, choices_metavar, command, console

FORMATS = ("dxf", "svg")


def drawing_file_name(machine: str, phi_deg: float, part: str | None, fmt: str) -> str:
    """``MACHINE[-PART]-phiA.FMT``, the angle as given (``-phi30``, ``-phi12.5``)."""
    return f"{machine}{'-' + part if part else ''}-phi{phi_deg:g}.{fmt}"


@command("export")
def export_cmd(
    machine: str = typer.Argument(..., help="machine file (TOML) or shipped name"),
    format: list[str] = typer.Option(["dxf"], "--format", metavar=choices_metavar(FORMATS),
                                     help="dxf (ezdxf, R2010, mm) or svg; repeatable for both"),
    phi_deg: float = typer.Option(0.0, help="the shaft angle the links are drawn at, deg"),
    part: str = typer.Option(None, help="only this link or cam (e.g. feed_cam): a part's"
                             " drawing"),
    out: Path = typer.Option(..., help="the directory to write MACHINE[-PART]-phiA.dxf|svg into"
                             " (new, empty or written by sewmech)"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """A machine as a workshop drawing at one shaft angle: every link's outline and joints on a
    layer of its own, the cams as true arcs with their centres and the follower's pitch curve,
    the paths of the needle eye, take-up eye and feed dog as polylines, a title block; mm."""
    import sewmech

    from ..drawing.cad import machine_drawing
    from ..files.cad import write_dxf, write_svg
    from ..files.outdir import output_dir, preflight

    fmts = []
    for f in format:
        f = _choice("--format", f, FORMATS)
        if f in fmts:
            raise OptionError("--format", f"{f!r} is given twice", "Give each format once")
        fmts.append(f)
    if not (math.isfinite(phi_deg) and abs(phi_deg) <= 1e6):
        raise OptionError("--phi-deg", f"must be a finite angle in deg, got {phi_deg:g}")
    m = _load(machine, sets)
    settings = _settings(m, inputs)
    preflight(out, command="export")
    d = machine_drawing(m, phi_deg=phi_deg, inputs=settings or None, part=part,
                        version=sewmech.__version__)
    written = []
    with output_dir(out, command="export", machine=m.name) as root:
        for f in fmts:
            name = drawing_file_name(m.name, phi_deg, part, f)
            (write_dxf if f == "dxf" else write_svg)(d, root / name)
            written.append(name)
    console.print(f"wrote {', '.join(escape(str(Path(out) / n)) for n in written)}:"
                  f" {len(d.entities)} entities on {len(d.layers)} layer"
                  f"{'' if len(d.layers) == 1 else 's'}", highlight=False)

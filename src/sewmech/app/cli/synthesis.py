"""The synthesis commands of the ``sewmech`` command line: ``synthesize function``, ``motion``,
``path`` and ``embroidery-take-up`` (docs/synthesis.md). Each finds a mechanism from
requirements, checks it, and with ``--out DIR`` writes its machine file (``DIR/NAME.toml``,
which ``sewmech check`` accepts), the page ``DIR/index.html`` with the answer against the
requirement, the figures and ``synthesis.json``. Registered on the shared app of
:mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import functools
import json
import math
import re
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import OptionError
from .common import _Group, _guard, app, console, print_json

synth = typer.Typer(name="synthesize", cls=_Group, no_args_is_help=True, add_completion=False,
                    help="Find a mechanism from requirements (classical synthesis) and write"
                         " its machine file and page (docs/synthesis.md).")
app.add_typer(synth, name="synthesize")

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$")
OUT_HELP = ("write the machine file NAME.toml, the page index.html (the answer against the"
            " requirement, figures) and synthesis.json into this directory (new, empty or"
            " written by sewmech)")


def _command(name: str):
    def deco(fn):
        @functools.wraps(fn)
        def run(*args, **kwargs):
            with _guard():
                return fn(*args, **kwargs)

        return synth.command(name)(run)
    return deco


def _name(name: str) -> str:
    if not _NAME.match(name):
        raise OptionError("--name", f"{name!r} is not a machine name", "Use letters, digits and"
                          " _ . - (starting with a letter), at most 64 characters")
    return name


def _numbers(option: str, text: str, n: int | None = None) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise OptionError(option, f"{text!r} is not a list of numbers separated by commas",
                          "Write e.g. 10,5,30") from None
    if not all(math.isfinite(v) for v in vals) or (n is not None and len(vals) != n):
        raise OptionError(option, f"{text!r}: needs {n} finite numbers" if n else
                          f"{text!r}: every number must be finite")
    return vals


def _write(out: Path, command: str, name: str, text: str, page, data: dict) -> None:
    """The machine file, the page (``page(root, file_name)``) and synthesis.json, through the
    output-directory guard."""
    from ..files.io import atomic_write
    from ..files.outdir import output_dir, preflight

    preflight(out, command=command)
    with output_dir(out, command=command) as root:
        with atomic_write(root / f"{name}.toml") as fh:
            fh.write(text)
        page(root, f"{name}.toml")
        with atomic_write(root / "synthesis.json") as fh:
            json.dump(data, fh, indent=1)
    console.print(f"wrote {escape(str(Path(out) / (name + '.toml')))} and"
                  f" {escape(str(Path(out) / 'index.html'))}", highlight=False)


def _show(title: str, rows: list[tuple[str, str]], notes) -> None:
    t = Table(title=escape(title), show_header=False)
    for k, v in rows:
        t.add_row(escape(k), escape(v))
    console.print(t)
    for n in notes:
        console.print(f"  - {escape(n)}", highlight=False)


@_command("function")
def function_cmd(
    function: str = typer.Option(..., "--function", help="y = f(x) as a formula in x: numbers,"
                                 " x, pi, e, + - * / ** and sin cos tan exp log log10 sqrt ..."),
    x_range: tuple[float, float] = typer.Option(..., help="x from .. to"),
    input_range_deg: tuple[float, float] = typer.Option(..., help="the input link's angle at"
                                                        " x from and at x to, deg (from +x,"
                                                        " A -> D along +x)"),
    output_range_deg: tuple[float, float] = typer.Option(..., help="the output link's angle at"
                                                         " f(x from) and f(x to), deg"),
    points: int = typer.Option(3, help="3: exact at three precision points; more: least squares"
                               " over that many evenly spaced points"),
    spacing: str = typer.Option("chebyshev", help="three points by chebyshev or even spacing"),
    ground_mm: float = typer.Option(100.0, help="the ground link AD, mm (scales the linkage)"),
    name: str = typer.Option("function-generator", help="the machine's name (and file name)"),
    out: Path = typer.Option(None, help=OUT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print the answer as JSON"),
):
    """A four-bar function generator (Freudenstein): its output angle follows y = f(x) while
    its input follows x; the structural error over the range; branch defect, dead centres and
    Grashof type found and reported."""
    from ...design.synthesis import machine_text, synthesize_function
    from ..report.synthesis import function_page, verify_machine

    _name(name)
    if not (math.isfinite(ground_mm) and 0.0 < ground_mm <= 1e5):
        raise OptionError("--ground-mm", f"must be a length in (0, 100000] mm, got {ground_mm:g}")
    if not 3 <= points <= 10000:
        raise OptionError("--points", f"must be 3 .. 10000, got {points}")
    res = synthesize_function(function, x_range, input_range_deg, output_range_deg,
                              ground_mm=ground_mm, points=points, spacing=spacing)
    t0, t1 = res.input_range_deg
    text = machine_text(res.fourbar, name=name, title=f"Function generator y = {function}",
                        notes=[f"A four-bar function generator: y = {function} for x in"
                               f" {res.x_range[0]:g} .. {res.x_range[1]:g}"
                               f" (sewmech synthesize function, {res.method}).",
                               "The input lever is the setting input 'input' (its angle from"
                               " +x); the output link's angle is that of D -> C"
                               + (" + 180 deg." if res.fourbar.output_u < 0 else ".")],
                        drive="setting", input_range_deg=(min(t0, t1), max(t0, t1)))
    m = verify_machine(text, f"{name}.toml")
    fb = res.fourbar
    data = {"kind": "function", "function": function, "method": res.method,
            "lengths_mm": {"AB": fb.a, "BC": fb.b, "DC": fb.c, "AD": fb.d},
            "K": [float(k) for k in res.K], "branch": fb.branch, "grashof": res.grashof.kind,
            "precision_x": res.x.tolist(), "precision_input_deg": res.theta2_deg.tolist(),
            "precision_output_deg": res.theta4_deg.tolist(),
            "max_structural_error": res.max_error,
            "max_structural_error_deg": res.max_error_deg,
            "min_transmission_deg": res.min_transmission_deg, "notes": list(res.notes)}
    if out is not None:
        holder = {}

        def page(root, file_name):
            holder["check"] = function_page(root, res, text, file_name, m)

        _write(out, "synthesize function", name, text, page, data)
    if as_json:
        print_json(data)
        return
    _show(f"function generator: y = {function} ({res.method})",
          [("AB, BC, DC, AD [mm]", f"{fb.a:.6g}, {fb.b:.6g}, {fb.c:.6g}, {fb.d:.6g}"),
           ("branch / Grashof", f"{fb.branch:+d} / {res.grashof.text}"),
           ("precision x", ", ".join(f"{v:.6g}" for v in res.x)),
           ("largest structural error", f"{res.max_error:.4g} (y), {res.max_error_deg:.4g} deg"),
           ("least transmission angle", f"{res.min_transmission_deg:.4g} deg")], res.notes)


def _parse_poses(poses: list[str]) -> np.ndarray:
    return np.array([_numbers("--pose", p, 3) for p in poses or []], dtype=float)


@_command("motion")
def motion_cmd(
    pose: list[str] = typer.Option(..., "--pose", help="a pose of the body: X,Y,ANGLE_DEG (its"
                                   " reference point mm and its u axis's angle); three or"
                                   " four times"),
    circle_point: list[str] = typer.Option(None, "--circle-point", help="three poses: a moving"
                                           " pivot U,V in the body's frame (mm), twice (the"
                                           " free choice; default: chosen by sewmech)"),
    name: str = typer.Option("motion-generator", help="the machine's name (and file name)"),
    out: Path = typer.Option(None, help=OUT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print the answer as JSON"),
):
    """A four-bar whose coupler carries a body through three or four poses (Burmester): the
    centre-point and circle-point curves for four, the dyads chosen free of branch and order
    defects."""
    from ...design.burmester import synthesize_motion
    from ...design.synthesis import machine_text
    from ..report.synthesis import motion_page, verify_machine

    _name(name)
    P = _parse_poses(pose)
    cps = None
    if circle_point:
        if len(circle_point) != 2:
            raise OptionError("--circle-point", f"give it twice (one a dyad), got"
                              f" {len(circle_point)}")
        cps = [_numbers("--circle-point", c, 2) for c in circle_point]
        if len(P) != 3:
            raise OptionError("--circle-point", "is the free choice of three poses; four poses"
                              " fix the circle points on Burmester's curve")
    res = synthesize_motion(P, cps)
    fb = res.fourbar
    if res.drive == "shaft":
        text = machine_text(fb, name=name, title=f"Motion generator through {len(P)} poses",
                            notes=[f"A four-bar that carries a body through {len(P)} poses"
                                   " (sewmech synthesize motion): P is the body's reference"
                                   " point; the body's angle is the coupler's +"
                                   f" {math.degrees(res.body_offset):.12g} deg.",
                                   "Poses at phi = " + ", ".join(f"{v:.9g}" for v in
                                                                  res.phi_deg) + " deg."],
                            ratio=res.ratio, phase_deg=float(res.input_deg[0]))
    else:
        lo, hi = float(res.input_deg.min()), float(res.input_deg.max())
        text = machine_text(fb, name=name, title=f"Motion generator through {len(P)} poses",
                            notes=[f"A four-bar that carries a body through {len(P)} poses"
                                   " (sewmech synthesize motion): P is the body's reference"
                                   " point; the body's angle is the coupler's +"
                                   f" {math.degrees(res.body_offset):.12g} deg.",
                                   "The input is a lever (setting input 'input'); the poses at"
                                   " its settings " + ", ".join(f"{v:.9g}" for v in
                                                                res.input_deg) + " deg."],
                            drive="setting", input_range_deg=(lo, hi))
    m = verify_machine(text, f"{name}.toml")
    data = {"kind": "motion", "poses": [[float(p[0]), float(p[1]), math.degrees(p[2])]
                                        for p in res.poses],
            "A_mm": list(fb.A), "D_mm": list(fb.D),
            "lengths_mm": {"AB": fb.a, "BC": fb.b, "DC": fb.c, "AD": fb.d},
            "coupler_point_mm": list(fb.coupler_point), "branch": fb.branch,
            "grashof": res.grashof.kind, "drive": res.drive,
            "phi_deg": [float(v) for v in res.phi_deg],
            "min_transmission_deg": res.min_transmission_deg,
            "pairs_tried": res.candidates[0], "pairs_usable": res.candidates[1],
            "notes": list(res.notes)}
    if out is not None:
        def page(root, file_name):
            motion_page(root, res, text, file_name, m)

        _write(out, "synthesize motion", name, text, page, data)
    if as_json:
        print_json(data)
        return
    _show(f"motion generator through {len(P)} poses",
          [("A, D [mm]", f"({fb.A[0]:.6g}, {fb.A[1]:.6g}), ({fb.D[0]:.6g}, {fb.D[1]:.6g})"),
           ("AB, BC, DC, AD [mm]", f"{fb.a:.6g}, {fb.b:.6g}, {fb.c:.6g}, {fb.d:.6g}"),
           ("branch / Grashof", f"{fb.branch:+d} / {res.grashof.text}"),
           ("poses at phi [deg]", ", ".join(f"{v:.6g}" for v in res.phi_deg)),
           ("least transmission angle", f"{res.min_transmission_deg:.4g} deg")], res.notes)


@_command("path")
def path_cmd(
    path: Path = typer.Argument(..., help="CSV with columns phi_deg, x_mm, y_mm: the points the"
                                " coupler point must pass at those shaft angles (3 or more)"),
    method: str = typer.Option("slsqp", help="the optimiser's method (sewmech optimize's)"),
    name: str = typer.Option("path-generator", help="the machine's name (and file name)"),
    out: Path = typer.Option(None, help=OUT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print the answer as JSON"),
):
    """A four-bar whose coupler point passes through points at given shaft angles (timed path
    generation): an exact three-point start, then the optimiser with exact gradients."""
    from ...design.burmester import synthesize_path
    from ..files.io import read_csv_columns
    from ..report.synthesis import path_page, verify_machine

    _name(name)
    cols = read_csv_columns(path, ["phi_deg", "x_mm", "y_mm"])
    Z = np.column_stack([cols["x_mm"], cols["y_mm"]])
    phi = np.asarray(cols["phi_deg"], dtype=float)
    res = synthesize_path(Z, phi, name=name, method=method)
    m = verify_machine(res.answer_text, f"{name}.toml")
    data = {"kind": "path", "points": len(Z), "start_rms_mm": res.start_rms_mm,
            "answer_rms_mm": res.answer_rms_mm, "answer_max_mm": res.answer_max_mm,
            "variables": {n: {"start": a, "answer": b} for n, (a, b) in res.variables.items()},
            "status": res.result.status, "notes": list(res.notes)}
    if out is not None:
        def page(root, file_name):
            path_page(root, res, Z, phi, file_name, m)
            from ..files.io import atomic_write

            with atomic_write(root / "problem.toml") as fh:
                fh.write(res.problem_text)

        _write(out, "synthesize path", name, res.answer_text, page, data)
    if as_json:
        print_json(data)
        return
    _show(f"path generator through {len(Z)} points",
          [("rms distance, start", f"{res.start_rms_mm:.4g} mm"),
           ("rms distance, answer", f"{res.answer_rms_mm:.4g} mm (largest"
                                    f" {res.answer_max_mm:.4g} mm)"),
           ("optimiser", f"{method}: {res.result.status}")], res.notes)


@_command("embroidery-take-up")
def take_up_cmd(
    crank_mm: float = typer.Option(17.5, help="the needle crank AB of the base machine, mm"),
    stroke_mm: float = typer.Option(124.0, help="thread the base machine draws per cycle (the"
                                    " paper's l2), mm"),
    k: str = typer.Option("0.93,0.62,0.38", "--k", help="K1,K2,K3 = BC/AB, DC/AB, AD/AB"),
    lengths_mm: str = typer.Option(None, help="BC,CD,AD as drawn, mm (instead of --k; the paper"
                                   " prints 16.3,10.9,6.6)"),
    ef_mm: float = typer.Option(None, help="the rod EF, mm (default: the paper's 80/31 DE)"),
    alpha_deg: float = typer.Option(None, help="lay the file out at this frame angle (default:"
                                    " the design positions')"),
    beta_deg: float = typer.Option(None, help="... and this angle from DC to DE (clockwise)"),
    name: str = typer.Option("take-up", help="the machine's name (and file name)"),
    out: Path = typer.Option(None, help=OUT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print the answer as JSON"),
):
    """The embroidery paper's double-crank take-up (Kozlov): the four-bar from the K's, DE =
    l2 / 4, EF, alpha and beta from the two design positions; then the paper's study of alpha
    and beta on the written machine."""
    from ...design.take_up_synthesis import synthesize_take_up
    from ..report.synthesis import take_up_page, verify_machine

    _name(name)
    kk = tuple(_numbers("--k", k, 3))
    lengths = tuple(_numbers("--lengths-mm", lengths_mm, 3)) if lengths_mm else None
    for opt, v in (("--alpha-deg", alpha_deg), ("--beta-deg", beta_deg)):
        if v is not None and not -360.0 <= v <= 360.0:
            raise OptionError(opt, f"must be in -360 .. 360 deg, got {v:g}")
    res = synthesize_take_up(crank_mm=crank_mm, stroke_mm=stroke_mm, k=kk, ef_mm=ef_mm,
                             lengths_mm=lengths, alpha_deg=alpha_deg, beta_deg=beta_deg,
                             name=name)
    m = verify_machine(res.text, f"{name}.toml")
    data = {"kind": "embroidery-take-up", "lengths_mm": {"AB": res.ab, "BC": res.bc,
                                                         "CD": res.cd, "AD": res.ad,
                                                         "DE": res.de, "EF": res.ef},
            "alpha_deg": res.alpha_deg, "beta_deg": res.beta_deg,
            "design_alpha_deg": res.design_alpha_deg, "design_beta_deg": res.design_beta_deg,
            "dc_turn_deg": res.dc_turn_deg, "eye_top_deg": res.eye_top_deg,
            "eye_bottom_deg": res.eye_bottom_deg, "drawn_mm": res.drawn_mm,
            "grashof": res.grashof.kind, "notes": list(res.notes)}
    if out is not None:
        def page(root, file_name):
            take_up_page(root, res, file_name, m)

        _write(out, "synthesize embroidery-take-up", name, res.text, page, data)
    if as_json:
        print_json(data)
        return
    _show("embroidery take-up (Kozlov's method)",
          [("AB, BC, CD, AD [mm]", f"{res.ab:.6g}, {res.bc:.6g}, {res.cd:.6g}, {res.ad:.6g}"),
           ("DE, EF [mm]", f"{res.de:.6g}, {res.ef:.6g}"),
           ("alpha, beta (design) [deg]", f"{res.design_alpha_deg:.6g}, {res.design_beta_deg:.6g}"),
           ("eye top, bottom at phi [deg]", f"{res.eye_top_deg:.4g}, {res.eye_bottom_deg:.4g}"),
           ("thread drawn per cycle [mm]", f"{res.drawn_mm:.6g}")], res.notes)

"""The design command of the ``sewmech`` command line: ``optimize`` (choose dimensions for a
problem file). Registered on the shared app of :mod:`sewmech.app.cli.common` when
:mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import math
from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

from ..display import number
from .common import command, console, print_json


@command("optimize")
def optimize_cmd(
    problem: Path = typer.Argument(..., help="problem file (TOML, docs/design.md)"),
    method: str = typer.Option("powell", help="golden (one variable), cyclic or powell (the"
                               " JB report's, with the interior penalty), slsqp (exact"
                               " gradients), de (differential evolution, one batch call per"
                               " generation), nsga2 (the Pareto front between the objective's"
                               " parts, and its compromise)"),
    seed: int = typer.Option(0, help="random seed (for the methods that draw; the others are"
                             " deterministic)"),
    as_json: bool = typer.Option(False, "--json", help="print status, x, objective,"
                                 " objective_start, constraints, n_evaluations as JSON"),
    out: Path = typer.Option(None, help="also write the problem's report here: index.html (the"
                             " variables, every metric before and after, the curves they are"
                             " read from, the mechanism before and after, the convergence),"
                             " each figure as PNG, SVG and CSV, the result as JSON and the"
                             " answer's drawing at phi = 0 as answer.dxf and answer.svg"),
):
    """Choose the dimensions of a design problem: the variables within their bounds that best
    meet the objective while every constraint holds."""
    from rich.progress import Progress

    from ...design.optimize import STATUSES, optimize
    from ...design.problem import OBJECTIVE_FORMS, Problem, load_problem, metric_unit

    spec, machine = load_problem(problem)
    p = Problem(spec, machine, str(problem))
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="optimize")
    with Progress(console=console, transient=True,
                  disable=not console.is_terminal) as progress:
        progress.add_task(f"{spec.problem.name}: {method}", total=None)
        r = optimize(p, method, seed=seed)
    data = {"problem": spec.problem.name, "machine": machine.name, "method": method,
            "seed": seed, "status": r.status, "message": str(r.message),
            "x": {n: float(v) for n, v in zip(p.names, r.x)},
            "units": dict(zip(p.names, p.units)),
            "x_start": {n: float(v) for n, v in zip(p.names, p.start)},
            "objective": _defined(r.fun), "objective_start": _defined(r.objective_start),
            "objective_form": OBJECTIVE_FORMS[spec.objective.form],
            "objective_parts": [{**{k: v for k, v in a.items() if k != "value"},
                                 "start": a["value"], "answer": b["value"]}
                                for a, b in zip(p.parts(p.start), p.parts(r.x))],
            "constraints": r.constraints, "n_evaluations": int(r.n_evaluations),
            "history": [_defined(h) for h in r.history]}
    # JSON has no NaN or infinity: an undefined figure is null, and a note beside it says why
    for key, note in (("objective", r.fun_note), ("objective_start", r.objective_start_note)):
        if data[key] is None:
            data[f"{key}_note"] = note
    for part in data["objective_parts"]:
        for key in ("start", "answer"):
            if part[key] is None:
                part[f"{key}_note"] = UNDEFINED_PART
    if any(h is None for h in data["history"]):
        data["history_note"] = ("null: the step's best design does not assemble over the whole"
                                " turn, or a metric cannot be formed on it (the searches count"
                                " it infinitely bad)")
    data["status_means"] = STATUSES[r.status]
    data["check"] = _json_safe(getattr(r, "check", None))
    if "front" in r:
        data["front"] = r.front
    if "best" in r:
        data["best"] = _json_safe(r.best)
    if out is not None:
        _write(out, p, data, problem)
    if as_json:
        print_json(data)
        return
    t = Table(title=f"{spec.problem.name} ({machine.name}), {method}: {r.status}")
    for col in ("variable", "start", "optimum", "unit", "bounds"):
        t.add_column(col)
    for n, s0, x, u, lo, hi in zip(p.names, p.start, r.x, p.units, p.lower, p.upper):
        t.add_row(n, f"{s0:.6g}", f"{x:.6g}", u, f"{lo:g} .. {hi:g}")
    console.print(t)
    console.print(escape(f"objective {_shown(data, 'objective_start')} ->"
                         f" {_shown(data, 'objective')} in {r.n_evaluations} evaluations"
                         f" ({r.message})"), highlight=False)
    console.print(f"  (normalised, dimensionless: {OBJECTIVE_FORMS[spec.objective.form]})",
                  highlight=False)
    if getattr(r, "check", None) is not None:
        c = r.check
        kkt = "" if c["kkt_residual"] is None else f"; KKT residual {c['kkt_residual']:.2g}"
        console.print(escape(f"  check: {c['how']} lowered the objective by"
                             f" {c['improvement']:.3g} (at most {c['tolerance']:.3g} allowed:"
                             f" {'passed' if c['passed'] else 'FAILED'}){kkt}"), highlight=False)
    if getattr(r, "best", None):
        b = r.best
        console.print(escape(f"  best feasible member by the objective: {b['member_objective']:.6g}"
                             f", polished by {b['polished_by']} to {b['objective']:.6g} at "
                             + ", ".join(f"{n} = {v:.6g}" for n, v in zip(p.names, b["x"],
                                                                          strict=True))
                             + f" ({b['status']})"), highlight=False)
    pt = Table(title="the objective's parts in their own units")
    for col in ("part", "at", "goal", "scale s", "start", "answer", "unit"):
        pt.add_column(col, justify="right" if col in ("scale s", "start", "answer") else "left",
                      overflow="fold")
    for part in data["objective_parts"]:
        scale = part["scale"]
        goal = part["sense"] if part["sense"] != "target" else f"target {part['target']:g}"
        if part["weight"] != 1.0:
            goal += f", w {part['weight']:g}"
        pt.add_row(part["metric"], _at(part), goal, number(scale, digits=6),
                   number(part["start"], scale, 6, "undefined"),
                   number(part["answer"], scale, 6, "undefined"), part["unit"])
    console.print(pt)
    if any(part[k] is None for part in data["objective_parts"] for k in ("start", "answer")):
        console.print(escape(f"  undefined: {UNDEFINED_PART.removeprefix('not defined: ')}"),
                      highlight=False)
    units = {c.metric: metric_unit(machine, c.metric) for c in spec.constraints}
    for name, c in r.constraints.items():
        mark = "[green]met[/]" if c["satisfied"] else "[red]VIOLATED[/]"
        unit = units.get(name.split(" (")[0], "")
        value = (f"undefined ({c['note'].removeprefix('not defined: ')})" if c["value"] is None
                 else f"{c['value']:.6g}")
        console.print(f"  {escape(name)} = {value}{' ' + unit if unit else ''} {mark}",
                      highlight=False)


#: why an objective part has no value at a design, in words
UNDEFINED_PART = ("not defined: the design does not assemble, or the metric cannot be formed"
                  " on it")


def _json_safe(x):
    """``x`` with every number that is not finite as None (JSON has neither NaN nor
    infinity), numpy numbers and arrays as Python's."""
    import numpy as np

    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple | np.ndarray):
        return [_json_safe(v) for v in x]
    if isinstance(x, bool | np.bool_):
        return bool(x)
    if isinstance(x, int | np.integer):
        return int(x)
    if isinstance(x, float | np.floating):
        return _defined(x)
    return x


def _defined(x) -> float | None:
    """``x`` as a float, or None where it is not a finite number (JSON has neither)."""
    x = float(x)
    return x if math.isfinite(x) else None


def _shown(data: dict, key: str) -> str:
    """A figure of the result as a line shows it: the number, or "undefined (why)"."""
    x = data[key]
    if x is None:
        return f"undefined ({data[f'{key}_note'].removeprefix('not defined: ')})"
    return f"{x:.6g}"


def _at(part: dict) -> str:
    """Where a part is read: the regulator setting of a feed metric, the angle of a channel."""
    from ..report.design import _is_channel

    if part["regulator_deg"] is not None:
        return f"regulator {part['regulator_deg']:g} deg"
    if _is_channel(part["metric"]):
        return f"phi {part['phi_deg']:g} deg"
    return ""


def _write(out: Path, problem, data: dict, problem_file: Path) -> None:
    from ..files.io import atomic_write, dump_json
    from ..files.outdir import output_dir
    from ..report.design import problem_page

    with output_dir(out, command="optimize") as root:
        problem_page(root, problem, data, problem_file)
        with atomic_write(root / "optimize.json") as fh:
            dump_json(data, fh, indent=1)
        why = _drawing(root, problem, data)
    if why:
        console.print(f"[yellow]note:[/] no drawing of the answer: {escape(why)}")


def _drawing(root: Path, problem, data: dict) -> str | None:
    """The answer's workshop drawing (answer.dxf, answer.svg: sewmech export's) at phi = 0, or
    at the first whole degree where it assembles; returns why there is none (the answer does
    not assemble anywhere, or lies outside a parameter's domain), else None."""
    import numpy as np

    import sewmech

    from ...engine.errors import SewmechError
    from ...engine.kinematics import kinematics
    from ..drawing.cad import machine_drawing
    from ..files.cad import write_dxf, write_svg

    x = [data["x"][n] for n in problem.names]
    if any(v is None for v in x):
        return "the optimiser gave no answer to draw"
    values = {n: float(v * f) for n, v, f in zip(problem.names, x, problem.factor, strict=True)}
    try:
        m = problem.machine.with_parameters(values, origin="the optimiser's answer")
        ok = kinematics(m, np.radians(np.arange(360.0)), on_failure="mask").feasible
        if not np.any(ok):
            return "it assembles at no whole degree of the turn"
        phi = float(np.argmax(ok))
        d = machine_drawing(m, phi_deg=phi, version=sewmech.__version__)
    except SewmechError as exc:
        return str(exc)
    write_dxf(d, root / "answer.dxf")
    write_svg(d, root / "answer.svg")
    return None

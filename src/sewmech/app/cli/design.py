"""The design command of the ``sewmech`` command line: ``optimize`` (choose dimensions for a
problem file). Registered on the shared app of :mod:`sewmech.app.cli.common` when
:mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

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
                             " each figure as PNG, SVG and CSV, and the result as JSON"),
):
    """Choose the dimensions of a design problem: the variables within their bounds that best
    meet the objective while every constraint holds."""
    from rich.progress import Progress

    from ...design.optimize import optimize
    from ...design.problem import Problem, load_problem

    spec, machine = load_problem(problem)
    p = Problem(spec, machine)
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="optimize")
    with Progress(console=console, transient=True) as progress:
        progress.add_task(f"{spec.problem.name}: {method}", total=None)
        r = optimize(p, method, seed=seed)
    data = {"problem": spec.problem.name, "machine": machine.name, "method": method,
            "seed": seed, "status": r.status, "message": str(r.message),
            "x": {n: float(v) for n, v in zip(p.names, r.x)},
            "units": dict(zip(p.names, p.units)),
            "x_start": {n: float(v) for n, v in zip(p.names, p.start)},
            "objective": float(r.fun), "objective_start": float(r.objective_start),
            "constraints": r.constraints, "n_evaluations": int(r.n_evaluations),
            "history": [float(h) for h in r.history]}
    if "front" in r:
        data["front"] = r.front
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
    console.print(f"objective {r.objective_start:.6g} -> {r.fun:.6g} in {r.n_evaluations}"
                  f" evaluations ({escape(str(r.message))})")
    for name, c in r.constraints.items():
        mark = "[green]met[/]" if c["satisfied"] else "[red]VIOLATED[/]"
        console.print(f"  {escape(name)} = {c['value']:.6g} {mark}")


def _write(out: Path, problem, data: dict, problem_file: Path) -> None:
    from ..files.io import atomic_write
    from ..files.outdir import output_dir
    from ..report.design import problem_page

    with output_dir(out, command="optimize") as root:
        problem_page(root, problem, data, problem_file)
        with atomic_write(root / "optimize.json") as fh:
            json.dump(data, fh, indent=1)

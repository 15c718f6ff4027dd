"""The design command of the ``sewmech`` command line: ``optimize`` (choose dimensions for a
problem file). Registered on the shared app of :mod:`sewmech.app.cli_common` when
:mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from .cli_common import command, console


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
    out: Path = typer.Option(None, help="also write the convergence plot (PNG, SVG) and the"
                             " result (JSON) here"),
):
    """Choose the dimensions of a design problem: the variables within their bounds that best
    meet the objective while every constraint holds."""
    from rich.progress import Progress

    from ..design.problem import Problem, load_problem, optimize

    spec, machine = load_problem(problem)
    p = Problem(spec, machine)
    if out is not None:
        from .outdir import preflight

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
        _write(out, spec.problem.name, data, p.names)
    if as_json:
        json.dump(data, sys.stdout)
        sys.stdout.write("\n")
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


def _write(out: Path, name: str, data: dict, names) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .figures import render
    from .io import atomic_write
    from .outdir import output_dir

    with output_dir(out, command="optimize") as root:
        fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
        h = np.array(data["history"], dtype=float)
        ax.plot(np.arange(len(h)), h, "o-", ms=3)
        if np.all(h[np.isfinite(h)] > 0) and h.size:
            ax.set_yscale("log")
        ax.set_xlabel("iteration")
        ax.set_ylabel("objective")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"{name}: {data['method']}, {data['status']}")
        try:
            render(fig, root, "convergence")
        finally:
            plt.close(fig)
        front = data.get("front")
        if front and front["f"]:
            F = np.array(front["f"])
            fig, ax = plt.subplots(figsize=(6.5, 5), constrained_layout=True)
            sc = ax.scatter(F[:, 0], F[:, 1], c=F[:, 2] if F.shape[1] > 2 else "C0", s=18)
            k = front["compromise"]
            ax.scatter([F[k, 0]], [F[k, 1]], marker="*", s=200, color="C3",
                       label="compromise (nearest the ideal point)")
            if F.shape[1] > 2:
                fig.colorbar(sc, ax=ax, label=front["parts"][2])
            ax.set_xlabel(front["parts"][0] + " (normalised)")
            ax.set_ylabel(front["parts"][1] + " (normalised)")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            ax.set_title(f"{name}: Pareto front ({len(F)} designs)")
            try:
                render(fig, root, "front")
            finally:
                plt.close(fig)
        with atomic_write(root / "optimize.json") as fh:
            json.dump(data, fh, indent=1)

"""The design command of the ``sewmech`` command line: ``optimize`` (choose dimensions for a
problem file). Registered on the shared app of :mod:`sewmech.app.cli_common` when
:mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from .cli_common import command, console, print_json


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
    out: Path = typer.Option(None, help="also write the convergence plot, the mechanism before"
                             " and after (PNG, SVG) and the result (JSON) here"),
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
        _write(out, spec.problem.name, data, p.names,
               (p.params(p.start), p.params(np.asarray(r.x)), machine))
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


def _paths_figure(name: str, before: np.ndarray, after: np.ndarray, machine):
    """Every point's path over a turn for the start (grey) and the answer (colour): the
    mechanism before and after, as the machine's own frame shows it (mm)."""
    import matplotlib.pyplot as plt

    from ..engine.kinematics import kinematics

    phi = np.radians(np.arange(0.0, 361.0, 2.0))
    fig, ax = plt.subplots(figsize=(7.5, 7), constrained_layout=True)
    for params, style, label in ((before, dict(color="0.6", lw=0.8), "start"),
                                 (after, dict(lw=1.3), "answer")):
        r = kinematics(machine, phi, params=params, on_failure="mask")
        labelled = False
        for i in range(len(r.point_names)):
            xy = r.p[:, i]
            if np.ptp(xy[:, 0]) + np.ptp(xy[:, 1]) < 1e-9:  # a fixed point: a dot
                ax.plot(xy[0, 0], xy[0, 1], "k.", ms=3)
                continue
            ax.plot(xy[:, 0], xy[:, 1], label=None if labelled else label, **style)
            labelled = True
        k = 0  # the mechanism at phi = 0, links as lines between their points
        for link, pts in _link_points(machine).items():
            idx = [r.point_names.index(q) for q in pts]
            if len(idx) > 1:
                ax.plot(r.p[k, idx, 0], r.p[k, idx, 1], "-o", ms=2, lw=0.6,
                        color=style.get("color", "C3"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{name}: point paths over a turn, start and answer (links at phi = 0)",
                 fontsize=9)
    return fig


def _link_points(machine) -> dict:
    """The points of each moving link (from the machine's pairs of points and links)."""
    out: dict = {}
    for pt, links in machine.point_links.items():
        for link in links:
            if link != "frame":
                out.setdefault(link, []).append(pt)
    return out


def _write(out: Path, name: str, data: dict, names, designs=None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .figures import save_figure
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
        save_figure(fig, root, "convergence")
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
            save_figure(fig, root, "front")
        if designs is not None:
            fig = _paths_figure(name, *designs)
            save_figure(fig, root, "mechanism")
        with atomic_write(root / "optimize.json") as fh:
            json.dump(data, fh, indent=1)

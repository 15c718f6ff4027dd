"""The sweep commands of the ``sewmech`` command line: ``sweep`` (evaluate a sweep file's
designs in chunks, in this process or on Dask) and ``sweep-summary`` (the feasible region, the
outputs' distributions and the best designs of a sweep's output). Registered on the shared app
of :mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli` imports this module."""

from __future__ import annotations

import contextlib
import json
import math
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ...engine.errors import OptionError
from ...engine.paths import user_path
from .common import command, console, err_console, print_json


@command("sweep")
def sweep_cmd(
    file: Path = typer.Argument(..., help="sweep file (TOML, docs/sweeps.md)"),
    out: Path = typer.Option(..., help="directory of the results: one Parquet file per chunk,"
                             " the curves in Zarr; a directory of the same sweep is resumed"),
    scheduler: str = typer.Option(None, help="address of a Dask scheduler to run on, e.g."
                                  " tcp://10.0.0.5:8786 (default: a local cluster)"),
    workers: int = typer.Option(None, help="worker processes of the local cluster (default:"
                                " one per core); 0 evaluates in this process, without Dask"),
    chunk: int = typer.Option(None, help="designs per chunk, each one batch call and one"
                              " Parquet file (default 250; a resumed sweep keeps its own)"),
    retries: int = typer.Option(2, help="attempts after a chunk's first failure before it is"
                                " reported failed"),
    as_json: bool = typer.Option(False, "--json", help="print the run's figures as JSON"),
):
    """Evaluate every design of a sweep file (a grid or a random, Latin-hypercube or Sobol
    sample of the machine's dimensions): outputs per design to Parquet, curves to Zarr,
    resuming an interrupted run."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    from ...design.evaluate import COARSE_STEP_DEG
    from ...design.sweep import COUNTS, chunk_bounds
    from ...design.sweep_file import load_sweep
    from ..sweep_run import done_chunks, read_record, run_sweep

    if not 0 <= retries <= 10:
        raise OptionError("--retries", f"must be in 0 .. 10, got {retries}", "Give e.g."
                          " --retries 2")
    sweep = load_sweep(file)
    root = user_path(out, "--out")

    class Rate(ProgressColumn):
        def render(self, task):
            rate = task.fields.get("rate")
            return Text(f"{rate:,.0f} designs/s" if rate else "", style="progress.data.speed")

    import time

    t0 = [time.perf_counter(), 0]
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("designs"), Rate(), TimeElapsedColumn(), TimeRemainingColumn(),
                  console=err_console, transient=True,
                  disable=as_json or not err_console.is_terminal) as progress:
        task = progress.add_task(escape(sweep.spec.sweep.name), total=sweep.n_designs)
        started = [False]

        def on_chunk(k: int, n: int) -> None:
            if not started[0]:  # (the designs found done count from the start)
                started[0] = True
                t0[0] = time.perf_counter()
                t0[1] = 0
            t0[1] += n
            dt = time.perf_counter() - t0[0]
            progress.update(task, advance=n, rate=t0[1] / dt if dt > 0 else None)

        if (root / "sweep.json").is_file():  # resumed: the designs found done
            with contextlib.suppress(Exception):  # (run_sweep says what is wrong)
                rec = read_record(root, "--out")
                bounds = chunk_bounds(sweep.n_designs, int(rec["chunk"]))
                have = done_chunks(root)
                progress.update(task, completed=bounds.designs_in(have))
        try:
            r = run_sweep(sweep, root, scheduler=scheduler, workers=workers, chunk=chunk,
                          retries=retries, on_chunk=on_chunk)
        except KeyboardInterrupt:
            n = len(done_chunks(root)) if root.is_dir() else 0
            if n:
                err_console.print(f"{n} chunks are written in {escape(str(root))}; run the"
                                  " same command again to compute the rest", highlight=False)
            raise
    feasible, total = _count_feasible(root)
    rate = r.designs_computed / r.seconds if r.seconds > 0 else math.nan
    data = {"sweep": sweep.spec.sweep.name, "out": str(root), "n_designs": sweep.n_designs,
            "n_chunks": r.n_chunks, "chunks_found_done": r.done_before,
            "chunks_computed": len(r.computed),
            "chunks_written_by_workers": r.written_by_workers,
            "designs_computed": r.designs_computed,
            "seconds": r.seconds, "designs_per_second": rate if math.isfinite(rate) else None,
            "feasible": feasible, "designs_written": total,
            "evaluation": {k: r.counts.get(k, 0) for k in COUNTS}}
    if as_json:
        print_json(data)
        return
    how = (f"{len(r.computed)} chunks computed in {r.seconds:.1f} s ({rate:,.0f} designs/s)"
           if r.computed else "nothing left to compute")
    if r.written_by_workers:
        how += f", {r.written_by_workers} of them written by the workers"
    console.print(f"{escape(sweep.spec.sweep.name)}: {sweep.n_designs:,} designs in"
                  f" {r.n_chunks} chunks; {r.done_before} found done, {how}", highlight=False)
    if r.computed:
        c = {k: r.counts.get(k, 0) for k in COUNTS}
        console.print(f"assembly decided on the {COARSE_STEP_DEG} deg grid for"
                      f" {c['assembly_coarse']:,} designs, on the whole 1 deg grid for"
                      f" {c['assembly_whole_grid']:,}; feed metrics located from predicted"
                      f" events {c['feed_located']:,} times, from whole turns"
                      f" {c['feed_whole_turn']:,} ({c['feed_checked']:,} checks)",
                      highlight=False)
    console.print(f"feasible: {feasible:,} of {total:,} designs"
                  f" ({100.0 * feasible / max(total, 1):.1f} %); `sewmech sweep-summary"
                  f" {escape(str(root))}` shows them", highlight=False)


def _count_feasible(root: Path) -> tuple[int, int]:
    from ..sweep_run import done_chunks, read_chunk

    feasible = total = 0
    for k in sorted(done_chunks(root)):
        col = read_chunk(root, k, ["feasible"]).column(0)
        total += len(col)
        feasible += int(np.count_nonzero(col.to_numpy(zero_copy_only=False)))
    return feasible, total


def load_results(root: Path, option: str = "DIR") -> tuple[dict, dict[str, np.ndarray], int]:
    """A sweep directory's record, its columns (the chunks written, in design order) and the
    number of chunks written."""
    import pyarrow as pa

    from ..sweep_run import done_chunks, read_chunk, read_record

    record = read_record(root, option)
    have = sorted(done_chunks(root))
    if not have:
        raise OptionError(option, f"{root}: no chunk of the sweep is written yet",
                          "Run `sewmech sweep` into it first")
    table = pa.concat_tables([read_chunk(root, k) for k in have])
    cols = {name: table.column(name).to_numpy(zero_copy_only=False)
            for name in table.column_names}
    return record, cols, len(have)


@command("sweep-summary")
def sweep_summary_cmd(
    directory: Path = typer.Argument(..., help="the --out directory of `sewmech sweep`"),
    out: Path = typer.Option(None, help="also write the figures (scatter matrix, histograms:"
                             " PNG, SVG), the best designs (CSV) and the summary (JSON) here"),
    color_by: str = typer.Option(None, help="the output that colours the scatter matrix"
                                 " (default: the first output)"),
    sort_by: str = typer.Option(None, help="the output the best designs are sorted by"
                                " (default: the first output)"),
    descending: bool = typer.Option(False, help="best = largest --sort-by (default: smallest)"),
    best: int = typer.Option(10, help="how many of the best feasible designs to list"),
    as_json: bool = typer.Option(False, "--json", help="print the summary as JSON"),
):
    """The feasible region of a sweep and the distributions of its outputs: feasible fraction,
    each output's range, the best feasible designs; with --out a scatter matrix of the
    parameters coloured by an output and histograms."""
    root = user_path(directory, "DIR")
    if not 1 <= best <= 10_000:
        raise OptionError("--best", f"must be in 1 .. 10000, got {best}", "Give e.g. --best 10")
    record, cols, n_written = load_results(root)
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="sweep-summary")
    params = [p.get("column", p["parameter"]) for p in record["parameters"]]
    outputs = [o["column"] for o in record["outputs"]]
    units = record["columns"]
    for option, value in (("--color-by", color_by), ("--sort-by", sort_by)):
        if value is not None and value not in outputs:
            raise OptionError(option, f"'{value}' is not an output of this sweep",
                              f"Outputs: {', '.join(outputs) or 'none'}")
    sort_by = sort_by or (outputs[0] if outputs else None)
    color_by = color_by or (outputs[0] if outputs else None)
    feasible = cols["feasible"].astype(bool)
    n = len(feasible)
    summary = {"sweep": record["name"], "machine": record["machine"]["name"],
               "n_designs": record["n_designs"], "designs_written": n,
               "chunks_written": n_written, "n_chunks": record["n_chunks"],
               "complete": n_written == record["n_chunks"],
               "assembles": int(np.count_nonzero(cols["assembles"])),
               "feasible": int(np.count_nonzero(feasible)),
               "feasible_fraction": float(np.count_nonzero(feasible) / n) if n else None,
               "outputs": {}, "feasible_region": {}, "sort_by": sort_by,
               "descending": descending, "best": []}
    for name in outputs:
        v = cols[name].astype(float)
        fin = np.isfinite(v)
        fv = v[feasible & fin]
        summary["outputs"][name] = {
            "unit": units.get(name, ""), "evaluated": int(np.count_nonzero(fin)),
            "min": _num(v[fin].min()) if fin.any() else None,
            "max": _num(v[fin].max()) if fin.any() else None,
            "feasible_min": _num(fv.min()) if fv.size else None,
            "feasible_max": _num(fv.max()) if fv.size else None}
    for p, name in zip(record["parameters"], params):
        v = cols[name][feasible]
        summary["feasible_region"][name] = {"unit": units.get(name, ""),
                                            "lower": p.get("lower"), "upper": p.get("upper"),
                                            "min": _num(v.min()) if v.size else None,
                                            "max": _num(v.max()) if v.size else None}
    rows = np.nonzero(feasible)[0]
    if sort_by is not None and rows.size:
        key = cols[sort_by][rows].astype(float)
        order = np.argsort(-key if descending else key, kind="stable")
        rows = rows[order]
    shown = ["design", *params, *outputs]
    for i in rows[:best]:
        summary["best"].append({c: _num(cols[c][i]) if c != "design" else int(cols[c][i])
                                for c in shown})
    if out is not None:
        _write_summary(out, summary, record, cols, params, outputs, color_by, rows[:best])
    if as_json:
        print_json(summary)
        return
    state = "complete" if summary["complete"] else (f"partial: {n_written} of"
                                                    f" {record['n_chunks']} chunks written")
    console.print(f"{escape(record['name'])} ({escape(record['machine']['name'])}):"
                  f" {n:,} designs ({state}); {summary['assembles']:,} assemble,"
                  f" {summary['feasible']:,} feasible"
                  f" ({100.0 * (summary['feasible_fraction'] or 0.0):.2f} %)", highlight=False)
    t = Table(title="outputs")
    for c in ("output", "unit", "evaluated", "min", "max", "feasible min", "feasible max"):
        t.add_column(c, justify="left" if c in ("output", "unit") else "right")
    for name, s in summary["outputs"].items():
        t.add_row(escape(name), s["unit"], f"{s['evaluated']:,}", *(_fmt(s[k]) for k in (
            "min", "max", "feasible_min", "feasible_max")))
    console.print(t)
    t = Table(title="feasible region: each parameter's range over the feasible designs")
    for c in ("parameter", "unit", "swept from", "to", "feasible min", "feasible max"):
        t.add_column(c, justify="left" if c in ("parameter", "unit") else "right")
    for name, s in summary["feasible_region"].items():
        t.add_row(escape(name), s["unit"], *(_fmt(s[k]) for k in ("lower", "upper", "min",
                                                                  "max")))
    console.print(t)
    if summary["best"]:  # a column per design: the names are long, the numbers short
        console.print(f"best {len(summary['best'])} feasible designs by {escape(sort_by)}"
                      f" ({'largest' if descending else 'smallest'} first):", highlight=False)
        t = Table()
        t.add_column("design")
        for b in summary["best"]:
            t.add_column(str(b["design"]), justify="right")
        for c in shown[1:]:
            unit = units.get(c, "")
            t.add_row(escape(c + (f" [{unit}]" if unit else "")),
                      *(f"{b[c]:.5g}" if b[c] is not None else "-" for b in summary["best"]))
        console.print(t)
    else:
        console.print("no feasible design", highlight=False)


def _num(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _fmt(x) -> str:
    return "-" if x is None else f"{x:.6g}"


def _spread_is_round_off(v: np.ndarray) -> bool:
    """Whether the finite values of ``v`` are one value: their spread no more than round-off of
    their size (a stitch that a lift cam cannot change, 3.7765 mm give or take 1.6e-11 mm)."""
    from ..display import is_round_off

    v = v[np.isfinite(v)]
    return v.size > 0 and is_round_off(float(np.ptp(v)), float(np.abs(v).max()))


def _constant_note(name: str, unit: str, v: np.ndarray, where: str) -> str:
    from ..display import number

    v = v[np.isfinite(v)]
    return (f"{name} = {number(float(np.median(v)), digits=6)} {unit} in {where} (its spread,"
            f" {np.ptp(v):.2g} {unit}, is round-off: shown as one value)")


def scatter_matrix(record: dict, summary: dict, cols: dict, params: list,
                   color_by: str | None, shown: np.ndarray):
    """The scatter matrix of the parameters (the rows ``shown``), the feasible designs coloured
    by ``color_by``, the others grey; the diagonal: each parameter's histogram. An output that
    takes one value over the feasible designs (up to round-off) is one colour and a note, never
    a colour bar that spreads its round-off over the whole scale."""
    import matplotlib.pyplot as plt

    feasible = cols["feasible"].astype(bool)
    units = record["columns"]
    k = len(params)
    fig, axes = plt.subplots(k, k, figsize=(2.2 * k + 1.5, 2.2 * k + 0.5), squeeze=False,
                             constrained_layout=True)
    f_shown = shown[feasible[shown]]
    i_shown = shown[~feasible[shown]]
    c = cols[color_by][f_shown].astype(float) if color_by else None
    note = None
    if c is not None and _spread_is_round_off(c):
        note = _constant_note(color_by, units.get(color_by, ""), c, "every feasible design")
        c = None
    sc = None
    for a in range(k):
        for b in range(k):
            ax = axes[a, b]
            xa, xb = cols[params[b]], cols[params[a]]
            if a == b:
                ax.hist([xa[feasible], xa], bins=30, color=["C2", "0.8"],
                        label=["feasible", "all"], histtype="stepfilled", alpha=0.7)
            else:
                ax.scatter(xa[i_shown], xb[i_shown], s=2, color="0.85", lw=0)
                if c is None:
                    ax.scatter(xa[f_shown], xb[f_shown], s=3, color="C2", lw=0)
                else:
                    sc = ax.scatter(xa[f_shown], xb[f_shown], s=3, c=c, lw=0, cmap="viridis")
            if a == k - 1:
                ax.set_xlabel(f"{params[b]} [{units.get(params[b], '')}]", fontsize=7)
            if b == 0:
                ax.set_ylabel(f"{params[a]} [{units.get(params[a], '')}]", fontsize=7)
            ax.tick_params(labelsize=6)
    if sc is not None:
        fig.colorbar(sc, ax=axes, label=f"{color_by} [{units.get(color_by, '')}]"
                     " (feasible designs; grey: not feasible)", shrink=0.8)
    title = (f"{record['name']}: {summary['feasible']:,} of {summary['designs_written']:,}"
             " designs feasible")
    if note is not None:  # wrapped to the figure's width (about 11 characters an inch)
        import textwrap

        title += "\n" + textwrap.fill(f"colour: {note}; green: feasible, grey: not",
                                      int(fig.get_figwidth() * 11))
    fig.suptitle(title, fontsize=9)
    return fig


def histograms(record: dict, cols: dict, outputs: list):
    """Each output's histogram, evaluated and feasible designs; an output that takes one value
    (up to round-off) is one bar at that value and says so."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    feasible = cols["feasible"].astype(bool)
    units = record["columns"]
    m = len(outputs)
    ncol = min(3, m)
    nrow = math.ceil(m / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 3 * nrow), squeeze=False,
                             constrained_layout=True)
    for j, name in enumerate(outputs):
        ax = axes[j // ncol, j % ncol]
        v = cols[name].astype(float)
        fin = np.isfinite(v)
        unit = units.get(name, "")
        if fin.any():
            if _spread_is_round_off(v[fin]):  # one bar, not 40 bins of round-off
                x = float(np.median(v[fin]))
                half = 0.05 * abs(x) or 1.0
                bins = np.array([x - half / 4, x + half / 4])
                v = np.where(fin, x, v)
                ax.set_xlim(x - half, x + half)
                ax.set_title(_constant_note(name, unit, cols[name].astype(float)[fin],
                                            "every design").replace(" (", "\n("), fontsize=7)
            else:
                bins = np.histogram_bin_edges(v[fin], bins=40)
            ax.hist(v[fin], bins=bins, color="0.75", label="evaluated")
            ax.hist(v[fin & feasible], bins=bins, color="C2", label="feasible")
        ax.set_xlabel(f"{name} [{unit}]", fontsize=8)
        ax.xaxis.set_major_locator(MaxNLocator(5))  # long tick labels never run together
        ax.set_ylabel("designs", fontsize=8)
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
    for j in range(m, nrow * ncol):
        axes[j // ncol, j % ncol].set_visible(False)
    fig.suptitle(f"{record['name']}: outputs", fontsize=9)
    return fig


def _write_summary(out: Path, summary: dict, record: dict, cols: dict, params: list,
                   outputs: list, color_by: str | None, best_rows: np.ndarray) -> None:
    import csv

    import matplotlib

    matplotlib.use("Agg")

    from ..drawing.figures import save_figure
    from ..files.io import atomic_write
    from ..files.outdir import output_dir

    units = record["columns"]
    rng = np.random.default_rng(0)
    shown = np.arange(len(cols["feasible"]))
    if shown.size > 20_000:  # a readable and quick figure: a fixed random subset
        shown = np.sort(rng.choice(shown, 20_000, replace=False))
    with output_dir(out, command="sweep-summary") as root:
        save_figure(scatter_matrix(record, summary, cols, params, color_by, shown), root,
                    "scatter-matrix")
        if outputs:
            save_figure(histograms(record, cols, outputs), root, "histograms")
        names = ["design", *params, *outputs, "feasible"]
        with atomic_write(root / "best.csv") as fh:
            w = csv.writer(fh)
            w.writerow([n + (f" [{units[n]}]" if units.get(n) else "") for n in names])
            for i in best_rows:
                w.writerow([repr(cols[n][i].item()) if n not in ("design", "feasible")
                            else cols[n][i].item() for n in names])
        with atomic_write(root / "summary.json") as fh:
            json.dump(summary, fh, indent=1)


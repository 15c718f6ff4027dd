"""The figures of a report: each saved as PNG and SVG with its data as CSV, and kept as an HTML
block with the PNG embedded.

Drawing a figure (its layout, then two renderers) costs most of a report's time, so it is done
by worker processes while the report goes on computing: a finished figure is pickled to a
worker, which lays it out once, writes the PNG and the SVG and sends the PNG back for the page.
The page reads the blocks in the order the figures were added. Without workers (``workers=0``)
the same happens in this process.
"""

from __future__ import annotations

import base64
import html
import io
import multiprocessing
import os
import pickle
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

import matplotlib
import pandas as pd

from .fastdraw import fast_text, freeze_ticks, png_bytes, reused_tick_updates
from ..files.io import atomic_write

#: the PNG resolution of every figure, dots per inch
PNG_DPI = 120


def render(fig, root: Path, stem: str) -> bytes:
    """Write ``fig`` as ``root/stem.png`` and ``.svg`` (atomically); return the PNG bytes. The
    layout is computed once and kept for both formats (each format is then drawn once)."""
    # lay out at the PNG's resolution: the PNG then draws with the layout's renderer and finds
    # its text extents measured (about 6 % less drawing; positions are fractions of the figure,
    # so the SVG is laid out the same)
    fig.set_dpi(PNG_DPI)
    with fast_text():
        engine = fig.get_layout_engine()
        if engine is not None:  # lay the figure out once; both formats keep its positions
            engine.execute(fig)
            fig.set_layout_engine(None)
        freeze_ticks(fig)
        with reused_tick_updates():
            # matplotlib's pixels, written fast (a report's PNGs: 3.1 MB, against 3.0 MB from
            # Pillow at zlib level 1)
            png = png_bytes(fig, PNG_DPI)
            svg = io.BytesIO()
            with matplotlib.rc_context({"svg.fonttype": "none"}):  # text as text, not outlines
                fig.savefig(svg, format="svg")
    for ext, payload in (("png", png), ("svg", svg.getvalue())):
        with atomic_write(Path(root) / f"{stem}.{ext}", "wb", encoding=None) as fh:
            fh.write(payload)
    return png


def subplots(nrows: int = 1, ncols: int = 1, **kw):
    """``matplotlib.pyplot.subplots`` without pyplot: a :class:`matplotlib.figure.Figure` of
    its own (the keywords of ``Figure.subplots`` go to the axes, the rest to the figure). The
    report's figures are drawn and saved, never shown, so they need no pyplot window manager;
    and a report process that never imports pyplot saves its 0.17 s before the workers
    start."""
    import inspect

    from matplotlib.figure import Figure

    axes = set(inspect.signature(Figure.subplots).parameters) - {"self", "nrows", "ncols"}
    fig = Figure(**{k: v for k, v in kw.items() if k not in axes})
    return fig, fig.subplots(nrows, ncols, **{k: v for k, v in kw.items() if k in axes})


def close(fig) -> None:
    """Let go of ``fig``: a figure pyplot made is closed there (one of :func:`subplots`
    is not pyplot's and needs nothing)."""
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close(fig)


def save_figure(fig, root: Path, stem: str) -> None:
    """Write ``fig`` as ``root/stem.png`` and ``.svg`` (:func:`render`) and close it, also when
    writing fails."""
    try:
        render(fig, root, stem)
    finally:
        close(fig)


def _render_pickled(payload: bytes, root: str, stem: str) -> bytes:
    """A worker's job: the figure arrives pickled."""
    fig = pickle.loads(payload)
    try:
        return render(fig, Path(root), stem)
    finally:
        close(fig)


def _worker_start(parent_pid: int, forked_from_main_thread: bool):
    from .workers import die_with_parent

    die_with_parent(parent_pid, forked_from_main_thread=forked_from_main_thread)
    import matplotlib

    matplotlib.use("Agg")

    from ...engine import _threads

    _threads.set_threads(1)  # the workers share the cores already: no kernel threads in them


def figure_pool(workers: int | None = None) -> ProcessPoolExecutor | None:
    """Worker processes for drawing figures: by default one per CPU core (the report's own
    computing is done by the time most figures wait to be drawn); None with ``workers=0`` or
    where processes cannot be forked.

    The workers are forked from this process (no script is imported again, so a report can be
    written from any script or notebook); they only unpickle and draw figures, and never touch
    the compiled kernels or their threads. They end with this process, however it ends
    (:mod:`sewmech.app.drawing.workers`), and hold none of its locks."""
    import threading

    n = (os.cpu_count() or 1) if workers is None else int(workers)
    if n <= 0 or "fork" not in multiprocessing.get_all_start_methods():
        return None
    ctx = multiprocessing.get_context("fork")
    # (with "fork", the executor starts every worker in the thread that first submits: this one)
    main = threading.current_thread() is threading.main_thread()
    return ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_worker_start,
                               initargs=(os.getpid(), main))


class _Pending:
    def __init__(self, future: Future, head: str, tail: str):
        self.future, self.head, self.tail = future, head, tail

    def html(self) -> str:
        b64 = base64.b64encode(self.future.result()).decode("ascii")
        return self.head + f'src="data:image/png;base64,{b64}">' + self.tail


class Figures:
    """Collects a report's figures: writes each one's PNG, SVG and CSV into ``root`` and keeps
    its HTML block (``blocks``, in the order added; other HTML may be inserted between them).

    ``pool``: worker processes from :func:`figure_pool` (None: draw here)."""

    def __init__(self, root: Path, machine: str, pool: ProcessPoolExecutor | None = None):
        self.root = Path(root)
        self.machine = machine
        self.pool = pool
        self._items: list = []

    def add(self, fig, name: str, title: str, caption: str, data: pd.DataFrame,
            table: pd.DataFrame | None = None) -> None:
        stem = f"{self.machine}-{name}"
        with atomic_write(self.root / f"{stem}.csv") as fh:
            data.to_csv(fh, index=False, float_format="%.10g")
        head = (f'<figure id="{name}"><h3>{html.escape(title)}</h3>'
                f'<img alt="{html.escape(title)}" ')
        tail = (f"<figcaption>{html.escape(caption)} Files: "
                f'<a href="{stem}.png">PNG</a>, <a href="{stem}.svg">SVG</a>, '
                f'<a href="{stem}.csv">data (CSV)</a>.</figcaption>'
                + (table_html(table) if table is not None else "") + "</figure>")
        if self.pool is None:
            try:
                png = render(fig, self.root, stem)
            finally:
                close(fig)
            future: Future = Future()
            future.set_result(png)
        else:
            payload = pickle.dumps(fig)
            close(fig)
            future = self.pool.submit(_render_pickled, payload, str(self.root), stem)
        self._items.append(_Pending(future, head, tail))

    def insert_html(self, index: int, block: str) -> None:
        """Put an HTML block (no figure) at position ``index`` of the blocks."""
        self._items.insert(index, block)

    def __len__(self) -> int:
        return len(self._items)

    @property
    def blocks(self) -> list[str]:
        """The HTML blocks, each figure's once it is drawn (waits for the workers)."""
        return [x.html() if isinstance(x, _Pending) else x for x in self._items]

    @property
    def figure_count(self) -> int:
        return sum(isinstance(x, _Pending) for x in self._items)


def table_html(df: pd.DataFrame, classes: str = "") -> str:
    """A table for the page, every value at the precision of its quantity
    (:func:`sewmech.app.display.table_cells`): round-off reads 0, a flag yes or no, a value
    that is not defined (NaN: no feed at the zero mark, no take-up setting that passes)
    "none", never "NaN"."""
    from ..display import table_cells

    return table_cells(df).to_html(index=False, classes=classes, border=0, escape=True)


def shade(ax, x, mask, color, label):
    """Shade the spans of ``x`` where ``mask`` holds over the axes' whole height (a window of
    the cycle: needle in the fabric, dog above the plate)."""
    ax.fill_between(x, 0, 1, where=mask, transform=ax.get_xaxis_transform(), color=color,
                    alpha=0.10, lw=0, label=label)

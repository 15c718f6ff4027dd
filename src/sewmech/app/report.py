"""The main job: one self-contained HTML report of a machine's kinematics and timing.

``write_report(machine, out_dir)`` writes ``out_dir/index.html`` (figures embedded, so the page
can be mailed to a colleague), every figure also as PNG and SVG, and every figure's data and
every table as CSV. The directory is built beside the target and swapped in at the end, so a
failed run leaves the previous report untouched and never a half-written one.

Sections so far: machine and convention, computed checks, motion diagrams (needle, shuttle,
take-up eye), the take-up eye path, the timing diagram (with the feed dog), the feed (dog
trajectories forward and reverse, stitch-length curve and scale marks, sensitivity study),
variants side by side, the parameter table and the machine file itself. The thread and dynamics
sections join as those analyses land.
"""

from __future__ import annotations

import collections
import contextlib
import gc
import html
import math
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..engine.extremes import require_reference
from ..engine.kinematics import kinematics
from ..engine.machine import Machine, file_value
from ..sewing import feed as FD
from ..sewing import timing as T
from ..sewing.checks import check_timing
from .figures import Figures, figure_pool, subplots, table_html
from .outdir import output_dir

MM_TO_M = 1e-3


def write_report(machine: Machine, out_dir: str | Path, *, step_deg: float = 1.0,
                 advance: Callable[[str], None] | None = None,
                 variants: Sequence[Machine] = (), workers: int | None = None,
                 collect_garbage: bool = True) -> Path:
    """Compute everything and write the report; returns the path of ``index.html``.

    step_deg: shaft-angle step of the diagrams, deg. advance: called with a step name after
    each step (progress display). variants: machines compared side by side with this one.
    Requires the machine's ``[sewing]`` roles. ``out_dir`` is written through
    :func:`sewmech.outdir.output_dir`: it must be new, empty or written by sewmech, and it
    changes only when the whole report has been built. ``workers``: processes that draw the
    figures meanwhile (default: one per CPU core; 0: draw here). ``collect_garbage=False``:
    what the report leaves for Python's garbage collector (its figures' reference cycles, a few
    MiB) is never collected but kept to the process's end, for a process that ends right
    after the report (the command line): collecting it cost 0.06-0.09 s at the end.
    """
    T.roles(machine)  # a machine the report cannot read fails before the output is touched
    reference = require_reference(machine)  # and one whose angle convention is false
    import matplotlib

    matplotlib.use("Agg")
    # what drawing needs, loaded before the workers are forked (they inherit it instead of
    # each loading it again); the figures are Figure objects of their own: no pyplot
    import matplotlib.backends.backend_agg
    import matplotlib.backends.backend_svg
    import matplotlib.figure

    with output_dir(out_dir, command="report") as root, _few_collections(collect_garbage):
        pool = figure_pool(workers)
        try:
            _build_report(machine, root, step_deg, step=advance or (lambda name: None),
                          variants=variants, reference=reference.text, pool=pool)
        finally:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
    return Path(out_dir) / "index.html"


@contextlib.contextmanager
def _few_collections(collect: bool = True):
    """Python's cyclic garbage collector, off while a report is built (here and in the workers
    forked meanwhile, which inherit it).

    Drawing creates and drops hundreds of thousands of small objects; at the default thresholds
    the collector ran about 380 times per report and its full collections walked every object of
    the loaded modules (numba, pandas, matplotlib) each time: 0.9 s of a 7 s report in one
    process. Everything alive now is frozen (never walked again; what the workers inherit is
    then not touched by their collections either, so fewer copy-on-write pages), and automatic
    collection is off until the report is written: the cycles a report leaves (its figures'
    artists, mostly) are a few MiB (the largest process's peak: 331 MiB against 324 with the
    young generation collected every 50,000 allocations, which still cost 0.1 s a process;
    the whole command 0.95x CPU). Restored on exit; with ``collect=False`` what was made
    meanwhile is frozen first (kept, never walked: see :func:`write_report`)."""
    old = gc.get_threshold()
    freeze = gc.get_freeze_count() == 0  # a caller's own freeze is left as it is
    if freeze:
        gc.freeze()
    gc.set_threshold(0)
    try:
        yield
    finally:
        if not collect:
            gc.freeze()
        gc.set_threshold(*old)
        if freeze and collect:
            gc.unfreeze()


def _build_report(machine: Machine, root: Path, step_deg: float, *, step, variants,
                  reference: str, pool) -> None:
    """Every section of the report, written into the directory ``root``."""
    import matplotlib

    matplotlib.use("Agg")
    s = T.roles(machine)
    has_feed = s.feed_dog is not None and s.regulator is not None
    # the sections that stand alone start now, in the workers if there are any
    names = (["feed"] if has_feed else []) + (["dynamics"] if machine.spec.masses else []) + (
        ["thread"] if machine.spec.thread is not None and machine.spec.thread.bobbin_case_radius
        else []) + (["balancing"] if machine.counterweights else []) + (
        ["accuracy"] if has_feed else []) + (["comparison"] if variants else [])
    sections = _Sections(pool, machine, root, variants, names)
    conv = machine.spec.convention
    n = int(round(360.0 / step_deg))
    phi_deg = np.arange(n + 1) * step_deg  # closed cycle for the plots
    res = kinematics(machine, np.radians(phi_deg))
    step("kinematics")

    checks = check_timing(machine)
    ns = T.needle_stroke(machine)
    w_in, w_below = T.needle_windows(machine)
    ll = T.loop_lift(machine) if s.shuttle_point else None
    sw = T.shuttle_swing(machine) if s.shuttle_link else None
    step("timing checks")

    figs = Figures(root, machine.name)
    ref = f"phi = {conv.reference_phi_deg:g} deg: {conv.reference_event}"

    # ---- motion diagrams ---------------------------------------------------------------
    cols = [("needle point", s.needle_point, "point")]
    if s.shuttle_link:
        cols.append(("shuttle", s.shuttle_link, "link"))
    if s.take_up_eye:
        cols.append(("take-up eye", s.take_up_eye, "point"))
    fig, axs = subplots(3, len(cols), figsize=(4.2 * len(cols), 7.5), sharex=True,
                            constrained_layout=True, squeeze=False)
    data = {"phi_deg": phi_deg}
    for j, (title, name, kind) in enumerate(cols):
        if kind == "point":
            pm = res.point(name)
            series = [(pm.p[:, 1], "height y [mm]"), (pm.v[:, 1] * MM_TO_M, "v_y [m/s]"),
                      (pm.a[:, 1] * MM_TO_M, "a_y [m/s^2]")]
        else:
            lm = res.link(name)
            series = [(np.degrees(np.unwrap(lm.theta)), "angle [deg]"),
                      (lm.omega, "omega [rad/s]"), (lm.epsilon, "epsilon [rad/s^2]")]
        for i, (y, label) in enumerate(series):
            ax = axs[i, j]
            ax.plot(phi_deg, y, lw=1.4)
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
            data[f"{name} {label}"] = y
        axs[0, j].set_title(title)
        axs[-1, j].set_xlabel("shaft angle phi [deg]")
        axs[-1, j].set_xticks(np.arange(0, 361, 90))
    fig.suptitle(f"{machine.name}: motion diagrams at {machine.rpm:g} rpm ({ref})")
    figs.add(fig, "motion", "Motion diagrams",
             f"Position, velocity and acceleration over one revolution at {machine.rpm:g}"
             " rpm (velocities in m/s, accelerations in m/s^2).", pd.DataFrame(data))

    # ---- take-up eye path ----------------------------------------------------------------
    if s.take_up_eye:
        p = res.point(s.take_up_eye).p
        fig, ax = subplots(figsize=(5.5, 5.5), constrained_layout=True)
        ax.plot(p[:, 0], p[:, 1], lw=1.6)
        for k in range(0, n, max(1, int(round(30 / step_deg)))):
            ax.plot(p[k, 0], p[k, 1], "o", ms=3, color="C1")
            ax.annotate(f"{phi_deg[k]:.0f}", p[k], textcoords="offset points", xytext=(4, 2),
                        fontsize=7)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"{machine.name}: take-up eye path (labels: phi in deg)")
        figs.add(fig, "eye-path", "Take-up eye path",
                 "The thread eye's coupler curve (the report's 'big knife'); dots every"
                 " 30 deg of shaft angle.",
                 pd.DataFrame({"phi_deg": phi_deg, "x_mm": p[:, 0], "y_mm": p[:, 1]}))

    # ---- timing diagram ------------------------------------------------------------------
    if has_feed:
        reg_max = FD.regulator_range_deg(machine)[1]
        fres = kinematics(machine, np.radians(phi_deg), points=[s.feed_dog],
                          inputs={s.regulator: math.radians(reg_max)})
        dog = fres.point(s.feed_dog).p
        dog_up = dog[:, 1] > s.plate_y
    rows = 1 + bool(s.shuttle_link) + bool(s.take_up_eye) + 2 * has_feed
    fig, axs = subplots(rows, 1, figsize=(9, 2.3 * rows + 0.6), sharex=True,
                            constrained_layout=True, squeeze=False)
    axs = axs[:, 0]
    tdata = {"phi_deg": phi_deg}
    y_needle = res.point(s.needle_point).p[:, 1]
    ax = axs[0]
    ax.plot(phi_deg, y_needle, label="needle point")
    ax.axhline(s.plate_y, color="k", lw=1, label="throat plate")
    ax.axhline(s.plate_y + s.fabric_thickness, color="0.5", lw=1, ls="--", label="fabric top")
    ax.set_ylabel("height y [mm]")
    tdata["needle_point_y_mm"] = y_needle
    i = 1
    if s.shuttle_link:
        th = np.degrees(np.unwrap(res.link(s.shuttle_link).theta))
        axs[i].plot(phi_deg, th, color="C2", label="shuttle angle")
        axs[i].set_ylabel("shuttle [deg]")
        tdata["shuttle_deg"] = th
        i += 1
    if s.take_up_eye:
        ye = res.point(s.take_up_eye).p[:, 1]
        axs[i].plot(phi_deg, ye, color="C3", label="take-up eye")
        axs[i].set_ylabel("eye y [mm]")
        tdata["take_up_eye_y_mm"] = ye
        i += 1
    if has_feed:
        axs[i].plot(phi_deg, dog[:, 0], color="C4", label="feed dog x (fore-aft)")
        axs[i].set_ylabel("dog x [mm]")
        axs[i + 1].plot(phi_deg, dog[:, 1], color="C5", label="feed dog tooth tip")
        axs[i + 1].axhline(s.plate_y, color="k", lw=1, label="throat plate")
        axs[i + 1].set_ylabel("dog y [mm]")
        tdata[f"dog_x_mm_at_regulator_{reg_max:g}deg"] = dog[:, 0]
        tdata[f"dog_y_mm_at_regulator_{reg_max:g}deg"] = dog[:, 1]
        tdata["dog_above_plate"] = dog_up
    inside = w_in.contains(phi_deg)
    tdata["needle_in_fabric"] = inside
    for ax in axs:
        _shade(ax, phi_deg, inside, "C0", "needle in fabric")
        if has_feed:
            _shade(ax, phi_deg, dog_up, "C5", "dog above plate")
        ax.axvline(ns.top_phi_deg, color="0.3", lw=0.8, ls=":")
        if ll is not None:
            ax.axvline(ll.phi_deg, color="C2", lw=0.8, ls="--")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    if ll is not None:
        axs[0].annotate(f"shuttle meets needle\nphi = {ll.phi_deg:.1f} deg, lift"
                        f" {ll.rise_mm:.2f} mm", (ll.phi_deg, ns.bottom_y),
                        textcoords="offset points", xytext=(8, 8), fontsize=7)
    axs[-1].set_xlabel("shaft angle phi [deg]")
    axs[-1].set_xticks(np.arange(0, 361, 30))
    fig.suptitle(f"{machine.name}: timing diagram ({ref}; dotted: needle top)")
    figs.add(fig, "timing-diagram", "Timing diagram",
             "Needle height with the throat plate and the fabric top, shuttle angle,"
             " take-up eye height and the feed dog's fore-aft and vertical motion (at the"
             " longest forward stitch) over one revolution; shaded: needle in the fabric"
             " and dog above the plate; dashed: the shuttle point meets the needle.",
             pd.DataFrame(tdata))
    step("figures")
    blocks = figs.blocks
    feed_tables = {}
    for name, (section_blocks, result) in sections.results():
        if name == "feed":
            feed_tables = result
            for done in ("feed trajectories", "stitch curve", "sensitivity"):
                step(done)
        elif name == "dynamics":
            result.to_csv(root / f"{machine.name}-dynamics-key-figures.csv", index=False,
                          float_format="%.10g")
            blocks.append(_dynamics_intro(machine, result))
        elif name == "balancing":
            result["comparison"].to_csv(root / f"{machine.name}-balancing-criteria.csv",
                                        index=False, float_format="%.10g")
            blocks.append(result["html"])
        elif name == "accuracy":
            result["table"].to_csv(root / f"{machine.name}-accuracy.csv", index=False,
                                   float_format="%.10g")
            blocks.append(result["html"])
        blocks += section_blocks
        if name != "feed":
            step(name)

    # ---- tables --------------------------------------------------------------------------
    chk = pd.DataFrame([{"check": c.name, "value": c.value, "unit": c.unit,
                         "expected": c.expected, "result": "pass" if c.passed else "FAIL",
                         "source": c.source} for c in checks])
    chk.to_csv(root / f"{machine.name}-checks.csv", index=False, float_format="%.10g")
    timing_rows = [("needle top dead centre", ns.top_phi_deg, "deg"),
                   ("needle bottom dead centre", ns.bottom_phi_deg, "deg"),
                   ("needle stroke", ns.stroke, "mm"),
                   ("needle enters fabric", w_in.start_deg % 360, "deg"),
                   ("needle leaves fabric", w_in.end_deg % 360, "deg"),
                   ("needle below plate from", w_below.start_deg % 360, "deg"),
                   ("needle below plate to", w_below.end_deg % 360, "deg")]
    if ll is not None:
        timing_rows += [("shuttle point meets needle", ll.phi_deg, "deg"),
                        ("  after needle bottom dead centre", ll.after_bdc_deg, "deg")]
    if sw is not None:
        timing_rows += [("shuttle angle min", sw.min_deg, "deg"),
                        ("shuttle angle max", sw.max_deg, "deg")]
    if has_feed:
        fc = feed_tables["cycle"]
        timing_rows += [(f"dog rises through the plate (regulator {reg_max:g} deg)",
                         float(fc.rise_deg), "deg"),
                        ("dog at the top of its lift", float(fc.top_deg), "deg"),
                        ("dog halfway through its feed stroke", float(fc.mid_feed_deg),
                         "deg"),
                        ("dog drops through the plate", float(fc.fall_deg), "deg"),
                        ("dog lift above the plate", float(fc.lift_mm), "mm"),
                        ("stitch length", float(fc.stitch_mm), "mm")]
    tim = pd.DataFrame(timing_rows, columns=["event", "value", "unit"])
    tim.to_csv(root / f"{machine.name}-timing-events.csv", index=False,
               float_format="%.10g")
    shown = [file_value(v, u) for v, u in zip(machine.defaults, machine.parameter_units)]
    par = pd.DataFrame({"parameter": machine.parameter_names,
                        "value": [x for x, _ in shown], "unit": [u for _, u in shown]})
    par.to_csv(root / f"{machine.name}-parameters.csv", index=False, float_format="%.10g")
    src = Path(machine.file)
    text = src.read_text(encoding="utf-8") if src.is_file() else ""
    if text:
        (root / src.name).write_text(text, encoding="utf-8")
    step("tables")

    for name, df in feed_tables.get("csv", {}).items():
        df.to_csv(root / f"{machine.name}-{name}.csv", index=False, float_format="%.10g")
    page = _page(machine, f"{ref} ({reference})", chk, tim, par, blocks, text, src.name,
                 feed_tables.get("html", []))
    (root / "index.html").write_text(page, encoding="utf-8")
    step("page")


#: what the sections that run in worker processes read (set before the workers are forked)
_SHARED: dict = {}


def _run_section(name: str):
    """One section of the report with its figures (drawn where it runs); returns its HTML
    blocks and what the page needs of it (the feed's tables, the dynamics' key figures)."""
    machine, root, variants = _SHARED["machine"], _SHARED["root"], _SHARED["variants"]
    figs = Figures(root, machine.name)
    result = None
    if name == "feed":
        result = _feed_section(figs, machine, lambda done: None)
    elif name == "thread":
        _thread_section(figs, machine)
    elif name == "dynamics":
        from .report_dynamics import dynamics_section

        result = dynamics_section(figs, machine, variants)
    elif name == "balancing":
        from .report_balancing import balancing_section, section_html

        sec = balancing_section(figs, machine)
        result = {"comparison": sec["comparison"], "html": section_html(machine, sec)}
    elif name == "accuracy":
        from .report_accuracy import accuracy_section

        result = accuracy_section(figs, machine)
    else:
        _comparison(figs, [machine] + list(variants))
    return figs.blocks, result


#: the sections, longest first by their CPU time in a worker (jb1-3 on the 2-core machine, after
#: the loop solver's tenfold: dynamics 1.9 s, balancing 1.8, feed 1.5, thread 0.8, the comparison
#: 0.4, accuracy 0.25): the two longest start in the workers, this process takes the feed when
#: its own figures are drawn, and the short ones fill in at the end
_SECTION_ORDER = ["dynamics", "balancing", "feed", "thread", "comparison", "accuracy"]


class _Sections:
    """The report's sections that need nothing of the others (feed, dynamics, thread, the
    comparison), started at once in the worker processes: each worker takes the next one when
    it is done, and this process, once its own part is drawn, takes the next one too, always
    the longest left (so that the last ones to finish are short and no core waits while a
    section waits). :meth:`results` gives them in page order."""

    def __init__(self, pool, machine, root, variants, names):
        _SHARED.update(machine=machine, root=root, variants=variants)
        self.names = names
        self.pool = pool
        self.futures: dict = {}
        self.lock = threading.Lock()
        # the longest first, so that the last ones to finish are short
        self.queue = collections.deque(sorted(names, key=_SECTION_ORDER.index))
        if pool is not None:
            for _ in range(min(pool._max_workers, len(self.queue))):
                self._next()

    def _next(self, done=None):
        with self.lock:
            if not self.queue or (done is not None and done.cancelled()):
                return
            name = self.queue.popleft()
            try:
                future = self.futures[name] = self.pool.submit(_run_section, name)
            except RuntimeError:  # the pool is shut down (an error or a signal): stop here
                self.queue.clear()
                return
        future.add_done_callback(self._next)

    def results(self):
        try:
            here = {}
            while True:
                with self.lock:
                    if not self.queue:
                        break
                    name = self.queue.popleft()
                here[name] = _run_section(name)
            for name in self.names:
                yield name, here[name] if name in here else self.futures[name].result()
        finally:
            _SHARED.clear()


def _feed_section(figs: Figures, machine: Machine, step) -> dict:
    """Dog trajectories, stitch curve with scale marks, sensitivity grid (figures + tables)."""
    lo, hi = FD.regulator_range_deg(machine)
    curve = FD.stitch_curve(machine, 121)  # the figure's curve, and the marks' start
    marks = FD.scale_marks(machine, 0.5, curve=curve)
    by_len = {m.stitch_mm: m.regulator_deg for m in marks}
    longest = min(max(by_len), -min(by_len))
    half = 0.5 * round(longest)  # a mark near the middle (marks are every 0.5 mm)
    wanted = sorted({-longest, -half, 0.0, half, longest} & set(by_len))
    regs = np.array([by_len[w] for w in wanted])
    c = FD.feed_cycles(machine, regs)
    fig, (ax, bx) = subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
    data = {"phi_deg": c.phi_deg}
    for k, reg in enumerate(regs):
        lab = f"{c.stitch_mm[k]:+.2f} mm (regulator {reg:+.2f} deg)"
        ax.plot(c.x[k], c.y[k], lw=1.4, label=lab)
        data[f"x_mm_reg_{reg:+.4f}deg"] = c.x[k]
        data[f"y_above_plate_mm_reg_{reg:+.4f}deg"] = c.y[k]
    for a in (ax, bx):
        a.axhline(0.0, color="k", lw=1)
        a.set_xlabel("dog tooth tip x [mm] (+x: towards the back)")
        a.set_ylabel("height above the throat plate [mm]")
        a.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower center")
    ax.set_title("tooth-tip paths by stitch length")
    f, r = int(np.argmax(c.stitch_mm)), int(np.argmin(c.stitch_mm))
    xc = 0.5 * (c.x[f].max() + c.x[f].min())
    bx.plot(c.x[f] - xc, c.y[f], lw=1.6, label=f"forward {c.stitch_mm[f]:+.2f} mm")
    xr = 0.5 * (c.x[r].max() + c.x[r].min())
    bx.plot(-(c.x[r] - xr), c.y[r], lw=1.6, ls="--",
            label=f"reverse {c.stitch_mm[r]:+.2f} mm, mirrored")
    bx.set_xlabel("x about the middle of the stroke [mm] (reverse mirrored)")
    bx.legend(fontsize=7, loc="lower center")
    bx.set_title("reverse feed against forward")
    figs.add(fig, "feed-trajectories", "Feed dog trajectories",
             "Paths of the dog's tooth tip over one revolution for stitch lengths from the"
             " longest reverse to the longest forward; right: the reverse path mirrored onto"
             " the forward one to compare their shapes. The fabric moves with the dog only"
             " above the plate line.", pd.DataFrame(data))
    step("feed trajectories")

    fig, (ax, bx) = subplots(2, 1, figsize=(8, 6.4), sharex=True, constrained_layout=True)
    ax.plot(curve.regulator_deg, curve.stitch_mm, lw=1.6)
    ax.plot([m.regulator_deg for m in marks], [m.stitch_mm for m in marks], "o", ms=4,
            color="C1", label="scale marks (every 0.5 mm)")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_ylabel("stitch length [mm] (+ forward)")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    bx.plot(curve.regulator_deg, curve.lift_mm, color="C2", label="lift above plate")
    bx.axhspan(*FD.FEED_DOG_RISE_MM, color="C2", alpha=0.1, label="DOMAIN.md 1.1 band")
    bx.set_ylabel("dog lift [mm]")
    bx.set_xlabel(f"regulator angle [deg] (travel {lo:g} .. {hi:g})")
    bx.legend(fontsize=8)
    bx.grid(True, alpha=0.3)
    fig.suptitle(f"{machine.name}: stitch length and lift against the regulator setting")
    mk = pd.DataFrame({"stitch_mm": [m.stitch_mm for m in marks],
                       "regulator_deg": [m.regulator_deg for m in marks]})
    figs.add(fig, "stitch-curve", "Stitch length and scale-plate marks",
             "Stitch length (the dog's fore-aft travel while above the plate) and lift over the"
             " regulator's travel; dots: the regulator angle of every 0.5 mm mark of the scale"
             " plate, forward and reverse (table below).", curve.to_pandas(), table=mk)
    step("stitch curve")

    sens = FD.sensitivity(machine, 0.05)
    n = len(sens.labels)
    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    fig, axs = subplots(nrow, ncol, figsize=(3.3 * ncol, 2.8 * nrow), squeeze=False,
                            constrained_layout=True)
    sc = sens.cycles
    sdata = {"phi_deg": sc.phi_deg}
    for i, label in enumerate(sens.labels):
        a = axs.flat[i]
        for j, (tag, st) in enumerate((("-5%", ":"), ("0", "-"), ("+5%", "--"))):
            a.plot(sc.x[i, j], sc.y[i, j], ls=st, lw=1.2, label=tag)
            sdata[f"{label} {tag} x_mm"] = sc.x[i, j]
            sdata[f"{label} {tag} y_mm"] = sc.y[i, j]
        a.axhline(0, color="k", lw=0.8)
        a.set_title(label, fontsize=8)
        a.tick_params(labelsize=7)
        a.grid(True, alpha=0.3)
    axs.flat[0].legend(fontsize=7)
    for a in list(axs.flat)[n:]:
        a.axis("off")
    fig.suptitle(f"{machine.name}: sensitivity of the dog path to each feed parameter"
                 f" (regulator {sens.regulator_deg:g} deg; x, height above plate in mm)")
    table = sens.table().drop(columns="names")
    figs.add(fig, "feed-sensitivity", "Feed sensitivity study",
             "Each structural parameter of the feed changed by -5 %, 0, +5 % (the others held);"
             " the table gives the change of stitch length, lift and feed timing (the shaft"
             " angle at which the dog is halfway through its feed stroke).",
             pd.DataFrame(sdata), table=table)
    step("sensitivity")
    return {"cycle": FD.feed_cycles(machine, hi), "csv": {"scale-marks": mk,
                                                           "feed-sensitivity-table": table}}


def _thread_section(figs: Figures, machine: Machine):
    """Thread balance: supply, demand and its parts, overfeed, with its own checks."""
    from ..sewing import thread as TH

    b = TH.thread_balance(machine)
    checks = TH.check_thread(machine, b)
    fig, (ax, bx) = subplots(2, 1, figsize=(9, 6.4), sharex=True, constrained_layout=True)
    ax.plot(b.phi_deg, b.supply, lw=1.8, label="take-up supply S")
    ax.plot(b.phi_deg, b.demand, lw=1.8, label="demand D (relative to the stitch set)")
    k = int(np.argmin(b.supply))
    ax.plot(b.phi_deg, b.bar - b.bar[k], lw=1, ls=":", label="  path to the eye (change)")
    ax.plot(b.phi_deg, b.penetration - b.penetration[k], lw=1, ls=":",
            label="  eye's leg through the fabric")
    ax.plot(b.phi_deg, b.loop, lw=1, ls=":", label="  loop round the bobbin case")
    ax.set_ylabel("thread [mm]")
    ax.legend(fontsize=7, loc="upper left")
    bx.plot(b.phi_deg, b.overfeed, color="C3", lw=1.8, label="overfeed O = S - D")
    bx.axhline(0, color="k", lw=0.8)
    bx.axhspan(0, TH.CHECK_SPRING_STROKE_MM, color="C2", alpha=0.1, label="check-spring stroke")
    bx.set_ylabel("overfeed [mm]")
    bx.set_xlabel("shaft angle phi [deg]")
    bx.set_xticks(np.arange(0, 361, 30))
    for a in (ax, bx):
        loop = (b.phi_deg - b.seizure_deg) % 360 < (b.cast_off_deg - b.seizure_deg) % 360
        _shade(a, b.phi_deg, loop, "C1", "loop on the shuttle")
        for x, st in ((b.needle_entry_deg, "--"), (b.take_up_top_deg, ":")):
            a.axvline(x, color="0.3", lw=0.8, ls=st)
        a.grid(True, alpha=0.3)
    bx.legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{machine.name}: needle-thread balance, stitch {b.stitch_mm:g} mm, fabric"
                 f" {b.fabric_mm:g} mm\n(dashed: the needle enters the fabric; dotted: least"
                 " supply, the stitch is set)")
    table = pd.DataFrame([{"check": c.name, "value": c.value, "unit": c.unit,
                           "expected": c.expected, "result": "pass" if c.passed else "FAIL",
                           "source": c.source} for c in checks])
    figs.add(fig, "thread-balance", "Needle-thread balance",
             "What the take-up releases (supply) against what needle, fabric and shuttle hold"
             " (demand) over one revolution, and their difference, the overfeed (DOMAIN.md 2.3);"
             " shaded: the loop on the shuttle from seizure to cast-off. The balance checks"
             " below are design diagnostics of the thread path, the take-up and the loop model"
             " (see the sewmech.thread documentation), separate from the machine-class checks.",
             b.to_pandas(), table=table)
    if machine.spec.thread.adjust is not None:
        _adjust_figure(figs, machine)
    _consumption_figure(figs, machine)


def _consumption_figure(figs: Figures, machine: Machine):
    """Thread per stitch against stitch length and fabric thickness, with the industry formula."""
    from ..sewing import thread as TH

    d = machine.spec.thread.thread_diameter
    length = np.linspace(1.0, 4.0, 31)
    fig, ax = subplots(figsize=(7.5, 4.2), constrained_layout=True)
    rows = []
    for k, t in enumerate((0.5, 1.0, 2.0, 4.0, 6.0)):
        c = TH.consumption_per_stitch(length, t, d)
        ax.plot(length, c["total"], color=f"C{k}", lw=1.6, label=f"fabric {t:g} mm")
        ax.plot(length, c["industry"], color=f"C{k}", lw=1, ls="--")
        rows += [{"stitch_mm": l, "fabric_mm": t, "needle_mm": n, "bobbin_mm": b,
                  "total_mm": tot, "industry_formula_mm": ind}
                 for l, n, b, tot, ind in zip(length, c["needle"], c["bobbin"], c["total"],
                                              c["industry"])]
    ax.set_xlabel("stitch length [mm]")
    ax.set_ylabel("needle + bobbin thread per stitch [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{machine.name}: thread per stitch\n(solid: l + t + pi d/2 per thread,"
                 f" d = {d:g} mm; dashed: C = 2 + 2TS)", fontsize=10)
    figs.add(fig, "thread-consumption", "Thread consumption per stitch",
             "Needle and bobbin thread of one balanced lockstitch against stitch length and"
             " fabric thickness (DOMAIN.md 2.1), beside the industry formula C = 2 + 2TS per"
             " inch of seam; the two differ by the thread-diameter term.", pd.DataFrame(rows))


def _adjust_figure(figs: Figures, machine: Machine):
    """The adjustable take-up: margin over (thickness, setting) and the recommended setting."""
    from ..sewing import thread as TH

    adj = machine.spec.thread.adjust
    r = TH.adjust_take_up(machine, adj.parameter, np.linspace(adj.min, adj.max, 57))
    unit = machine.parameter_units[machine.parameter_index(adj.parameter)]
    fig, (ax, bx) = subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    im = ax.pcolormesh(r.settings, r.thickness_mm, r.margin, cmap="RdYlGn", vmin=-5, vmax=5,
                       shading="nearest")
    ax.contour(r.settings, r.thickness_mm, r.margin, levels=[0.0], colors="k", linewidths=1)
    ax.plot(r.best, r.thickness_mm, "o-", color="k", ms=3, label="recommended")
    ax.set_xlabel(f"{adj.parameter} [{unit}]")
    ax.set_ylabel("fabric thickness [mm]")
    ax.set_title("margin to the balance checks [mm] (black line: 0)")
    ax.legend(fontsize=7)
    fig.colorbar(im, ax=ax)
    bx.plot(r.thickness_mm, r.best, "o-")
    bx.set_xlabel("fabric thickness [mm]")
    bx.set_ylabel(f"recommended {adj.parameter} [{unit}]")
    bx.grid(True, alpha=0.3)
    bx.set_title("setting per thickness (gaps: no setting passes)")
    data = pd.DataFrame(r.margin, columns=[f"{adj.parameter}={v:.4g}" for v in r.settings])
    data.insert(0, "fabric_mm", r.thickness_mm)
    figs.add(fig, "take-up-adjustment", "Adjustable take-up",
             f"The take-up's adjustable dimension {adj.parameter} over its range against fabric"
             " thickness: the margin to all the thread-balance checks, and the setting with the"
             " largest margin for each thickness (table).", data, table=r.table())


def _dynamics_intro(machine: Machine, key: pd.DataFrame) -> str:
    loads = "; ".join(f"{ld.name} {ld.force_N:g} N over "
                      + ", ".join(f"{a:g}-{b:g}" for a, b in ld.windows_deg) + " deg"
                      for ld in machine.spec.loads) or "none"
    return (f'<h2 id="dynamics">Dynamics</h2><p>Inverse dynamics of the whole machine at'
            f" {machine.rpm:g} rpm, gravity on, at the longest forward stitch (the JB dynamics"
            f" report's hardest case). Process loads: {html.escape(loads)}. Link masses:"
            " see the machine file's [masses] tables.</p>" + table_html(key.round(5))
            + f'<p>Data: <a href="{machine.name}-dynamics-key-figures.csv">key figures'
            " (CSV)</a>.</p>")


def _key_figures(m: Machine) -> dict:
    """The numbers a designer compares between machine variants."""
    s = T.roles(m)
    out = {}
    ns = T.needle_stroke(m)
    out["needle stroke [mm]"] = ns.stroke
    if s.shuttle_link:
        out["shuttle swing [deg]"] = T.shuttle_swing(m).swing_deg
    if s.shuttle_point:
        out["loop lift [mm]"] = T.loop_lift(m).rise_mm
    if s.take_up_eye:
        out["take-up lag [deg]"] = T.take_up_lag_deg(m)
    if s.feed_dog and s.regulator:
        lo, hi = FD.regulator_range_deg(m)
        c = FD.feed_cycles(m, [lo, hi])
        out["longest forward stitch [mm]"] = float(c.stitch_mm[1])
        out["longest reverse stitch [mm]"] = float(c.stitch_mm[0])
        out["dog lift, longest forward [mm]"] = float(c.lift_mm[1])
        out["dog rises through plate [deg]"] = float(c.rise_deg[1])
        out["dog drops through plate [deg]"] = float(c.fall_deg[1])
        out["mid feed stroke [deg]"] = float(c.mid_feed_deg[1])
    return out


def _comparison(figs: Figures, machines: Sequence[Machine]):
    """Key figures, dog paths and stitch curves of machine variants side by side."""
    table = pd.DataFrame({m.name: _key_figures(m) for m in machines})
    table.insert(0, "figure", table.index)
    fig, (ax, bx) = subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    data = {}
    for m in machines:
        s = m.spec.sewing
        if not (s and s.feed_dog and s.regulator):
            continue
        lo, hi = FD.regulator_range_deg(m)
        c = FD.feed_cycles(m, hi)
        ax.plot(c.x - 0.5 * (c.x.max() + c.x.min()), c.y, lw=1.5, label=m.name)
        curve = FD.stitch_curve(m, 61)
        bx.plot(curve.regulator_deg, curve.stitch_mm, lw=1.5, label=m.name)
        data[f"{m.name} phi_deg"] = c.phi_deg
        data[f"{m.name} x_mm"] = c.x
        data[f"{m.name} y_above_plate_mm"] = c.y
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("dog x about mid-stroke [mm]")
    ax.set_ylabel("height above plate [mm]")
    ax.set_title("dog path at the longest forward stitch")
    bx.set_xlabel("regulator angle [deg]")
    bx.set_ylabel("stitch length [mm]")
    bx.set_title("stitch-length curves")
    for a in (ax, bx):
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
    names = " against ".join(m.name for m in machines)
    figs.add(fig, "comparison", f"Variants side by side: {names}",
             "Key figures of each variant (table), the dog's path at the longest forward stitch"
             " and the stitch-length curves.", pd.DataFrame(data), table=table)


def _shade(ax, x, mask, color, label):
    ax.fill_between(x, 0, 1, where=mask, transform=ax.get_xaxis_transform(), color=color,
                    alpha=0.10, lw=0, label=label)


_CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{margin-bottom:0.2em} .sub{color:#555;margin-top:0}
table{border-collapse:collapse;margin:0.5em 0 1.5em 0;font-size:0.9em}
th,td{padding:0.25em 0.7em;border-bottom:1px solid #ddd;text-align:left}
td:nth-child(2){font-variant-numeric:tabular-nums}
.checks td:nth-child(5){font-weight:bold}
figure{margin:1.5em 0} figure img{max-width:100%} figcaption{color:#444;font-size:0.9em}
pre{background:#f6f6f6;padding:1em;overflow-x:auto;font-size:0.8em}
.pass{color:#1a7f37} .fail{color:#cf222e}
"""


def _changes_html(machine) -> str:
    """The values changed with ``--set`` (the file below shows the file as it is)."""
    if not machine.changes:
        return ""
    items = []
    for name, value in machine.changes.items():
        unit = ("mm" if name.rsplit(".", 1)[-1] in ("width", "stroke") else "deg") \
            if name not in machine.parameter_names else \
            machine.parameter_units[machine.parameter_index(name)]
        shown = f"{math.degrees(value):.6g} deg" if unit in ("rad", "deg") else \
            "{:.6g} {}".format(*file_value(value, unit)).rstrip(" 1")
        items.append(f"<li><code>{html.escape(name)}</code> = {html.escape(shown)}</li>")
    return ('<p class="fail">This report is of a variant: these values differ from the machine'
            f' file (set with --set):</p><ul>{"".join(items)}</ul>')


def _page(machine, ref, chk, tim, par, blocks, file_text, file_name, extra=()) -> str:
    info = machine.spec.machine
    n_fail = int((chk["result"] != "pass").sum()) if len(chk) else 0
    verdict = (f'<p class="pass">All {len(chk)} checks pass.</p>' if n_fail == 0 else
               f'<p class="fail">{n_fail} of {len(chk)} checks fail.</p>')
    chk_html = table_html(chk, "checks").replace("<td>pass</td>", '<td class="pass">pass</td>')
    chk_html = chk_html.replace("<td>FAIL</td>", '<td class="fail">FAIL</td>')
    e = html.escape
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>sewmech report: {e(info.name)}</title><style>{_CSS}</style></head><body>
<h1>{e(info.title or info.name)}</h1>
<p class="sub">{e(info.description)}</p>
<p>Angle convention: {e(ref)}. {e(machine.spec.convention.description)} Working speed
{machine.rpm:g} rpm. Lengths in mm. Machine file: <a href="{e(file_name)}">{e(file_name)}</a>.</p>
{_changes_html(machine)}<h2>Checks</h2>{verdict}{chk_html}
<p>Data: <a href="{e(info.name)}-checks.csv">checks (CSV)</a>.</p>
<h2>Timing</h2>{table_html(tim)}
<p>Data: <a href="{e(info.name)}-timing-events.csv">timing events (CSV)</a>.</p>
<h2>Figures</h2>
{''.join(blocks)}
{''.join(extra)}
<h2>Machine data</h2>
<p>Every value of the machine file as a named parameter (angles shown in degrees). Sources and
estimates are recorded beside each value in the file below.
<a href="{e(info.name)}-parameters.csv">parameters (CSV)</a>.</p>
{table_html(par)}
<details><summary>Machine file {e(file_name)}</summary><pre>{e(file_text)}</pre></details>
<p class="sub">Written by sewmech.</p>
</body></html>
"""

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
import math
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ...engine.extremes import require_reference
from ...engine.kinematics import kinematics
from ...engine.machine import Machine, file_value
from ...sewing import feed as FD
from ...sewing import timing as T
from ...sewing.checks import check_timing
from ..drawing.figures import Figures, figure_pool, shade, subplots
from ..drawing.mechanism import mechanism_figure
from ..files.outdir import output_dir
from .comparison import comparison_section
from .feed import feed_section
from .page import dynamics_intro, left_out_html, page_html
from .thread import thread_section

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

    with output_dir(out_dir, command="report", machine=machine.name) as root, _few_collections(collect_garbage):
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
        # the housing's section: the balancing worker's when there is one (it reuses its
        # answer on the vibration criterion), else its own
        ["vibration"] if _has_vibration(machine) and not machine.counterweights else []) + (
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

    # ---- the mechanism, every point and pair labelled: the key to the tables' names --------
    _mechanism(figs, machine, res, phi_deg)

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
    load_on = None
    if machine.spec.loads:  # where each process load acts, at the diagram's setting
        from ...engine.dynamics import inverse_dynamics

        at = {s.regulator: math.radians(reg_max)} if has_feed else None
        load_on = inverse_dynamics(machine, np.radians(phi_deg), inputs=at).load_on > 0.5
    rows = 1 + bool(s.shuttle_link) + bool(s.take_up_eye) + 2 * has_feed + (
        load_on is not None)
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
        i += 2
    if load_on is not None:
        ax = axs[i]
        names = [ld.name for ld in machine.spec.loads]
        for j, name in enumerate(names):
            on = load_on[:, j]
            ax.fill_between(phi_deg, j - 0.35, j + 0.35, where=on, step="mid",
                            color=f"C{(j + 6) % 10}", alpha=0.8, label=name)
            tdata[f"load_acts: {name}"] = on
        ax.set_yticks(range(len(names)), [n if len(n) <= 28 else n[:27] + "…" for n in names],
                      fontsize=7)
        ax.set_ylim(-0.7, len(names) - 0.3)
        ax.set_ylabel("process loads")
    inside = w_in.contains(phi_deg)
    tdata["needle_in_fabric"] = inside
    for ax in axs:
        shade(ax, phi_deg, inside, "C0", "needle in fabric")
        if has_feed:
            shade(ax, phi_deg, dog_up, "C5", "dog above plate")
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
             " and dog above the plate; dashed: the shuttle point meets the needle."
             + (" Last row: where each process load of the machine file acts (its windows"
                " and its conditions on the motion, at the working speed)."
                if load_on is not None else ""),
             pd.DataFrame(tdata))
    step("figures")
    blocks = figs.blocks
    mechanism = blocks.pop(0)
    blocks.insert(0, '<h2 id="motion-timing">Motion and timing</h2>')
    feed_tables = {}
    order = list(_SECTIONS)

    def left_out(upto: int) -> None:  # a note for every section before ``upto`` not computed
        while order and len(_SECTIONS) - len(order) < upto:
            other = order.pop(0)
            blocks.append(left_out_html(_SECTION_IDS.get(other, other), _SECTIONS[other],
                                        _left_out(machine, other)))

    def in_order():  # the balancing worker's housing section follows the balancing section
        for name, (section_blocks, result) in sections.results():
            yield name, (section_blocks, result)
            if name == "balancing" and result.get("vibration") is not None:
                yield "vibration", result["vibration"]

    for name, (section_blocks, result) in in_order():
        left_out(list(_SECTIONS).index(name))
        order.pop(0)
        if name in _SECTION_IDS:  # the sections whose text has no heading of its own
            blocks.append(f'<h2 id="{_SECTION_IDS[name]}">{_SECTIONS[name]}</h2>')
        if name == "feed":
            feed_tables = result
            for done in ("feed trajectories", "stitch curve", "sensitivity"):
                step(done)
        elif name == "dynamics":
            result.to_csv(root / f"{machine.name}-dynamics-key-figures.csv", index=False,
                          float_format="%.10g")
            blocks.append(dynamics_intro(machine, result))
        elif name == "balancing":
            result["comparison"].to_csv(root / f"{machine.name}-balancing-criteria.csv",
                                        index=False, float_format="%.10g")
            blocks.append(result["html"])
        elif name == "vibration":
            for what in ("table", "levels", "modes"):
                stem = {"table": "vibration-key-figures", "levels": "vibration-levels",
                        "modes": "housing-modes"}[what]
                result[what].to_csv(root / f"{machine.name}-{stem}.csv", index=False,
                                    float_format="%.10g")
            blocks.append(result["html"])
        elif name == "accuracy":
            result["table"].to_csv(root / f"{machine.name}-accuracy.csv", index=False,
                                   float_format="%.10g")
            blocks.append(result["html"])
        blocks += section_blocks
        if name != "feed":
            step(name)
    left_out(len(_SECTIONS))

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
    page = page_html(machine, f"{ref} ({reference})", chk, tim, par, blocks, text, src.name,
                     feed_tables.get("html", []), mechanism=mechanism)
    (root / "index.html").write_text(page, encoding="utf-8")
    step("page")


#: the report's sections in page order, with their titles
_SECTIONS = {"feed": "Feed", "dynamics": "Dynamics", "thread": "Needle thread",
             "balancing": "Balancing", "vibration": "Vibration and running",
             "accuracy": "Accuracy", "comparison": "Variants"}
#: the ids of the sections whose own text carries no heading (the others' do, with their name)
_SECTION_IDS = {"feed": "feed", "thread": "thread", "comparison": "variants"}


def _left_out(machine: Machine, name: str) -> str:
    """Why the report has no section ``name`` for this machine."""
    file = Path(machine.file).name
    return {
        "feed": f"Left out because the [sewing] table of {file} names no feed_dog and"
                " regulator: the machine has no feed to analyse.",
        "dynamics": f"Left out because {file} has no [masses] tables: the forces need every"
                    " moving link's mass (docs/machine-files.md).",
        "thread": f"Left out because {file} has no [thread] table with a bobbin_case_radius:"
                  " the thread balance needs the needle thread's path and the loop round the"
                  " bobbin case.",
        "balancing": f"Left out because {file} has no [counterweights] table: there is no"
                     " counterweight to choose. Add one to balance the machine"
                     " (docs/balancing.md).",
        "vibration": f"Left out because {file} has no [housing] table (or no [masses]): the"
                     " housing's vibration needs its mass and mounts and the mechanisms'"
                     " forces (docs/vibration.md).",
        "accuracy": "Left out because the accuracy section studies the feed, and the machine"
                    " has none.",
        "comparison": "Left out because no variant was given to compare: name one in the"
                      " file's [machine] variants or with --compare.",
    }[name]


def _has_vibration(machine: Machine) -> bool:
    return machine.spec.housing is not None and bool(machine.spec.masses)


def _mechanism(figs: Figures, machine: Machine, res, phi_deg: np.ndarray) -> None:
    """The labelled drawing at the convention's shaft angle (the nearest of the grid)."""
    conv = machine.spec.convention
    k = int(np.argmin(np.abs((phi_deg - conv.reference_phi_deg + 180.0) % 360.0 - 180.0)))
    settings = "".join(f", {name} at {spec.default_deg:g} deg"
                       for name, spec in machine.spec.inputs.items())
    at = f"phi = {phi_deg[k]:g} deg ({conv.reference_event}){settings}"
    fig, data = mechanism_figure(machine, res, k, title=f"{machine.name} at {at}")
    figs.add(fig, "mechanism", "Points, links and pairs by name",
             f"Every point of the machine file and every pair of the force analysis (italic),"
             f" at {at}: the names the checks, the force tables and the machine file use."
             " Triangles: points on the frame. A pin between two links carries its point's"
             " name; where more links share a point, each pin is named point:link; a"
             " slider's guide, a slot, a cam contact and a crank's driving torque are named"
             " after their unit or point (unit.guide, point.slot, unit.cam, unit.torque)"
             + (", a cam contact labelled at its cam's axis" if machine.spec.cams else "")
             + ", a torque at its crank's. Dashed: the paths of the needle point, the take-up"
             " eye, the shuttle point and the feed dog over the turn. The data: every name,"
             " its place and its label's place, mm.", data)


#: what the sections that run in worker processes read (set before the workers are forked)
_SHARED: dict = {}


def _run_section(name: str):
    """One section of the report with its figures (drawn where it runs); returns its HTML
    blocks and what the page needs of it (the feed's tables, the dynamics' key figures)."""
    machine, root, variants = _SHARED["machine"], _SHARED["root"], _SHARED["variants"]
    figs = Figures(root, machine.name)
    result = None
    if name == "feed":
        result = feed_section(figs, machine, lambda done: None)
    elif name == "thread":
        thread_section(figs, machine)
    elif name == "dynamics":
        from .dynamics import dynamics_section

        result = dynamics_section(figs, machine, variants)
    elif name == "balancing":
        from .balancing import balancing_section, section_html

        sec = balancing_section(figs, machine)
        result = {"comparison": sec["comparison"], "html": section_html(machine, sec)}
        if _has_vibration(machine):  # the housing's section, with the answer on vibration
            from .vibration import vibration_section

            vfigs = Figures(root, machine.name)
            vres = vibration_section(vfigs, machine, sec["results"].get("vibration"))
            result["vibration"] = (vfigs.blocks, vres)
    elif name == "vibration":
        from .vibration import vibration_section

        result = vibration_section(figs, machine)
    elif name == "accuracy":
        from .accuracy import accuracy_section

        result = accuracy_section(figs, machine)
    else:
        comparison_section(figs, [machine] + list(variants))
    return figs.blocks, result


#: the sections, longest first by their CPU time in a worker (jb1-3 on the 2-core machine, after
#: the loop solver's tenfold: dynamics 1.9 s, balancing 1.8, feed 1.5, thread 0.8, the comparison
#: 0.4, accuracy 0.25): the two longest start in the workers, this process takes the feed when
#: its own figures are drawn, and the short ones fill in at the end
_SECTION_ORDER = ["dynamics", "balancing", "feed", "vibration", "thread", "comparison",
                  "accuracy"]


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

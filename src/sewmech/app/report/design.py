"""The report of a solved design problem (``sewmech optimize PROBLEM --out DIR``): one
self-contained page, ``DIR/index.html``, with the problem, the variables from start to answer,
every metric of the objective and the constraints before and after, the curves those metrics are
read from (the feed dog's path, the needle thread's overfeed, a channel over the turn) for the
start and the answer, the mechanism before and after, the convergence and, for NSGA-II, the
Pareto front. Every figure is also written as PNG, SVG and CSV (:class:`Figures`).
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ...engine.errors import SewmechError
from ..drawing.figures import Figures, subplots, table_html

_FEED = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


def _start_and_answer(before, after):
    """(design, line style, label) of the start (grey, dashed) and of the answer."""
    return ((before, {"color": "0.5", "ls": "--"}, "start"),
            (after, {"color": "C0"}, "answer"))


def _is_channel(metric: str) -> bool:
    """A kinematic channel at an angle or an event (p_POINT_x, theta_LINK, ...), not a named
    metric."""
    from ...design._dynamic_metrics import is_dynamic
    from ...design.evaluate import THREAD_METRICS
    from ...sewing.gradients import METRICS

    return not (metric in METRICS or metric in THREAD_METRICS or ":" in metric
                or is_dynamic(metric))


def _channel_of(metric: str) -> str | None:
    """The channel a metric is read from (a channel itself, or the channel of ``min:``,
    ``max:``, ``range:``, ``mean:``, ``rms:``), else None."""
    from ...design import metrics as km

    family, arg = km.split(metric)
    if arg is not None and family in km.AGGREGATES:
        return arg
    return metric if _is_channel(metric) else None


def problem_page(root: Path, problem, data: dict, problem_file: Path) -> None:
    """Write ``root/index.html`` and its figures for ``problem`` (a
    :class:`sewmech.design.problem.Problem`) and its solution ``data`` (what ``sewmech optimize
    --json`` prints)."""
    import matplotlib

    matplotlib.use("Agg")

    machine = problem.machine
    x_after = np.array([data["x"][n] for n in problem.names])
    before, after = problem.params(problem.start), problem.params(x_after)
    figs = Figures(root, "problem")
    _convergence(figs, data)
    if data.get("front") and data["front"]["f"]:
        _front(figs, data)
    _mechanism(figs, data["problem"], before, after, machine)
    refs = [*problem.spec.objective.parts, *problem.spec.constraints]
    settings = sorted({r.regulator_deg for r in refs if r.metric in _FEED},
                      key=lambda v: -1e9 if v is None else v)
    for reg in settings:
        _feed_paths(figs, machine, reg, before, after)
    if any(r.metric.startswith("thread_") for r in refs):
        _overfeed(figs, machine, before, after)
    channels = sorted({(_channel_of(r.metric), r.regulator_deg) for r in refs
                       if _channel_of(r.metric) is not None},
                      key=lambda c: (c[0], -1e9 if c[1] is None else c[1]))
    for channel, reg in channels:
        _channel(figs, machine, channel, before, after, reg)
    from ...design import metrics as km
    from ...design._dynamic_metrics import is_dynamic

    for unit, reg in sorted({(km.split(r.metric)[1], r.regulator_deg) for r in refs
                             if km.split(r.metric)[0] in km.TRANSMISSION},
                            key=lambda c: (c[0], -1e9 if c[1] is None else c[1])):
        _transmission(figs, machine, unit, before, after, reg)
    for name, reg in sorted({(r.metric, r.regulator_deg) for r in refs if is_dynamic(r.metric)},
                            key=lambda c: (c[0], -1e9 if c[1] is None else c[1])):
        _force_curve(figs, problem, name, before, after, reg)
    metrics = _metrics_table(problem, x_after)
    text = problem_file.read_text(encoding="utf-8")
    page = page_html(data, problem, metrics, figs.blocks, text, problem_file.name)
    from ..files.io import atomic_write

    with atomic_write(root / "index.html") as fh:
        fh.write(page)
    with atomic_write(root / "problem-metrics.csv") as fh:
        metrics.to_csv(fh, index=False, float_format="%.10g")


def _metrics_table(problem, x_after: np.ndarray) -> pd.DataFrame:
    """Every metric of the objective and the constraints at the start and at the answer (the
    exactly located values), with its band."""
    rows = []
    for role, refs in (("objective", problem.spec.objective.parts),
                       ("constraint", problem.spec.constraints)):
        for ref in refs:
            where = (f"regulator {ref.regulator_deg:g} deg" if ref.regulator_deg is not None
                     else f"at {ref.at}" if getattr(ref, "at", None)
                     else f"phi {ref.phi_deg:g} deg" if _is_channel(ref.metric) else "")
            vals = []
            for x in (problem.start, x_after):
                try:
                    vals.append(problem.metric(ref, x)[0])
                except SewmechError:  # a design whose metric cannot be formed: shown as none
                    vals.append(math.nan)
            band = ""
            if role == "constraint":
                band = " .. ".join(("" if b is None else f"{b:g}") for b in (ref.min, ref.max))
            else:
                band = ref.sense + (f" {ref.target:g}" if ref.sense == "target" else "")
            rows.append({"role": role, "metric": ref.metric, "at": where, "start": vals[0],
                         "answer": vals[1], "change": vals[1] - vals[0], "band or sense": band})
    return pd.DataFrame(rows)


def _convergence(figs: Figures, data: dict) -> None:
    h = np.array(data["history"], dtype=float)
    fig, ax = subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(np.arange(len(h)), h, "o-", ms=3)
    if h.size and np.all(h[np.isfinite(h)] > 0):
        ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("objective (dimensionless)")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{data['problem']}: {data['method']}, {data['status']}")
    figs.add(fig, "convergence", "Convergence",
             f"The best objective after each iteration of {data['method']}"
             f" ({data['n_evaluations']} designs evaluated).",
             pd.DataFrame({"iteration": np.arange(len(h)), "objective": h}))


def _front(figs: Figures, data: dict) -> None:
    front = data["front"]
    F = np.array(front["f"])
    fig, ax = subplots(figsize=(6.5, 5), constrained_layout=True)
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
    ax.set_title(f"{data['problem']}: Pareto front ({len(F)} designs)")
    figs.add(fig, "front", "Pareto front",
             "The designs no other design beats in every part of the objective (NSGA-II), and"
             " the compromise taken as the answer.",
             pd.DataFrame(F, columns=[f"{p} (normalised)" for p in front["parts"]]))


def _mechanism(figs: Figures, name: str, before, after, machine) -> None:
    """Every point's path over a turn for the start (grey) and the answer (colour), the links
    at phi = 0."""
    from ...engine.kinematics import kinematics
    from ..drawing.mechanism import link_points

    phi = np.radians(np.arange(0.0, 361.0, 2.0))
    fig, ax = subplots(figsize=(7.5, 7), constrained_layout=True)
    cols = {}
    links = link_points(machine)
    for params, style, label in ((before, dict(color="0.6", lw=0.8), "start"),
                                 (after, dict(lw=1.3), "answer")):
        r = kinematics(machine, phi, params=params, on_failure="mask")
        labelled = False
        for i, pt in enumerate(r.point_names):
            xy = r.p[:, i]
            cols[f"{label} {pt} x [mm]"] = xy[:, 0]
            cols[f"{label} {pt} y [mm]"] = xy[:, 1]
            if np.ptp(xy[:, 0]) + np.ptp(xy[:, 1]) < 1e-9:  # a fixed point: a dot
                ax.plot(xy[0, 0], xy[0, 1], "k.", ms=3)
                continue
            ax.plot(xy[:, 0], xy[:, 1], label=None if labelled else label, **style)
            labelled = True
        for pts in links.values():
            idx = [r.point_names.index(q) for q in pts if q in r.point_names]
            if len(idx) > 1:
                ax.plot(r.p[0, idx, 0], r.p[0, idx, 1], "-o", ms=2, lw=0.6,
                        color=style.get("color", "C3"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{name}: point paths over a turn, start and answer (links at phi = 0)",
                 fontsize=9)
    figs.add(fig, "mechanism", "The mechanism before and after",
             "Every point's path over one turn of the shaft, for the start (grey) and the"
             " answer; the links drawn at phi = 0.",
             pd.DataFrame({"phi_deg": np.degrees(phi), **cols}))


def _feed_paths(figs: Figures, machine, reg, before, after) -> None:
    from ...sewing.feed import feed_cycles

    s = machine.spec.sewing
    reg = machine.spec.inputs[s.regulator].default_deg if reg is None else reg
    fig, ax = subplots(figsize=(7, 4.2), constrained_layout=True)
    cols = {}
    for params, style, label in _start_and_answer(before, after):
        c = feed_cycles(machine, reg, params=params, on_failure="mask")
        ax.plot(c.x, c.y, label=f"{label}: stitch {float(c.stitch_mm):.3f} mm, lift"
                f" {float(c.lift_mm):.3f} mm", **style)
        cols[f"{label} x [mm]"] = c.x
        cols[f"{label} y above the plate [mm]"] = c.y
        phi_deg = c.phi_deg
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("height above the throat plate [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Feed dog tooth tip at regulator {reg:g} deg")
    figs.add(fig, f"feed-{reg:g}", f"The feed dog at regulator {reg:g} deg",
             "The path of the dog's tooth tip over a turn, relative to the throat plate, for"
             " the start (dashed) and the answer.",
             pd.DataFrame({"phi_deg": phi_deg, **cols}))


def _overfeed(figs: Figures, machine, before, after) -> None:
    from ...sewing.thread import thread_balance

    fig, ax = subplots(figsize=(7, 4.2), constrained_layout=True)
    cols = {}
    for params, style, label in _start_and_answer(before, after):
        b = thread_balance(machine, params=params)
        ax.plot(b.phi_deg, b.overfeed, label=f"{label}: least while the loop grows"
                f" {b.min_overfeed_while_loop_grows:.2f} mm", **style)
        cols["phi_deg"] = b.phi_deg
        cols[f"{label} overfeed [mm]"] = b.overfeed
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel("overfeed: supply - demand [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Needle thread: overfeed over a cycle")
    figs.add(fig, "overfeed", "The needle thread before and after",
             "The thread the take-up supplies beyond what the needle, the fabric and the loop"
             " demand, over one cycle, for the start (dashed) and the answer.",
             pd.DataFrame(cols))


def _channel(figs: Figures, machine, channel: str, before, after, reg: float | None = None
             ) -> None:
    """A channel over a turn for the start and the answer, at the regulator setting ``reg``
    (deg; None: the machine's working setting)."""
    from ...engine.kinematics import kinematics

    phi = np.radians(np.arange(0.0, 361.0, 1.0))
    fig, ax = subplots(figsize=(7, 4.2), constrained_layout=True)
    cols = {"phi_deg": np.degrees(phi)}
    angle = channel.startswith("theta_")
    s = machine.spec.sewing
    inputs = {s.regulator: math.radians(reg)} if reg is not None else None
    unit = "mm"
    for params, style, label in _start_and_answer(before, after):
        v, unit = kinematics(machine, phi, params=params, inputs=inputs,
                             on_failure="mask").channel(channel)
        v = np.degrees(np.unwrap(v)) if angle else v
        unit = "deg" if angle else unit
        ax.plot(np.degrees(phi), v, label=label, **style)
        cols[f"{label} {channel} [{unit}]"] = v
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel(f"{channel} [{unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    at = "" if reg is None else f" at regulator {reg:g} deg"
    figs.add(fig, f"channel-{channel}" + ("" if reg is None else f"-{reg:g}"),
             f"{channel} over a turn{at}",
             f"{channel} for the start (dashed) and the answer{at}.", pd.DataFrame(cols))


def _inputs(machine, reg: float | None):
    s = machine.spec.sewing
    return {s.regulator: math.radians(reg)} if reg is not None else None


def _transmission(figs: Figures, machine, unit: str, before, after, reg: float | None = None
                  ) -> None:
    """A unit's transmission angle over a turn (deg, 90 less |psi|) for the start and the
    answer."""
    from ...design.metrics import psi_curve

    phi = np.radians(np.arange(0.0, 361.0, 1.0))
    fig, ax = subplots(figsize=(7, 4.2), constrained_layout=True)
    cols = {"phi_deg": np.degrees(phi)}
    for params, style, label in _start_and_answer(before, after):
        mu = 90.0 - np.abs(psi_curve(machine, unit, phi, params, _inputs(machine, reg)))
        ax.plot(np.degrees(phi), mu, label=label, **style)
        cols[f"{label} transmission angle {unit} [deg]"] = mu
    ax.axhline(90.0, color="0.7", lw=0.8)
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel(f"transmission angle of {unit} [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    at = "" if reg is None else f" at regulator {reg:g} deg"
    figs.add(fig, f"transmission-{unit}" + ("" if reg is None else f"-{reg:g}"),
             f"transmission angle of {unit} over a turn{at}",
             f"The transmission angle of {unit} (90 deg is best) for the start (dashed) and the"
             f" answer{at}.", pd.DataFrame(cols))


def _force_curve(figs: Figures, problem, name: str, before, after, reg: float | None = None
                 ) -> None:
    """A force metric's curve over the turn on its grid (the quantity whose peak, RMS, mean or
    least value the metric is) for the start and the answer."""
    from ...design._dynamic_metrics import split, unit_of

    family, arg = split(name)
    quantity = {"peak_torque": "|driving torque|", "rms_torque": "driving torque",
                "peak_force": f"|force| in {arg}", "peak_bearing_reaction":
                    "|bearing reaction|" + (f" ({arg})" if arg else " (the larger bearing)"),
                "peak_shaking_force": "|shaking force|", "peak_shaking_moment":
                    "|shaking moment|", "friction_loss": "friction power",
                "least_contact_force": f"force of the contact {arg}"}[family]
    fm = problem.forces
    inputs = _inputs(problem.machine, reg)
    c = fm.curves([name], np.stack([before, after]), inputs)[name]
    phi = np.degrees(fm.phi)
    unit = unit_of(name)
    fig, ax = subplots(figsize=(7, 4.2), constrained_layout=True)
    cols = {"phi_deg": phi}
    for k, (_, style, label) in enumerate(_start_and_answer(before, after)):
        ax.plot(phi, c[k], label=label, **style)
        cols[f"{label} {name} [{unit}]"] = c[k]
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel(f"{quantity} [{unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    at = "" if reg is None else f" at regulator {reg:g} deg"
    figs.add(fig, "force-" + name.replace(":", "-") + ("" if reg is None else f"-{reg:g}"),
             f"{quantity} over a turn ({name}){at}",
             f"The {quantity} {name} is read from, at every {360.0 / len(phi):g} deg of the turn (the"
             f" problem's [dynamics] grid), for the start (dashed) and the answer{at}.",
             pd.DataFrame(cols))


def _objective(data: dict, key: str) -> str:
    """The objective as the page says it: its value, or "undefined (why)"."""
    x = data[key]
    if x is None:
        return f"undefined ({data.get(key + '_note', '').removeprefix('not defined: ')})"
    return f"{x:.6g}"


def page_html(data: dict, problem, metrics: pd.DataFrame, blocks, text: str, file_name: str
          ) -> str:
    from .page import CSS

    e = html.escape
    spec = problem.spec
    var = pd.DataFrame({"variable": problem.names, "unit": problem.units,
                        "lower": problem.lower, "start": problem.start,
                        "answer": [data["x"][n] for n in problem.names],
                        "upper": problem.upper})
    cons = pd.DataFrame([{"constraint": n, "value": c["value"], "min": c["min"],
                          "max": c["max"], "met": "yes" if c["satisfied"] else "NO"}
                         for n, c in data["constraints"].items()])
    ok = data["status"] == "success"
    verdict = (f'<p class="{"pass" if ok else "fail"}">{e(data["status"])}: {e(data["message"])}'
               f" ({data['n_evaluations']} designs evaluated)</p>")
    check = data.get("check")
    if check:
        kkt = "" if check.get("kkt_residual") is None else \
            f"; the KKT residual of the exact derivatives is {check['kkt_residual']:.2g}"
        verdict += (f"<p>Optimality check: {e(check['how'])} lowered the objective by"
                    f" {check['improvement']:.3g} (at most {check['tolerance']:.3g} allowed:"
                    f" {'passed' if check['passed'] else 'failed'}){e(kkt)}.</p>")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>sewmech problem: {e(data['problem'])}</title><style>{CSS}</style></head><body>
<h1>{e(data['problem'])}</h1>
<p class="sub">{e(spec.problem.description or '')}</p>
<p>Machine {e(data['machine'])}; method {e(data['method'])}; objective
{e(_objective(data, 'objective_start'))} at the start, {e(_objective(data, 'objective'))} at
the answer (dimensionless: each part divided by its scale). Lengths in mm, angles in
degrees.</p>
{verdict}
<h2>Variables</h2>{table_html(var)}
<h2>Metrics before and after</h2>
<p>Each metric located exactly on the kinematics, at the start and at the answer.
Data: <a href="problem-metrics.csv">metrics (CSV)</a>.</p>{table_html(metrics)}
<h2>Constraints at the answer</h2>{table_html(cons)}
<h2>Figures</h2>
{''.join(blocks)}
<p>The answer's workshop drawing at phi = 0 (<code>sewmech export</code>'s, mm, a layer per
link and per cam): <a href="answer.dxf">DXF</a>, <a href="answer.svg">SVG</a>.</p>
<details><summary>Problem file {e(file_name)}</summary><pre>{e(text)}</pre></details>
<p class="sub">Written by sewmech.</p>
</body></html>
"""

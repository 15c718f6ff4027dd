"""The page of a synthesis (``sewmech synthesize ... --out DIR``): DIR/index.html with the
requirement, the free choices and findings, the answer against the requirement (each precision
point re-evaluated through the kinematics engine on the written machine file), the figures
(each also as PNG, SVG and CSV) and the machine file itself.

Every figure and table here reads the machine file as written (loaded back), so the page shows
what ``sewmech check`` and the other commands will see.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..drawing.figures import Figures, subplots, table_html


def verify_machine(text: str, file_name: str):
    """The machine file ``text`` loaded, validated and proved to assemble (at its working
    setting and every setting limit) as ``sewmech check`` does; the machine. A failure here is
    a bug of the synthesis (its answer was checked before it was written)."""
    from ...engine.assembly import prove_assembly
    from ...engine.errors import SewmechError
    from ...engine.extremes import require_reference
    from ...engine.machine import machine_from_toml

    m = machine_from_toml(text, file_name)
    settings = [None]
    for name, spec in m.spec.inputs.items():
        settings += [{name: math.radians(v)} for v in (spec.min_deg, spec.max_deg)
                     if v is not None]
    for inputs in settings:
        proof = prove_assembly(m, inputs=inputs, step_deg=5.0)
        if not proof.ok:
            f = proof.failures[0]
            raise SewmechError(file_name, f"the synthesised machine does not assemble over the"
                               f" turn: unit '{f.unit}' fails over phi {f.from_deg:.4g} .."
                               f" {f.to_deg:.4g} deg ({f.reason})", "This is a bug in sewmech:"
                               " please report it with the command line")
    require_reference(m)
    return m


def _links_at(ax, xy: dict, segments, style) -> None:
    for a, b in segments:
        if a in xy and b in xy:
            ax.plot([xy[a][0], xy[b][0]], [xy[a][1], xy[b][1]], **style)


def _fourbar_xy(r, k: int) -> dict:
    return {n: r.p[k, i] for i, n in enumerate(r.point_names)}


_SEGMENTS = (("A", "B"), ("B", "C"), ("C", "D"), ("B", "P"), ("C", "P"))


def _page(root: Path, title: str, sub: str, sections: list[str], text: str, file_name: str,
          figs: Figures) -> None:
    from ..files.io import atomic_write
    from .page import CSS

    e = html.escape
    page = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>sewmech'
            f" synthesis: {e(title)}</title><style>{CSS}</style></head><body>\n"
            f"<h1>{e(title)}</h1><p class=\"sub\">{e(sub)}</p>\n" + "\n".join(sections)
            + "<h2>Figures</h2>" + "".join(figs.blocks)
            + f"<details open><summary>Machine file {e(file_name)} (check it with"
              f" <code>sewmech check {e(file_name)}</code>)</summary><pre>{e(text)}</pre>"
              "</details><p class=\"sub\">Written by sewmech.</p></body></html>\n")
    with atomic_write(root / "index.html") as fh:
        fh.write(page)


def _notes_html(notes) -> str:
    return "<h2>Free choices and findings</h2><ul>" + "".join(
        f"<li>{html.escape(n)}</li>" for n in notes) + "</ul>"


# ---- function generation ----------------------------------------------------------------------


def precision_check_function(machine, res) -> pd.DataFrame:
    """The output angle of the written machine at each precision point (the input set there,
    the kinematics engine), against the function's: the error there, deg."""
    from ...engine.kinematics import kinematics

    rows = []
    for x, y, t2, t4 in zip(res.x, res.y, res.theta2_deg, res.theta4_deg, strict=True):
        r = kinematics(machine, [0.0], inputs={"input": math.radians(t2)}, points=["C", "D"],
                       links=[], variables=[])
        c = r.point("C").p[0] - r.point("D").p[0]
        th = math.atan2(c[1], c[0]) + (0.0 if res.fourbar.output_u > 0 else math.pi)
        err = math.degrees(math.remainder(th - math.radians(t4), 2 * math.pi))
        rows.append({"x": x, "y = f(x)": y, "input [deg]": t2, "output asked [deg]": t4,
                     "output of the machine file [deg]": t4 + err, "error [deg]": err})
    return pd.DataFrame(rows)


def function_page(root: Path, res, text: str, file_name: str, machine) -> pd.DataFrame:
    """Write the page of a function generator; returns its precision-point table."""
    import matplotlib

    matplotlib.use("Agg")
    stem = Path(file_name).stem
    figs = Figures(root, stem)
    check = precision_check_function(machine, res)
    fig, (ax, ax2) = subplots(2, 1, figsize=(7, 6.5), constrained_layout=True, sharex=True)
    from ...design.synthesis import function_of_x

    f = function_of_x(res.function)
    ax.plot(res.x_grid, f(res.x_grid), color="0.5", lw=2.5, label=f"y = {res.function}")
    ax.plot(res.x_grid, res.y_generated, color="C0", lw=1.2, label="generated by the four-bar")
    ax.plot(res.x, res.y, "o", color="C3", label="precision points")
    ax.set_ylabel("y")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{res.method}: y = {res.function}")
    ax2.plot(res.x_grid, res.error, color="C0")
    ax2.plot(res.x, np.zeros_like(res.x), "o", color="C3")
    ax2.axhline(0.0, color="k", lw=0.7)
    ax2.set_xlabel("x")
    ax2.set_ylabel("structural error y_gen - f(x)")
    ax2.grid(True, alpha=0.3)
    figs.add(fig, "function", "The function and the structural error",
             f"y = {res.function} and what the four-bar generates over the range; below, the"
             f" structural error (largest {res.max_error:.4g} in y, {res.max_error_deg:.4g} deg"
             " of the output).",
             pd.DataFrame({"x": res.x_grid, "y": f(res.x_grid), "y_generated": res.y_generated,
                           "error": res.error, "error_deg": res.error_deg}))
    _mechanism_at_inputs(figs, machine, res.theta2_deg, "input")
    e = html.escape
    fb = res.fourbar
    lengths = pd.DataFrame([{"AB (input) [mm]": fb.a, "BC (coupler) [mm]": fb.b,
                             "DC (output) [mm]": fb.c, "AD (ground) [mm]": fb.d,
                             "K1": res.K[0], "K2": res.K[1], "K3": res.K[2],
                             "branch": fb.branch, "Grashof": res.grashof.kind,
                             "least transmission angle [deg]": res.min_transmission_deg}])
    sections = [
        f"<h2>Requirement</h2><p>y = {e(res.function)} for x in {res.x_range[0]:g} ..."
        f" {res.x_range[1]:g}; input angle {res.input_range_deg[0]:g} .."
        f" {res.input_range_deg[1]:g} deg, output angle {res.output_range_deg[0]:g} .."
        f" {res.output_range_deg[1]:g} deg ({e(res.method)}).</p>",
        "<h2>The four-bar</h2>" + table_html(lengths),
        "<h2>At the precision points, through the machine file</h2><p>The machine file's"
        " output angle (the kinematics engine, the input set to each point) against the"
        " function's.</p>" + table_html(check),
        f"<p>Structural error over the range: largest {res.max_error:.6g} (units of y),"
        f" {res.max_error_deg:.6g} deg of the output; Freudenstein's equation at the points:"
        f" rms residual {res.residual_rms:.3g}.</p>",
        _notes_html(res.notes)]
    _page(root, f"Function generator: y = {res.function}", "Freudenstein synthesis"
          f" ({res.method})", sections, text, file_name, figs)
    return check


def _mechanism_at_inputs(figs, machine, inputs_deg, name: str, title: str | None = None):
    from ...engine.kinematics import kinematics

    fig, ax = subplots(figsize=(7, 6), constrained_layout=True)
    rows = []
    for k, t in enumerate(inputs_deg):
        r = kinematics(machine, [0.0], inputs={name: math.radians(t)}, on_failure="mask")
        xy = _fourbar_xy(r, 0)
        _links_at(ax, xy, _SEGMENTS, {"color": f"C{k % 10}", "lw": 1.5, "marker": "o",
                                      "ms": 3})
        for n, q in xy.items():
            rows.append({"position": k + 1, "input_deg": t, "point": n, "x_mm": q[0],
                         "y_mm": q[1]})
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(title or "The four-bar at each precision point")
    figs.add(fig, "mechanism", "The four-bar at the precision points",
             "The linkage drawn at each precision point (one colour each).", pd.DataFrame(rows))


# ---- motion generation ------------------------------------------------------------------------


def precision_check_motion(machine, res) -> pd.DataFrame:
    """The body's pose in the written machine at each pose's shaft angle (or setting), against
    the pose asked for: position error mm, angle error deg."""
    from ...engine.kinematics import kinematics

    rows = []
    for k, (pose, phi) in enumerate(zip(res.poses, res.phi_deg, strict=True)):
        if res.drive == "shaft":
            r = kinematics(machine, [math.radians(phi)], points=["P"], links=["coupler"],
                           variables=[])
        else:
            r = kinematics(machine, [0.0], inputs={"input": math.radians(phi)}, points=["P"],
                           links=["coupler"], variables=[])
        p = r.point("P").p[0]
        ang = r.link("coupler").theta[0] + res.body_offset
        rows.append({"pose": k + 1, "x asked [mm]": pose[0], "y asked [mm]": pose[1],
                     "angle asked [deg]": math.degrees(pose[2]),
                     "at phi or setting [deg]": phi,
                     "position error [mm]": float(np.hypot(*(p - pose[:2]))),
                     "angle error [deg]": math.degrees(math.remainder(ang - pose[2],
                                                                      2 * math.pi))})
    return pd.DataFrame(rows)


def motion_page(root: Path, res, text: str, file_name: str, machine) -> pd.DataFrame:
    import matplotlib

    matplotlib.use("Agg")
    from ...engine.kinematics import kinematics

    stem = Path(file_name).stem
    figs = Figures(root, stem)
    check = precision_check_motion(machine, res)
    fig, ax = subplots(figsize=(7.5, 7), constrained_layout=True)
    span = max(np.ptp(res.poses[:, 0]), np.ptp(res.poses[:, 1]), 1.0)
    rows = []
    for k, (pose, phi) in enumerate(zip(res.poses, res.phi_deg, strict=True)):
        if res.drive == "shaft":
            r = kinematics(machine, [math.radians(phi)], on_failure="mask")
        else:
            r = kinematics(machine, [0.0], inputs={"input": math.radians(phi)},
                           on_failure="mask")
        xy = _fourbar_xy(r, 0)
        col = f"C{k % 10}"
        _links_at(ax, xy, _SEGMENTS, {"color": col, "lw": 1.2, "marker": "o", "ms": 3})
        L = 0.15 * span
        ax.annotate("", xy=(pose[0] + L * math.cos(pose[2]), pose[1] + L * math.sin(pose[2])),
                    xytext=(pose[0], pose[1]),
                    arrowprops={"arrowstyle": "-|>", "color": col, "lw": 2})
        ax.text(pose[0], pose[1], f" {k + 1}", color=col, fontsize=9)
        rows += [{"pose": k + 1, "point": n, "x_mm": q[0], "y_mm": q[1]} for n, q in xy.items()]
    if res.drive == "shaft":
        r = kinematics(machine, np.radians(np.arange(0.0, 361.0, 2.0)), points=["P"], links=[],
                       variables=[], on_failure="mask")
        ax.plot(r.point("P").p[:, 0], r.point("P").p[:, 1], color="0.6", lw=0.8, ls="--",
                label="coupler point over the turn")
        ax.legend(fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title("The body (arrows: its u axis) and the four-bar in each pose")
    figs.add(fig, "poses", "The four-bar in each pose",
             "The poses asked for (arrow: the body's reference point and u axis) and the"
             " four-bar of the machine file at each.", pd.DataFrame(rows))
    if res.curves is not None:
        c = res.curves
        fig, ax = subplots(figsize=(7.5, 7), constrained_layout=True)
        for br, mk in ((1, "."), (-1, "x")):
            s = c.branch == br
            ax.plot(c.centre[s, 0], c.centre[s, 1], mk, ms=2, color="C0",
                    label=f"centre points (closure {br:+d})")
            ax.plot(c.circle[s, 0], c.circle[s, 1], mk, ms=2, color="C1",
                    label=f"circle points, pose 1 (closure {br:+d})")
        for d, lab in zip(res.dyads, ("input", "output"), strict=True):
            ax.plot([d.K[0], d.M1[0]], [d.K[1], d.M1[1]], "k-o", lw=1.5, ms=5)
            ax.text(d.K[0], d.K[1], f" {lab} pivot", fontsize=8)
        ax.plot(res.poses[:, 0], res.poses[:, 1], "s", color="C3", label="poses")
        lim = 4 * span
        cx, cy = res.poses[:, 0].mean(), res.poses[:, 1].mean()
        ax.set_xlim(cx - lim, cx + lim)
        ax.set_ylim(cy - lim, cy + lim)
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title("Burmester's centre-point and circle-point curves")
        figs.add(fig, "burmester", "Burmester's curves",
                 "The centre points (frame pivots) and circle points (moving pivots, in pose"
                 " 1) of every dyad that guides the body through the four poses, and the two"
                 " chosen.", pd.DataFrame({"beta2_deg": np.degrees(c.beta2),
                                            "closure": c.branch, "centre_x_mm": c.centre[:, 0],
                                            "centre_y_mm": c.centre[:, 1],
                                            "circle_x_mm": c.circle[:, 0],
                                            "circle_y_mm": c.circle[:, 1],
                                            "residual_mm": c.residual}))
    fb = res.fourbar
    lengths = pd.DataFrame([{"AB (input) [mm]": fb.a, "BC (coupler) [mm]": fb.b,
                             "DC (output) [mm]": fb.c, "AD (ground) [mm]": fb.d,
                             "branch": fb.branch, "Grashof": res.grashof.kind,
                             "input": "shaft crank" if res.drive == "shaft" else "lever",
                             "least transmission angle [deg]": res.min_transmission_deg}])
    sections = ["<h2>Requirement</h2>" + table_html(pd.DataFrame(
        {"pose": np.arange(1, len(res.poses) + 1), "x [mm]": res.poses[:, 0],
         "y [mm]": res.poses[:, 1], "angle [deg]": np.degrees(res.poses[:, 2])})),
        "<h2>The four-bar</h2>" + table_html(lengths),
        "<h2>At the poses, through the machine file</h2>" + table_html(check),
        _notes_html(res.notes)]
    _page(root, f"Motion generator through {len(res.poses)} poses", "Burmester synthesis",
          sections, text, file_name, figs)
    return check


# ---- path generation --------------------------------------------------------------------------


def path_page(root: Path, res, points, phi_deg, file_name: str, machine) -> pd.DataFrame:
    import matplotlib

    matplotlib.use("Agg")
    from ...engine.kinematics import kinematics
    from ...engine.machine import machine_from_toml

    stem = Path(file_name).stem
    figs = Figures(root, stem)
    Z = np.asarray(points, dtype=float)
    start = machine_from_toml(res.start_text, file_name)
    turn = np.radians(np.arange(0.0, 361.0, 1.0))
    fig, ax = subplots(figsize=(7.5, 6.5), constrained_layout=True)
    cols = {"phi_deg": np.degrees(turn)}
    for m, lab, st in ((start, "exact three-point start", {"color": "0.6", "ls": "--"}),
                       (machine, "answer", {"color": "C0"})):
        p = kinematics(m, turn, points=["P"], links=[], variables=[],
                       on_failure="mask").point("P").p
        ax.plot(p[:, 0], p[:, 1], label=lab, **st)
        cols[f"{lab} x [mm]"], cols[f"{lab} y [mm]"] = p[:, 0], p[:, 1]
    ax.plot(Z[:, 0], Z[:, 1], "o", color="C3", label="path points")
    for k in res.start.exact:
        ax.plot(Z[k, 0], Z[k, 1], "s", mfc="none", color="k", ms=9)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title("Coupler point P: the points, the start, the answer")
    figs.add(fig, "path", "The path", "The points asked for (squares: the three the start"
             " meets exactly), the coupler point's path of the start and of the answer.",
             pd.DataFrame(cols))
    p = kinematics(machine, np.radians(phi_deg), points=["P"], links=[],
                   variables=[]).point("P").p
    check = pd.DataFrame({"point": np.arange(1, len(Z) + 1), "phi [deg]": phi_deg,
                          "x asked [mm]": Z[:, 0], "y asked [mm]": Z[:, 1],
                          "x [mm]": p[:, 0], "y [mm]": p[:, 1],
                          "distance [mm]": np.linalg.norm(p - Z, axis=-1)})
    var = pd.DataFrame([{"variable": n, "start": a, "answer": b}
                        for n, (a, b) in res.variables.items()])
    sections = [f"<h2>Requirement</h2><p>The coupler point P through {len(Z)} points at their"
                " shaft angles (timed path generation).</p>",
                "<h2>At the points, through the machine file</h2>" + table_html(check),
                f"<p>rms distance: start {res.start_rms_mm:.4g} mm, answer"
                f" {res.answer_rms_mm:.4g} mm (largest {res.answer_max_mm:.4g} mm).</p>",
                "<h2>Variables</h2>" + table_html(var), _notes_html(res.notes),
                "<details><summary>The design problem solved (for <code>sewmech optimize"
                f"</code>)</summary><pre>{html.escape(res.problem_text)}</pre></details>"]
    _page(root, f"Path generator through {len(Z)} points", "Timed path generation: an exact"
          " start, then the optimiser", sections, res.answer_text, file_name, figs)
    return check


# ---- the embroidery take-up -------------------------------------------------------------------


def take_up_page(root: Path, res, file_name: str, machine) -> pd.DataFrame:
    import matplotlib

    matplotlib.use("Agg")
    from ...engine.kinematics import kinematics
    from ...sewing import embroidery as EM

    stem = Path(file_name).stem
    figs = Figures(root, stem)
    table = EM.paper_table(machine)
    fig, ax = subplots(figsize=(7.5, 4.5), constrained_layout=True)
    phi, L = EM.thread_drawn(machine, [p[1] for p in EM.PAPER_PAIRS],
                             [p[0] for p in EM.PAPER_PAIRS], n_points=72)
    cols = {"phi_deg": phi}
    for (b, a), row in zip(EM.PAPER_PAIRS, L, strict=True):
        ax.plot(phi, row, label=f"beta {b:g}, alpha {a:g} deg")
        cols[f"beta={b:g}, alpha={a:g} L_mm"] = row
    ax.set_xlabel("phi [deg]")
    ax.set_ylabel("thread drawn L [mm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("L(phi) = l_max - l for the paper's six (beta, alpha) pairs")
    figs.add(fig, "thread-drawn", "Thread drawn for the paper's pairs", "The study of alpha and"
             " beta that follows the design (sewmech.embroidery), on the written machine.",
             pd.DataFrame(cols))
    turn = np.radians(np.arange(0.0, 361.0, 2.0))
    r = kinematics(machine, turn, on_failure="mask")
    fig, ax = subplots(figsize=(6, 7), constrained_layout=True)
    for n in ("B", "C", "E", "Q"):
        p = r.point(n).p
        ax.plot(p[:, 0], p[:, 1], lw=0.8, label=f"{n} over the turn")
    xy = _fourbar_xy(r, 0)
    _links_at(ax, xy, (("A", "B"), ("B", "C"), ("C", "D"), ("D", "E"), ("E", "F")),
              {"color": "k", "lw": 1.6, "marker": "o", "ms": 3})
    for n in ("A", "D", "M", "N"):
        ax.text(xy[n][0], xy[n][1], f" {n}", fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title("The take-up at phi = 0 and its paths")
    figs.add(fig, "mechanism", "The mechanism", "The take-up at phi = 0 (the needle's top)"
             " and the paths of B, C, E and the eye Q.",
             pd.DataFrame({"phi_deg": np.degrees(turn),
                           **{f"{n} {c} [mm]": r.point(n).p[:, i] for n in ("B", "C", "E", "Q")
                              for i, c in enumerate("xy")}}))
    lengths = pd.DataFrame([
        {"link": "BC", "computed [mm]": res.bc, "the paper [mm]": 16.3},
        {"link": "CD", "computed [mm]": res.cd, "the paper [mm]": 10.9},
        {"link": "AD", "computed [mm]": res.ad, "the paper [mm]": 6.6},
        {"link": "DE", "computed [mm]": res.de, "the paper [mm]": 31.0},
        {"link": "EF", "computed [mm]": res.ef, "the paper [mm]": 80.0}])
    paper = res.ab == 17.5 and abs(res.de - 31.0) < 1e-12
    sections = [
        f"<h2>Requirement</h2><p>Crank AB {res.ab:g} mm (the needle crank of the base"
        f" machine), thread drawn per cycle l2 = {4 * res.de:g} mm.</p>",
        "<h2>Link lengths</h2>" + (table_html(lengths) if paper else table_html(
            lengths.drop(columns=["the paper [mm]"])))
        + ("<p>The paper prints its lengths to 0.1 mm; the method gives them exactly.</p>"
           if paper else ""),
        f"<h2>Design positions</h2><p>alpha = {res.design_alpha_deg:.6g} deg, beta ="
        f" {res.design_beta_deg:.6g} deg from the two design positions; DC turns"
        f" {res.dc_turn_deg:.9g} deg between them; laid out at alpha = {res.alpha_deg:.6g},"
        f" beta = {res.beta_deg:.6g} deg: the eye at its top at phi = {res.eye_top_deg:.4g}"
        f" deg and its bottom at {res.eye_bottom_deg:.4g} deg; thread drawn per cycle"
        f" {res.drawn_mm:.9g} mm. Grashof: {html.escape(res.grashof.text)}.</p>",
        "<h2>The study of alpha and beta: L at the paper's 12 positions</h2>"
        + table_html(table), _notes_html(res.notes)]
    _page(root, "Embroidery take-up (Kozlov's method)", "The double-crank thread take-up"
          " designed from the stroke and the crank", sections, res.text, file_name, figs)
    return table

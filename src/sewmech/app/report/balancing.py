"""The report's balancing section (and ``sewmech balance --out``): the chosen counterweights,
the shaking force's components and hodograph before and after, the upper shaft's bearing
reactions as polar plots, every criterion side by side, the balancing paper's workflow with the
lead insert, and the trade-off front to choose from."""

from __future__ import annotations

import html
from collections.abc import Sequence

import numpy as np
import pandas as pd

from ...design.balancing import (CRITERIA, FIGURES, BalanceResult, balance, balance_basis,
                                paper_workflow, shaft_counterweight, tradeoff)
from ...engine.machine import Machine
from .page import arc_cam_note

#: labels and units of the figures, for tables
FIGURE_LABELS = {"delta_q_N": ("Delta-Q = | max|Qx| - max|Qy| |", "N"),
                 "peak_force_N": ("peak shaking force |Q|", "N"),
                 "rms_force_N": ("RMS shaking force |Q|", "N"),
                 "peak_moment_Nm": ("peak shaking moment", "N m"),
                 "bearing_front_peak_N": ("peak front bearing reaction", "N"),
                 "bearing_rear_peak_N": ("peak rear bearing reaction", "N"),
                 "bearing_front_rms_N": ("RMS front bearing reaction", "N"),
                 "bearing_rear_rms_N": ("RMS rear bearing reaction", "N"),
                 "torque_fluctuation_Nm": ("driving-torque fluctuation (max - min)", "N m"),
                 "vibration_x_db": ("vibration level at the control point along x",
                                    "dB re 5e-8 m/s"),
                 "vibration_y_db": ("vibration level at the control point along y",
                                    "dB re 5e-8 m/s")}


def results_frame(results: dict[str, BalanceResult]) -> pd.DataFrame:
    """Each criterion's answer as a row: status, counterweights, figures after."""
    rows = []
    for crit, r in results.items():
        row = {"criterion": crit, "status": r.status}
        if not r.proposed:  # nothing proposed: no counterweights, no figures after
            rows.append(row)
            continue
        for name, cw in r.counterweights.items():
            row[f"{name} S [g cm]"] = cw["static_moment_gcm"]
            row[f"{name} angle [deg]"] = cw["angle_deg"]
        for k in FIGURES:
            if r.after[k] is not None:
                row[f"{k}"] = float(r.after[k])
        rows.append(row)
    return pd.DataFrame(rows)


def balancing_section(figs, machine: Machine, *, criterion: str | None = None,
                      counterweights: Sequence[str] | None = None, rpm: float | None = None,
                      weights: dict | None = None, front: bool = True,
                      moment_point: tuple[float, float] | None = None) -> dict:
    """Add the balancing figures to ``figs`` (:class:`~sewmech.app.drawing.figures.Figures`).

    criterion: the one shown before/after (default: the paper's delta-q on the shaft's
    counterweight if there is one, else weighted); counterweights: those varied by every
    criterion but delta-q (default: all of the file's); rpm: default the file's;
    moment_point: the shaking moment's point (x, y mm; default the upper shaft's axis). Returns a dict
    with ``main`` (the shown :class:`BalanceResult`), ``results`` (criterion -> result),
    ``paper`` (:func:`sewmech.design.balancing.paper_workflow`, or None), ``key`` (a table of
    key figures) and ``html`` (the section's text blocks: intro, comparison and the paper's
    workflow)."""
    from ..drawing.figures import subplots

    B = balance_basis(machine, counterweights, rpm=rpm, moment_point=moment_point)
    shaft_cw = shaft_counterweight(machine)
    if shaft_cw is None:
        Bq = None
    elif B.names == (shaft_cw,):
        Bq = B
    else:
        Bq = balance_basis(machine, [shaft_cw], rpm=rpm, moment_point=moment_point)
    results: dict[str, BalanceResult] = {}
    for crit in CRITERIA:
        if crit == "delta-q":
            if Bq is not None:
                results[crit] = balance(machine, crit, [shaft_cw], basis=Bq)
            elif len(B.counterweights) == 1:
                results[crit] = balance(machine, crit, basis=B)
            continue
        if crit == "bearings" and not B.has_bearings:
            continue
        if crit in ("vibration", "equal-levels") and B.housing is None:
            continue  # no [housing]: no vibration to predict
        if crit == "equal-levels":  # one counterweight along its angle: the shaft's
            if Bq is not None:
                results[crit] = balance(machine, crit, [shaft_cw], basis=Bq)
            elif len(B.counterweights) == 1:
                results[crit] = balance(machine, crit, basis=B)
            continue
        results[crit] = balance(machine, crit, basis=B, weights=weights if crit == "weighted"
                                else None)
    if criterion is None:
        criterion = "delta-q" if "delta-q" in results else "weighted"
    main = results[criterion]
    paper = (paper_workflow(machine, shaft_cw, basis=Bq, result=results.get("delta-q"))
             if shaft_cw else None)
    if not main.proposed:  # delta-q without a root: the figures show what is achievable
        criterion = f"{main.alternative.criterion} (delta-q has no root)"
        main = main.alternative
    proposed = {c: r for c, r in results.items() if r.proposed}
    rpm = main.rpm
    phi_deg = np.degrees(main.curves["phi"])
    before, after = main.curves["before"], main.curves["after"]
    name = machine.name
    cws = ", ".join(f"{n} {c['static_moment_gcm']:.4g} g cm at {c['angle_deg']:.4g} deg"
                    for n, c in main.counterweights.items())

    # ---- components of Q (the paper's figures 3 and 4) ------------------------------------
    fig, axs = subplots(1, 2, figsize=(10, 3.8), sharey=True, constrained_layout=True)
    for ax, q, title in ((axs[0], before["F"], "as the file has it"),
                         (axs[1], after["F"], f"balanced ({criterion})")):
        ax.plot(phi_deg, q[:, 0], label="Qx")
        ax.plot(phi_deg, q[:, 1], label="Qy")
        for k, c in ((0, "C0"), (1, "C1")):
            peak = np.abs(q[:, k]).max()
            ax.axhline(peak, color=c, lw=0.7, ls=":")
            ax.axhline(-peak, color=c, lw=0.7, ls=":")
        ax.set_title(f"{title}: max|Qx| {np.abs(q[:, 0]).max():.3g} N,"
                     f" max|Qy| {np.abs(q[:, 1]).max():.3g} N", fontsize=9)
        ax.set_xlabel("shaft angle phi [deg]")
        ax.set_xticks(np.arange(0, 361, 60))
        ax.grid(True, alpha=0.3)
    axs[0].set_ylabel("resultant inertia force on the frame [N]")
    axs[0].legend(fontsize=8)
    fig.suptitle(f"{name}: shaking force components at {rpm:g} rpm")
    figs.add(fig, "bal-components", "Shaking force components, before and after",
             "The x and y components of the resultant inertia force of all moving links on"
             f" the frame over one turn, as the file has it and with {cws} (dotted: each"
             " component's peak). The balancing paper's criterion makes the two peaks equal."
             + arc_cam_note(machine),
             pd.DataFrame({"phi_deg": phi_deg, "Qx_before_N": before["F"][:, 0],
                           "Qy_before_N": before["F"][:, 1], "Qx_after_N": after["F"][:, 0],
                           "Qy_after_N": after["F"][:, 1]}))

    # ---- hodographs of every criterion ------------------------------------------------------
    fig, ax = subplots(figsize=(6.2, 6.2), constrained_layout=True)
    ax.plot(before["F"][:, 0], before["F"][:, 1], color="k", lw=1.6, label="as the file has it")
    data = {"phi_deg": phi_deg, "Qx_before_N": before["F"][:, 0],
            "Qy_before_N": before["F"][:, 1]}
    for k, (crit, r) in enumerate(proposed.items()):
        F = r.curves["after"]["F"]
        ax.plot(F[:, 0], F[:, 1], lw=1.1, color=f"C{k}", label=crit,
                ls="-" if crit == criterion else "--")
        data[f"Qx_{crit}_N"], data[f"Qy_{crit}_N"] = F[:, 0], F[:, 1]
    ax.plot([0], [0], "k+", ms=10)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("Qx [N]")
    ax.set_ylabel("Qy [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{name}: shaking force hodograph, each criterion's answer")
    figs.add(fig, "bal-hodograph", "Shaking force hodographs",
             "The tip of the shaking force vector over one turn before balancing and with each"
             " criterion's counterweights (solid: the one shown in the other figures)."
             + arc_cam_note(machine),
             pd.DataFrame(data))

    # ---- bearings as polar plots -------------------------------------------------------------
    if B.has_bearings:
        fig, axs = subplots(1, 2, figsize=(10, 5), subplot_kw={"projection": "polar"},
                                constrained_layout=True)
        bdata = {"phi_deg": phi_deg}
        for ax, key, side in ((axs[0], "Bf", "front"), (axs[1], "Br", "rear")):
            for q, label, style in ((before, "before", "k-"), (after, criterion, "C3-")):
                R = q[key]
                ang = np.arctan2(R[:, 1], R[:, 0])
                ax.plot(np.append(ang, ang[0]), np.append(np.hypot(R[:, 0], R[:, 1]),
                                                          np.hypot(*R[0])), style, lw=1.3,
                        label=f"{label}: peak {np.hypot(R[:, 0], R[:, 1]).max():.3g} N")
                bdata[f"{side}_x_{label}_N"], bdata[f"{side}_y_{label}_N"] = R[:, 0], R[:, 1]
            ax.set_title(f"{side} bearing", fontsize=10)
            ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.1, -0.15))
        fig.suptitle(f"{name}: upper-shaft bearing reactions (direction and size, N)")
        figs.add(fig, "bal-bearings", "Upper-shaft bearing reactions, before and after",
                 "The force each bearing of the upper shaft takes, as a polar plot (angle: its"
                 " direction in the frame; radius: its size in N) over one turn, before and"
                 f" with the {criterion} counterweights." + arc_cam_note(machine),
                 pd.DataFrame(bdata))

    # ---- the paper's bench figure, predicted ---------------------------------------------------
    Bl = Bq if Bq is not None else (B if len(B.counterweights) == 1 else None)
    if Bl is not None and Bl.housing is not None:
        _levels_figure(figs, machine, Bl, results)

    # ---- trade-off front ---------------------------------------------------------------------
    if front:
        T = tradeoff(B)
        names = list(T["axes"])
        vals = [T["figures"][a] for a in names]
        labels = {"peak_force_N": "peak shaking force [N]",
                  "peak_moment_Nm": "peak shaking moment [N m]",
                  "bearings_peak_N": "larger peak bearing reaction [N]",
                  "torque_fluctuation_Nm": "torque fluctuation [N m]"}
        flat = ""
        # a figure the counterweights cannot change (the moment about the shaft of weights on
        # the shaft) goes to the colour, the two that move to the axes
        if np.ptp(vals[1]) <= 1e-9 * max(np.abs(vals[1]).max(), 1e-12):
            names[1], names[2], vals[1], vals[2] = names[2], names[1], vals[2], vals[1]
            flat = f"; {labels[names[2]].split(' [')[0]} {vals[2][0]:.4g} for every set"
        fx, fy, fc = vals

        def of(figures, key):
            if key == "bearings_peak_N":
                return max(figures["bearing_front_peak_N"], figures["bearing_rear_peak_N"])
            return figures[key]

        fig, ax = subplots(figsize=(7.5, 5.6), constrained_layout=True)
        # the cloud as pixels (also in the SVG): thousands of markers as paths cost more than
        # they show
        sc = ax.scatter(fx, fy, c=fc, s=6, cmap="viridis", alpha=0.5, rasterized=True)
        on = T["front"]
        ax.scatter(fx[on], fy[on], c=fc[on], s=28, cmap="viridis", edgecolors="k",
                   linewidths=0.6, label="not dominated")
        for k, (crit, r) in enumerate(proposed.items()):
            ax.scatter([of(r.after, names[0])], [of(r.after, names[1])], marker="*", s=150,
                       color=f"C{k}", edgecolors="k", zorder=5,
                       label=f"{crit} ({of(r.after, names[2]):.3g})")
        ax.scatter([of(main.before, names[0])], [of(main.before, names[1])], marker="X", s=90,
                   color="k", label=f"as the file has it ({of(main.before, names[2]):.3g})")
        fig.colorbar(sc, ax=ax, label=labels[names[2]])
        ax.set_xlabel(labels[names[0]])
        ax.set_ylabel(labels[names[1]])
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
        ax.set_title(f"{name}: {len(fx)} counterweight sets, {int(on.sum())} not dominated{flat}",
                     fontsize=9)
        table = {names[0]: fx, names[1]: fy, names[2]: fc, "front": on}
        for j, c in enumerate(B.names):
            S = np.hypot(T["xy"][:, j, 0], T["xy"][:, j, 1]) * 100.0
            table[f"{c}_static_moment_gcm"] = S
            table[f"{c}_angle_deg"] = np.degrees(np.arctan2(T["xy"][:, j, 1], T["xy"][:, j, 0]))
        figs.add(fig, "bal-front", "Trade-off: shaking force, shaking moment, bearings",
                 "Counterweight sets spread over the plane of each counterweight (a"
                 " low-discrepancy sample, evaluated exactly from the balancing basis), with the"
                 " sets no"
                 " other beats in all three figures ringed, and each criterion's answer (stars;"
                 " the colour's figure in brackets). A designer picks from the ringed ones.",
                 pd.DataFrame(table))

    # ---- tables ------------------------------------------------------------------------------
    comp = pd.DataFrame([{"figure": FIGURE_LABELS[k][0], "unit": FIGURE_LABELS[k][1],
                          "before": main.before[k],
                          **{c: r.after[k] for c, r in proposed.items()}}
                         for k in FIGURES if main.before[k] is not None])
    key = pd.DataFrame([(FIGURE_LABELS[k][0] + " before", main.before[k], FIGURE_LABELS[k][1])
                        for k in FIGURES if main.before[k] is not None]
                       + [(FIGURE_LABELS[k][0] + f" after ({criterion})", main.after[k],
                           FIGURE_LABELS[k][1]) for k in FIGURES if main.after[k] is not None],
                       columns=["figure", "value", "unit"])
    return {"main": main, "results": results, "paper": paper, "key": key, "comparison": comp,
            "basis_error": max(r.basis_error for r in results.values())}


def _levels_figure(figs, machine: Machine, B, results: dict) -> None:
    """v_x(S) and v_y(S) at the control point as the balancing paper draws its measured ones,
    predicted by the housing's model, with the predicted crossing (equal-levels) beside the
    Delta-Q answer."""
    from ...design._vibration_criteria import level_curves
    from ..drawing.figures import subplots

    cw = B.counterweights[0].name
    lc = level_curves(B)
    fig, ax = subplots(figsize=(7.5, 4.6), constrained_layout=True)
    ax.plot(lc["S_gcm"], lc["vx_mm_s"], color="C0", label="x (predicted)")
    ax.plot(lc["S_gcm"], lc["vy_mm_s"], color="C1", label="y (predicted)")
    marks = []
    for crit, style in (("equal-levels", "-"), ("delta-q", "-.")):
        r = results.get(crit)
        if r is not None and r.status == "optimal":
            S = r.counterweights[cw]["static_moment_gcm"]
            marks.append(f"{crit} {S:.4g} g cm")
            ax.axvline(S, color="k", ls=style, lw=0.9,
                       label=("x = y" if crit == "equal-levels" else "Delta-Q = 0")
                       + f": {S:.4g} g cm")
    ax.set_xlabel(f"static moment of '{cw}' along {lc['beta_deg']:.4g} deg, S [g cm]")
    ax.set_ylabel(f"vibration velocity at '{B.control_name}' [mm/s RMS]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{machine.name}: the control point's vibration against the counterweight at"
                 f" {B.rpm:g} rpm", fontsize=10)
    figs.add(fig, "bal-levels", "Vibration at the control point against the counterweight",
             "The RMS vibration velocity of the housing's control point"
             f" '{B.control_name}' along x and y as the static moment of '{cw}' grows along its"
             " angle, predicted by the housing's model: the curves the balancing paper measures"
             " on the bench, whose crossing is its chosen counterweight"
             f" ({'; '.join(marks) or 'no crossing and no Delta-Q root'}). Where the x = y"
             " crossing and Delta-Q = 0 differ, the housing (its mass, mounts and the control"
             " point's place) is why; trial-balance --calibrate fits it to measurements.",
             pd.DataFrame({"S_gcm": lc["S_gcm"], "vx_mm_s": lc["vx_mm_s"],
                           "vy_mm_s": lc["vy_mm_s"]}))


def section_html(machine: Machine, sec: dict) -> str:
    """The balancing section's heading and text: what was balanced, every criterion's answer
    side by side, and the paper's workflow."""
    from ..display import is_round_off
    from ..drawing.figures import table_html

    main = sec["main"]
    names = ", ".join(html.escape(n) for n in main.counterweights)
    none = "".join(f" <b>{html.escape(c)}</b> proposes nothing: {html.escape(r.message)}."
                   for c, r in sec["results"].items() if not r.proposed)
    err = sec["basis_error"]  # round-off of the forces (the basis is exact): said so
    agree = ("as the balancing basis predicts, to round-off" if is_round_off(
        err, main.before["peak_force_N"]) else f"largest difference from the balancing basis"
        f" {err:.2g} N")
    return (f'<h2 id="balancing">Balancing</h2><p>Counterweights chosen at {main.rpm:g} rpm for'
            f" each criterion (docs/balancing.md), every answer computed again on the whole"
            f" machine ({agree}). Shown below: <b>{html.escape(main.criterion)}</b>"
            f" ({html.escape(main.status)}: {html.escape(main.message)}) on {names}.{none}</p>"
            + table_html(sec["comparison"]) + paper_html(sec["paper"]))


def paper_html(paper: dict | None) -> str:
    """The balancing paper's workflow as a short table (empty without a shaft counterweight):
    S_1, S_add, S_opt and the built counterweight's recipe, or why there is none."""
    if not paper:
        return ""
    rows = [("S_1: static moment the shaft's crank has (all its solids)", paper["s1_gcm"],
             "g cm", f"at {paper['s1_angle_deg']:.4g} deg")]
    if paper["s_add_gcm"] is not None:
        rows += [("S_add: the extra counterweight for Delta-Q = 0", paper["s_add_gcm"], "g cm",
                  f"at {paper['s_add_angle_deg']:.4g} deg ({paper['status']})"),
                 ("S_opt = |S_1 + S_add|: the crank's net static moment with it",
                  paper["s_opt_gcm"], "g cm", f"at {paper['s_opt_angle_deg']:.4g} deg")]
    b = paper.get("build")
    if b:
        ins, blk = b["insert"], b["block"]
        rows += [(f"built {b['factor']:g} x stronger", b["s_built_gcm"], "g cm",
                  b.get("factor_note", "")),
                 ("steel cup: outer diameter", blk["diameter_mm"], "mm",
                  f"its axis parallel to the shaft at {blk['radius_mm']:.4g} mm, clamped on the"
                  f" {b['bore_mm']:.4g} mm shaft"),
                 ("steel cup: length", blk["length_mm"], "mm",
                  f"{blk['steel_g']:.4g} g of steel; bottom {blk['bottom_mm']:.3g} mm"),
                 ("lead insert: hole diameter", ins["diameter_mm"], "mm",
                  f"on the cup's axis; side walls {blk['side_wall_mm']:.3g} mm, its edge"
                  f" {b['hole_edge_mm']:.3g} mm from the shaft's axis ({b['clearance_mm']:.3g}"
                  f" mm of steel to the shaft; at least {b['wall_mm']:g} mm everywhere)"),
                 ("lead insert: hole depth", ins["depth_mm"], "mm",
                  f"{ins['mass_g']:.4g} g of lead, adds {ins['s_gcm']:.4g} g cm"),
                 ("trim to S_add: the lead drilled out", b["trim_diameter_mm"], "mm",
                  "diameter, the insert's depth and radius"),
                 ("trim to S_add: or a hole into the steel", b["trim_diameter_body_mm"], "mm",
                  "diameter, same depth and radius"),
                 ("plain steel counterweight of the built S", b["body_only_mass_g"], "g",
                  "at the same radius")]
    df = pd.DataFrame(rows, columns=["step", "value", "unit", "where"])
    from ..drawing.figures import table_html

    refused = ("" if b else "<p>No recipe for the built counterweight: "
               f"{html.escape(paper.get('build_refused', ''))}.</p>")
    return ("<h3>The balancing paper's method</h3><p>Delta-Q = 0 chooses the extra"
            f" counterweight <b>{html.escape(paper['counterweight'])}</b> on"
            f" {html.escape(paper['link'])}; it is built stronger with a drilled lead insert"
            " and trimmed on the machine until the x and y vibration velocities are equal"
            " (<code>sewmech trial-balance</code>).</p>" + table_html(df) + refused)

"""The report's feed section: the dog's paths forward and reverse, the stitch-length curve with
the scale-plate marks, and the feed sensitivity study (figures and tables)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ...engine.machine import Machine
from ...sewing import feed as FD
from ..display import signed
from ..drawing.figures import Figures, subplots


def feed_section(figs: Figures, machine: Machine, step) -> dict:
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
        lab = f"{signed(c.stitch_mm[k])} mm (regulator {signed(reg)} deg)"
        ax.plot(c.x[k], c.y[k], lw=1.4, label=lab)
        data[f"x_mm_reg_{signed(reg, 4)}deg"] = c.x[k]
        data[f"y_above_plate_mm_reg_{signed(reg, 4)}deg"] = c.y[k]
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
    bx.axhspan(*FD.FEED_DOG_RISE_MM, color="C2", alpha=0.1,
               label="published band [Sdelai-sam-1999]")
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
             " plate, forward and reverse (table below); shaded: the lift of the Podolsk"
             " household machine [Sdelai-sam-1999].", curve.to_pandas(), table=mk)
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

"""The report's thread section: the needle thread's supply against its demand over the cycle,
the overfeed and its checks, the consumption per stitch, and the adjustable take-up."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...engine.machine import Machine
from ..drawing.figures import Figures, shade, subplots


def thread_section(figs: Figures, machine: Machine):
    """Thread balance: supply, demand and its parts, overfeed, with its own checks."""
    from ...sewing import thread as TH

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
        shade(a, b.phi_deg, loop, "C1", "loop on the shuttle")
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
             " (demand) over one revolution, and their difference, the overfeed"
             " ([Krasowska-take-up]);"
             " shaded: the loop on the shuttle from seizure to cast-off. The balance checks"
             " below are design diagnostics of the thread path, the take-up and the loop model"
             " (see the sewmech.thread documentation), separate from the machine-class checks.",
             b.to_pandas(), table=table)
    if machine.spec.thread.adjust is not None:
        _adjust_figure(figs, machine)
    _consumption_figure(figs, machine)


def _consumption_figure(figs: Figures, machine: Machine):
    """Thread per stitch against stitch length and fabric thickness, with the industry formula."""
    from ...sewing import thread as TH

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
             " fabric thickness ([Thread-consumption-301], [Malek-2020]), beside the industry"
             " formula C = 2 + 2TS per"
             " inch of seam; the two differ by the thread-diameter term.", pd.DataFrame(rows))


def _adjust_figure(figs: Figures, machine: Machine):
    """The adjustable take-up: margin over (thickness, setting) and the recommended setting."""
    from ...sewing import thread as TH

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

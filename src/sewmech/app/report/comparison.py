"""The report's comparison of machine variants: their key figures, dog paths and stitch-length
curves side by side."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from ...engine.machine import Machine
from ...sewing import feed as FD
from ...sewing import timing as T
from ..drawing.figures import Figures, subplots


def key_figures(m: Machine) -> dict:
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


def comparison_section(figs: Figures, machines: Sequence[Machine]):
    """Key figures, dog paths and stitch curves of machine variants side by side."""
    table = pd.DataFrame({m.name: key_figures(m) for m in machines})
    table.insert(0, "figure", table.index)
    names = " against ".join(m.name for m in machines)
    if not any(m.spec.sewing and m.spec.sewing.feed_dog and m.spec.sewing.regulator
               for m in machines):
        _table_only(figs, table, names)
        return
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
    figs.add(fig, "comparison", f"Variants side by side: {names}",
             "Key figures of each variant (table), the dog's path at the longest forward stitch"
             " and the stitch-length curves.", pd.DataFrame(data), table=table)


def _table_only(figs: Figures, table: pd.DataFrame, names: str) -> None:
    """The key figures alone, when no machine compared has a feed dog: the figure of dog paths
    and stitch curves would be two empty axes (and matplotlib's warning of a legend without
    lines)."""
    import html

    from ..drawing.figures import table_html
    from ..files.io import atomic_write

    stem = f"{figs.machine}-comparison"
    with atomic_write(figs.root / f"{stem}.csv") as fh:
        table.to_csv(fh, index=False, float_format="%.10g")
    title = f"Variants side by side: {names}"
    figs.insert_html(len(figs), f'<figure id="comparison"><h3>{html.escape(title)}</h3>'
                     f"<figcaption>Key figures of each variant (no dog paths or stitch curves:"
                     f" none of them has a feed dog and a stitch regulator). Files: "
                     f'<a href="{stem}.csv">data (CSV)</a>.</figcaption>'
                     f"{table_html(table)}</figure>")

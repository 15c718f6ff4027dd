"""The report's accuracy section: how the stitch length, the feed lift and the dog's height when
the needle reaches the plate stray with the dimensions' tolerances (worst case, RSS, the
dimensions that matter), from the exact derivatives, with a Pareto chart of the stitch
length's contributions. (The Monte Carlo check is `sewmech tolerance`; the report keeps to the
derivatives, which take a fraction of a second.)"""

from __future__ import annotations

import html

import numpy as np
import pandas as pd

from ...design.tolerance_file import ToleranceSpec, tolerances_of
from ...engine.machine import Machine
from ...sewing.feed import regulator_range_deg
from ...sewing.gradients import METRICS

#: the default tolerances of the report: IT9 on every length (docs/accuracy.md)
REPORT_GRADE = 9


def accuracy_section(figs, machine: Machine) -> dict:
    """Add the accuracy figure to ``figs``; return {"table": DataFrame, "html": str}."""
    from ..drawing.figures import subplots

    spec = ToleranceSpec.model_validate({"defaults": {"it_grade": REPORT_GRADE}})
    tol = tolerances_of(machine, spec)
    reg = regulator_range_deg(machine)[1]
    rows, grads = [], {}
    for name, f in METRICS.items():
        g = f(machine, reg)
        grads[name] = g
        c = (g.d_dparam * tol) ** 2
        rss = float(np.sqrt(c.sum()))
        top = [machine.parameter_names[j] for j in np.argsort(-c)[:3] if c[j] > 0]
        shares = [f"{n} {100 * c[machine.parameter_names.index(n)] / rss ** 2:.0f} %"
                  for n in top]
        rows.append({"metric": name, "value": g.value, "unit": g.unit,
                     "worst case +-": float(np.sum(np.abs(g.d_dparam) * tol)), "RSS +-": rss,
                     "per deg of regulator": float(g.d_dparam[machine.parameter_names.index(
                         f"input.{machine.spec.sewing.regulator}")]) * np.pi / 180.0,
                     "largest shares": ", ".join(shares)})
    table = pd.DataFrame(rows)
    g = grads["stitch_length"]
    c = (g.d_dparam * tol) ** 2
    order = [j for j in np.argsort(-c)[:12] if c[j] > 0]
    share = c[order] / c.sum()
    names = [machine.parameter_names[j] for j in order]
    fig, ax = subplots(figsize=(8, 0.35 * len(names) + 1.6), constrained_layout=True)
    ax.barh(range(len(names))[::-1], 100 * share, color="C0")
    ax.set_yticks(range(len(names))[::-1], names, fontsize=8)
    ax.set_xlabel("share of the stitch length's RSS variance [%]")
    ax2 = ax.twiny()
    ax2.plot(100 * np.cumsum(share), range(len(names))[::-1], "C3o-", ms=3)
    ax2.set_xlim(0, 100)
    ax2.set_xlabel("cumulative share [%]", color="C3")
    ax.set_title(f"{machine.name}: what makes the stitch length ({g.value:.3f} mm at regulator"
                 f" {reg:g} deg) stray, every length at IT{REPORT_GRADE}", fontsize=9)
    figs.add(fig, "accuracy-stitch", "Stitch length: the dimensions that matter",
             f"Each dimension's share of the stitch length's variance when every length is"
             f" made within +-IT{REPORT_GRADE}/2 of its size (ISO 286-1 [ISO-286]), from the exact"
             " derivatives of the stitch length (the dog's rise and fall through the plate"
             " moving with the design); the line is the running total.",
             pd.DataFrame({"parameter": names, "derivative": g.d_dparam[order],
                           "tolerance": tol[order], "share": share}))
    intro = (f'<h2 id="accuracy">Accuracy</h2><p>How far the feed strays when every length is'
             f" made within +-IT{REPORT_GRADE}/2 of its size (ISO 286-1 [ISO-286]; angles"
             f" exact), at the longest forward stitch (regulator {reg:g} deg): worst case and"
             " RSS from the exact derivatives of each metric by every dimension"
             " (docs/accuracy.md; <code>sewmech tolerance</code> adds the Monte Carlo check"
             " and allocation).</p>")
    from ..drawing.figures import table_html

    return {"table": table, "html": intro + table_html(table.round(6))
            + f'<p>Data: <a href="{html.escape(machine.name)}-accuracy.csv">table (CSV)</a>.'
              "</p>"}

"""The report's HTML page: the head with the machine and its convention, the checks, the timing
events, the figures, the machine data and the machine file itself."""

from __future__ import annotations

import html
import math

import pandas as pd

from ...engine.machine import Machine, file_value
from ..drawing.figures import table_html

CSS = """
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


def dynamics_intro(machine: Machine, key: pd.DataFrame) -> str:
    loads = "; ".join(f"{ld.name} {ld.force_N:g} N over "
                      + ", ".join(f"{a:g}-{b:g}" for a, b in ld.windows_deg) + " deg"
                      for ld in machine.spec.loads) or "none"
    return (f'<h2 id="dynamics">Dynamics</h2><p>Inverse dynamics of the whole machine at'
            f" {machine.rpm:g} rpm, gravity on, at the longest forward stitch (the JB dynamics"
            f" report's hardest case). Process loads: {html.escape(loads)}. Link masses:"
            " see the machine file's [masses] tables.</p>" + table_html(key.round(5))
            + f'<p>Data: <a href="{machine.name}-dynamics-key-figures.csv">key figures'
            " (CSV)</a>.</p>")


def page_html(machine, ref, chk, tim, par, blocks, file_text, file_name, extra=()) -> str:
    info = machine.spec.machine
    n_fail = int((chk["result"] != "pass").sum()) if len(chk) else 0
    verdict = (f'<p class="pass">All {len(chk)} checks pass.</p>' if n_fail == 0 else
               f'<p class="fail">{n_fail} of {len(chk)} checks fail.</p>')
    chk_html = table_html(chk, "checks").replace("<td>pass</td>", '<td class="pass">pass</td>')
    chk_html = chk_html.replace("<td>FAIL</td>", '<td class="fail">FAIL</td>')
    e = html.escape
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>sewmech report: {e(info.name)}</title><style>{CSS}</style></head><body>
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

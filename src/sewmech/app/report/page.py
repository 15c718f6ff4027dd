"""The report's HTML page: the head with the machine and its convention, a contents list, the
labelled mechanism, the checks, the timing events, the sections (a section left out says why),
the machine data, the machine file itself and the references its citations resolve to."""

from __future__ import annotations

import html
import math
import re

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
nav#contents ol{margin:0.2em 0;padding-left:1.6em} nav#contents li{margin:0.25em 0}
nav#contents .figs{font-size:0.85em} dl.refs dt{font-weight:bold;margin-top:0.5em}
dl.refs dd{margin-left:1.5em} .left-out{font-style:italic}
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
            " see the machine file's [masses] tables.</p>" + table_html(key)
            + f'<p>Data: <a href="{machine.name}-dynamics-key-figures.csv">key figures'
            " (CSV)</a>.</p>")


def arc_cam_note(machine: Machine) -> str:
    """One sentence for the captions of curves that show the accelerations of cam-driven parts
    (forces, torques), when the machine has a cam made of several circular arcs; else ""."""
    cams = [name for name, c in machine.spec.cams.items()
            if c.constant_width is not None or (c.arcs is not None and len(c.arcs) > 1)]
    if not cams:
        return ""
    return (f" The sudden steps and kinks come from the circular-arc cam"
            f"{'s' if len(cams) > 1 else ''} ({', '.join(cams)}): where two arcs meet, the"
            " profile's curvature jumps, and with it the follower's acceleration and every force"
            " that depends on it; they belong to the cam, not to the numerics.")


def left_out_html(section: str, title: str, reason: str) -> str:
    """The heading of a section the report leaves out, and why (it stays in the contents)."""
    return (f'<h2 id="{section}">{html.escape(title)}</h2>'
            f'<p class="sub left-out">{html.escape(reason)}</p>')


_HEADING = re.compile(r'<h2 id="([^"]+)">(.*?)</h2>(<p class="sub left-out">)?', re.S)
_FIGURE = re.compile(r'<figure id="([^"]+)"><h3>(.*?)</h3>', re.S)


def contents_html(body: str) -> str:
    """A contents list of ``body``: every section (an ``h2`` with an id) and after it its
    figures (a ``figure`` with an id and an ``h3``) on one line, each a link to its id."""
    marks = sorted([(m.start(), "h2", m.group(1), m.group(2), bool(m.group(3)))
                    for m in _HEADING.finditer(body)]
                   + [(m.start(), "fig", m.group(1), m.group(2), False)
                      for m in _FIGURE.finditer(body)])
    items: list[list] = []
    for _, kind, ident, title, left_out in marks:
        link = f'<a href="#{ident}">{title}</a>' + (" (left out)" if left_out else "")
        if kind == "h2" or not items:
            items.append([link, []])
        else:
            items[-1][1].append(link)
    lis = "".join(f"<li>{head}" + (f'<br><span class="figs">{" · ".join(sub)}</span>'
                                   if sub else "") + "</li>" for head, sub in items)
    return f'<nav id="contents"><h2>Contents</h2><ol>{lis}</ol></nav>'


def references_html(body: str) -> tuple[str, str]:
    """``body`` with every cited key (``[JB-dynamics]``) a link to its entry, and the
    References section listing the entries cited (sewmech.sewing.references)."""
    from ...sewing.references import KEY_PATTERN, NOT_KEYS, cited

    refs = cited(body)
    if not refs:
        return body, ""
    known = {r.key for r in refs}

    def link(m):
        key = m.group(1)
        if key not in known or key in NOT_KEYS:
            return m.group(0)
        return f'<a class="ref" href="#ref-{key}">[{key}]</a>'

    linked = KEY_PATTERN.sub(link, body)
    entries = "".join(
        f'<dt id="ref-{r.key}">[{html.escape(r.key)}]</dt><dd>{html.escape(r.source)}'
        + (f' <a href="{html.escape(r.url)}">{html.escape(r.url)}</a>' if r.url else "")
        + "</dd>" for r in refs)
    return linked, ('<h2 id="references">References</h2><p>The sources this report cites by'
                    " key: the published facts the checks hold the machine to, and where the"
                    " machine file's values come from. The list of every fact sewmech uses,"
                    " with its value and how it is used, is docs/references.md in sewmech's"
                    f" sources.</p><dl class=\"refs\">{entries}</dl>")


def page_html(machine, ref, chk, tim, par, blocks, file_text, file_name, extra=(),
              mechanism: str = "") -> str:
    """The whole page: the head, its contents list, the labelled mechanism, the checks, the
    timing, every section's blocks (``blocks``, headings included), the machine data, the
    machine file and the references cited."""
    info = machine.spec.machine
    n_fail = int((chk["result"] != "pass").sum()) if len(chk) else 0
    verdict = (f'<p class="pass">All {len(chk)} checks pass.</p>' if n_fail == 0 else
               f'<p class="fail">{n_fail} of {len(chk)} checks fail.</p>')
    chk_html = table_html(chk, "checks").replace("<td>pass</td>", '<td class="pass">pass</td>')
    chk_html = chk_html.replace("<td>FAIL</td>", '<td class="fail">FAIL</td>')
    e = html.escape
    body = f"""{('<h2 id="machine">The mechanism</h2>' + mechanism) if mechanism else ''}
<h2 id="checks">Checks</h2>{verdict}{chk_html}
<p>Each check's source is a key of the references below.
Data: <a href="{e(info.name)}-checks.csv">checks (CSV)</a>.</p>
<h2 id="timing">Timing</h2>{table_html(tim)}
<p>Data: <a href="{e(info.name)}-timing-events.csv">timing events (CSV)</a>.</p>
{''.join(blocks)}
{''.join(extra)}
<h2 id="machine-data">Machine data</h2>
<p>Every value of the machine file as a named parameter (angles shown in degrees). Sources and
estimates are recorded beside each value in the file below.
<a href="{e(info.name)}-parameters.csv">parameters (CSV)</a>.</p>
{table_html(par)}
<details><summary>Machine file {e(file_name)}</summary><pre>{e(file_text)}</pre></details>
"""
    body, references = references_html(body)
    body += references
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>sewmech report: {e(info.name)}</title><style>{CSS}</style></head><body>
<h1>{e(info.title or info.name)}</h1>
<p class="sub">{e(info.description)}</p>
<p>Angle convention: {e(ref)}. {e(machine.spec.convention.description)} Working speed
{machine.rpm:g} rpm. Lengths in mm. Machine file: <a href="{e(file_name)}">{e(file_name)}</a>.</p>
{_changes_html(machine)}{contents_html(body)}
{body}
<p class="sub">Written by sewmech.</p>
</body></html>
"""

"""The table of current figures, built from the results files ``benchmarks/results/*.json``.

Each benchmark writes its results file with ``figures``: one row per job with sewmech's figure,
its anchor (another program, or sewmech's own simpler job) and the anchor's figure, the ratio,
the target, and whether it is met, plus the ``date`` and ``commit`` of the run
(``_timing.write_results``). This script reads every results file and prints one Markdown table
of them, the same table that heads BENCHMARKS.md; it runs no benchmark.

    python benchmarks/table.py           print the table (``make bench-table``)
    python benchmarks/table.py --write   print it and rewrite the block between the markers
                                         in BENCHMARKS.md (``make bench`` does this)
    python benchmarks/table.py --check   exit 1 if BENCHMARKS.md's block is not the table

"met" is recomputed here from the figure (or the ratio) against the target, never copied. A
results file without ``figures`` or with a row missing a field is named with what is missing
(and the exit status is 1); the rest of the table is still printed. A file without ``date`` or
``commit`` gets them from the git log of that file.
"""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))
from _timing import OPS, RATIO_KINDS, meets  # noqa: E402

RESULTS = HERE / "results"
DOC = HERE.parent / "BENCHMARKS.md"
START = "<!-- current-figures:start -->"
END = "<!-- current-figures:end -->"
HEADER = ("job", "anchor", "sewmech", "ratio", "target", "met", "date", "commit")
REQUIRED = ("job", "figure", "unit")


@dataclass(frozen=True)
class Row:
    results: str  # the results file's name
    job: str
    figure: float
    unit: str
    anchor: str | None
    anchor_figure: float | None
    ratio: float | None
    ratio_kind: str
    target: float | None
    target_op: str
    target_on: str
    condition: bool | None
    condition_text: str
    met: bool | None
    date: str
    commit: str


def git_stamp(path: Path) -> tuple[str, str]:
    """(date, commit) of the last commit that changed ``path`` (merges left out), or ("?", "?")
    when git cannot say (not a checkout, or the file never committed)."""
    try:
        out = subprocess.run(["git", "log", "-1", "--no-merges", "--format=%cs %h", "--",
                              path.name], cwd=path.parent, capture_output=True, text=True,
                             check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        return "?", "?"
    return (out[0], out[1]) if len(out) == 2 else ("?", "?")


def _problem_in_row(r: object, k: int) -> str | None:
    if not isinstance(r, dict):
        return f"row {k + 1} is not an object"
    missing = [f for f in REQUIRED if f not in r]
    if missing:
        return f"row {k + 1} ({r.get('job', 'no job')!r}) has no {', '.join(missing)}"
    if not isinstance(r["figure"], int | float) or isinstance(r["figure"], bool):
        return f"row {k + 1} ({r['job']!r}): figure is {r['figure']!r}, not a number"
    if r.get("target") is not None:
        if r.get("target_op", "<=") not in OPS:
            return f"row {k + 1} ({r['job']!r}): target_op {r.get('target_op')!r} is not one of" \
                   f" {', '.join(OPS)}"
        if r.get("target_on", "figure") not in ("figure", "ratio"):
            return f"row {k + 1} ({r['job']!r}): target_on {r.get('target_on')!r} is not" \
                   " 'figure' or 'ratio'"
        if r.get("target_on") == "ratio" and r.get("ratio") is None:
            return f"row {k + 1} ({r['job']!r}): the target is on the ratio and it has no ratio"
    if r.get("ratio_kind", "faster") not in RATIO_KINDS:
        return f"row {k + 1} ({r['job']!r}): ratio_kind {r.get('ratio_kind')!r} is not one of" \
               f" {', '.join(RATIO_KINDS)}"
    return None


def load(results: Path = RESULTS) -> tuple[list[Row], list[str]]:
    """Every row of every results file (files by name, rows in their order), and the problems
    found: one sentence each, naming the file and what is missing."""
    rows: list[Row] = []
    problems: list[str] = []
    for path in sorted(results.glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            problems.append(f"{path.name}: not readable JSON ({e})")
            continue
        figures = data.get("figures") if isinstance(data, dict) else None
        if not isinstance(figures, list):
            problems.append(f"{path.name}: no 'figures' list (the rows of this table): run its"
                            " benchmark again, which writes them through"
                            " _timing.write_results")
            continue
        date, commit = data.get("date"), data.get("commit")
        if not date or not commit:
            git_date, git_commit = git_stamp(path)
            date, commit = date or git_date, commit or git_commit
        for k, r in enumerate(figures):
            problem = _problem_in_row(r, k)
            if problem is not None:
                problems.append(f"{path.name}: {problem}")
                continue
            met = meets(r)
            if "met" in r and r["met"] != met:
                problems.append(f"{path.name}: row {k + 1} ({r['job']!r}) says met ="
                                f" {r['met']} but its figure against its target gives {met}"
                                " (the table shows the latter)")
            rows.append(Row(path.name, r["job"], float(r["figure"]), r["unit"], r.get("anchor"),
                            r.get("anchor_figure"), r.get("ratio"),
                            r.get("ratio_kind", "faster"), r.get("target"),
                            r.get("target_op", "<="), r.get("target_on", "figure"),
                            r.get("condition"), r.get("condition_text", "a further condition"),
                            met, str(r.get("date") or date), str(r.get("commit") or commit)))
    return rows, problems


def number(v: float) -> str:
    """Three significant figures, thousands written out."""
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    return f"{v:.3g}"


def ratio_text(value: float, kind: str) -> str:
    return f"{number(value)}x " + ("faster" if kind == "faster" else "the time")


def cells(r: Row) -> tuple[str, ...]:
    anchor = "" if r.anchor is None else (
        r.anchor if r.anchor_figure is None
        else f"{r.anchor}: {number(r.anchor_figure)} {r.unit}")
    ratio = "" if r.ratio is None else ratio_text(r.ratio, r.ratio_kind)
    if r.target is None:
        target, met = "(information)", ""
    else:
        target = (f"{r.target_op} {ratio_text(r.target, r.ratio_kind)}" if r.target_on == "ratio"
                  else f"{r.target_op} {number(r.target)} {r.unit}")
        if r.condition is not None:
            target += f", and {r.condition_text}" + ("" if r.condition else " (not held)")
        met = "met" if r.met else "**MISSED**"
    return (r.job, anchor, f"{number(r.figure)} {r.unit}", ratio, target, met, r.date, r.commit)


def _escape(cell: str) -> str:
    return cell.replace("|", "\\|")


def render(rows: list[Row]) -> str:
    """The Markdown table and a line counting the targets met and missed."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(_escape(c) for c in cells(r)) + " |" for r in rows]
    judged = [r for r in rows if r.met is not None]
    missed = [r for r in judged if not r.met]
    lines += ["", f"{len(judged)} targets: {len(judged) - len(missed)} met,"
                  f" {len(missed)} missed; {len(rows) - len(judged)} figures for information."]
    return "\n".join(lines)


def replace_block(text: str, block: str) -> str:
    """``text`` with everything between the START and END markers replaced by ``block``."""
    i, j = text.find(START), text.find(END)
    if i < 0 or j < i:
        raise ValueError(f"the markers {START} ... {END} are not in the document")
    return text[:i + len(START)] + "\n" + block + "\n" + text[j:]


def current_block(text: str) -> str:
    i, j = text.find(START), text.find(END)
    if i < 0 or j < i:
        raise ValueError(f"the markers {START} ... {END} are not in the document")
    return text[i + len(START):j].strip("\n")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    unknown = [a for a in argv if a not in ("--write", "--check")]
    if unknown:
        print(f"table.py: unknown option {unknown[0]} (use --write or --check)", file=sys.stderr)
        return 2
    rows, problems = load()
    table = render(rows)
    print(table)
    for p in problems:
        print(f"table.py: {p}", file=sys.stderr)
    status = 1 if problems else 0
    if "--write" in argv:
        text = DOC.read_text(encoding="utf-8")
        new = replace_block(text, table)
        if new != text:
            DOC.write_text(new, encoding="utf-8")
            print(f"table.py: {DOC.name} rewritten", file=sys.stderr)
    elif "--check" in argv:
        if current_block(DOC.read_text(encoding="utf-8")) != table:
            print(f"table.py: the table in {DOC.name} is not the one the results files give:"
                  " run python benchmarks/table.py --write", file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())

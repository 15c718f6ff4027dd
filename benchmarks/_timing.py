"""Timing harness shared by the benchmark scripts (not a benchmark itself).

The machine is shared and slow phases come and go, so contenders are never timed one after the
other: :func:`interleave` runs them in rounds (A, B, A, B, ...) and reports each one's best and
median time and, for every pair, the median of the ratios measured within one round, where both
met the same machine. A verdict reads that ratio.
"""

from __future__ import annotations

import datetime
import json
import os
import statistics
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def best(fn, repeat: int = 7, number: int = 1) -> tuple[float, float]:
    """(best, median) time per call of ``fn()`` in seconds over ``repeat`` repeats of ``number``
    calls each, after one warm-up call (numba compile or cache load). For one contender alone;
    contenders compared with each other go through :func:`interleave`."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return min(times), float(np.median(times))


@dataclass
class Timings:
    """Per-call seconds of each contender in each round (``rounds[name][k]``)."""

    rounds: dict[str, list[float]] = field(default_factory=dict)

    def best(self, name: str) -> float:
        return min(self.rounds[name])

    def median(self, name: str) -> float:
        return statistics.median(self.rounds[name])

    def ratio(self, slow: str, fast: str) -> float:
        """Median over the rounds of slow / fast, each ratio taken within one round."""
        return statistics.median(a / b for a, b in zip(self.rounds[slow], self.rounds[fast]))

    def ratio_range(self, slow: str, fast: str) -> tuple[float, float]:
        r = [a / b for a, b in zip(self.rounds[slow], self.rounds[fast])]
        return min(r), max(r)


@dataclass(frozen=True)
class Own:
    """What a contender returns to report a time it measured itself (seconds per call), e.g. a
    solver's own clock that leaves out its model building."""

    seconds: float


def interleave(contenders: dict[str, Callable[[], object]], *, rounds: int = 7,
               number: int | dict[str, int] = 1, warmup: bool = True) -> Timings:
    """Time every contender in each of ``rounds`` rounds, one after the other within a round
    (the order turns from round to round). A contender's time in a round is the mean of
    ``number`` calls (one count for all, or a count per contender), so that short calls are
    timed over many repeats; a contender that returns
    :class:`Own` is timed by its own clock."""
    if warmup:
        for fn in contenders.values():
            fn()
    names = list(contenders)
    out = Timings({n: [] for n in names})
    for k in range(rounds):
        order = names[k % len(names):] + names[:k % len(names)]
        for name in order:
            fn = contenders[name]
            calls = number[name] if isinstance(number, dict) else number
            own = []
            t0 = time.perf_counter()
            for _ in range(calls):
                r = fn()
                if isinstance(r, Own):
                    own.append(r.seconds)
            wall = (time.perf_counter() - t0) / calls
            out.rounds[name].append(sum(own) / len(own) if own else wall)
    return out


def table(rows: list[tuple], header: tuple[str, ...]) -> str:
    """A plain text table, columns padded to their widest cell."""
    cells = [tuple(str(c) for c in header)] + [tuple(str(c) for c in r) for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


# ---- the results files and the table of current figures ------------------------------------------
# Every benchmark writes ``benchmarks/results/<name>.json``: its own keys (other scripts and the
# history read them) plus ``figures``, the rows of the table of current figures at the top of
# BENCHMARKS.md (``benchmarks/table.py``), and the ``date`` and ``commit`` of the run.

OPS = {"<=": lambda a, b: a <= b, "<": lambda a, b: a < b,
       ">=": lambda a, b: a >= b, ">": lambda a, b: a > b}
RATIO_KINDS = ("faster", "time")  # anchor / sewmech ("5x faster"), sewmech / anchor ("0.9x the time")


def figure(job: str, value: float, unit: str, *, target: float | None = None, op: str = "<=",
           on: str = "figure", anchor: str | None = None, anchor_value: float | None = None,
           ratio: float | None = None, ratio_kind: str = "faster",
           condition: tuple[str, bool] | None = None) -> dict:
    """One row of the table of current figures.

    ``value`` is sewmech's figure in ``unit``; ``anchor`` names what it is measured against
    (another program, or sewmech's own simpler job) and ``anchor_value`` is the anchor's figure
    in the same unit. ``ratio`` is read as ``ratio_kind``: "faster" (the anchor's time over
    sewmech's, the bigger the better) or "time" (sewmech's time over the anchor's). The target
    is ``op target`` on the figure or on the ratio (``on``); ``condition`` is a further
    requirement of the verdict that is not a number, (what it asks, whether it holds), e.g.
    ("a smaller objective than pylinkage's", True). ``met`` is
    computed here, by :func:`meets`, the same way the table recomputes it."""
    if op not in OPS:
        raise ValueError(f"op must be one of {sorted(OPS)}, not {op!r}")
    if on not in ("figure", "ratio"):
        raise ValueError(f"on must be 'figure' or 'ratio', not {on!r}")
    if ratio_kind not in RATIO_KINDS:
        raise ValueError(f"ratio_kind must be one of {RATIO_KINDS}, not {ratio_kind!r}")
    row = {"job": job, "figure": float(value), "unit": unit, "anchor": anchor,
           "anchor_figure": None if anchor_value is None else float(anchor_value),
           "ratio": None if ratio is None else float(ratio), "ratio_kind": ratio_kind,
           "target": None if target is None else float(target), "target_op": op,
           "target_on": on}
    if condition is not None:
        row["condition_text"], row["condition"] = str(condition[0]), bool(condition[1])
    row["met"] = meets(row)
    return row


def meets(row: dict) -> bool | None:
    """Whether a row of :func:`figure` meets its target (None: no target, information)."""
    if row.get("target") is None:
        return None
    value = row["ratio"] if row.get("target_on") == "ratio" else row["figure"]
    if value is None:
        return False
    return bool(OPS[row.get("target_op", "<=")](value, row["target"])
                and row.get("condition", True))


def run_stamp(root=None) -> dict:
    """The date (UTC) of a run, the commit it measured (``git rev-parse --short HEAD``, with a
    ``+`` when ``src/`` or ``benchmarks/*.py`` differ from it: uncommitted code was measured)
    and the machine's load average over the last minute at the end of the run (the machine is
    shared: a figure measured under a load above its core count is suspect)."""
    root = Path(root) if root is not None else Path(__file__).resolve().parent.parent
    stamp = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d"),
             "commit": None, "load_1min": None}
    try:
        stamp["load_1min"] = round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root,
                                capture_output=True, text=True, check=True).stdout.strip()
        changed = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", "src",
                                  "benchmarks/*.py"], cwd=root).returncode != 0
    except (OSError, subprocess.CalledProcessError):
        return stamp
    stamp["commit"] = commit + ("+" if changed else "")
    return stamp


def write_results(path, payload: dict, figures: list[dict], *, indent: int = 1) -> None:
    """Write a benchmark's results: its own ``payload`` keys unchanged, plus ``figures`` (rows
    of :func:`figure`) and the run's ``date``, ``commit`` and load (:func:`run_stamp`)."""
    path = Path(path)
    out = dict(payload)
    out["figures"] = figures
    out.update(run_stamp())
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=indent) + "\n", encoding="utf-8")

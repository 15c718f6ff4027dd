"""Timing harness shared by the benchmark scripts (not a benchmark itself).

The machine is shared and slow phases come and go, so contenders are never timed one after the
other: :func:`interleave` runs them in rounds (A, B, A, B, ...) and reports each one's best and
median time and, for every pair, the median of the ratios measured within one round, where both
met the same machine. A verdict reads that ratio.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field

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

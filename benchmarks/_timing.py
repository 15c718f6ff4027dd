"""Timing helper shared by the benchmark scripts (not a benchmark itself)."""

from __future__ import annotations

import time

import numpy as np


def best(fn, repeat: int = 7) -> tuple[float, float]:
    """(best, median) wall time of ``fn()`` in seconds over ``repeat`` calls after one warm-up
    call (numba compile or cache load)."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))

"""Big batches of designs on every CPU core: the compiled kernels release the GIL, so chunks of
designs run on Python threads at once, each writing its own rows of the output arrays.

Threads instead of numba's ``parallel=True``: a ``prange`` kernel is a second compiled copy of
the whole interpreter (ten seconds of compiling on the first big batch after an install); the
threads run the one serial kernel. ``NUMBA_NUM_THREADS`` (default: the CPU count) sets their
number.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from numba import config

_POOL: ThreadPoolExecutor | None = None
_THREADS: int | None = None


def n_threads() -> int:
    """Threads for big batches: :func:`set_threads`, else ``NUMBA_NUM_THREADS``."""
    return _THREADS if _THREADS is not None else max(1, int(config.NUMBA_NUM_THREADS))


def set_threads(n: int | None) -> None:
    """Use ``n`` threads for big batches in this process (None: ``NUMBA_NUM_THREADS``); a
    process that shares the cores with others (a report's workers) uses one."""
    global _THREADS
    _THREADS = None if n is None else max(1, int(n))


def run_chunks(kernel, n_design: int, args: tuple, *, chunks_per_thread: int = 4) -> int:
    """``kernel(d0, d1, *args)`` over designs [0, n_design) in contiguous chunks on the
    threads (four per thread balance the load); returns the sum of what the calls return."""
    global _POOL
    threads = n_threads()
    n_chunks = min(n_design, chunks_per_thread * threads)
    if threads == 1 or n_chunks <= 1:
        return int(kernel(0, n_design, *args))
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="sewmech-kernel")
    bounds = [k * n_design // n_chunks for k in range(n_chunks + 1)]
    futures = [_POOL.submit(kernel, bounds[k], bounds[k + 1], *args) for k in range(n_chunks)]
    return sum(int(f.result()) for f in futures)

"""Where the page's sessions compute (issue 34): worker processes, or the server's own process.

A turn is mostly Python and numpy around the compiled kernels (about four fifths of its time
holds the GIL, measured on JB1-3), so threads of one process share one core. ``sewmech serve``
therefore computes in worker processes (``--workers N``, default one per core): each session
lives in one worker, which holds its compiled machine and prepared calls for as long as the
server keeps the session, computes its turns and encodes their JSON; the server's process
only reads requests and sends answers. A new session goes to the worker with the fewest
sessions. A worker computes one request at a time; the server sends it at most one turn and
one other request (the checks, an export) of a session at a time (the others wait in the
server, not in the worker's queue), so a page that sends many requests at once cannot make the
other pages wait behind all of them. Sessions never share anything: each has its own machine, in whichever process.

With ``--workers 0`` (:class:`LocalCompute`) the sessions live in the server's own process and
compute on its threads, as before issue 34: one core for the Python part of the work.

A worker ends with the server however the server ends (:mod:`sewmech.app.drawing.workers`);
a worker that dies (killed, out of memory) is started again, and the pages whose sessions it
held are told to load their machine again.
"""

from __future__ import annotations

import asyncio
import json
import logging
import multiprocessing
import os
import threading
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from ...engine.errors import AssemblyError, SewmechError
from .encode import NotJSON
from .session import PageError, Session, error_dict

log = logging.getLogger("sewmech.serve")

#: the most worker processes ``--workers`` takes
MAX_WORKERS = 64


def default_workers() -> int:
    """One worker per core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_workers(workers) -> int:
    """``workers`` as a count of worker processes (0: compute in the server's process), or a
    ValueError that says what is allowed."""
    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, int):
        raise ValueError(f"workers must be a whole number 0 .. {MAX_WORKERS}, got {workers!r}")
    if not 0 <= workers <= MAX_WORKERS:
        raise ValueError(f"workers must be 0 .. {MAX_WORKERS} (0: compute in the server's own"
                         f" process), got {workers}")
    return workers


class SessionGone(Exception):
    """A session the compute side does not hold (dropped, or its worker started again)."""


class ErrorAnswer(Exception):
    """An error already turned into its answer: an HTTP status and the JSON error body."""

    def __init__(self, status: int, body: dict):
        super().__init__(body.get("what", ""))
        self.status, self.body = status, body


def error_answer(exc: BaseException) -> tuple[int, dict] | None:
    """(status, body) of an error of the library or of a request, the page's way; None for a
    bug (an error nobody raised on purpose)."""
    if isinstance(exc, ErrorAnswer):
        return exc.status, exc.body
    if isinstance(exc, AssemblyError):
        body = error_dict(exc)
        body.update(unit=exc.unit, phi_deg=exc.phi_deg, ranges_deg=exc.ranges_deg)
        return 422, body
    if isinstance(exc, PageError):
        return 400, error_dict(exc)
    if isinstance(exc, SewmechError | ValueError | KeyError):  # located errors of the library
        return 422, error_dict(exc)
    if isinstance(exc, MemoryError):
        return 507, {"kind": "MemoryError", "where": "server", "what": "out of memory",
                     "hint": "Try a smaller file"}
    return None


def bug_answer(exc: BaseException) -> tuple[int, dict]:
    return 500, {"kind": "InternalError", "where": "server",
                 "what": f"internal error ({type(exc).__name__})",
                 "hint": "This is a bug in sewmech: please report it with the machine file; the"
                 " server's log has the details"}


def perform(session: Session, what: str, args: tuple):
    """A session's call: a turn or the checks as JSON bytes with the time it took (computing
    and encoding, ms), any other call's answer as it is."""
    if what not in ("turn", "checks"):
        return getattr(session, what)(*args)
    t0 = time.perf_counter()
    try:
        if what == "turn":  # computed and written under the session's lock (.encode)
            body = session.turn_json(*args)
        else:
            answer = session.checks(*args)
            try:
                body = json.dumps(answer, separators=(",", ":"), allow_nan=False).encode()
            except ValueError as exc:
                raise NotJSON(str(exc)) from None
    except NotJSON as exc:  # a NaN or infinity the session let through: a bug
        raise RuntimeError(f"a non-finite number in the {what}: {exc}") from None
    return body, (time.perf_counter() - t0) * 1e3


# ---- in a worker process ------------------------------------------------------------------------
#: the sessions of this worker, token -> Session
_SESSIONS: dict[str, Session] = {}


def _worker_start(parent_pid: int, from_main_thread: bool) -> None:
    from ...engine import _threads
    from ..drawing.workers import die_with_parent

    die_with_parent(parent_pid, forked_from_main_thread=from_main_thread)
    _threads.set_threads(1)  # the workers share the cores already: no kernel threads in them


def _worker_warm(text: str | None, file: str) -> int:
    """Load the compiled kernels (a machine's first turn and checks), so that the first page
    does not wait for them."""
    if text is not None:
        try:
            Session.from_text(text, file).warm()
        except Exception:  # noqa: BLE001  (a page that opens it gets the error)
            pass
    return os.getpid()


def _failed(exc: BaseException):
    known = error_answer(exc)
    if known is not None:
        return ("error", *known)
    return ("bug", *bug_answer(exc), "".join(traceback.format_exception(exc)))


def _worker_open(token: str, text: str, file: str):
    try:
        s = Session.from_text(text, file)
        s.warm()
        info = s.info()
    except Exception as exc:  # noqa: BLE001  (every error goes back as its answer)
        return _failed(exc)
    _SESSIONS[token] = s
    return ("ok", info)


def _worker_call(token: str, what: str, args: tuple):
    s = _SESSIONS.get(token)
    if s is None:
        return ("gone",)
    try:
        return ("ok", perform(s, what, args))
    except Exception as exc:  # noqa: BLE001
        return _failed(exc)


def _worker_drop(tokens: list[str]) -> None:
    for t in tokens:
        _SESSIONS.pop(t, None)


# ---- in the server's process ---------------------------------------------------------------------
class LocalCompute:
    """Sessions in the server's own process, computed on its threads (``workers=0``)."""

    workers = 0

    def __init__(self, warm: tuple[str, str] | None = None):
        self.sessions: dict[str, Session] = {}

    async def open(self, token: str, text: str, file: str) -> dict:
        from starlette.concurrency import run_in_threadpool

        session = await run_in_threadpool(Session.from_text, text, file)
        await run_in_threadpool(session.warm)
        self.sessions[token] = session
        return session.info()

    async def call(self, token: str, what: str, *args):
        from starlette.concurrency import run_in_threadpool

        s = self.sessions.get(token)
        if s is None:
            raise SessionGone(what)
        return await run_in_threadpool(perform, s, what, args)

    def drop(self, token: str) -> None:
        self.sessions.pop(token, None)

    def close(self) -> None:
        self.sessions.clear()


class ProcessCompute:
    """Sessions in ``n`` worker processes (module docstring)."""

    def __init__(self, n: int, warm: tuple[str, str] | None = None):
        self.workers = n
        self._warm = warm
        # forked, as the report's figure workers are: started here, before the server runs
        # (in `sewmech serve`, from its only thread); nothing of a script is imported again
        self._ctx = multiprocessing.get_context("fork")
        self.pools: list[ProcessPoolExecutor] = [self._start() for _ in range(n)]
        self.where: dict[str, int] = {}   # token -> worker
        self.count = [0] * n              # sessions per worker
        self._closed = False

    def _start(self) -> ProcessPoolExecutor:
        """A worker, forked now from this thread, loading the kernels in the background."""
        main = threading.current_thread() is threading.main_thread()
        pool = ProcessPoolExecutor(max_workers=1, mp_context=self._ctx,
                                   initializer=_worker_start, initargs=(os.getpid(), main))
        text, file = self._warm or (None, "")
        pool.submit(_worker_warm, text, file)
        return pool

    def pids(self) -> list[int]:
        return [pid for p in self.pools for pid in (p._processes or {})]

    async def _run(self, i: int, fn, *args):
        pool = self.pools[i]
        try:
            return await asyncio.wrap_future(pool.submit(fn, *args))
        except BrokenProcessPool:
            self._restart(i, pool)
            raise ErrorAnswer(503, {
                "kind": "WorkerError", "where": "server",
                "what": "the process that computed this page's machine ended (killed, or out"
                        " of memory); it has been started again",
                "hint": "Load the machine again"}) from None

    def _restart(self, i: int, broken: ProcessPoolExecutor) -> None:
        if self.pools[i] is not broken or self._closed:
            return  # another request saw it first
        log.warning("a worker process of the page's server ended; starting it again (its %d"
                    " pages must load their machine again)", self.count[i])
        broken.shutdown(wait=False, cancel_futures=True)
        for token in [t for t, w in self.where.items() if w == i]:
            del self.where[token]
        self.count[i] = 0
        self.pools[i] = self._start()

    def _answer(self, result, what: str):
        kind = result[0]
        if kind == "ok":
            return result[1]
        if kind == "gone":
            raise SessionGone(what)
        if kind == "bug":
            log.error("internal error in %s (in a worker process):\n%s", what, result[3])
        raise ErrorAnswer(result[1], result[2])

    async def open(self, token: str, text: str, file: str) -> dict:
        i = min(range(self.workers), key=lambda k: (self.count[k], k))
        self.where[token] = i  # counted now: pages that open at once go to different workers
        self.count[i] += 1
        try:
            return self._answer(await self._run(i, _worker_open, token, text, file), "open")
        except BaseException:
            self.drop(token)
            raise

    async def call(self, token: str, what: str, *args):
        i = self.where.get(token)
        if i is None:
            raise SessionGone(what)
        return self._answer(await self._run(i, _worker_call, token, what, args), what)

    def drop(self, token: str) -> None:
        i = self.where.pop(token, None)
        if i is None:
            return
        self.count[i] -= 1
        try:
            self.pools[i].submit(_worker_drop, [token])
        except (RuntimeError, BrokenProcessPool):  # shut down, or dead: nothing to drop
            pass

    def close(self) -> None:
        """Stop the workers now: the server is stopping, nobody waits for what they compute
        (a worker still loading the kernels would otherwise hold up a Ctrl-C for seconds)."""
        self._closed = True
        procs = [proc for p in self.pools for proc in (p._processes or {}).values()]
        for p in self.pools:
            p.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            if proc.is_alive():
                proc.terminate()  # SIGTERM, whose default action the workers take
        for proc in procs:
            proc.join(10)


def compute(workers: int, warm: tuple[str, str] | None = None):
    """The sessions' home for ``workers`` worker processes (0, or where processes cannot be
    forked: this process)."""
    if workers and "fork" in multiprocessing.get_all_start_methods():
        return ProcessCompute(workers, warm)
    return LocalCompute(warm)

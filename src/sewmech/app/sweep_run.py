"""Running a design sweep: chunks of designs in this process or on Dask, each finished chunk
written at once, so that an interrupted sweep resumes where it stopped (docs/sweeps.md).

The output directory::

    DIR/sweep.json                  what was swept: the sweep file and the machine file (their
                                    texts and SHA-256), the sewmech version, the chunk size,
                                    the columns and their units
    DIR/chunks/chunk-000012.parquet designs 12 * chunk .. 13 * chunk - 1, one row per design
    DIR/curves.zarr                 [curves]: one array per channel, (designs, angles)
    DIR/.sewmech.lock               held while a run writes (a second run stops at once)

Safety, as for every ``--out`` (:mod:`sewmech.app.files.outdir`), but in place because finished
chunks must survive an interruption:

- A chunk's Parquet file is written under a temporary name in ``chunks/`` and renamed into
  place, after the chunk's curves are in the Zarr store (whose chunk files zarr itself writes
  by rename): a chunk is done exactly when its Parquet file exists, and no reader ever sees a
  half-written one. Temporary files of a killed run are removed by the next one.
- A directory that holds anything else (files the user put there) is refused before any work;
  so is a sweep directory whose recorded sweep file, machine file or sewmech version differ
  from this run's (the results would mix).
- A chunk that fails is retried (``retries`` times); one that still fails is reported with its
  index and error, the other chunks are finished, and the command exits non-zero saying how to
  resume. Nothing is dropped silently.

Workers: ``workers=0`` evaluates in this process (the kernels on every core through threads);
otherwise a Dask ``LocalCluster`` of ``workers`` processes with one thread each (numba, OpenMP
and BLAS held to one thread per process so that the processes do not oversubscribe the cores),
or the cluster at ``scheduler``. Every worker loads the compiled kernels from numba's on-disk
cache once, when it starts (a worker plugin), and builds the sweep once from its texts.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from distributed.diagnostics.plugin import WorkerPlugin

from ..design.sweep import Chunk, chunk_bounds, column_units, curve_phi_deg, evaluate_chunk
from ..design.sweep_file import Sweep
from ..engine.errors import OptionError, OutputError, SewmechError
from ..engine.paths import user_path
from .files.io import atomic_write
from .files.outdir import LOCK, dir_lock, dir_mode

RECORD = "sweep.json"
CHUNKS = "chunks"
CURVES = "curves.zarr"
CHUNK_RE = re.compile(r"chunk-(\d{6,})\.parquet")
#: the temporary names a sweep writes under before renaming (a killed run may leave them)
ROOT_TMP_RE = re.compile(r"\.(sweep\.json|curves\.zarr)\..+\.tmp")
CHUNK_TMP_RE = re.compile(r"\.(chunk-\d{6,}\.parquet|writers)\..+\.tmp")
#: designs per chunk: the whole-turn assembly check of 250 JB1-3 designs holds about 250 MB
#: of kinematics in a worker (1 GB at 1000)
DEFAULT_CHUNK = 250
#: how long to wait for the scheduler at --scheduler's address
CONNECT_TIMEOUT = "20s"
#: environment of every worker process: one thread each for numba (sewmech's kernel threads),
#: OpenMP and the BLAS libraries, so that N processes use N cores
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "SEWMECH_LOCAL_WORKER": "1"}


class SweepError(SewmechError):
    """Chunks of a sweep failed (after their retries)."""


@dataclass
class RunReport:
    """What a run did: chunks in all, found done, computed now, failed (index -> error)."""

    n_chunks: int
    done_before: int
    computed: list[int] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    designs_computed: int = 0
    seconds: float = 0.0
    stopped: bool = False
    #: chunks of this run written by the Dask workers themselves (the rest by this process)
    written_by_workers: int = 0
    #: how this run's designs were evaluated, added over its chunks (:attr:`sewmech.design.
    #: sweep.Chunk.counts`: the assembly decided on the coarse grid or the whole one, the feed
    #: metrics located from predicted events or from whole turns, and the checks)
    counts: dict = field(default_factory=dict)


def done_chunks(root: Path) -> set[int]:
    d = root / CHUNKS
    if not d.is_dir():
        return set()
    return {int(m.group(1)) for name in os.listdir(d) if (m := CHUNK_RE.fullmatch(name))}


def chunk_path(root: Path, k: int) -> Path:
    return root / CHUNKS / f"chunk-{k:06d}.parquet"


def read_chunk(root: Path, k: int, columns: list[str] | None = None):
    """A written chunk as a pyarrow table; a chunk that is not a whole Parquet file (cut short
    by a copy, or edited) is a located error that says how to have it computed again (it was
    pyarrow's "Parquet magic bytes not found in footer", without a place or a way out)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = chunk_path(root, k)
    try:
        return pq.read_table(path, columns=columns)
    except (pa.ArrowException, OSError) as exc:
        why = " ".join(str(exc).split())
        raise OutputError(str(path), f"is not a whole chunk of the sweep ({why[:200].rstrip('.')})",
                          "Delete this file and run the same `sewmech sweep` command again:"
                          " it computes the missing chunks") from None


def _record(sweep: Sweep, chunk: int) -> dict:
    from .. import __version__

    spec = sweep.spec
    return {"written_by": "sewmech sweep", "sewmech_version": __version__,
            "name": spec.sweep.name,
            "sweep": {"file": sweep.file, "sha256": sweep.sweep_sha256, "text": sweep.text},
            "machine": {"name": sweep.machine.name, "file": sweep.machine_file,
                        "sha256": sweep.machine_sha256, "text": sweep.machine_text},
            "n_designs": sweep.n_designs, "chunk": chunk,
            "n_chunks": len(chunk_bounds(sweep.n_designs, chunk)),
            "sampling": spec.sampling.model_dump(),
            "parameters": [{**p.model_dump(), "column": c}
                           for p, c in zip(spec.parameters, sweep.columns)],
            "outputs": [{**o.model_dump(), "column": o.column} for o in spec.outputs],
            "columns": column_units(sweep),
            "curves": None if spec.curves is None else {
                "channels": list(spec.curves.channels),
                "phi_deg": curve_phi_deg(sweep).tolist(),
                "inputs_deg": dict(spec.curves.inputs)}}


def read_record(root: Path, option: str = "DIR") -> dict:
    """The record of a sweep directory, or an OutputError saying why it is not one."""
    try:
        data = json.loads((root / RECORD).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise OutputError(f"{option} {root}", f"is not a sweep's output (no {RECORD})",
                          "Give the --out directory of a `sewmech sweep` run") from None
    except (OSError, ValueError) as exc:
        raise OutputError(f"{option} {root}", f"{RECORD} cannot be read ({exc})",
                          "Run the sweep again into a new directory") from None
    if not isinstance(data, dict) or data.get("written_by") != "sewmech sweep":
        raise OutputError(f"{option} {root}", f"{RECORD} was not written by sewmech sweep",
                          "Give the --out directory of a `sewmech sweep` run")
    return data


def _foreign(root: Path) -> list[str]:
    """Entries of a sweep directory that a sweep does not write."""
    out = []
    for entry in sorted(os.listdir(root)):
        path = root / entry
        if entry in (LOCK, RECORD) and path.is_file() and not path.is_symlink():
            continue
        if ROOT_TMP_RE.fullmatch(entry) and not path.is_symlink():
            continue  # ours: a killed run's temporary file (or Zarr store being made)
        if entry == CHUNKS and path.is_dir() and not path.is_symlink():
            out += [f"{CHUNKS}/{e}" for e in sorted(os.listdir(path))
                    if not ((CHUNK_RE.fullmatch(e) or CHUNK_TMP_RE.fullmatch(e))
                            and (path / e).is_file())]
            continue
        if entry == CURVES and path.is_dir() and not path.is_symlink() and (
                path / "zarr.json").is_file():
            continue
        if _summary_dir(path):  # `sweep-summary DIR --out DIR/NAME`, as it suggests
            continue
        out.append(entry)
    return out


def _summary_dir(path: Path) -> bool:
    """Whether ``path`` is a directory that ``sewmech sweep-summary --out`` wrote (its manifest
    records only that command's files, and it holds nothing else): inside the sweep's
    directory, where sweep-summary suggests to put it, it kept the sweep from being resumed."""
    from .files.outdir import MANIFEST, _read_manifest
    from .files.outdir import _foreign as foreign_files

    if path.is_symlink() or not path.is_dir() or not (path / MANIFEST).is_file():
        return False
    try:
        manifest = _read_manifest(path)
    except OutputError:
        return False
    return bool(manifest) and all(r.get("command") == "sweep-summary"
                                  for r in manifest.values()) and not foreign_files(path, manifest)


def prepare_dir(root: Path, sweep: Sweep, chunk: int | None, option: str = "--out") -> int:
    """Check the output directory for the sweep (nothing is written); returns the chunk size
    to use. Called before the long work starts, and again with the directory's lock held."""
    from .files.outdir import _refuse_broken_link

    _refuse_broken_link(root, option)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{option} {root}", "is a file, not a directory",
                          "Give a directory for the sweep (it is created if missing)")
    entries = [e for e in os.listdir(root) if e != LOCK and not ROOT_TMP_RE.fullmatch(e)] \
        if root.exists() else []
    record = None
    if (root / RECORD).is_file():
        record = read_record(root, option)
    elif entries:
        raise OutputError(f"{option} {root}", f"the directory holds {len(entries)} file(s)"
                          f" that are not a sweep's ({', '.join(sorted(entries)[:3])})",
                          "sewmech writes a sweep only into a new or empty directory, or"
                          " resumes one it wrote; choose another directory")
    foreign = _foreign(root) if root.exists() else []
    if foreign:
        raise OutputError(f"{option} {root}", f"the directory holds {len(foreign)} file(s)"
                          f" that sewmech did not write ({', '.join(foreign[:3])})",
                          "sewmech never replaces or deletes your files: move them elsewhere,"
                          " or choose another directory")
    if record is not None:
        from .. import __version__

        for what, key, mine in (("sweep file", "sweep", sweep.sweep_sha256),
                                ("machine file", "machine", sweep.machine_sha256)):
            rec = record.get(key) or {}
            if rec.get("sha256") != mine:
                raise OutputError(f"{option} {root}", f"holds a sweep of another {what}"
                                  f" ({rec.get('file', '?')}, sha256"
                                  f" {str(rec.get('sha256'))[:12]}; this one's is {mine[:12]})",
                                  f"Resume with the {what} as it was ({RECORD} holds its text),"
                                  " or give a new --out directory for this one")
        if record.get("sewmech_version") != __version__:
            raise OutputError(f"{option} {root}", f"was written by sewmech"
                              f" {record.get('sewmech_version')}, this is {__version__}",
                              "Resume with that version, or give a new --out directory")
        recorded = int(record.get("chunk", 0))
        if chunk is not None and chunk != recorded:
            raise OptionError("--chunk", f"this sweep was started with --chunk {recorded}; a"
                              f" resumed sweep keeps its chunks", f"Leave out --chunk, or give"
                              f" --chunk {recorded}")
        return recorded
    return DEFAULT_CHUNK if chunk is None else chunk


def _write_json(path: Path, data: dict) -> None:
    with atomic_write(path) as fh:
        json.dump(data, fh, indent=1)


def _init_outputs(root: Path, sweep: Sweep, chunk: int) -> None:
    """The record first (so that a run killed from here on leaves a sweep directory that the
    next run resumes), then the chunks' directory and the curves' Zarr store if not there yet;
    temporary files and directories of a killed run removed."""
    import shutil

    for d, pattern in ((root, ROOT_TMP_RE), (root / CHUNKS, CHUNK_TMP_RE)):
        if d.is_dir():
            for e in os.listdir(d):
                if pattern.fullmatch(e):
                    if (d / e).is_dir() and not (d / e).is_symlink():
                        shutil.rmtree(d / e, ignore_errors=True)
                    else:
                        with contextlib.suppress(OSError):
                            (d / e).unlink()
    if not (root / RECORD).is_file():
        _write_json(root / RECORD, _record(sweep, chunk))
    (root / CHUNKS).mkdir(mode=dir_mode(), exist_ok=True)
    if sweep.spec.curves is not None and not (root / CURVES / "zarr.json").is_file():
        import zarr

        n, phi = sweep.n_designs, curve_phi_deg(sweep)
        tmp = Path(tempfile.mkdtemp(prefix=f".{CURVES}.", suffix=".tmp", dir=root))
        g = zarr.open_group(str(tmp), mode="w")
        g.attrs.update({"phi_deg": phi.tolist(), "units": "channels' units (docs/notation.md)",
                        "inputs_deg": dict(sweep.spec.curves.inputs)})
        for ch in sweep.spec.curves.channels:
            g.create_array(ch, shape=(n, len(phi)), chunks=(chunk, len(phi)), dtype="f8",
                           fill_value=np.nan)
        os.replace(tmp, root / CURVES)  # the store appears whole


def write_chunk(root: Path, sweep: Sweep, k: int, c: Chunk) -> None:
    """Chunk ``k``'s curves into the Zarr store, then its Parquet file by rename."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if c.curves:
        import zarr

        g = zarr.open_group(str(root / CURVES), mode="r+")
        n = len(c.columns["design"])
        for ch, v in c.curves.items():
            g[ch][c.start:c.start + n] = v
    units = column_units(sweep)
    fields = [pa.field(name, pa.array(c.columns[name]).type,
                       metadata={"unit": units[name]} if units[name] else None)
              for name in units]
    table = pa.table({name: c.columns[name] for name in units}, schema=pa.schema(fields))
    # under a temporary name beside it, renamed when whole (the names the sweep counts as its
    # own: io.atomic_write's)
    with atomic_write(chunk_path(root, k), "wb", encoding=None) as fh:
        pq.write_table(table, fh)


# ---- running ------------------------------------------------------------------------------------

def default_workers() -> int:
    """Worker processes of a local cluster: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (not on Linux)
        return max(1, os.cpu_count() or 1)


#: the most worker processes of a local cluster per core this process may use: each worker
#: runs one thread, so more than one a core only share the cores, and each holds its own
#: interpreter and kernels (about 150 MB). 1000 workers on 2 cores never finished starting
#: (no progress in 120 s, about 150 GB asked of a 23 GB machine)
WORKERS_PER_CORE = 4


def check_workers(workers: int | None) -> None:
    """``--workers``: 0 (this process) up to :data:`WORKERS_PER_CORE` a usable core."""
    if workers is None:
        return
    cores = default_workers()
    most = WORKERS_PER_CORE * cores
    if not 0 <= workers <= most:
        raise OptionError("--workers", f"must be in 0 .. {most} on this machine ({cores} usable"
                          f" core{'s' if cores != 1 else ''}, at most {WORKERS_PER_CORE} worker"
                          f" processes a core: each runs one thread and holds its own memory,"
                          f" about 150 MB), got {workers}", f"Leave it out for one worker a"
                          f" core ({cores}), give --workers 0 to run in this process, or run"
                          " on a cluster of more machines with --scheduler")


def run_sweep(sweep: Sweep, out: str | Path, *, scheduler: str | None = None,
              workers: int | None = None, chunk: int | None = None, retries: int = 2,
              on_chunk: Callable[[int, int], None] | None = None,
              stop_after: int | None = None, client=None) -> RunReport:
    """Run the chunks of ``sweep`` that ``out`` lacks (see the module doc) and write them.

    ``on_chunk(k, n_designs)`` is called after each chunk is written (a progress bar);
    ``stop_after`` stops cleanly after that many chunks of this run (the tests' interruption);
    ``client``, a ``distributed.Client`` already connected, is used instead of a new cluster.
    Raises SweepError (after finishing every other chunk) when some chunk failed.
    """
    root = user_path(out, "--out")
    if chunk is not None and not 1 <= chunk <= 10_000_000:
        raise OptionError("--chunk", f"must be in 1 .. 10000000 designs, got {chunk}",
                          "Give e.g. --chunk 250")
    if scheduler is not None and workers is not None:
        raise OptionError("--workers", "a cluster given by --scheduler has its own workers",
                          "Leave out --workers (start `dask worker` processes on the cluster)")
    check_workers(workers)
    size = prepare_dir(root, sweep, chunk)  # a directory not this sweep's: before any work
    here = client is None and scheduler is None and workers == 0
    if (root / RECORD).is_file() and len(done_chunks(root)) >= len(
            chunk_bounds(sweep.n_designs, size)):
        here = True  # nothing left to compute: no cluster to start
    with contextlib.ExitStack() as stack:
        if not here and client is None:  # (an unreachable scheduler: before any writing)
            client = stack.enter_context(_client(scheduler, default_workers()
                                                 if workers is None else workers))
        made = not root.exists()
        if made:
            try:
                root.mkdir(mode=dir_mode(), parents=True)
            except OSError as exc:
                from .files.outdir import _os_error

                raise _os_error(root, exc, "--out") from None
            # a run that made the directory and stops before its first chunk takes it away
            # again (the lock's exit runs first: callbacks run last in, first out)
            stack.enter_context(_removed_on_failure(root))
        stack.enter_context(dir_lock(root))
        chunk = prepare_dir(root, sweep, chunk)
        try:
            _init_outputs(root, sweep, chunk)
        except OSError as exc:
            from .files.outdir import _os_error

            raise _os_error(root, exc, "--out") from None
        bounds = chunk_bounds(sweep.n_designs, chunk)
        have = done_chunks(root)
        # the chunks to compute, in order, drawn as they are needed (never a list of them all)
        todo = (k for k in range(len(bounds)) if k not in have)
        report = RunReport(len(bounds), len(have))
        t0 = time.perf_counter()

        def finished(k: int, c: Chunk | dict) -> bool:
            if isinstance(c, dict):  # a worker wrote it: its counts came back
                report.written_by_workers += 1
                counts = c
            else:
                write_chunk(root, sweep, k, c)
                counts = c.counts
            for key, v in counts.items():
                report.counts[key] = report.counts.get(key, 0) + int(v)
            report.computed.append(k)
            report.designs_computed += bounds[k][1] - bounds[k][0]
            if on_chunk is not None:
                on_chunk(k, bounds[k][1] - bounds[k][0])
            if stop_after is not None and len(report.computed) >= stop_after:
                report.stopped = True
                return False
            return True

        if sum(1 for k in have if k < len(bounds)) < len(bounds):
            try:
                if here:
                    _run_here(sweep, bounds, todo, retries, finished, report)
                else:
                    _run_dask(sweep, bounds, todo, retries, finished, report, client,
                              root)
            except OSError as exc:
                if exc.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                    raise
                raise OutputError(f"--out {root}", f"the disk is full (or your quota is used"
                                  f" up) after {len(report.computed)} chunk(s) of this run;"
                                  f" the {len(have) + len(report.computed)} finished chunks are"
                                  " kept, nothing half-written", "Free some space (or move the"
                                  " directory to a larger disk) and run the same command again:"
                                  " it computes only the missing chunks") from None
        report.seconds = time.perf_counter() - t0
        if report.failed:  # (inside: a directory this run made, with no chunk, goes again)
            shown = "; ".join(f"chunk {k} (designs {bounds[k][0]} .. {bounds[k][1] - 1}): {e}"
                              for k, e in sorted(report.failed.items())[:3])
            more = f" and {len(report.failed) - 3} more" if len(report.failed) > 3 else ""
            written = len(bounds) - len(report.failed)
            raise SweepError(str(root), f"{len(report.failed)} of {len(bounds)} chunks failed"
                             f" after {retries + 1} attempt{'s' if retries else ''} each:"
                             f" {shown}{more}; the other {written} chunks are written"
                             + (" (none: the directory this run made is removed again)"
                                if made and not written and not have else ""),
                             "Fix the cause and run the same command again: it computes only"
                             " the missing chunks")
    return report


@contextlib.contextmanager
def _removed_on_failure(root: Path):
    """Remove the sweep directory this run created if the run ends (an error, Ctrl-C) with no
    chunk written: what is there is only the sweep's own record and empty stores."""
    import shutil

    try:
        yield
    except BaseException:
        if not done_chunks(root) and all(
                entry in (RECORD, LOCK, CHUNKS, CURVES) or ROOT_TMP_RE.fullmatch(entry)
                for entry in os.listdir(root)):
            shutil.rmtree(root, ignore_errors=True)
        raise


def _run_here(sweep, bounds, todo, retries, finished, report) -> None:
    for k in todo:
        c = None
        for attempt in range(retries + 1):
            try:
                c = evaluate_chunk(sweep, *bounds[k])
                break
            except (KeyboardInterrupt, MemoryError):
                raise
            except Exception as exc:  # noqa: BLE001  (reported with its chunk, never dropped)
                if attempt == retries:
                    report.failed[k] = f"{type(exc).__name__}: {exc}"
        if c is not None and not finished(k, c):
            return


def local_cluster(workers: int):
    """A Dask LocalCluster of ``workers`` processes with one thread each, numba, OpenMP and
    BLAS held to one thread in every worker (:data:`WORKER_ENV`)."""
    import dask
    from distributed import LocalCluster

    interrupted: list[bool] = []
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENV}), \
                _interrupt_after() as interrupted, _environment_kept():
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=50)
    except Exception:
        if interrupted:  # the Ctrl-C reached the starting workers too ("Nanny failed to
            raise KeyboardInterrupt from None  # start"): it is why the start failed
        raise
    if interrupted:  # Ctrl-C while it started: now that it can be closed in order
        cluster.close()
        raise KeyboardInterrupt
    return cluster


@contextlib.contextmanager
def _environment_kept():
    """This process's environment as it was: Dask's nanny writes the workers' variables
    (:data:`WORKER_ENV`: one kernel thread, ...) into the environment of the process that
    starts them, where they would stay and reach every process it starts later."""
    before = {k: os.environ.get(k) for k in WORKER_ENV}
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def _interrupt_after():
    """Hold a Ctrl-C back while a local cluster starts, and say afterwards whether one came
    (a list, true if so). A KeyboardInterrupt inside Dask's start left a cluster half made,
    which Dask's exit handler then failed to close, with a traceback; a cluster starts in one
    or two seconds, and the Ctrl-C takes effect right after."""
    import signal
    import threading

    came: list[bool] = []
    if threading.current_thread() is not threading.main_thread():
        yield came
        return
    old = signal.signal(signal.SIGINT, lambda signum, frame: came.append(True))
    try:
        yield came
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def _client(scheduler: str | None, workers: int):
    """A Dask client: of a new local cluster of ``workers`` processes, or of the scheduler at
    ``scheduler``."""
    from distributed import Client

    if scheduler is None:
        with _environment_kept(), local_cluster(workers) as cluster, \
                Client(cluster) as client:  # (a worker restarted meanwhile writes it again)
            yield client
        return
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise OptionError("--scheduler", f"cannot reach a Dask scheduler at {scheduler!r}"
                          f" ({exc})", "Start one with `dask scheduler` and give its address,"
                          " e.g. tcp://10.0.0.5:8786") from None
    with client:
        yield client


def _probe_path(root: Path, token: str) -> Path:
    """The file by which a worker knows it sees this run's directory (``chunks/`` holds it
    while the run lasts; its name is one of the sweep's temporary names)."""
    return root / CHUNKS / f".writers.{token}.tmp"


def evaluate_and_write(texts: tuple[str, str, str, str], root: str, token: str, k: int,
                       start: int, stop: int) -> Chunk | dict:
    """A Dask task: chunk ``k`` (designs ``start .. stop - 1``) evaluated and, when this worker
    sees the run's directory (a shared file system: the run's probe file there holds
    ``token``), written into it by the worker itself, exactly as :func:`write_chunk` writes
    (curves first, the Parquet file last by rename), returning the chunk's counts (a dict);
    a worker that does not see it returns the chunk for the client to write."""
    from ..design.sweep import evaluate_texts, sweep_of_texts

    c = evaluate_texts(texts, start, stop)
    path = Path(root)
    try:
        seen = _probe_path(path, token).read_text(encoding="ascii") == token
    except (OSError, UnicodeDecodeError):
        seen = False
    if not seen:
        return c
    write_chunk(path, sweep_of_texts(texts), k, c)
    return c.counts


def _run_dask(sweep, bounds, todo, retries, finished, report, client, root: Path) -> None:
    """The chunks as Dask tasks (at most four per worker thread in flight), each written by
    the worker that computed it where the worker sees ``root`` (else here, as it arrives);
    this process records which chunks are done."""
    import secrets

    from distributed import as_completed

    from ..design.sweep import texts_of

    client.register_plugin(_Warm(), name="sewmech-warm")
    threads = max(1, sum(client.nthreads().values()))
    texts = client.scatter(texts_of(sweep), broadcast=True)
    queue = iter(todo)
    keys = {}
    token = secrets.token_hex(16)

    def submit():
        k = next(queue, None)
        if k is None:
            return None
        f = client.submit(evaluate_and_write, texts, str(root), token, k, *bounds[k],
                          retries=retries, pure=False,
                          key=f"sewmech-sweep-{sweep.sweep_sha256[:8]}-chunk-{k}"
                              f"-{os.getpid()}-{time.monotonic_ns()}")
        keys[f.key] = k
        return f

    _probe_path(root, token).write_text(token, encoding="ascii")  # (a worker that reads it
    # before it is whole writes nothing itself: its chunk comes here)
    try:
        first = [f for f in (submit() for _ in range(4 * threads)) if f is not None]
        running = as_completed(first, with_results=False)
        for f in running:
            k = keys.pop(f.key)
            if f.status == "finished":
                c = f.result()
                f.release()
                if not finished(k, c):
                    for other in list(running.futures):
                        other.cancel()
                    return
            else:
                exc = f.exception()
                report.failed[k] = f"{type(exc).__name__}: {exc}"
                f.release()
            nxt = submit()
            if nxt is not None:
                running.add(nxt)
    finally:
        # the probe, and what writers killed mid-chunk left (their chunks were computed and
        # written again elsewhere)
        for e in os.listdir(root / CHUNKS):
            if CHUNK_TMP_RE.fullmatch(e):
                with contextlib.suppress(OSError):
                    (root / CHUNKS / e).unlink()


class _Warm(WorkerPlugin):
    """Worker plugin: :func:`sewmech.design.sweep.prepare_worker` when a worker starts."""

    idempotent = True

    def setup(self, worker=None):
        import signal
        import threading

        from ..design.sweep import prepare_worker

        prepare_worker()
        # a local cluster's workers share the terminal's process group: Ctrl-C is for the
        # command, which stops them itself (no traceback from each worker); a worker of the
        # user's own cluster keeps its Ctrl-C
        if os.environ.get("SEWMECH_LOCAL_WORKER") == "1" and (
                threading.current_thread() is threading.main_thread()):
            signal.signal(signal.SIGINT, signal.SIG_IGN)

    def teardown(self, worker=None):
        pass

"""Output directories that never lose the user's files.

Every command that writes files (``--out DIR``) goes through :func:`output_dir`:

- DIR must be new, empty, or a directory sewmech wrote itself: a manifest
  (``.sewmech-manifest.json``) records every file sewmech wrote with its size and modification
  time. A directory holding anything else (or a file sewmech wrote and the user changed since)
  is refused before any work is done, so nothing of the user's is ever replaced or deleted.
- A lock (``.sewmech.lock``, ``flock``) keeps concurrent runs apart: a second run into the same
  directory stops at once with an error instead of mixing its files with the first one's.
- Files are written into a staging directory inside DIR and moved into place only when the
  whole job has succeeded; files of the same command's previous run that this run did not
  write again are removed (they are sewmech's own). On any error or interruption (Ctrl-C,
  SIGTERM, SIGHUP) the staging directory is removed, and DIR too if this run created it.
  The lock file stays (it is sewmech's own and harmless; removing it could let two runs
  lock two different files).
- Files and directories get the modes the umask gives (0644 and 0755 under umask 022).

A sweep (:mod:`sewmech.app.sweep_run`) writes in place instead, chunk by chunk, each file by
rename, so that an interrupted run keeps its finished chunks; it holds the same lock
(:func:`dir_lock`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ...engine.errors import OutputError

MANIFEST = ".sewmech-manifest.json"
LOCK = ".sewmech.lock"
STAGING_PREFIX = ".sewmech-staging-"

_UMASK: int | None = None


def umask() -> int:
    """The process's umask (read once: reading it means setting it)."""
    global _UMASK
    if _UMASK is None:
        _UMASK = os.umask(0o022)
        os.umask(_UMASK)
    return _UMASK


def file_mode() -> int:
    """Mode of a new file under the umask (0644 under umask 022)."""
    return 0o666 & ~umask()


def dir_mode() -> int:
    """Mode of a new directory under the umask (0755 under umask 022)."""
    return 0o777 & ~umask()


def _own(name: str) -> bool:
    return name in (MANIFEST, LOCK) or name.startswith(STAGING_PREFIX)


def _read_manifest(root: Path) -> dict:
    try:
        data = json.loads((root / MANIFEST).read_text(encoding="utf-8"))
        files = data.get("files", {}) if isinstance(data, dict) else {}
        return {k: v for k, v in files.items() if isinstance(v, dict)} \
            if isinstance(files, dict) else {}
    except (OSError, ValueError):
        return {}


def _stamp(path: Path) -> list[int]:
    st = path.stat()
    return [st.st_size, st.st_mtime_ns]


def _foreign(root: Path, manifest: dict) -> list[str]:
    """Entries of ``root`` that sewmech did not write, or wrote and someone changed since."""
    out = []
    for entry in sorted(os.listdir(root)):
        if _own(entry):
            continue
        rec = manifest.get(entry)
        path = root / entry
        if rec is None or not path.is_file() or path.is_symlink():
            out.append(entry)
            continue
        try:
            if _stamp(path) != [rec.get("size"), rec.get("mtime_ns")]:
                out.append(entry)
        except OSError:
            out.append(entry)
    return out


def _refuse_foreign(root: Path, manifest: dict, command: str, option: str) -> None:
    foreign = _foreign(root, manifest)
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more"
                                           if len(foreign) > 3 else "")
        hint = ("sewmech writes only into a new or empty directory, or one it wrote itself, so"
                " that none of your files is replaced or deleted; choose another directory,"
                f" e.g. {option} {root / command.split()[0]}")
        if not manifest and _legacy_report(root):
            hint += (" (this looks like a report of an earlier sewmech, which kept no record of"
                     " its files: remove the directory yourself if you no longer need it)")
        raise OutputError(f"{option} {root}", f"the directory holds {len(foreign)} file(s)"
                          f" that sewmech did not write, or that changed since it wrote them"
                          f" ({shown})", hint)


def _legacy_report(root: Path) -> bool:
    try:
        with open(root / "index.html", encoding="utf-8", errors="replace") as fh:
            return "Written by sewmech." in fh.read(2_000_000)
    except OSError:
        return False


def preflight(path: str | Path, *, command: str, option: str = "--out") -> None:
    """The checks of :func:`output_dir` that need no writing, for a command to run before its
    long work: ``path`` is a file, holds files sewmech did not write, or is locked by another
    run. Nothing is created; :func:`output_dir` checks again under its lock."""
    root = Path(path).expanduser()
    try:
        if not root.exists():
            return
        if not root.is_dir():
            raise OutputError(f"{option} {root}", "is a file, not a directory",
                              "Give a directory for the output (it is created if missing)")
        _refuse_foreign(root, _read_manifest(root), command, option)
        lock = root / LOCK
        if lock.exists():
            fd = os.open(lock, os.O_RDONLY)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                other = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
                raise OutputError(f"{option} {root}", f"another sewmech run (pid {other}) is"
                                  " writing into this directory", "Wait for it to finish, or"
                                  " choose another directory") from None
            finally:
                os.close(fd)
    except OutputError:
        raise
    except OSError as exc:
        raise _os_error(root, exc, option) from None


def _os_error(path: Path, exc: OSError, option: str) -> OutputError:
    if exc.errno == errno.ENAMETOOLONG:
        return OutputError(f"{option} {path}", "the path is too long for the file system",
                           "Choose a shorter path")
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return OutputError(f"{option} {path}", f"cannot write there ({exc.strerror})",
                           "Choose a directory you can write to")
    if exc.errno == errno.ENOTDIR:
        return OutputError(f"{option} {path}", "a part of the path is a file, not a directory",
                           "Choose a path whose parents are directories")
    if exc.errno == errno.ENOSPC:
        return OutputError(f"{option} {path}", "the disk is full", "Free some space")
    return OutputError(f"{option} {path}", f"cannot write there ({exc.strerror or exc})",
                       "Choose another directory")


@contextlib.contextmanager
def _signals_held():
    """SIGINT, SIGTERM and SIGHUP wait while the staged files are moved into place."""
    sigs = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (ValueError, OSError):  # not the main thread of the interpreter
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextlib.contextmanager
def output_dir(path: str | Path, *, command: str, option: str = "--out") -> Iterator[Path]:
    """Write a command's files safely into the directory ``path`` (see the module docstring).

    Yields the staging directory to write into (flat: files only). On normal exit its files
    replace the directory's files of the same names (which sewmech wrote) and the files of
    ``command``'s previous run that were not written again are removed.

    Raises
    ------
    OutputError
        ``path`` is a file, cannot be created or written, holds files that sewmech did not
        write, or another sewmech run holds its lock.
    """
    root = Path(path).expanduser()
    created: list[Path] = []
    lock_fd = None
    lock_created = False
    staging: Path | None = None
    try:
        try:
            if root.exists() and not root.is_dir():
                raise OutputError(f"{option} {root}", "is a file, not a directory",
                                  "Give a directory for the output (it is created if missing)")
            missing = []
            p = root
            while not p.exists():
                missing.append(p)
                if p.parent == p:
                    break
                p = p.parent
            for d in reversed(missing):
                try:
                    d.mkdir(mode=dir_mode())
                except FileExistsError:  # another run made it a moment ago
                    if not d.is_dir():
                        raise
                    continue
                created.append(d)
            lock_path = root / LOCK
            lock_created = not lock_path.exists()
            lock_fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, file_mode())
        except OutputError:
            raise
        except OSError as exc:
            raise _os_error(root, exc, option) from None
        try:
            fcntl.flock(lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            other = os.pread(lock_fd, 32, 0).decode("ascii", "replace").strip() or "?"
            lock_created = False  # the other run's lock
            raise OutputError(f"{option} {root}", f"another sewmech run (pid {other}) is"
                              " writing into this directory", "Wait for it to finish, or"
                              " choose another directory") from None
        os.ftruncate(lock_fd, 0)
        os.pwrite(lock_fd, str(os.getpid()).encode(), 0)
        manifest = _read_manifest(root)
        _refuse_foreign(root, manifest, command, option)
        for entry in os.listdir(root):  # staging left by a run that was killed outright
            if entry.startswith(STAGING_PREFIX):
                shutil.rmtree(root / entry, ignore_errors=True)
        try:
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=root))
            os.chmod(staging, dir_mode())
        except OSError as exc:
            raise _os_error(root, exc, option) from None
        yield staging
        with _signals_held():
            _commit(root, staging, manifest, command)
        staging = None
    except BaseException:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        if lock_created:
            with contextlib.suppress(OSError):
                os.unlink(root / LOCK)
        for d in reversed(created):  # innermost first
            with contextlib.suppress(OSError):
                d.rmdir()  # only if empty: never anything of the user's
        raise
    finally:
        if lock_fd is not None:
            os.close(lock_fd)


def _commit(root: Path, staging: Path, manifest: dict, command: str) -> None:
    """Move the staged files into place, drop the command's stale files, save the manifest."""
    written = sorted(os.listdir(staging))
    for name in written:
        os.replace(staging / name, root / name)
    for name, rec in list(manifest.items()):
        if rec.get("command") == command and name not in written:
            with contextlib.suppress(OSError):
                (root / name).unlink()
            manifest.pop(name)
    for name in written:
        manifest[name] = {"command": command, "size": None, "mtime_ns": None}
        manifest[name]["size"], manifest[name]["mtime_ns"] = _stamp(root / name)
    tmp = staging / MANIFEST
    tmp.write_text(json.dumps({"written_by": "sewmech", "files": manifest}, indent=1,
                              sort_keys=True), encoding="utf-8")
    os.chmod(tmp, file_mode())
    os.replace(tmp, root / MANIFEST)
    staging.rmdir()


@contextlib.contextmanager
def dir_lock(root: Path, option: str = "--out") -> Iterator[None]:
    """Hold ``root``'s lock (``.sewmech.lock``; ``root`` must exist) for a command that writes
    into the directory in place rather than through a staging directory (a sweep, which keeps
    every finished chunk). Raises OutputError if another run holds it. A lock file this call
    created is removed again if the body fails (e.g. refuses a directory of the user's)."""
    lock = root / LOCK
    created = not lock.exists()
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, file_mode())
    except OSError as exc:
        raise _os_error(root, exc, option) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            created = False  # the other run's lock
            other = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
            raise OutputError(f"{option} {root}", f"another sewmech run (pid {other}) is"
                              " writing into this directory", "Wait for it to finish, or"
                              " choose another directory") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.unlink(lock)
        raise
    finally:
        os.close(fd)

"""Output directories that never lose the user's files.

Every command that writes files (``--out DIR``) goes through :func:`output_dir`:

- DIR must be new, empty, or a directory sewmech wrote itself: a manifest
  (``.sewmech-manifest.json``) records every file sewmech wrote with its size and modification
  time. A directory holding anything else (or a file sewmech wrote and the user changed since)
  is refused before any work is done, so nothing of the user's is ever replaced or deleted.
  The manifest is read as input like any other: every entry must name a plain file directly
  inside DIR (no ``..``, no path, no absolute name), or the directory is refused.
- A lock (``.sewmech.lock``, ``flock``) keeps concurrent runs apart: a second run into the same
  directory stops at once with an error instead of mixing its files with the first one's. The
  lock belongs to the process that took it: processes forked from it (a report's figure
  workers) close their copy at once, so the kernel releases the lock when the owner dies,
  however it dies.
- Files are written into a staging directory inside DIR and moved into place only when the
  whole job has succeeded, one file at a time, each move refusing to replace anything that is
  not the unchanged file sewmech wrote there (a file the user saved into DIR during the run is
  never replaced: the result is then kept aside in ``DIR/sewmech-kept-COMMAND-TIME/`` and the
  command says so). Files of the same command's previous run (on the same machine) that this
  run did not write again are removed if unchanged (they are sewmech's own). On any error or interruption (Ctrl-C,
  SIGTERM, SIGHUP) the staging directory is removed, and DIR too if this run created it. A run
  killed outright (SIGKILL, power loss) leaves its staging directory and its process id in the
  lock file: the next run removes the one, notices the other and says so. Before its first
  move a run writes the list of files it moves in (a journal in its staging directory), so a
  run killed in the middle of its moves (some files in, the previous ones set aside) is rolled
  back by the next run: each previous file returns (:func:`_roll_back`).
- Files and directories get the modes the umask gives (0644 and 0755 under umask 022).

A sweep (:mod:`sewmech.app.sweep_run`) writes in place instead, chunk by chunk, each file by
rename, so that an interrupted run keeps its finished chunks; it holds the same lock
(:func:`dir_lock`).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import json
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from ...engine.errors import OutputError
from ...engine.paths import user_path

MANIFEST = ".sewmech-manifest.json"
LOCK = ".sewmech.lock"
STAGING_PREFIX = ".sewmech-staging-"
#: in a staging directory: the files a commit moves in, written before the first move
JOURNAL = ".sewmech-commit.json"
#: a run's result that could not be moved into place (a file of the user's was in the way)
KEPT_PREFIX = "sewmech-kept-"

_UMASK: int | None = None

#: descriptors of the locks this process holds: a forked child closes its copies at once
#: (an flock belongs to the open file, which a child would otherwise keep open, and with it
#: the lock, after its parent died)
_HELD_LOCKS: set[int] = set()


def _close_inherited_locks() -> None:
    for fd in list(_HELD_LOCKS):
        with contextlib.suppress(OSError):
            os.close(fd)
    _HELD_LOCKS.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_inherited_locks)


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
    return name in (MANIFEST, LOCK) or name.startswith((STAGING_PREFIX, KEPT_PREFIX))


def _note(text: str) -> None:
    """A notice for the person running the command (stderr; not an error)."""
    with contextlib.suppress(OSError, ValueError):
        print(f"note: {text}", file=sys.stderr, flush=True)


# ---- the manifest: sewmech's record of the files it wrote ----------------------------------


def _plain_name(name: object) -> bool:
    """A name of a file directly inside a directory: no path, no ``..``, nothing sewmech keeps
    for itself."""
    return (isinstance(name, str) and name not in ("", ".", "..") and "/" not in name
            and "\\" not in name and "\0" not in name and not _own(name))


def _valid_record(rec: object) -> bool:
    return (isinstance(rec, dict) and isinstance(rec.get("command"), str)
            and isinstance(rec.get("machine", ""), str)
            and all(isinstance(rec.get(k), int) and not isinstance(rec.get(k), bool)
                    for k in ("size", "mtime_ns")) and rec["size"] >= 0)


def _read_manifest(root: Path, option: str = "--out") -> dict:
    """The manifest's entries (name -> record); {} if there is none. A manifest that cannot be
    read, or that names anything but a plain file directly inside ``root``, is refused: it is
    damaged or was not written by sewmech, and following it could delete a file elsewhere."""
    path = root / MANIFEST
    try:
        if not path.exists() and not path.is_symlink():
            return {}
        if path.is_symlink() or not path.is_file():
            raise ValueError("it is not a plain file")
        if path.stat().st_size > 64 * 2**20:
            raise ValueError("it is larger than any record sewmech writes")
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or data.get("written_by") != "sewmech" \
                or not isinstance(data.get("files"), dict):
            raise ValueError("it is not a record sewmech wrote")
        files = data["files"]
        for name, rec in files.items():
            if not _plain_name(name):
                raise ValueError(f"it names {name!r}, which is not a file directly inside the"
                                 " directory")
            if not _valid_record(rec):
                raise ValueError(f"its entry for {name!r} is not one sewmech writes")
        return dict(files)
    except (ValueError, OSError, RecursionError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise OutputError(f"{option} {root}", f"its {MANIFEST} (sewmech's record of the files it"
                          f" wrote there) is damaged: {why}", "sewmech changes nothing in a"
                          " directory whose record it cannot trust; choose another directory"
                          " (and remove this one yourself if you no longer need it)") from None


def _stamp(path: Path) -> list[int]:
    st = path.stat()
    return [st.st_size, st.st_mtime_ns]


def _is_ours(path: Path, rec: dict | None) -> bool:
    """Whether ``path`` is the unchanged regular file that ``rec`` records."""
    if rec is None:
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and [st.st_size, st.st_mtime_ns] == [
        rec.get("size"), rec.get("mtime_ns")]


def _foreign(root: Path, manifest: dict) -> list[str]:
    """Entries of ``root`` that sewmech did not write, or wrote and someone changed since."""
    return [entry for entry in sorted(os.listdir(root))
            if not _own(entry) and not _is_ours(root / entry, manifest.get(entry))]


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


# ---- the lock -------------------------------------------------------------------------------


def _open_lock(root: Path, path: Path, flags: int, option: str) -> int:
    """Open the lock file, which must be sewmech's own regular file: never through a symbolic
    link (a link to a file of the user's would have that file truncated)."""
    try:
        fd = os.open(path, flags | getattr(os, "O_NOFOLLOW", 0), file_mode())
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise
        fd = None
    if fd is None or not stat.S_ISREG(os.fstat(fd).st_mode):
        if fd is not None:
            os.close(fd)
        raise OutputError(f"{option} {root}", f"its {LOCK} (sewmech's lock) is not a plain"
                          " file (a symbolic link, a directory, ...)", "sewmech leaves what is"
                          " not its own alone; choose another directory")
    return fd


def _locked_by_other(root: Path, fd: int, option: str) -> OutputError:
    other = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
    return OutputError(f"{option} {root}", f"another sewmech run (pid {other}) is writing into"
                       " this directory", "Wait for it to finish, or choose another directory")


def _take_lock(root: Path, fd: int, option: str) -> str | None:
    """Lock the open lock file ``fd`` for this process (or raise OutputError: another run holds
    it). Returns the process id of a run that held it and never released it (killed
    outright), else None."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise _locked_by_other(root, fd, option) from None
    _HELD_LOCKS.add(fd)
    before = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode(), 0)
    return before or None


def _release_lock(fd: int) -> None:
    """Say that the run ended (an empty lock file) and let go of the lock."""
    _HELD_LOCKS.discard(fd)
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
    os.close(fd)


def preflight(path: str | Path, *, command: str, option: str = "--out") -> None:
    """The checks of :func:`output_dir` that need no writing, for a command to run before its
    long work: ``path`` is a file, holds files sewmech did not write, has a damaged record, or
    is locked by another run. Nothing is created; :func:`output_dir` checks again under its
    lock."""
    root = user_path(path, option)
    try:
        _refuse_broken_link(root, option)
        if not root.exists():
            return
        if not root.is_dir():
            raise OutputError(f"{option} {root}", "is a file, not a directory",
                              "Give a directory for the output (it is created if missing)")
        manifest = _read_manifest(root, option)
        killed = _moved_in_by_a_killed_run(root)
        if killed:  # its new files are the killed run's (output_dir rolls them back)
            manifest = {**killed, **{n: r for n, r in manifest.items() if n not in killed
                                     or _is_ours(root / n, r)}}
        _refuse_foreign(root, manifest, command, option)
        lock = root / LOCK
        if lock.exists():
            fd = _open_lock(root, lock, os.O_RDONLY, option)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise _locked_by_other(root, fd, option) from None
            finally:
                os.close(fd)
    except OutputError:
        raise
    except OSError as exc:
        raise _os_error(root, exc, option) from None


def _refuse_broken_link(root: Path, option: str) -> None:
    """``root`` a symbolic link that leads nowhere (its target missing, or a loop of links):
    said so, instead of "cannot write there (File exists)" from the directory it could not
    make. sewmech does not make the link's target."""
    if not root.is_symlink():
        return
    try:
        root.stat()
        return
    except FileNotFoundError:
        what = f"a symbolic link to {os.readlink(root)}, which does not exist"
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            return
        what = "a symbolic link in a loop of links (it leads to no file or directory)"
    raise OutputError(f"{option} {root}", f"is {what}", "Give a directory (it is created if"
                      " missing), or make the link's target directory first")


#: what a write into a full file system raises (the disk, the user's quota, a file size limit)
_DISK_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


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
    if exc.errno in _DISK_FULL:
        return OutputError(f"{option} {path}", "the disk is full (or a quota or file-size limit is reached);"
                           " nothing half-written was left behind",
                           "Free some space, or choose a directory on another disk")
    return OutputError(f"{option} {path}", f"cannot write there ({exc.strerror or exc})",
                       "Choose another directory")


def _name_too_long(root: Path, name: str, option: str) -> OutputError:
    """A result's file name beyond the file system's 255 bytes (a machine name of 300
    characters: the names start with it). It was the OSError of a staging temp file."""
    m = re.fullmatch(r"\.(.+)\.[A-Za-z0-9_]+\.tmp", name)  # (atomic_write's temporary file)
    name = m.group(1) if m else name
    shown = name if len(name) <= 60 else f"{name[:28]}...{name[-28:]}"
    return OutputError(f"{option} {root}", f"a file name of the result is too long for the file"
                       f" system ({len(name.encode())} bytes, at most 255: {shown})",
                       "The result's names start with the machine's name: give it a shorter"
                       " [machine] name")


#: the exception a command's signal handler raised to stop it (set by the command line, see
#: :func:`request_stop`), or None. Python swallows an exception raised while a weakref callback
#: or a ``__del__`` runs (matplotlib's figures run many), so a signal that lands in one would
#: otherwise let the run go on and move its files in; the commit checks it once more.
_stop: BaseException | None = None


def request_stop(exc: BaseException | None) -> None:
    """Note that the command is to stop with ``exc`` (None: forget an earlier request)."""
    global _stop
    _stop = exc


def stop_requested() -> BaseException | None:
    """The exception a stop was requested with (:func:`request_stop`), or None."""
    return _stop


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


# ---- moving a file without replacing anything ----------------------------------------------

_RENAME_NOREPLACE = 1
_AT_FDCWD = -100


def _renameat2():
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    return fn


_RENAMEAT2 = _renameat2()


def move_no_replace(src: Path, dst: Path) -> None:
    """Move the file ``src`` to ``dst`` (same file system) in one step that fails with
    FileExistsError if anything is at ``dst``, however recently it appeared: renameat2's
    RENAME_NOREPLACE where the kernel and file system have it, else a hard link (which never
    replaces) and the old name removed."""
    if _RENAMEAT2 is not None:
        rc = _RENAMEAT2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst),
                        _RENAME_NOREPLACE)
        if rc == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise FileExistsError(err, os.strerror(err), str(dst))
        if err not in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP):
            raise OSError(err, os.strerror(err), str(src))
    try:
        os.link(src, dst)
    except FileExistsError:
        raise
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        # a file system without hard links either: the narrowest check there is
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst)) from None
        os.rename(src, dst)
        return
    os.unlink(src)


# ---- the output directory ------------------------------------------------------------------


@contextlib.contextmanager
def output_dir(path: str | Path, *, command: str, option: str = "--out",
               notice: Callable[[str], None] | None = None,
               machine: str | None = None) -> Iterator[Path]:
    """Write a command's files safely into the directory ``path`` (see the module docstring).

    Yields the staging directory to write into (flat: files only). On normal exit its files
    replace the directory's files of the same names (which sewmech wrote, unchanged since) and
    the files of ``command``'s previous run that were not written again are removed: of the
    same ``machine`` (its name, recorded with each file) where the command is about one (the
    kinematics of a second machine into the same directory deleted the first machine's file).
    ``notice``: called with a sentence when something the person should know happened (a
    killed run's leftovers recovered); default: ``note: ...`` on stderr.

    Raises
    ------
    OutputError
        ``path`` is a file, cannot be created or written, holds files that sewmech did not
        write, has a damaged record, another sewmech run holds its lock, or a file of the
        user's appeared in the way while the command ran (the result is then kept aside in
        ``path`` and the error says where).
    """
    notice = notice or _note
    root = user_path(path, option)
    created: list[Path] = []
    lock_fd = None
    lock_created = False
    staging: Path | None = None
    try:
        try:
            _refuse_broken_link(root, option)
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
            lock_fd = _open_lock(root, lock_path, os.O_RDWR | os.O_CREAT, option)
        except OutputError:
            raise
        except OSError as exc:
            raise _os_error(root, exc, option) from None
        try:
            killed = _take_lock(root, lock_fd, option)
        except OutputError:
            lock_created = False  # the other run's lock
            raise
        manifest = _read_manifest(root, option)
        left = [e for e in os.listdir(root) if e.startswith(STAGING_PREFIX)]
        for entry in left:  # staging left by a run that was killed outright
            if (root / entry).is_dir() and not (root / entry).is_symlink():
                _roll_back(root, root / entry, manifest)  # if it was killed mid-move
            shutil.rmtree(root / entry, ignore_errors=True)
        _refuse_foreign(root, manifest, command, option)
        if left:
            notice(f"{option} {root}: a run (pid {killed or '?'}) was stopped before it"
                   " finished; its unfinished files were removed and the directory is as"
                   " that run found it")
        try:
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=root))
            os.chmod(staging, dir_mode())
        except OSError as exc:
            raise _os_error(root, exc, option) from None
        try:
            yield staging
        except OSError as exc:
            if exc.errno in _DISK_FULL:  # (a write deep inside a writer says only that)
                raise _os_error(root, exc, option) from None
            if exc.errno == errno.ENAMETOOLONG and exc.filename is not None:
                raise _name_too_long(root, Path(str(exc.filename)).name, option) from None
            raise
        with _signals_held():
            if _stop is not None:  # a signal whose exception was swallowed: nothing moves in
                raise _stop
            try:
                _commit(root, staging, manifest, command, option, notice, machine)
            except OSError as exc:
                raise _os_error(root, exc, option) from None
        staging = None
    except BaseException:
        if staging is not None:
            with contextlib.suppress(OSError):
                _roll_back(root, staging, manifest)  # (an error while it moved files in)
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
            _release_lock(lock_fd)


def _moved_in_by_a_killed_run(root: Path) -> dict:
    """Records, as the manifest's, of the files a run killed while it moved them in had
    journalled (:func:`_commit`): the next :func:`output_dir` rolls them back
    (:func:`_roll_back`), so they are not the user's."""
    out: dict = {}
    for e in os.listdir(root):
        if not e.startswith(STAGING_PREFIX):
            continue
        try:
            journal = json.loads((root / e / JOURNAL).read_text(encoding="utf-8"))["files"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if isinstance(journal, dict):
            out.update({n: {"size": st[0], "mtime_ns": st[1]} for n, st in journal.items()
                        if _plain_name(n) and isinstance(st, list) and len(st) == 2})
    return out


def _roll_back(root: Path, staging: Path, manifest: dict) -> None:
    """Put ``root`` back as a run found it that was stopped (killed outright, or an error)
    while it moved its staged files into place (:func:`_commit`): each name of its journal
    that holds the run's new file (its size and time, and no longer in ``staging``) gets its
    previous file back from the staging's ``.aside-*`` directory (or is removed, if it had
    none), a previous file moved aside and not replaced is moved back, and so are the
    previous run's stale files it had set aside. Nothing is done when the run had not begun
    to move (no journal) or had finished (``manifest`` records the new files), and nothing
    that is not exactly the run's own file is touched."""
    try:
        journal = json.loads((staging / JOURNAL).read_text(encoding="utf-8"))["files"]
        if not isinstance(journal, dict):
            return
    except (OSError, ValueError, KeyError, TypeError):
        return  # the moves had not begun
    if all((rec := manifest.get(n)) is not None and [rec.get("size"), rec.get("mtime_ns")]
           == list(st) for n, st in journal.items()):
        return  # the run's manifest is in place: it finished
    asides = [staging / e for e in os.listdir(staging) if e.startswith(".aside-")]

    def previous(name: str) -> Path | None:
        return next((d / name for d in asides if os.path.lexists(d / name)), None)

    for name, st in journal.items():
        if not _plain_name(name):
            continue
        path, old = root / name, previous(name)
        try:
            new_here = (not os.path.lexists(staging / name) and os.path.lexists(path)
                        and stat.S_ISREG(os.lstat(path).st_mode) and _stamp(path) == list(st))
        except OSError:
            new_here = False
        with contextlib.suppress(OSError):
            if new_here and old is not None:
                os.replace(old, path)
            elif new_here:
                os.unlink(path)
            elif old is not None and not os.path.lexists(path):
                move_no_replace(old, path)
    for d in asides:  # the previous run's stale files, set aside
        for e in os.listdir(d):
            if e != MANIFEST and e not in journal and _plain_name(e):
                with contextlib.suppress(OSError):
                    move_no_replace(d / e, root / e)


def _kept_dir_name(command: str) -> str:
    slug = re.sub(r"[^a-z0-9]+", "-", command.lower()).strip("-") or "run"
    return f"{KEPT_PREFIX}{slug}-{time.strftime('%Y%m%d-%H%M%S')}"


def _commit(root: Path, staging: Path, manifest: dict, command: str, option: str,
            notice: Callable[[str], None], machine: str | None = None) -> None:
    """Move the staged files into place, drop the command's stale files, save the manifest.

    The directory was checked when the run started; it is checked again here, file by file,
    each check and move one step: a name that holds anything but the unchanged file sewmech
    wrote there is never replaced. If one does, nothing more is moved: what is left of the
    result is kept in ``root/sewmech-kept-COMMAND-TIME/`` and an OutputError says so; what
    was moved already stays, recorded in the manifest."""
    written = sorted(os.listdir(staging))
    # what this commit moves in, with each file's size and time (a rename keeps both): a run
    # killed in the middle of the moves is rolled back from it by the next run
    tmp = staging / (JOURNAL + ".tmp")
    tmp.write_text(json.dumps({"files": {n: _stamp(staging / n) for n in written}}),
                   encoding="utf-8")
    os.replace(tmp, staging / JOURNAL)
    aside = Path(tempfile.mkdtemp(prefix=".aside-", dir=staging))  # replaced files of ours
    in_the_way = [n for n in written if os.path.lexists(root / n)
                  and not _is_ours(root / n, manifest.get(n))]
    moved: list[str] = []
    conflict: list[str] = list(in_the_way)
    if not conflict:
        for name in written:
            if os.path.lexists(root / name):
                os.rename(root / name, aside / name)  # ours, checked once more where it is now
                if not _is_ours(aside / name, manifest.get(name)):
                    with contextlib.suppress(OSError):
                        move_no_replace(aside / name, root / name)
                    conflict.append(name)
                    break
            try:
                move_no_replace(staging / name, root / name)
            except FileExistsError:
                conflict.append(name)
                break
            moved.append(name)
    for name, rec in list(manifest.items()):
        if rec.get("command") != command or rec.get("machine") != machine or name in written:
            continue  # another command's, or another machine's: not this run's previous one
        if conflict:
            continue  # the previous run's files stay while this run's are not all in place
        path = root / name
        if _is_ours(path, rec):
            with contextlib.suppress(OSError):
                os.rename(path, aside / name)
                if not _is_ours(aside / name, rec):  # changed in between: put it back
                    move_no_replace(aside / name, path)
        manifest.pop(name)
        if os.path.lexists(path):
            notice(f"{option} {root}: {name} changed since sewmech wrote it, so it is left as"
                   " it is (no longer sewmech's)")
    for name in conflict:  # a file of ours moved aside and not replaced: no longer recorded
        if not _is_ours(root / name, manifest.get(name)):
            manifest.pop(name, None)
    for name in moved:
        manifest[name] = {"command": command, "size": None, "mtime_ns": None,
                          **({"machine": machine} if machine is not None else {})}
        manifest[name]["size"], manifest[name]["mtime_ns"] = _stamp(root / name)
    tmp = Path(aside) / MANIFEST
    tmp.write_text(json.dumps({"written_by": "sewmech", "files": manifest}, indent=1,
                              sort_keys=True), encoding="utf-8")
    os.chmod(tmp, file_mode())
    os.replace(tmp, root / MANIFEST)
    shutil.rmtree(aside, ignore_errors=True)
    (staging / JOURNAL).unlink()  # the commit is over (its manifest in place)
    if not conflict:
        staging.rmdir()
        return
    kept = root / _kept_dir_name(command)
    os.rename(staging, kept)
    os.chmod(kept, dir_mode())
    shown = ", ".join(conflict[:3]) + (f" and {len(conflict) - 3} more"
                                        if len(conflict) > 3 else "")
    raise OutputError(f"{option} {root}", f"while the command ran, file(s) appeared or changed"
                      f" there that sewmech did not write ({shown}); none of them was"
                      f" replaced" + (f", {len(moved)} of the {len(written)} result files were"
                                      " moved in before" if moved else ""),
                      f"The result is kept in {kept}; move your files elsewhere and run the"
                      " command again, or take the result from there")


@contextlib.contextmanager
def dir_lock(root: Path, option: str = "--out",
             notice: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold ``root``'s lock (``.sewmech.lock``; ``root`` must exist) for a command that writes
    into the directory in place rather than through a staging directory (a sweep, which keeps
    every finished chunk). Raises OutputError if another run holds it. A lock file this call
    created is removed again if the body fails (e.g. refuses a directory of the user's). A
    run that held the lock and was killed outright is noticed (``notice``, default stderr)."""
    notice = notice or _note
    lock = root / LOCK
    created = not lock.exists()
    try:
        fd = _open_lock(root, lock, os.O_RDWR | os.O_CREAT, option)
    except OSError as exc:
        raise _os_error(root, exc, option) from None
    try:
        try:
            killed = _take_lock(root, fd, option)
        except OutputError:
            created = False  # the other run's lock
            raise
        if killed is not None:
            notice(f"{option} {root}: a run (pid {killed}) was stopped before it finished;"
                   " its finished chunks are kept and the rest is computed now")
        yield
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.unlink(lock)
        raise
    finally:
        _release_lock(fd)

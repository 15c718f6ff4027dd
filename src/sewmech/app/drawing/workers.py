"""Worker processes sewmech starts die with the command that started them.

A report draws its figures in worker processes forked from the command's process. If the
command is killed outright (SIGKILL, the out-of-memory killer, a closed terminal's SIGHUP
after the handler is gone), nothing of Python runs in it any more, so its workers must find
out for themselves: each worker

- asks the kernel to kill it when its parent dies (Linux's ``PR_SET_PDEATHSIG``; only when
  the parent forked it from its main thread, since the kernel ties the signal to the thread),
- watches its parent from a thread of its own and exits as soon as it is gone (everywhere,
  and whatever thread forked it),
- takes the default action on SIGTERM and SIGHUP (it inherited the command's handlers, which
  turn a signal into an orderly stop of the *command*: in a worker they kept it alive) and
  leaves Ctrl-C to the command, which stops its workers itself,
- and holds no lock of its parent's (:mod:`sewmech.app.files.outdir` closes them at fork), so
  a killed command's output directory is free again for the next run.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

#: how often a worker looks whether its parent is still there, s
WATCH_INTERVAL_S = 0.2
_PR_SET_PDEATHSIG = 1


def _death_signal() -> bool:
    """Ask the kernel for SIGKILL when the parent dies (Linux); False where there is none."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:  # reparented: the parent is gone
            os._exit(1)
        time.sleep(WATCH_INTERVAL_S)


def die_with_parent(parent_pid: int, *, forked_from_main_thread: bool = True) -> None:
    """Call first thing in a worker process: it then ends when the process ``parent_pid``
    (its parent) ends, however that ends (see the module docstring)."""
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if forked_from_main_thread:
        _death_signal()
    if os.getppid() != parent_pid:  # the parent died before the death signal was asked for
        os._exit(1)
    threading.Thread(target=_watch, args=(parent_pid,), name="sewmech-parent-watch",
                     daemon=True).start()

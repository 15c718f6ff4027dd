"""A line on stderr when a command has to compile kernels first, so that a wait is never silent.

numba compiles a kernel on its first call and keeps the machine code on disk; the install
(:mod:`sewmech.engine.warm`) compiles the kernels the everyday commands need, and the others
(the design sensitivities' tangent kernel, the run in time's integrator) are compiled by the
first command that calls them. numba announces each compile that the disk cache could not
spare (the ``numba:compile`` event, never raised for a kernel loaded from the cache); this
module listens and says once per process and kernel family what is being compiled and about
how long it takes, before the compile starts::

    sewmech: compiling the design sensitivities' tangent kernel once (about 30 s of CPU;
    kept for later runs) ...

The kernels' modules register the listener when they are imported (:func:`install`). Nothing
of it runs on a call that finds its kernel compiled.

Two things make numba's compiler, which is Python code, cheaper to run (measured on the
install's compile: benchmarks/HISTORY.md):

- **The cyclic garbage collector pauses while a sewmech kernel compiles** (the listener turns
  it off when the outermost compile of one of sewmech's kernels starts and back on when it
  ends; other packages' kernels compile as numba would compile them). A compile makes
  millions of small objects, and the collector's passes over them cost about 3.5 s of the
  install's compile; the garbage left (about 170 MB at the install's peak) is collected by
  the collector's next pass after the compile.
- **:func:`roomy` runs a compiling call on a data stack of its own.** CPython (3.11 and later)
  keeps its frames in chunks of 16 KB and frees a chunk as soon as the frame at its start
  returns. numba's compile recurses up and down by many frames, and where the recursion goes
  back and forth across the end of a chunk, every crossing maps and unmaps a chunk of memory:
  590,000 times in the install's compile, 1 to 9 s of system time depending on how deep the
  compile happened to start. A call made by :func:`roomy` has a frame of half a megabyte,
  which takes a chunk of 1 MB to itself, and the compile's frames fit in the other half.
  The install (:mod:`sewmech.engine.warm`) calls each of its steps so; a kernel compiled on
  its first use inside a command compiles where the command's call happens to be.
"""

from __future__ import annotations

import gc
import sys
import threading
import types

from numba.core import event

#: the kernels a call compiles, (module, function; None: any of the module's) -> (what the user
#: is told, about how many seconds of CPU compiling it takes from an empty cache on the 2-core
#: machine, callees included: benchmarks/results/compile.json). Smaller kernels (a second or
#: two) compile without a word.
FAMILIES = {
    ("sewmech.engine._kernels", "evaluate_program"): ("the kinematics interpreter", 12),
    ("sewmech.engine._kernels", "force_solve"): ("the force solver", 15),
    ("sewmech.engine._tangents", "tangents"): ("the design sensitivities' tangent kernel", 30),
    ("sewmech.engine._force_tangents", "force_tangents"): (
        "the force analysis' derivatives by the design", 18),
    ("sewmech.engine._running", None): ("the run in time's integrator", 8),
}

_LOCK = threading.Lock()
_said: set[tuple] = set()
_depth = 0
#: while the outermost compile of a sewmech kernel runs: whether the garbage collector ran
#: before it (it is paused meanwhile and resumed when the compile ends)
_restore: bool | None = None
#: True while :mod:`sewmech.engine.warm` runs: it lists what it compiles itself
quiet = False


class _Listener(event.Listener):
    def on_start(self, ev) -> None:
        global _depth, _restore
        with _LOCK:
            _depth += 1
            if _depth != 1:  # only a compile that a call started, not its callees
                return
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            module = getattr(func, "__module__", "") or ""
            if module.startswith("sewmech."):  # someone else's kernel compiles as it would
                _restore = gc.isenabled()
                gc.disable()
            if quiet:
                return
            key = (module, getattr(func, "__name__", ""))
            if key not in FAMILIES:
                key = (module, None)
            if key not in FAMILIES or key in _said:
                return
            _said.add(key)
        what, seconds = FAMILIES[key]
        try:
            print(f"sewmech: compiling {what} once (about {seconds} s of CPU; kept for later"
                  " runs) ...", file=sys.stderr, flush=True)
        except (OSError, ValueError):  # a closed stderr stops no computation
            pass

    def on_end(self, ev) -> None:
        global _depth, _restore
        with _LOCK:
            _depth -= 1
            if _depth == 0 and _restore is not None:
                if _restore:
                    gc.enable()
                _restore = None


_installed = False


def install() -> None:
    """Listen to numba's compile events (once per process)."""
    global _installed
    with _LOCK:
        if not _installed:
            event.register("numba:compile", _Listener())
            _installed = True


#: slots of the frame :func:`roomy` calls from: 512 KB, so that CPython gives it a chunk of 1 MB
#: (chunks double from 16 KB until the frame fits) and the compile has the other half
_ROOM_SLOTS = 1 << 16


def _room(fn, args, kwargs):
    return fn(*args, **kwargs)


_code = _room.__code__
#: :func:`_room` with a frame of _ROOM_SLOTS more stack slots than it uses (a frame's size is
#: its locals and its stack; nothing reads the slots it does not use)
_roomy_call = types.FunctionType(_code.replace(co_stacksize=_code.co_stacksize + _ROOM_SLOTS),
                                 _room.__globals__, "_roomy_call")


def roomy(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` from a frame that takes a fresh chunk of CPython's data stack
    with room for the frames of a compile (see the module doc); its result.

    For calls that may compile: it costs a chunk's allocation, a few microseconds."""
    return _roomy_call(fn, args, kwargs)

"""A line on stderr when a command has to compile kernels first, so that a wait is never silent.

numba compiles a kernel on its first call and keeps the machine code on disk; the install
(:mod:`sewmech.engine.warm`) compiles the kernels the everyday commands need, and the others
(the design sensitivities' tangent kernel, the run in time's integrator) are compiled by the
first command that calls them. numba announces each compile that the disk cache could not
spare (the ``numba:compile`` event, never raised for a kernel loaded from the cache); this
module listens and says once per process and kernel family what is being compiled and about
how long it takes, before the compile starts::

    sewmech: compiling the design sensitivities' tangent kernel once (about 40 s of CPU;
    kept for later runs) ...

The kernels' modules register the listener when they are imported (:func:`install`). Nothing
of it runs on a call that finds its kernel compiled.
"""

from __future__ import annotations

import sys
import threading

from numba.core import event

#: the kernels a call compiles, (module, function; None: any of the module's) -> (what the user
#: is told, about how many seconds of CPU compiling it takes from an empty cache on the 2-core
#: machine, callees included: benchmarks/results/compile.json). Smaller kernels (a second or
#: two) compile without a word.
FAMILIES = {
    ("sewmech.engine._kernels", "evaluate_program"): ("the kinematics interpreter", 20),
    ("sewmech.engine._kernels", "force_solve"): ("the force solver", 15),
    ("sewmech.engine._tangents", "tangents"): ("the design sensitivities' tangent kernel", 40),
    ("sewmech.engine._force_tangents", "force_tangents"): (
        "the force analysis' derivatives by the design", 20),
    ("sewmech.engine._running", None): ("the run in time's integrator", 10),
}

_LOCK = threading.Lock()
_said: set[tuple] = set()
_depth = 0
#: True while :mod:`sewmech.engine.warm` runs: it lists what it compiles itself
quiet = False


class _Listener(event.Listener):
    def on_start(self, ev) -> None:
        global _depth
        with _LOCK:
            _depth += 1
            if _depth != 1 or quiet:  # only a compile that a call started, not its callees
                return
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            module = getattr(func, "__module__", "")
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
        global _depth
        with _LOCK:
            _depth -= 1


_installed = False


def install() -> None:
    """Listen to numba's compile events (once per process)."""
    global _installed
    with _LOCK:
        if not _installed:
            event.register("numba:compile", _Listener())
            _installed = True

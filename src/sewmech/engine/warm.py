"""Compile the kernels once, ahead of the first command: ``python -m sewmech.engine.warm``.

numba compiles a kernel on its first call and keeps the machine code on disk (beside the
sources, or in ``NUMBA_CACHE_DIR``). ``make install`` (and so ``make demo`` and ``make test``)
runs this right after installing: it compiles the kinematics interpreter and the force solver,
which nearly every command calls first, in 26-29 s of CPU from an empty cache on the 2-core
machine (benchmarks/results/compile.json). The big kernels that only some commands call, the
design sensitivities' tangent kernel (sensitivities, tolerances, gradients; about 30 s), the
force analysis' derivatives by the design (dynamic gradients; about 18 s) and the run in
time's integrator (about 8 s), are compiled by the first command that needs them, which says
so on stderr (:mod:`sewmech.engine._compiling`); ``--all`` compiles them here too (``make
test`` does, so that no test meets a compile). It says what it compiles, step by step, so that
a silent ``make`` is never mistaken for a hung one. Running it again costs about a second (it
only loads the kernels).

Each step runs from a frame with room for numba's recursion (:func:`_compiling.roomy`), with
the garbage collector paused (:mod:`sewmech.engine._compiling`) and glibc's malloc keeping
what the compile frees (:func:`keep_freed_memory`): 41.5 s of CPU before these, of which
8.6 s system time, mostly CPython's frame chunks mapped and unmapped.

It also writes the package's bytecode (``__pycache__``): where ``PYTHONDONTWRITEBYTECODE`` is
set, as on our 2-core CI machine, Python would otherwise compile every sewmech module from
source in every process (about 0.15 s per command).
"""

from __future__ import annotations

import sys
import time

#: what is compiled, in order: (what the user is told, what calls it, compiled at the install)
STEPS = (
    ("the kinematics interpreter", "kinematics", True),
    ("the force solver and its block solvers", "dynamics", True),
    ("the force directions of the pairs", "pairs", True),
    ("friction in the pairs", "friction", True),
    ("the design sensitivities' tangent kernel", "sensitivities", False),
    ("the force analysis' derivatives by the design", "force_tangents", False),
    ("the run in time's integrator", "run", False),
)


def warm(progress=None, *, everything: bool = False) -> float:
    """Call the install's compiled kernels (``everything``: every kernel) once with the argument
    types sewmech uses; returns seconds.

    ``progress(k, n, what, seconds)`` is called before each of the ``n`` steps (``STEPS``)
    with ``seconds=None`` and after it with the seconds it took."""
    import numpy as np

    from . import _compiling
    from .dynamics import inverse_dynamics, pair_geometry
    from .kinematics import kinematics
    from .machine import load_machine
    from .sensitivity import sensitivities

    t0 = time.perf_counter()
    m = load_machine("jb1-3")  # closed-form units, loop units and cams: every code path
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    kin = None

    def run(step):
        nonlocal kin
        if step == "kinematics":
            kin = kinematics(m, phi)
        elif step == "dynamics":
            inverse_dynamics(m, phi)
        elif step == "pairs":
            pair_geometry(m, kin)
        elif step == "friction":  # jb1-3 has [friction]: its kernels and Anderson's steps
            inverse_dynamics(m, phi)
        elif step == "sensitivities":  # one kernel for every level, every unit type
            sensitivities(m, phi)
            sensitivities(m, phi, rates=True)
        elif step == "force_tangents":  # one kernel for every kind of term
            from .dynamic_sensitivity import dynamics_sensitivities

            dynamics_sensitivities(m, phi)
        else:  # a short run at a low speed: the tables, the integrator, the samples
            from .running import run

            run(m, rpm=100.0, run_time=0.2, step_deg=10.0, energy_method=False)

    steps = [(what, step) for what, step, install in STEPS if install or everything]
    quiet = _compiling.quiet
    _compiling.quiet = True  # the steps are listed here
    try:
        for k, (what, step) in enumerate(steps, start=1):
            if progress is not None:
                progress(k, len(steps), what, None)
            t = time.perf_counter()
            _compiling.roomy(run, step)  # numba's recursion on a data stack of its own
            if progress is not None:
                progress(k, len(steps), what, time.perf_counter() - t)
    finally:
        _compiling.quiet = quiet
    return time.perf_counter() - t0


def keep_freed_memory() -> bool:
    """Ask glibc's malloc to keep the memory the compile frees for its next allocations, instead
    of returning it to the system and faulting it in again (0.4-0.7 s of the install's compile,
    benchmarks/HISTORY.md). For this process only, which compiles and exits. Returns whether
    every setting was accepted; without glibc (macOS, Windows, musl) nothing is done."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # no mallopt
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return all((
        mallopt(-3, 32 << 20),  # M_MMAP_THRESHOLD: blocks below 32 MB on the heap (the most that
        # older glibc accepts)
        mallopt(-1, 1 << 30),  # M_TRIM_THRESHOLD: keep up to 1 GB free at the heap's top
        mallopt(-2, 64 << 20),  # M_TOP_PAD: grow the heap 64 MB at a time
    ))


def bytecode() -> None:
    """Write the bytecode of every sewmech module (what importing would write if allowed)."""
    import compileall
    from pathlib import Path

    compileall.compile_dir(str(Path(__file__).resolve().parents[1]), quiet=1)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args not in ([], ["--all"]):
        print("usage: python -m sewmech.engine.warm [--all]\n  --all  also the kernels that"
              " are otherwise compiled on their first use (the design sensitivities', the run"
              " in time's)", file=sys.stderr)
        return 2
    everything = args == ["--all"]
    keep_freed_memory()

    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    if everything:
        say("sewmech: compiling every numerical kernel once, so that no command waits for the"
            " compiler later (about 75 s of CPU; each step is listed as it is compiled)")
    else:
        say("sewmech: compiling the numerical kernels the commands call first, so that they"
            " need not wait for the compiler (about 30 s of CPU; each step is listed as it is"
            " compiled; the design sensitivities' and the run in time's kernels are compiled"
            " on their first use)")
    bytecode()

    def progress(k: int, n: int, what: str, seconds: float | None) -> None:
        if seconds is None:
            print(f"  [{k}/{n}] {what} ...", end="", file=sys.stderr, flush=True)
        else:
            say(f" {seconds:.1f} s")

    seconds = warm(progress, everything=everything)
    say(f"sewmech: kernels compiled and cached ({seconds:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

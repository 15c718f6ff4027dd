"""Compile the kernels once, ahead of the first command: ``python -m sewmech.engine.warm``.

numba compiles the interpreter, the force solver and the design sensitivities' tangent kernel
on their first call and keeps the machine code on disk (beside the sources); compiling takes
about 2.5 min of CPU from an empty cache (155 s measured; 165 s of wall time on an idle 2-core
machine, more on a busy one; the two tangent kernels about 60 % of it), which a user would otherwise meet on their
first command (the tangent kernels on their first sensitivities). It says what it compiles,
step by step, so that a silent ``make`` is never mistaken for a hung one. ``make install`` (and so ``make demo`` and ``make test``) runs this right
after installing, so every command finds the kernels compiled. Running
it again costs about a second (it only loads them).

It also writes the package's bytecode (``__pycache__``): where ``PYTHONDONTWRITEBYTECODE`` is
set, as on our 2-core CI machine, Python would otherwise compile every sewmech module from
source in every process (about 0.15 s per command).
"""

from __future__ import annotations

import sys
import time

#: what is compiled, in order: (what the user is told, what calls it)
STEPS = (
    ("the kinematics interpreter", "kinematics"),
    ("the force solver and its block solvers", "dynamics"),
    ("the force directions of the pairs", "pairs"),
    ("friction in the pairs", "friction"),
    ("the design sensitivities' tangent kernel (positions)", "sensitivities"),
    ("the design sensitivities' tangent kernel (rates)", "rates"),
    ("the run in time's integrator", "run"),
)


def warm(progress=None) -> float:
    """Call every compiled kernel once with the argument types sewmech uses; returns seconds.

    ``progress(k, n, what, seconds)`` is called before each of the ``n`` steps (``STEPS``)
    with ``seconds=None`` and after it with the seconds it took."""
    import numpy as np

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
        elif step == "sensitivities":
            sensitivities(m, phi)  # every level of positions, every unit type
        elif step == "rates":
            sensitivities(m, phi, rates=True)
        else:  # a short run at a low speed: the tables, the integrator, the samples
            from .running import run

            run(m, rpm=100.0, run_time=0.2, step_deg=10.0, energy_method=False)

    for k, (what, step) in enumerate(STEPS, start=1):
        if progress is not None:
            progress(k, len(STEPS), what, None)
        t = time.perf_counter()
        run(step)
        if progress is not None:
            progress(k, len(STEPS), what, time.perf_counter() - t)
    return time.perf_counter() - t0


def bytecode() -> None:
    """Write the bytecode of every sewmech module (what importing would write if allowed)."""
    import compileall
    from pathlib import Path

    compileall.compile_dir(str(Path(__file__).resolve().parents[1]), quiet=1)


def main() -> int:
    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    say("sewmech: compiling the numerical kernels once, so that no command waits for the"
        " compiler later (about 2.5 min; each step is listed as it is compiled)")
    bytecode()

    def progress(k: int, n: int, what: str, seconds: float | None) -> None:
        if seconds is None:
            print(f"  [{k}/{n}] {what} ...", end="", file=sys.stderr, flush=True)
        else:
            say(f" {seconds:.1f} s")

    seconds = warm(progress)
    say(f"sewmech: kernels compiled and cached ({seconds:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

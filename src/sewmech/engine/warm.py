"""Compile the kernels once, ahead of the first command: ``python -m sewmech.engine.warm``.

numba compiles the interpreter, the force solver and the design sensitivities' tangent kernel
on their first call and keeps the machine code on disk (beside the sources); compiling takes
about 75-90 s on a 2-core machine (the two tangent kernels about 50 s of it), which a user
would otherwise meet on their first command (the tangent kernels on their first
sensitivities). ``make install`` (and so ``make demo`` and ``make test``) runs this right
after installing, so every command finds the kernels compiled. Running
it again costs about a second (it only loads them).

It also writes the package's bytecode (``__pycache__``): where ``PYTHONDONTWRITEBYTECODE`` is
set, as on our 2-core CI machine, Python would otherwise compile every sewmech module from
source in every process (about 0.15 s per command).
"""

from __future__ import annotations

import sys
import time


def warm() -> float:
    """Call every compiled kernel once with the argument types sewmech uses; returns seconds."""
    import numpy as np

    from .dynamics import inverse_dynamics, pair_geometry
    from .kinematics import kinematics
    from .machine import load_machine
    from .sensitivity import sensitivities

    t = time.perf_counter()
    m = load_machine("jb1-3")  # closed-form units, loop units and cams: every code path
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    kin = kinematics(m, phi)  # the interpreter
    inverse_dynamics(m, phi)  # the force solver with its block solvers
    pair_geometry(m, kin)  # force directions of the pairs
    sensitivities(m, phi)  # the tangent kernels (positions; every level), every unit type
    sensitivities(m, phi, rates=True)
    return time.perf_counter() - t


def bytecode() -> None:
    """Write the bytecode of every sewmech module (what importing would write if allowed)."""
    import compileall
    from pathlib import Path

    compileall.compile_dir(str(Path(__file__).resolve().parents[1]), quiet=1)


def main() -> int:
    bytecode()
    seconds = warm()
    print(f"sewmech: kernels compiled and cached ({seconds:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""sewmech: kinematics, dynamics, balancing and optimisation of sewing-machine mechanisms.

Units everywhere inside: mm, kg, s, N, rad. Degrees appear only at the edges (files, CLI,
plots) and are named so (``phi_deg``).

The package is built in layers, each importing only the ones below it (docs/architecture.md):

- ``sewmech.engine``: machine files, compilation, kernels, kinematics, dynamics;
- ``sewmech.sewing``: timing, feed, thread, transmission, embroidery;
- ``sewmech.design``: balancing, tolerances, optimisation, sweeps;
- ``sewmech.app``: the command line, the report, plots, file writers.

Every module also has a short public name, ``sewmech.<module>`` (``sewmech.dynamics`` is
``sewmech.engine.dynamics``), so that code written against the names of the README does not
depend on the layout.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys


def _interrupts_while_starting() -> None:
    """Ctrl-C while a sewmech process is still starting (its imports take about a second)
    ends it with one line, not a traceback. The ``sewmech`` command stops with exit code 130
    (its command line then handles Ctrl-C itself: :func:`sewmech.app.cli.common._guard`); a
    worker process of a local Dask cluster that a sewmech command started
    (``SEWMECH_LOCAL_WORKER=1``) ignores it: a terminal sends Ctrl-C to every process of its
    foreground group, and the command that started the cluster stops it. Nothing changes for
    a program that imports sewmech as a library."""
    import os
    import signal

    if os.environ.get("SEWMECH_LOCAL_WORKER") == "1":
        import multiprocessing

        # (a process the cluster spawned: multiprocessing marks it while it imports the
        # main script again, with the command's sys.argv, and names its parent afterwards)
        if getattr(multiprocessing.current_process(), "_inheriting", False) or \
                multiprocessing.parent_process() is not None:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    elif _is_the_command() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupted_while_starting)


def _interrupted_while_starting(signum, frame) -> None:  # pragma: no cover (a real Ctrl-C)
    import os

    os.write(2, b"error: interrupted (Ctrl-C) while starting; nothing was written\n")
    os._exit(130)


def _is_the_command() -> bool:
    """Whether this process is the ``sewmech`` command (not a program importing sewmech)."""
    import os

    return bool(sys.argv) and os.path.basename(sys.argv[0]) == "sewmech"


def _check_environment() -> None:
    """NUMBA_NUM_THREADS, which numba reads once when it is first imported, must be a whole
    number of threads >= 1. numba raises a ValueError with a traceback while it is imported
    for 0 (every command, ``--help`` too) and prints a warning with a traceback in it for text
    that is no number. Checked here, before numba is imported: the ``sewmech`` command stops
    with one located line and exit code 2 (docs/errors.md); a program that imports sewmech gets
    the same line as an :class:`~sewmech.engine.errors.OptionError`."""
    import os

    value = os.environ.get("NUMBA_NUM_THREADS")
    if value is None:
        return
    try:
        n = int(value)  # as numba reads it
    except ValueError:
        n = None
    if n is not None and n >= 1:
        return
    from .engine.errors import OptionError

    what = (f"is {value!r}, not a whole number" if n is None
            else f"is {n}: numba needs at least one thread")
    exc = OptionError("NUMBA_NUM_THREADS", f"{what} (the environment variable numba reads for"
                      " its number of threads)", "Give a whole number >= 1, e.g."
                      " NUMBA_NUM_THREADS=2, or unset it (numba then takes one thread a core)")
    if _is_the_command():
        os.write(2, f"error: {exc}\n".encode("utf-8", "replace"))
        raise SystemExit(2)
    raise exc


_interrupts_while_starting()
_check_environment()

# (the imports after the handler: they are what takes the time)
from .engine.errors import AssemblyError, ConvergenceError, MachineFileError, SewmechError  # noqa: E402,I001
from .engine.kinematics import KinematicsPlan, kinematics, rpm_to_rad_s  # noqa: E402
from .engine.machine import (  # noqa: E402
    Machine,
    compile_machine,
    load_machine,
    machine_from_toml,
    shipped_machines,
)
from .engine.results import KinematicsResult, LinkMotion, PointMotion, VariableMotion  # noqa: E402
from .engine.spec import MachineSpec, load_machine_spec, parse_machine  # noqa: E402

__version__ = "0.1.0"

#: the short public name of every module -> where it lives under the package
MODULES = {
    **{m: f"engine.{m}" for m in ("errors", "spec", "cams", "mass", "machine", "results",
                                  "kinematics", "dynamics", "extremes", "margins", "assembly",
                                  "counterweights", "sensitivity")},
    **{m: f"sewing.{m}" for m in ("timing", "checks", "feed", "thread", "transmission",
                                  "embroidery", "gradients", "thread_gradients", "references")},
    **{m: f"design.{m}" for m in ("balancing", "vibration", "inserts", "tolerances",
                                  "tolerance_file", "methods", "problem", "evaluate", "optimize",
                                  "sweep_file", "sweep", "synthesis", "burmester",
                                  "take_up_synthesis", "minmax_balance")},
    # the application layer's rooms (app/cli/, app/report/, ...) under their earlier names
    "cli": "app.cli", "cli_common": "app.cli.common", "cli_balancing": "app.cli.balancing",
    "cli_accuracy": "app.cli.accuracy", "cli_design": "app.cli.design",
    "cli_serve": "app.cli.serve", "cli_sweep": "app.cli.sweep",
    "report": "app.report", "report_dynamics": "app.report.dynamics",
    "report_balancing": "app.report.balancing", "report_accuracy": "app.report.accuracy",
    "report_design": "app.report.design",
    "web": "app.web", "sweep_run": "app.sweep_run",
    "figures": "app.drawing.figures", "plot": "app.drawing.plot",
    "io": "app.files.io", "outdir": "app.files.outdir",
}


class _ShortNames(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``sewmech.<module>`` as the module of its layer (the same module object)."""

    def find_spec(self, fullname, path=None, target=None):
        package, _, name = fullname.rpartition(".")
        if package != __name__ or name not in MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        name = spec.name.rpartition(".")[2]
        module = importlib.import_module(f"{__name__}.{MODULES[name]}")
        # the import system sets __spec__ of what this returns to the short name's spec;
        # keep the module's own (a package found by importlib.resources needs its real one)
        spec.loader_state = module.__spec__
        return module

    def exec_module(self, module):
        # the layer's module is already executed: only its own spec back
        if isinstance(module.__spec__.loader_state, importlib.machinery.ModuleSpec):
            module.__spec__ = module.__spec__.loader_state


sys.meta_path.append(_ShortNames())
# the modules imported above are registered now: a later `import sewmech.kinematics` must not
# rebind `sewmech.kinematics`, the function, to the module
for _name in ("errors", "spec", "machine", "results", "kinematics"):
    sys.modules.setdefault(f"{__name__}.{_name}", sys.modules[f"{__name__}.engine.{_name}"])
    if _name != "kinematics":
        globals()[_name] = sys.modules[f"{__name__}.engine.{_name}"]
del _name


def __getattr__(name: str):
    """``sewmech.<module>`` as an attribute, imported on first use."""
    if name in MODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "AssemblyError",
    "ConvergenceError",
    "KinematicsPlan",
    "KinematicsResult",
    "LinkMotion",
    "Machine",
    "MachineFileError",
    "MachineSpec",
    "PointMotion",
    "SewmechError",
    "VariableMotion",
    "compile_machine",
    "kinematics",
    "load_machine",
    "load_machine_spec",
    "machine_from_toml",
    "parse_machine",
    "rpm_to_rad_s",
    "shipped_machines",
]

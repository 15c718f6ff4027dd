"""The ``sewmech`` command line (typer + rich), one module a family of commands:

- :mod:`.common`: the typer app, the error guard, the options' checks;
- :mod:`.analysis`: ``machines``, ``check``, ``kinematics``, ``dynamics``, ``feed``,
  ``embroidery-take-up``, ``report``, ``demo``;
- :mod:`.balancing`: ``balance``, ``trial-balance``, ``influence-balance``, ``level-change``;
- :mod:`.vibration`: ``vibration`` (the housing on its mounts);
- :mod:`.accuracy`: ``sensitivity``, ``tolerance``;
- :mod:`.design`: ``optimize``;
- :mod:`.synthesis`: ``synthesize function|motion|path|embroidery-take-up``;
- :mod:`.drawing`: ``export`` (DXF, SVG);
- :mod:`.sweep`: ``sweep``, ``sweep-summary``;
- :mod:`.serve`: ``serve``;
- :mod:`.run`: ``run`` (the machine run in time with its motor).

Importing this package registers every command on :data:`app`; :func:`main` is the entry point.
"""

from __future__ import annotations

# each module registers its commands on the app; `sewmech --help` lists them in this order
from . import analysis, balancing, vibration, accuracy, design, synthesis, drawing, sweep, serve, run  # noqa: F401, I001
from .common import (DEFAULT_MACHINE, EXIT_ERROR, EXIT_INTERNAL, EXIT_SIGINT, MIN_STEP_DEG,
                     Format, Terminated, app, err_console, run_as_process)

__all__ = ["DEFAULT_MACHINE", "EXIT_ERROR", "EXIT_INTERNAL", "EXIT_SIGINT", "MIN_STEP_DEG",
           "Format", "Terminated", "app", "err_console", "main"]


def main():  # pragma: no cover - entry point
    run_as_process()

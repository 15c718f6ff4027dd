"""The HTML reports, one module a section:

- :mod:`.build`: :func:`write_report`, the main job: every section of a machine, drawn in worker
  processes, written into a guarded output directory;
- :mod:`.page`: the report's HTML page around the sections;
- :mod:`.feed`, :mod:`.thread`, :mod:`.dynamics`, :mod:`.balancing`, :mod:`.accuracy`,
  :mod:`.comparison`: the sections (``dynamics`` and ``balancing`` are also written by
  ``sewmech dynamics --out`` and ``sewmech balance --out``);
- :mod:`.design`: the page of a solved design problem (``sewmech optimize --out``).
"""

from __future__ import annotations

from .build import write_report

__all__ = ["write_report"]

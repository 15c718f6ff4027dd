"""The applications on top: what people run and read. Numeric code below never imports these.

- ``cli/``: the ``sewmech`` command line, one module a family of commands;
- ``report/``: the HTML report, one module a section, and the page of a solved design problem;
- ``web/``: the interactive page (``sewmech serve``);
- ``drawing/``: figures (PNG, SVG, CSV) and matplotlib's speed-ups;
- ``files/``: output directories and the CSV and JSON files;
- ``display``: how numbers are shown to people (round-off as 0, flags as yes/no);
- ``sweep_run``: a design sweep's chunks in this process or on Dask, written as they finish.
"""

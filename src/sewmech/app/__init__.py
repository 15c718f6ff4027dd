"""The applications on top: what people run and read.

``cli`` (the ``sewmech`` command), ``report`` and ``report_dynamics`` (the HTML report and its
figures), ``plot`` (figures of results), ``io`` (CSV and JSON writers) and ``outdir`` (output
directories that never lose the user's files). Numeric code below never imports these.
"""

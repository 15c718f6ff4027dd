"""The engine: machine files, their compilation, the compiled kernels and what they compute.

From the bottom up: ``errors`` (every error sewmech raises), ``spec`` (TOML -> validated
``MachineSpec``), ``cams`` and ``mass`` (cam profiles, mass properties of parts),
``machine`` (the compiled ``Machine``: index arrays, parameters and their domains),
``_kernels``/``_blocks`` (the numba interpreter and force solver), ``results``,
``kinematics`` and ``dynamics`` (positions to forces, one compiled call per batch of designs),
``_events``/``extremes`` (events and extremes located on the exact motion), ``assembly``
(assembly proved over the whole turn). Knows nothing of sewing, files on disk beyond machine
files, plots or the command line.
"""

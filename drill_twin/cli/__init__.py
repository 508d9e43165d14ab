"""
The ``drill-twin`` command line: one module per subcommand, wired in ``main``.

A subcommand's module imports at its top what its parser and the checks of its arguments need
(the configuration, numpy). The modules that do its work and are slow to import are imported
inside its ``run`` (and the helpers ``run`` calls): the numerical core (numba kernels, half a
second), matplotlib, rerun and dask (a second each), rclpy, and the MCAP files (a tenth of a
second), so that ``drill-twin --help`` and a mistyped argument answer at once.
"""

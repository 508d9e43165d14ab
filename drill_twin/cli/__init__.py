"""The ``drill-twin`` command line: one module per subcommand, wired in ``main``."""

"""One module per ``otmm-qp`` subcommand: ``NAME``, ``HELP``, ``add_arguments``, ``run``."""

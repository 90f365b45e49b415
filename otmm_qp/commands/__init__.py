"""Subcommands of the ``otmm-qp`` CLI, one module each (contracts §2)."""

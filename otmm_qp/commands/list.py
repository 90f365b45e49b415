"""``otmm-qp list``: every registered plugin, by group."""

from __future__ import annotations

import argparse

from otmm_qp import registry

NAME = "list"
HELP = "list registered robots, filters, p-functions, backends, trajectories"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """No options."""


def run(args: argparse.Namespace) -> int:
    """Print every registered plugin, by group."""
    for group in registry.GROUPS:
        print(f"{group.rsplit('.', 1)[-1]}:")
        for name, spec in registry.specs(group).items():
            print(f"  {name:<24} {spec.value}  [{spec.distribution}]")
    return 0

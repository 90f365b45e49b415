"""``otmm-qp study {run,show,report,verdict,tradeoff,plants}``: the study command tree.

One module per subcommand (``otmm_qp/commands/study_<name>.py``, each with ``HELP``,
``add_arguments`` and ``run``), listed in :data:`SUBCOMMANDS`. ``otmm-qp study FILE`` (no
subcommand) is ``otmm-qp study run FILE``.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence
from types import ModuleType

from otmm_qp.exceptions import ConfigError

NAME = "study"
HELP = "run a study (many random tasks x controllers) and analyse it: run, show, report, ..."

#: The subcommands, each a module ``otmm_qp.commands.study_<name>``.
SUBCOMMANDS = ("run", "show", "report", "verdict", "tradeoff", "plants")


def subcommand(name: str) -> ModuleType:
    """The module of ``otmm-qp study NAME``."""
    return importlib.import_module(f"otmm_qp.commands.study_{name}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """One subparser per :data:`SUBCOMMANDS` entry."""
    commands = parser.add_subparsers(
        dest="study_command", metavar="{" + ",".join(SUBCOMMANDS) + "}"
    )
    for name in SUBCOMMANDS:
        module = subcommand(name)
        sub = commands.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(study_module=module)


def normalise(arguments: Sequence[str]) -> list[str]:
    """``study FILE ...`` (no subcommand) is ``study run FILE ...``."""
    arguments = list(arguments)
    if not arguments or arguments[0] in SUBCOMMANDS or arguments[0] in ("-h", "--help"):
        return arguments
    return ["run", *arguments]


def run(args: argparse.Namespace) -> int:
    """Run the chosen subcommand."""
    module = getattr(args, "study_module", None)
    if module is None:
        raise ConfigError("study", f"give a subcommand ({', '.join(SUBCOMMANDS)}) or a study file")
    return int(module.run(args))

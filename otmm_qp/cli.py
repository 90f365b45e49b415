"""Command-line interface: ``otmm-qp [run CONFIG] | list | report DIR | bench | ...``.

A thin dispatcher over the modules of :mod:`otmm_qp.commands` (one per subcommand). Bad input
of any kind prints one line ``otmm-qp: error: ...`` and exits with status 2; results already
computed are written before the error is reported. SIGTERM is handled like SIGINT (exit 130).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from types import ModuleType

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before anything imports NumPy (see otmm_qp.blas_threads)

from otmm_qp.exceptions import OtmmError  # noqa: E402
from otmm_qp.runner import interrupt  # noqa: E402

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
#: Subcommand modules in ``otmm_qp.commands``, imported by name.
COMMAND_MODULES = ("run", "list", "report", "bench", "study", "replay", "init")


def _command(name: str) -> ModuleType:
    return importlib.import_module(f"otmm_qp.commands.{name}")


def _parser() -> tuple[argparse.ArgumentParser, dict[str, ModuleType]]:
    parser = argparse.ArgumentParser(
        prog="otmm-qp",
        description="Compare velocity-level IK controllers near kinematic singularities. "
        "With no command, reproduces the OTMM paper into ./results/paper.",
    )
    subparsers = parser.add_subparsers(dest="command")
    modules = {}
    for name in COMMAND_MODULES:
        module = _command(name)
        modules[module.NAME] = module
        module.add_arguments(subparsers.add_parser(module.NAME, help=module.HELP))
    return parser, modules


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``otmm-qp`` console script."""
    parser, modules = _parser()
    arguments = list(sys.argv[1:] if argv is None else argv)
    if not arguments or (arguments[0].startswith("-") and arguments[0] not in ("-h", "--help")):
        arguments = ["run", *arguments]  # no command: the paper reproduction (`otmm-qp --force`)
    args = parser.parse_args(arguments)
    try:
        with interrupt.handle_stop_signals():
            status = int(modules[args.command or "run"].run(args))
            if status != EXIT_INTERRUPTED:  # the command already said it was interrupted
                interrupt.check()  # a stop request Python swallowed still counts
            return status
    except OtmmError as error:
        print(f"otmm-qp: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("otmm-qp: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # e.g. `otmm-qp list | head -1`: the reader left; silence the flush at exit.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())

"""Command-line interface: ``otmm-qp [run CONFIG] | list | report DIR | study ... | ...``.

A thin dispatcher over the modules of :mod:`otmm_qp.commands` (one per command, listed in
:data:`COMMAND_MODULES`; a command with subcommands, like ``study``, lists its own). Bad input
of any kind — a bad argument too — prints one line ``otmm-qp: error: ...`` of at most 200
characters (details, if any, on the lines after it) and exits with status 2; results already
computed are written before the error is reported. SIGINT and SIGTERM, from the first moment
of :func:`main` on, are one line and exit 130.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import NoReturn

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before anything imports NumPy (see otmm_qp.blas_threads)

from otmm_qp import interrupt  # noqa: E402
from otmm_qp.exceptions import FIRST_LINE_LIMIT, OtmmError, error_lines  # noqa: E402

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
#: Subcommand modules in ``otmm_qp.commands``, imported by name (a new command: one entry).
COMMAND_MODULES = ("run", "list", "report", "bench", "study", "replay", "pareto", "migrate", "init")
#: Longest error line of a bad argument, ``otmm-qp: error: `` included [characters].
MAX_ERROR_LINE = FIRST_LINE_LIMIT


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line ``otmm-qp: error: ...``, exit 2."""

    def error(self, message: str) -> NoReturn:
        """Print the one line (cut to :data:`MAX_ERROR_LINE`) and exit 2."""
        command = self.prog.removeprefix("otmm-qp").strip()
        text = f"otmm-qp: error: {command + ': ' if command else ''}{' '.join(message.split())}"
        if len(text) > MAX_ERROR_LINE:
            text = text[: MAX_ERROR_LINE - 1] + "…"
        print(text, file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def _command(name: str) -> ModuleType:
    return importlib.import_module(f"otmm_qp.commands.{name}")


def _parser() -> tuple[argparse.ArgumentParser, dict[str, ModuleType]]:
    parser = OneLineParser(
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
    """Entry point of the ``otmm-qp`` console script.

    The stop signals are handled first (:func:`otmm_qp.interrupt.handle_stop_signals`), before
    the commands' imports (1-7 s): Ctrl-C or SIGTERM at any time is one line and exit 130. As the
    console script (``argv`` None) the signals are ignored once the outcome is decided.
    """
    try:
        with interrupt.handle_stop_signals(then_ignore=argv is None):
            status = _dispatch(argv)
            if status != EXIT_INTERRUPTED:  # the command already said it was interrupted
                interrupt.check()  # a stop request Python swallowed still counts
            return status
    except KeyboardInterrupt:
        print("otmm-qp: interrupted", file=sys.stderr)
        _forget_unhandled_interrupt()
        return EXIT_INTERRUPTED


def _forget_unhandled_interrupt() -> None:
    """Clear CPython's "ended by an unhandled KeyboardInterrupt" mark: the interrupt was handled.

    A KeyboardInterrupt that passes through a C extension's ``PyRun_String`` while it imports
    marks the interpreter (``_PyRuntime.signals.unhandled_keyboard_interrupt``), which then
    kills itself with SIGINT at exit, after this function's exit 130 and line (4 of 30 early
    Ctrl-Cs). Running an empty string through ``PyRun_SimpleString`` (public C API) resets it.
    """
    import ctypes

    with contextlib.suppress(AttributeError, OSError):
        ctypes.pythonapi.PyRun_SimpleString(b"")


def _dispatch(argv: Sequence[str] | None) -> int:
    """Parse ``argv`` and run its command; bad input is one line and status 2."""
    parser, modules = _parser()
    arguments = list(sys.argv[1:] if argv is None else argv)
    if not arguments or (arguments[0].startswith("-") and arguments[0] not in ("-h", "--help")):
        arguments = ["run", *arguments]  # no command: the paper reproduction (`otmm-qp --force`)
    normalise = getattr(modules.get(arguments[0]), "normalise", None)
    if normalise is not None:  # e.g. `study FILE` is `study run FILE`
        arguments = [arguments[0], *normalise(arguments[1:])]
    try:
        args = parser.parse_args(arguments)
    except SystemExit as stop:  # --help, or a bad argument (already said in one line)
        return int(stop.code or 0)
    try:
        return int(modules[args.command or "run"].run(args))
    except OtmmError as error:
        print("\n".join(error_lines(error)), file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        # e.g. `otmm-qp list | head -1`: the reader left; silence the flush at exit.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())

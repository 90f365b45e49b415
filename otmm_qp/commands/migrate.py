"""``otmm-qp migrate FILE [-o OUT] [--from N]``: rewrite an older run or study file.

Reads ``FILE`` with the hardened reader, rewrites it into the current schema value by value
(:func:`otmm_qp.migration.versions.migrate`: qp's ``damping: μ`` of schema 1 becomes
``regularization: μ``, a pose_circle without ``profile`` gets ``profile: constant``, older limit
keys become one ``limits`` list, …) in the schema its keys say
(:func:`otmm_qp.migration.versions.read_schema`: never guessed from a plugin type otmm-qp does
not ship; an ambiguous file is refused, naming ``--from N``), prints the schema it read the file
in and one line per key changed, and writes the result (``version:`` first) to ``OUT``, or to
stdout without ``-o``. The result is validated before it is written. Comments are not kept.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from otmm_qp.migration.changes import CURRENT_VERSION, RELEASES

NAME = "migrate"
HELP = "rewrite a run or study file of an older schema into the current one (value by value)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``FILE``, ``-o OUT``, ``--from N``."""
    parser.add_argument("file", type=Path, help="the run or study YAML file to migrate")
    parser.add_argument(
        "-o", "--out", type=Path, default=None, help="write here (default: print to stdout)"
    )
    parser.add_argument(
        "--from",
        dest="from_version",
        type=int,
        default=None,
        metavar="N",
        help="the schema the file is written in when it states no version "
        f"(1: {RELEASES[1]}; default: the one its keys say, else 1, as run reads it)",
    )


def run(args: argparse.Namespace) -> int:
    """Migrate, report, check and write; bad input raises OtmmError (exit 2 in the CLI)."""
    from otmm_qp.config.current_schema import CURRENT_SCHEMA
    from otmm_qp.config.emit import dump_config, write_config
    from otmm_qp.config.load import parse
    from otmm_qp.config.schema import SuiteConfig
    from otmm_qp.config.yaml_loader import load_yaml
    from otmm_qp.exceptions import ConfigError
    from otmm_qp.migration.versions import migrate

    if args.from_version is not None and not 1 <= args.from_version <= CURRENT_VERSION:
        raise ConfigError("--from", f"must be in [1, {CURRENT_VERSION}], got {args.from_version}")
    source = str(args.file)
    if not args.file.is_file():
        raise ConfigError(source, "no such file")
    if args.out is not None:
        _check_out(args.out)
    migration = migrate(load_yaml(args.file), source, args.from_version, current=CURRENT_SCHEMA)
    if "generators" in migration.data:
        from otmm_qp.studies.spec import parse_study

        parse_study(migration.data, f"{source} (migrated)")
    else:
        parse(SuiteConfig, migration.data, f"{source} (migrated)")
    if args.out is not None:
        try:
            write_config(args.out, migration.data)
        except OSError as error:
            raise ConfigError("-o", f"cannot write {args.out}: {error.strerror}") from None
    report = sys.stderr if args.out is None else sys.stdout
    print(
        f"otmm-qp: {source}: read as schema {migration.source_version} "
        f"({RELEASES[migration.source_version]}; {migration.reason}), written as schema "
        f"{CURRENT_VERSION}",
        file=report,
    )
    for line in migration.changes or ["no value changed; version added"]:
        print(f"  {line}", file=report)
    if args.out is None:
        sys.stdout.write(dump_config(migration.data))
    else:
        print(f"  written: {args.out}", file=report)
    return 0


def _check_out(out: Path) -> None:
    """Refuse an ``-o`` that is a folder or lies in a folder that does not exist.

    Raises:
        ConfigError: Naming ``-o`` and the path.
    """
    from otmm_qp.exceptions import ConfigError

    if out.is_dir():
        raise ConfigError("-o", f"{out} is a folder; name the file to write")
    if not out.parent.is_dir():
        raise ConfigError("-o", f"folder {out.parent} does not exist")

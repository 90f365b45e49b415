"""``otmm-qp list``: every registered plugin, by group; ``--params``: what each one accepts.

The default listing reads only the entry points (no plugin is imported, so it stays fast).
``--params`` loads the plugins and prints, under each, its parameters with their defaults and
declared constraints (:func:`otmm_qp.validation.parameters`); a third-party plugin that declares
none lists its signature with ``not declared``. Parameters whose meaning changed between schema
versions follow (what they mean now and meant before, :mod:`otmm_qp.migration.changes`), then
renamed or removed parameters, marked
``(refused)`` with what to write instead. ``--params NAME ...`` restricts it to the plugins of
those names. The plant presets follow (``plant: {preset: NAME}``, :mod:`otmm_qp.plants.presets`),
each with its stages; ``--params`` adds every stage's values (``--params NAME`` a preset's).
"""

from __future__ import annotations

import argparse

from otmm_qp import registry
from otmm_qp.exceptions import OtmmError
from otmm_qp.migration.changes import CHANGES
from otmm_qp.plants.presets import PRESETS, preset_lines
from otmm_qp.validation import parameters

NAME = "list"
HELP = "list registered robots, filters, p-functions, backends, trajectories, ..."

#: Parameters the framework passes itself, hidden from the listing, by group.
RESERVED = {registry.P_FUNCTIONS: ("s", "sigma_s")}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--params [NAME ...]``."""
    parser.add_argument(
        "--params",
        nargs="*",
        metavar="NAME",
        default=None,
        help="also show each plugin's parameters, defaults and allowed values "
        "(only the named plugins when names are given)",
    )


def reserved_parameters(group: str, plugin: object) -> tuple[str, ...]:
    """Parameters the framework passes ``plugin`` itself (a trajectory's ``start``, ...)."""
    return (*RESERVED.get(group, ()), *getattr(plugin, "framework_parameters", ()))


def parameter_lines(group: str, name: str) -> list[str]:
    """The indented ``name = default: allowed`` lines of one plugin (or why it cannot load)."""
    try:
        plugin = registry.load(group, name)
    except OtmmError as error:
        return [f"      (cannot be loaded: {error})"]
    rows = parameters(plugin, reserved_parameters(group, plugin))
    lines = [f"      {row.name} = {row.default}: {row.allowed}" for row in rows]
    lines += [
        f"      {change.key} (meaning changed in schema {change.version}): now {change.now}; "
        f"in schema {change.version - 1} it was {change.was}"
        for change in CHANGES
        if change.kind == "value"
        and change.group == group.rsplit(".", 1)[-1]
        and name in change.types
    ]
    removed = getattr(plugin, "removed_parameters", None) or {}
    lines += [f"      {name} (refused): {why}" for name, why in removed.items()]
    return lines or ["      (no parameters)"]


def run(args: argparse.Namespace) -> int:
    """Print every registered plugin, by group (with ``--params``, their parameters).

    Raises:
        OtmmError: A name given to ``--params`` that no plugin is registered under.
    """
    wanted: list[str] | None = args.params
    if wanted:
        known = {name for group in registry.GROUPS for name in registry.specs(group)}
        known |= set(PRESETS)
        unknown = [name for name in wanted if name not in known]
        if unknown:
            raise OtmmError(
                f"--params: no plugin named {', '.join(map(repr, unknown))}; "
                "`otmm-qp list` shows the registered names"
            )
    for group in registry.GROUPS:
        lines = []
        for name, spec in registry.specs(group).items():
            if wanted and name not in wanted:
                continue
            lines.append(f"  {name:<24} {spec.value}  [{spec.distribution}]")
            if wanted is not None:
                lines += parameter_lines(group, name)
        if lines or not wanted:  # named plugins: only the groups that hold them
            print(f"{group.rsplit('.', 1)[-1]}:")
            for line in lines:
                print(line)
    presets = preset_lines(wanted is not None, wanted or None)
    if presets or not wanted:
        print("plant presets (plant: {preset: NAME}):")
        for line in presets:
            print(line)
    return 0

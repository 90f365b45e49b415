"""Names of a study's tasks: the generator entry's label, its seed name and ``task_id``.

``task_id = f"{robot}/{label}/{task_index}"`` (the study contract), where ``label`` is the
entry's ``name`` if it has one, else ``f"{type}#{position}"``. Task seeds are drawn from the
entry's *seed name*: its ``name``, else its ``type`` for the first entry of that type (so a
study with one entry per type keeps its tasks), else ``f"{type}#{position}"``. Two entries
therefore never share seeds; names that would collide are refused.
"""

from __future__ import annotations

from otmm_qp.exceptions import ConfigError
from otmm_qp.studies.schema import StudyConfig


def entry_label(config: StudyConfig, generator: int) -> str:
    """Label of generator entry ``generator`` in ``task_id``."""
    gen = config.generators[generator]
    return gen.name if gen.name is not None else f"{gen.type}#{generator}"


def seed_name(config: StudyConfig, generator: int) -> str:
    """Name the tasks of entry ``generator`` are seeded from (see the module docstring)."""
    gen = config.generators[generator]
    if gen.name is not None:
        return gen.name
    first = next(i for i, g in enumerate(config.generators) if g.type == gen.type)
    return gen.type if first == generator else f"{gen.type}#{generator}"


def task_id(config: StudyConfig, robot: int, generator: int, index: int) -> str:
    """``robot/label/index`` of one task."""
    return f"{config.robots[robot].name}/{entry_label(config, generator)}/{index}"


def check_entries(config: StudyConfig, source: str = "study") -> None:
    """Refuse generator entries whose labels or seed names collide.

    Raises:
        ConfigError: One line naming both entries.
    """
    for kind, names in (
        ("label", [entry_label(config, j) for j in range(len(config.generators))]),
        ("seed name", [seed_name(config, j) for j in range(len(config.generators))]),
    ):
        seen: dict[str, int] = {}
        for j, name in enumerate(names):
            if name in seen:
                raise ConfigError(
                    f"{source}: generators.{j}.name",
                    f"{kind} {name!r} is also that of generators.{seen[name]}; "
                    "give each entry a distinct name",
                )
            seen[name] = j

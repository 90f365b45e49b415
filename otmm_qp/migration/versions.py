r"""Schema versions of config files: refuse a changed meaning, migrate an older file.

Every run and study file may state ``version: N`` (the schema it is written in; see
:mod:`otmm_qp.migration.changes` for what each version changed). When a file is read
(:func:`check_schema`, called by :func:`otmm_qp.config.load.parse` on the parsed YAML):

- ``version`` must be an integer in ``[1, CURRENT_VERSION]``;
- a key that no longer exists (a *name* change: ``limit_gain``, ``damping_floor``, …) is
  refused in every file;
- a key whose meaning or default changed (a *value* change: qp's ``damping``, pose_circle
  without ``profile``) is refused where the file does not state a version at least the
  change's: a file without ``version`` could be of any schema from the first one its kind
  existed in (run files: 1, study files: 2, studies came in 0.2);
- all of them at once: a first line naming the file and the command that fixes it, then one
  line per key with the file's own value, what it meant, what it means now and what to write.

:func:`migrate` rewrites an older file into the current schema value by value (the
converters of the table) and says what it changed. Both read the file in the schema
:func:`read_schema` gives: its ``version``, else the one given (``--from``), else the one its
keys say — a key that exists in only one schema (:func:`schema_evidence`), never a plugin type
otmm-qp does not ship — else the oldest; keys of both schemas where a key's meaning depends on
which is refused, naming ``--from``. So every key ``run`` refuses is one ``migrate`` rewrites.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from typing import Any, NamedTuple

from otmm_qp.exceptions import ConfigError, shown
from otmm_qp.migration.changes import CHANGES, CURRENT_VERSION, RELEASES, Block, SchemaChange
from otmm_qp.migration.evidence import CurrentSchema, block_evidence, record_evidence

__all__ = [
    "CURRENT_VERSION",
    "Migration",
    "check_schema",
    "file_version",
    "gone_keys",
    "read_schema",
    "schema_evidence",
    "migrate",
    "plugin_blocks",
    "versioned",
]

#: The config key stating the schema version.
VERSION_KEY = "version"

#: Keys holding plugin blocks ``{type: NAME, ...}`` (or lists of them) → the registry group.
_BLOCK_KEYS = {
    "robot": "robots",
    "trajectory": "trajectories",
    "filters": "filters",
    "backend": "backends",
    "conditioning": "conditioning",
    "plant": "plants",
    "generators": "task_generators",
}
#: Keys holding lists of records that hold blocks.
_RECORD_LISTS = ("experiments", "controllers", "robots", "plants")

#: What a schema-1 (otmm-qp 0.1.0) run file could say: keys by record, parameters by plugin.
_SCHEMA_1_KEYS = {
    "file": {"name", "description", "dt", "loop_modes", "clik_gain", "metrics", "claims"}
    | {"experiments"},
    "experiments": {"name", "description", "robot", "q0", "trajectory", "controllers"}
    | {"duration", "dt", "loop_modes", "clik_gain", "task_weight"},
    "controllers": {"name", "filters", "backend"},
}
_SCHEMA_1_PLUGINS: dict[str, dict[str, set[str]]] = {
    "robots": {
        "planar": {"link_lengths", "limits", "velocity_limits"},
        "pinocchio": {"name", "urdf", "package_dirs", "frame", "task", "position_limits"}
        | {"velocity_limits", "locked_joints"},
    },
    "filters": {
        "identity": set(),
        "otmm": {"sigma_s", "p", "p_params", "corank"},
        "servo_scaling": {"lower_threshold", "hard_stop_threshold", "leaving_factor"}
        | {"lookahead"},
    },
    "backends": {
        "pinv": {"rcond"},
        "dls": {"damping"},
        "dls_adaptive": {"alpha", "w0", "sigma_threshold"},
        "dls_sigma": {"lambda_max", "epsilon"},
        "sdls": {"gamma_max", "rcond"},
        "pink": {"solver", "damping", "lm_damping", "limits"},
        "mink": {"solver", "damping", "lm_damping", "limits"},
        "drake": {"stuck_scaling"},
        "qp": {"damping", "solver", "limit_gain", "acceleration_limit", "posture_weight"}
        | {"posture_gain", "q_nominal", "infeasible_policy", "fast_path"},
        "qp_scaled": {"solver", "limit_gain", "acceleration_limit", "stuck_threshold"}
        | {"regularization", "infeasible_policy"},
    },
    "trajectories": {
        "circle": {"centre", "radius", "period", "direction", "start_angle", "normal", "turns"},
        "quintic_line": {"end", "duration", "begin"},
        "constant_velocity_line": {"end", "duration", "begin"},
        "pose_line": {"duration", "end", "end_rpy", "end_quaternion", "profile"},
        "pose_circle": {"centre", "radius", "period", "direction", "start_angle", "normal"}
        | {"turns", "end_rpy", "end_quaternion"},
    },
}


class Found(NamedTuple):
    """One plugin block of a file: where it is, its registry group, the block."""

    path: str
    group: str
    block: Block


def _blocks(value: Any, path: str, group: str) -> Iterator[Found]:
    if isinstance(value, dict) and "type" in value:
        yield Found(path, group, value)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _blocks(item, f"{path}.{i}", group)


def plugin_blocks(data: Any, path: str = "") -> Iterator[Found]:
    """Every plugin block ``{type: NAME, ...}`` of a parsed run or study file, in file order."""
    if not isinstance(data, dict):
        return
    for key, value in data.items():
        where = f"{path}.{key}" if path else str(key)
        if key in _BLOCK_KEYS:
            yield from _blocks(value, where, _BLOCK_KEYS[key])
        elif key in _RECORD_LISTS and isinstance(value, list):
            for i, item in enumerate(value):
                yield from plugin_blocks(item, f"{where}.{i}")


def file_version(data: Mapping[str, Any], source: str) -> int | None:
    """The file's ``version`` (None when it states none).

    Raises:
        ConfigError: Not an integer in ``[1, CURRENT_VERSION]``.
    """
    if VERSION_KEY not in data:
        return None
    value = data[VERSION_KEY]
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= CURRENT_VERSION:
        raise ConfigError(
            f"{source}: {VERSION_KEY}",
            f"must be an integer in [1, {CURRENT_VERSION}] (the schema the file is written "
            f"in; {CURRENT_VERSION} is {RELEASES[CURRENT_VERSION]}'s), got {shown(value)}",
        )
    return value


#: Longest composite value (a ``limits`` list to write) shown in full [characters].
FLOW_LIMIT = 240


def _flow(value: Any, limit: int = 80) -> str:
    """A value as YAML flow text, cut to ``limit`` characters (each entry to 40).

    A mapping or list is cut at :data:`FLOW_LIMIT` instead, so a ``limits`` list to write is
    shown whole at any ordinary size.
    """
    if isinstance(value, Mapping):
        text = "{" + ", ".join(f"{k}: {_flow(v, 40)}" for k, v in value.items()) + "}"
        limit = max(limit, FLOW_LIMIT)
    elif isinstance(value, list):
        text = "[" + ", ".join(_flow(v, FLOW_LIMIT) for v in value) + "]"
        limit = max(limit, FLOW_LIMIT)
    elif isinstance(value, str):
        text = value
    else:
        text = json.dumps(value) if isinstance(value, bool) or value is None else repr(value)
    return shown(text, limit, quote=False)


def _written(change: SchemaChange, block: Block) -> str:
    """What to write instead: the keys the converter changes, with the block's values."""
    after = change.convert(dict(block))
    changed = [k for k in after if k not in block or after[k] != block[k]]
    text = ", ".join(f"{key}: {_flow(after[key])}" for key in changed) or "nothing"
    if change.also is not None:
        text += f" or {change.also(block)}"
    return text


def _explained(change: SchemaChange, block: Block) -> str:
    """What happened to the key and what to write, with the block's own values (no path)."""
    since = f"schema {change.version} ({RELEASES[change.version]})"
    written = _written(change, block)
    if change.kind == "name":
        return f"{change.now} since {since}: write {written}"
    value = _flow(block[change.key]) if change.key in block else "(absent)"
    before = f"schema {change.version - 1} ({RELEASES[change.version - 1]})"
    return (
        f"{value} meant {change.was} in {before}; since {since} it means {change.now}: "
        f"write {written}"
    )


def gone_keys(group: str, block: Block) -> dict[str, str]:
    """The keys of ``block`` that no longer exist, each with what to write (its own values).

    Args:
        group: The block's registry group, last part (``backends``).
        block: ``{type: NAME, **params}``.

    Returns:
        ``{key: "renamed to … since schema 2 (…): write …"}`` for the name changes.
    """
    return {
        change.key: _explained(change, block)
        for change in CHANGES
        if change.kind == "name" and change.concerns(group, block)
    }


def _pending(data: Any, version: int) -> list[tuple[SchemaChange, Found]]:
    """The changes concerning the file's blocks: every name change, value changes > version."""
    pending = []
    for found in plugin_blocks(data):
        for change in CHANGES:
            later = change.kind == "name" or change.version > version
            if later and change.concerns(found.group, found.block):
                pending.append((change, found))
    return pending


class Reading(NamedTuple):
    """The schema a file is read in, and why.

    Attributes:
        version: The schema.
        reason: Why (its ``version``, ``--from``, a key that exists only in that schema, …).
        told: Whether something in the file or the command says so (False: nothing does, and
            the file is read in the oldest schema its kind can be in, as ``run`` refuses it).
    """

    version: int
    reason: str
    told: bool


#: :data:`_SCHEMA_1_KEYS` as frozen sets, by record level.
_SCHEMA_1 = {level: frozenset(keys) for level, keys in _SCHEMA_1_KEYS.items()}


def schema_evidence(data: Mapping[str, Any], current: CurrentSchema) -> dict[int, list[str]]:
    """The keys of a run file that exist in only one schema: ``{1: [...], 2: [...]}``.

    Record keys and the keys of every plugin block otmm-qp ships
    (:mod:`otmm_qp.migration.evidence`, ``current`` saying what the current schema has); a
    plugin type it does not ship says nothing.
    """
    found: dict[int, list[str]] = {1: [], 2: []}

    def add(more: dict[int, list[str]]) -> None:
        for version, paths in more.items():
            found[version] += paths

    add(record_evidence(current, "file", data, "", _SCHEMA_1["file"]))
    for i, experiment in enumerate(data.get("experiments") or []):
        if not isinstance(experiment, Mapping):
            continue
        where = f"experiments.{i}"
        add(record_evidence(current, "experiments", experiment, where, _SCHEMA_1["experiments"]))
        for j, controller in enumerate(experiment.get("controllers") or []):
            if isinstance(controller, Mapping):
                at = f"{where}.controllers.{j}"
                add(
                    record_evidence(
                        current, "controllers", controller, at, _SCHEMA_1["controllers"]
                    )
                )
    for block in plugin_blocks(data):
        plugins = _SCHEMA_1_PLUGINS.get(block.group, {})
        add(block_evidence(current, block.group, block.block, block.path, plugins))
    return found


def _meaning_changed(data: Any, version: int) -> list[tuple[SchemaChange, Found]]:
    """The value changes after ``version`` concerning the file's blocks."""
    return [(change, found) for change, found in _pending(data, version) if change.kind == "value"]


def read_schema(
    data: Mapping[str, Any],
    source: str,
    first_version: int = 1,
    from_version: int | None = None,
    *,
    current: CurrentSchema,
) -> Reading:
    """The schema to read a file in: its ``version``, else ``from_version``, else inferred.

    Inferred from the keys that exist in only one schema (:func:`schema_evidence`), never
    from a plugin type otmm-qp does not ship; with none, the oldest schema the file's kind
    can be in (``first_version``: run files 1, study files 2), which is how ``run`` reads
    a key whose meaning changed. Keys of both schemas in a file where a key's meaning depends
    on which is ambiguous and refused, naming ``--from``; where no key's meaning depends on
    it, the file is the same in either.

    Raises:
        ConfigError: An invalid ``version``, ``from_version`` contradicting it, or an
            ambiguous file (naming ``otmm-qp migrate FILE --from N``).
    """
    stated = file_version(data, source)
    if stated is not None and from_version is not None and stated != from_version:
        raise ConfigError(
            f"{source}: {VERSION_KEY}", f"the file says {stated}, --from says {from_version}"
        )
    if stated is not None:
        return Reading(stated, "its version", True)
    if from_version is not None:
        return Reading(from_version, "--from", True)
    if first_version >= CURRENT_VERSION or "generators" in data:
        return Reading(CURRENT_VERSION, "a study file (studies came in schema 2)", True)
    found = schema_evidence(data, current)
    old, new = found[1], found[2]
    if old and new:
        if not _meaning_changed(data, first_version):
            same = "no key whose meaning changed: the file is the same in schema 1 and 2"
            return Reading(CURRENT_VERSION, same, True)
        raise ConfigError(
            source,
            f"cannot tell its schema (it has keys of schema 1 and of 2, and one whose meaning "
            f"depends on which); fix: otmm-qp migrate {source} --from 1 (or --from 2)",
            [f"only in schema 1: {', '.join(old)}", f"only in schema 2: {', '.join(new)}"],
        )
    if new:
        return Reading(2, f"{new[0]} exists only in schema 2", True)
    if old:
        return Reading(1, f"{old[0]} exists only in schema 1", True)
    return Reading(
        first_version,
        "no key tells its schema, so the oldest, as run reads it (--from 2 if written for 0.2)",
        False,
    )


def check_schema(data: Any, source: str, first_version: int = 1, *, current: CurrentSchema) -> None:
    """Refuse a file with a key that is gone or whose meaning changed since its version.

    The file is read as :func:`read_schema` reads it, as ``otmm-qp migrate`` does: the keys
    listed are the ones ``migrate`` rewrites. A file that states no version but whose keys say
    schema 2 is still refused when one of its keys changed meaning: it must say so
    (``version: 2``); nothing runs on an inference.

    Args:
        data: The parsed YAML (anything: only mappings are inspected).
        source: The file name, for the message.
        first_version: The oldest schema a file of this kind can be in when it states none
            (run files 1, study files 2).
        current: What the current schema has
            (:data:`otmm_qp.config.current_schema.CURRENT_SCHEMA`).

    Raises:
        ConfigError: A first line naming the file and the command that fixes it, then one
            line saying which schema it was read in and one per key with its own value, what
            it meant, what it means now and what to write.
    """
    if not isinstance(data, dict):
        return
    stated = file_version(data, source)
    if stated is not None and stated < first_version:
        raise ConfigError(
            f"{source}: {VERSION_KEY}",
            f"this kind of file starts at schema {first_version} "
            f"({RELEASES[first_version]}), got {stated}",
        )
    if not _pending(data, first_version if stated is None else stated):
        return  # nothing changed for any schema the file can be in
    reading = read_schema(data, source, first_version, current=current)
    pending = _pending(data, reading.version)
    kept = [] if stated is not None else _meaning_changed(data, first_version)
    kept = [item for item in kept if item not in pending]
    if not pending and not kept:
        return
    name = source  # whole (the CLI's one_line cuts a very long one)
    details = [f"read as schema {reading.version} ({RELEASES[reading.version]}): {reading.reason}"]
    details += [
        f"{found.path}.{change.key}: {_explained(change, found.block)}" for change, found in pending
    ]
    details += [
        f"{found.path}.{change.key}: {_flow(found.block.get(change.key, '(absent)'))} means "
        f"{change.now} (in schema {change.version - 1} it meant {change.was}: if so, "
        f"otmm-qp migrate {name} --from {change.version - 1})"
        for change, found in kept
    ]
    if pending:
        if not reading.told and any(change.kind == "value" for change, _ in pending):
            details.append(
                f"written for {RELEASES[CURRENT_VERSION]}? add version: {CURRENT_VERSION} "
                "to keep today's meaning instead"
            )
        message = f"{len(pending)} key(s) from an older schema; fix: otmm-qp migrate {name}"
    else:
        message = (
            f"states no version and {len(kept)} key(s) changed meaning; fix: add version: "
            f"{CURRENT_VERSION} (or otmm-qp migrate {name})"
        )
    raise ConfigError(name, message, details)


class Migration(NamedTuple):
    """A file rewritten into the current schema.

    Attributes:
        data: The rewritten file (``version: CURRENT_VERSION`` first).
        source_version: The schema it was read in.
        reason: Why that schema (stated, given or inferred).
        changes: One line per key changed, ``PATH: old → new``.
    """

    data: dict[str, Any]
    source_version: int
    reason: str
    changes: list[str]


def _migrate_block(block: Block, group: str, version: int) -> tuple[Block, list[SchemaChange]]:
    applied = []
    for change in CHANGES:
        later = change.kind == "name" or change.version > version
        if later and change.concerns(group, block):
            block = change.convert(block)
            applied.append(change)
    return block, applied


def _rewrite(value: Any, group: str, version: int, path: str, log: list[str]) -> Any:
    """A block (or list of blocks) with every pending change converted, logged."""
    if isinstance(value, list):
        return [_rewrite(item, group, version, f"{path}.{i}", log) for i, item in enumerate(value)]
    if not (isinstance(value, dict) and "type" in value):
        return value
    new, applied = _migrate_block(dict(value), group, version)
    if applied:
        before = {k: value[k] for k in value if k not in new or new[k] != value[k]}
        after = {k: new[k] for k in new if k not in value or new[k] != value[k]}
        old_text = ", ".join(f"{k}: {_flow(v)}" for k, v in before.items())
        absent = ", ".join(f"{k} (absent)" for k in after if k not in value)
        new_text = ", ".join(f"{k}: {_flow(v)}" for k, v in after.items())
        log.append(f"{path}: {', '.join(filter(None, (old_text, absent)))} → {new_text}")
    return new


def _walk(data: Any, version: int, path: str, log: list[str]) -> Any:
    if not isinstance(data, dict):
        return data
    out: dict[str, Any] = {}
    for key, value in data.items():
        where = f"{path}.{key}" if path else str(key)
        if key in _BLOCK_KEYS:
            out[key] = _rewrite(value, _BLOCK_KEYS[key], version, where, log)
        elif key in _RECORD_LISTS and isinstance(value, list):
            out[key] = [_walk(item, version, f"{where}.{i}", log) for i, item in enumerate(value)]
        else:
            out[key] = value
    return out


def migrate(
    data: Any, source: str, from_version: int | None = None, *, current: CurrentSchema
) -> Migration:
    """Rewrite a parsed run or study file into the current schema, value by value.

    Args:
        data: The parsed YAML.
        source: The file name, for messages.
        from_version: The schema to read it in when it states none (None: inferred).
        current: What the current schema has
            (:data:`otmm_qp.config.current_schema.CURRENT_SCHEMA`).

    Raises:
        ConfigError: Not a mapping, an invalid ``version``, or ``from_version`` contradicting
            the file's own ``version``.
    """
    if not isinstance(data, dict):
        raise ConfigError(source, f"top level must be a mapping, got {type(data).__name__}")
    version, reason, _ = read_schema(data, source, from_version=from_version, current=current)
    log: list[str] = []
    body = _walk({k: v for k, v in data.items() if k != VERSION_KEY}, version, "", log)
    return Migration(versioned(body), version, reason, log)


def versioned(record: Mapping[str, Any]) -> dict[str, Any]:
    """``record`` with ``version: CURRENT_VERSION`` first: how every emitted config is written."""
    return {VERSION_KEY: CURRENT_VERSION, **{k: v for k, v in record.items() if k != VERSION_KEY}}

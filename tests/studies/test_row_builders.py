"""Issue 39: a study row is composed of the column groups of ``studies/columns.py`` only.

Work units carry typed planned episodes (the reference is a kind, not a ``-1`` index), and the
reader judges a study once into one frame whose table and rows agree with the former
Arrow → dicts → Arrow → dicts path.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path
from typing import Any

import pyarrow as pa
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.studies.columns import (
    DERIVED_COLUMNS,
    EPISODE_COLUMNS,
    TASK_PREFIX,
    episode_row,
    failed_reference_columns,
    identity_columns,
    judged_columns,
    metric_columns,
    outcome_columns,
    task_reference,
)
from otmm_qp.studies.criteria import failure_causes
from otmm_qp.studies.episodes import run_chunk
from otmm_qp.studies.execute import make_chunks, payload_of
from otmm_qp.studies.keys import episode_id
from otmm_qp.studies.rows import is_reference, join_reference, kept_limits, read, relative_error
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import read_study_folder
from otmm_qp.studies.task import CONTROLLER, OFFLINE, REFERENCE, PlannedEpisode, StudyTask
from tests.studies.conftest import SMALL

STUDIES = Path(__file__).resolve().parents[2] / "otmm_qp" / "studies"
#: Every stored or judged column name.
COLUMN_NAMES = frozenset(c.name for c in (*EPISODE_COLUMNS, *DERIVED_COLUMNS))
#: Records in ``studies/`` keyed by column-like names that are not episode rows:
#: ``(module, sorted keys)`` → what the record is. An entry no longer in the code fails too.
NOT_ROWS: dict[tuple[str, tuple[str, ...]], str] = {
    ("drilldown.py", ("generator", "robot")): "the run config `study show` writes",
    ("drilldown.py", ("duration", "robot")): "the run config `study show` writes",
    ("drilldown.py", ("dt",)): "the run config `study show` writes",
    ("execute.py", ("study",)): "the study.json marker",
    ("spec.py", ("backend", "filters")): "a controller record (episode keys)",
    ("spec.py", ("plant",)): "a controller record (episode keys)",
    (
        "spec.py",
        ("controller", "dt", "duration", "generator", "loop_mode", "robot", "task_index"),
    ): "the record an episode key hashes",
    (
        "spec.py",
        ("controller", "dt", "duration", "generator", "robot", "success", "task_index"),
    ): "the record a reference episode key hashes",
    ("verdicts.py", ("robot",)): "a verdict group's label",
}


def row_sites(source: str) -> list[tuple[int, tuple[str, ...]]]:
    """``(line, column names)`` of each place ``source`` sets episode columns by name.

    A dict display with a column-name key, a subscript store ``x["column"] = ...``, and
    ``x.update(column=...)``, ``dict(column=...)`` or ``x.setdefault("column", ...)``.
    """
    sites: list[tuple[int, tuple[str, ...]]] = []

    def named(values: list[Any]) -> tuple[str, ...]:
        return tuple(sorted({v for v in values if v in COLUMN_NAMES}))

    for node in ast.walk(ast.parse(source)):
        found: tuple[str, ...] = ()
        if isinstance(node, ast.Dict):
            found = named([k.value for k in node.keys if isinstance(k, ast.Constant)])
        elif isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            found = named(
                [
                    t.slice.value
                    for t in targets
                    if isinstance(t, ast.Subscript) and isinstance(t.slice, ast.Constant)
                ]
            )
        elif isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name in ("update", "dict", "setdefault"):
                keys = [k.arg for k in node.keywords]
                if name == "setdefault" and node.args and isinstance(node.args[0], ast.Constant):
                    keys.append(node.args[0].value)
                found = named(keys)
        if found:
            sites.append((node.lineno, found))
    return sorted(sites)


def test_the_detector_finds_every_way_a_row_is_filled() -> None:
    planted = (
        "row = {'study': s}\n"
        "row['success'] = True\n"
        "row.update(status='ok')\n"
        "row.setdefault('reference.max_error', 1.0)\n"
        "other = {'t': 1, 'name': 2}\n"
        "row['not_a_column'] = 1\n"
    )
    assert row_sites(planted) == [
        (1, ("study",)),
        (2, ("success",)),
        (3, ("status",)),
        (4, ("reference.max_error",)),
    ]


def test_no_study_row_is_built_outside_the_column_builders() -> None:
    seen: set[tuple[str, tuple[str, ...]]] = set()
    outside = []
    for path in sorted(STUDIES.rglob("*.py")):
        if path.name == "columns.py":
            continue
        module = str(path.relative_to(STUDIES))
        for line, names in row_sites(path.read_text(encoding="utf-8")):
            if (module, names) in NOT_ROWS:
                seen.add((module, names))
            else:
                outside.append(f"{module}:{line} sets {', '.join(names)}")
    assert not outside, "episode columns set outside studies/columns.py:\n" + "\n".join(outside)
    assert seen == set(NOT_ROWS), f"stale allow-list entries: {set(NOT_ROWS) - seen}"


def test_episode_row_refuses_undeclared_and_doubly_set_columns() -> None:
    assert episode_row({"status": "ok"}, {f"{TASK_PREFIX}x": 1.0}) == {
        "status": "ok",
        "task.x": 1.0,
    }
    with pytest.raises(ValueError, match="'statuss' is not a declared episode column"):
        episode_row({"statuss": "ok"})
    with pytest.raises(ValueError, match="'status' is set by two column groups"):
        episode_row(outcome_columns("ok", None), outcome_columns("error", "boom"))
    with pytest.raises(ValueError, match="'failure_causes' is not a declared"):
        episode_row(judged_columns((), True, 0.0))  # judged on read, never stored


def test_groups_hold_only_their_declared_group() -> None:
    config = parse_study(SMALL)
    groups = {c.name: c.group for c in EPISODE_COLUMNS}
    identity = identity_columns(config, StudyTask(0, 1, 0, 7), "ab" * 32)
    assert {groups[n] for n in identity} == {"identity"}
    assert identity["episode_id"] == episode_id("ab" * 32) == "ab" * 5
    assert identity["generator"] == "beyond_reach" and identity["task_seed"] == 7
    metrics = metric_columns({"max_error": 0.5}, {"max_speed_ratio": 1.0, "max_jump_ratio": 2.0})
    assert {groups[n] for n in metrics} == {"metric"}
    assert metrics["max_error"] == 0.5 and metrics["final_error"] is None
    failed = failed_reference_columns()
    assert {groups[n] for n in failed} == {"reference"}
    assert failed["reference.status"] == "failed" and math.isnan(failed["reference.upper"])


def _task(robot: int = 0) -> StudyTask:
    return StudyTask(robot, 0, 3, 11)


@pytest.mark.parametrize(
    ("kind", "mode", "controller", "message"),
    [
        (REFERENCE, OFFLINE, 0, "no controller index"),
        (REFERENCE, "clik", None, "loop mode 'offline'"),
        (CONTROLLER, "clik", None, "controller index >= 0"),
        (CONTROLLER, "clik", -1, "controller index >= 0"),
        ("oracle", OFFLINE, None, "kind: 'oracle'"),
    ],
)
def test_a_planned_episode_refuses_a_mixed_kind(
    kind: Any, mode: str, controller: int | None, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        PlannedEpisode("k", _task(), kind, mode, controller)


def test_plan_episodes_are_typed_and_the_units_carry_them() -> None:
    plan = plan_study(parse_study(SMALL))
    references = [e for e in plan.episodes if e.is_reference]
    assert len(references) == 3 and all(e.controller is None for e in references)
    assert all(e.loop_mode == OFFLINE for e in references)
    assert {e.controller for e in plan.episodes if not e.is_reference} == {0, 1}
    done = {plan.episodes[1].key}  # one controller episode stored already
    units = [u for chunk in make_chunks(plan, done) for u in chunk]
    carried = [e for u in units for e in u.episodes]
    missing = [e.key for e in plan.episodes if e.key not in done]
    assert sorted(e.key for e in carried) == sorted(missing)
    assert len(carried) == len(plan.episodes) - 1
    assert all(e.task == u.task for u in units for e in u.episodes)
    with pytest.raises(ValueError, match="not of the unit's task"):
        type(units[0])(_task(robot=5), units[0].episodes)


def test_worker_rows_keep_the_reference_first_and_judge_success_with_it() -> None:
    plan = plan_study(parse_study(SMALL))
    config = plan.config
    result = run_chunk(payload_of(plan), make_chunks(plan, set())[0])
    first, *others = result.rows
    assert first["controller"] == "oracle" and first["information"] == OFFLINE
    assert first["status"] == "ok" and first["reference.status"] is not None
    reference = task_reference(first)
    assert reference["reference.final_error"] == first["final_error"]
    for row in others:
        assert set(row) >= {"status", "success", "duration", "information"}
        assert row["success"] is (not failure_causes({**reference, **row}, config.success))


def _former_read(out: Path) -> tuple[pa.Table, list[dict[str, Any]]]:
    """The reader before issue 39: dicts judged, back to Arrow, back to dicts."""
    config, data = read_study_folder(out)
    assert data.table is not None
    rows = data.table.to_pylist()
    join_reference(rows)
    for row in rows:
        if not row.get("episode_id"):
            row["episode_id"] = episode_id(str(row.get("episode_key", "")))
        causes = () if is_reference(row) else failure_causes(row, config.success)
        row["failure_causes"] = list(causes)
        row["success"] = not causes
        row["kept_limits"] = kept_limits(row)
        row["oracle_relative_error"] = relative_error(row)
    schema = data.table.schema
    for column in DERIVED_COLUMNS:
        if schema.get_field_index(column.name) < 0:
            schema = schema.append(pa.field(column.name, column.type))
    table = pa.Table.from_pylist(rows, schema=schema)
    again = table.to_pylist()
    for row in again:
        row["failure_causes"] = tuple(row["failure_causes"])
    return table, again


def _same(a: Any, b: Any) -> bool:
    """Equal, NaN equal to NaN (a float column may hold NaN)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return bool(a == b) and type(a) is type(b)


def test_one_judged_frame_equals_the_former_round_trip(small_study: Path) -> None:
    frame = read(small_study)
    table, rows = _former_read(small_study)
    assert frame.table.schema.equals(table.schema, check_metadata=True)
    assert frame.table.num_rows == table.num_rows == len(frame.rows.rows) == 9
    for name in table.column_names:
        new, old = frame.table.column(name).to_pylist(), table.column(name).to_pylist()
        assert all(_same(a, b) for a, b in zip(new, old, strict=True)), name
    for new_row, old_row in zip(frame.rows.rows, rows, strict=True):
        assert list(new_row) == list(old_row)
        assert all(_same(new_row[k], old_row[k]) for k in old_row), new_row["episode_key"]
    # discriminating: the fixture has failures and a defined oracle-relative error
    assert any(r["failure_causes"] for r in frame.rows.rows)
    assert any(
        r["oracle_relative_error"] is not None and r["oracle_relative_error"] >= 0.0
        for r in frame.rows.rows
        if not is_reference(r)
    )


_STORED = sorted(c.name for c in EPISODE_COLUMNS)


@given(
    names=st.lists(st.sampled_from(_STORED), min_size=1, max_size=12, unique=True),
    cuts=st.lists(st.integers(0, 12), max_size=4),
    seed=st.integers(0, 2**16),
)
def test_composition_is_the_union_of_disjoint_groups(
    names: list[str], cuts: list[int], seed: int
) -> None:
    row = {name: f"{name}-{seed}" for name in names}
    bounds = sorted({0, len(names), *(min(c, len(names)) for c in cuts)})
    groups = [dict(list(row.items())[a:b]) for a, b in zip(bounds, bounds[1:], strict=False)]
    assert episode_row(*groups) == row
    assert episode_row(*reversed(groups)) == row  # the groups' order does not matter
    clash = {names[seed % len(names)]: None}  # one column set again by another group
    with pytest.raises(ValueError, match="set by two column groups"):
        episode_row(*groups, clash)

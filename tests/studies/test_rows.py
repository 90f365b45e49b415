"""The declared episode schema: every part typed alike, read directly by pyarrow and DuckDB.

``otmm_qp.studies.load`` joins the reference and judges success once; old folders (types
inferred per part) are read with one line saying so; parts are read into buffers sized to
them (a 4 GB address-space limit does not break a report).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest

from otmm_qp.metrics.metrics import METRIC_NAMES
from otmm_qp.reference import REFERENCE_COLUMNS
from otmm_qp.studies import load
from otmm_qp.studies.columns import (
    DOC_BEGIN,
    DOC_END,
    EPISODE_COLUMNS,
    SCHEMA_VERSION,
    SCHEMA_VERSION_KEY,
    TASK_PREFIX,
    markdown_reference,
)
from otmm_qp.studies.criteria import RATIO_COLUMNS, failure_causes
from otmm_qp.studies.episodes import run_chunk
from otmm_qp.studies.execute import make_chunks, payload_of
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import (
    EPISODES,
    STUDY_ID_KEY,
    PartWriter,
    study_id,
    write_marker,
)
from tests.studies.conftest import SMALL

ROOT = Path(__file__).resolve().parents[2]
DECLARED = {c.name for c in EPISODE_COLUMNS}


@pytest.fixture(scope="module")
def study(small_study: Path) -> Path:
    return small_study


def _parts(out: Path) -> list[Path]:
    return sorted((out / EPISODES).glob("part-*.parquet"))


def test_every_part_has_the_declared_schema_and_version(study: Path) -> None:
    parts = _parts(study)
    assert len(parts) == 3  # one task per chunk
    schemas = [pq.read_schema(p) for p in parts]
    for schema in schemas:
        assert schema.metadata[SCHEMA_VERSION_KEY] == str(SCHEMA_VERSION).encode()
        for column in EPISODE_COLUMNS:
            assert schema.field(column.name).type == column.type, column.name
        assert not [f.name for f in schema if f.type == pa.null()]
    # the descriptors of both generators are in every part, even a part of one generator
    fields = [{f.name: f.type for f in s.remove_metadata()} for s in schemas]
    assert all(f == fields[0] for f in fields)
    assert {"task.closest_distance", "task.overshoot"} <= set(fields[0])


def test_standard_readers_see_every_row(study: Path) -> None:
    rows = load(study).num_rows
    assert rows == 3 * 3  # pinv, dls and the reference per task
    assert ds.dataset(study / EPISODES).to_table().num_rows == rows
    assert pq.read_table(study / EPISODES).num_rows == rows
    glob = str(study / EPISODES / "*.parquet")
    assert duckdb.sql(f"select count(*) from '{glob}'").fetchall() == [(rows,)]


def test_worker_rows_hold_only_declared_columns() -> None:
    plan = plan_study(parse_study(SMALL))
    result = run_chunk(payload_of(plan), make_chunks(plan, set())[0])
    for row in result.rows:
        undeclared = [k for k in row if k not in DECLARED and not k.startswith(TASK_PREFIX)]
        assert not undeclared
    assert set(METRIC_NAMES) | set(REFERENCE_COLUMNS) | set(RATIO_COLUMNS) <= DECLARED


def test_load_joins_the_reference_and_judges_success_once(study: Path) -> None:
    table = load(study)
    rows = table.to_pylist()
    config = parse_study(SMALL)
    oracle = {r["task_id"]: r for r in rows if r["controller"] == "oracle"}
    for row in rows:
        if row["controller"] == "oracle":
            assert row["failure_causes"] == []
            continue
        reference = oracle[row["task_id"]]
        assert row["reference.status"] == reference["reference.status"]
        assert row["reference.final_error"] == reference["final_error"]
        assert row["oracle_relative_error"] == row["max_error"] - row["reference.max_error"]
        assert row["failure_causes"] == list(failure_causes(row, config.success))
        assert row["success"] is (not row["failure_causes"])


def _row(key: str, message: str | None) -> dict[str, object]:
    return {"study": "mixed", "episode_key": key, "controller": "pinv", "error_message": message}


def test_a_part_with_an_error_and_one_without_read_directly(tmp_path: Path) -> None:
    writer = PartWriter(tmp_path, "abc")
    writer.write([_row("a" * 16, "ValueError: boom")], [])
    writer.write([_row("b" * 16, None)], [])
    assert ds.dataset(tmp_path / EPISODES).to_table().num_rows == 2
    glob = str(tmp_path / EPISODES / "*.parquet")
    assert duckdb.sql(f"select count(error_message) from '{glob}'").fetchall() == [(1,)]


def _old_folder(out: Path) -> None:
    """A study folder as the earlier release wrote it: types inferred per part."""
    plan = plan_study(parse_study(SMALL))
    ident = study_id(plan.config.model_dump(mode="json"))
    write_marker(
        out,
        {
            "study": "small",
            "study_id": ident,
            "config": plan.config.model_dump(mode="json"),
            "episode_keys": [e.key for e in plan.episodes],
        },
    )
    (out / EPISODES).mkdir()
    rows = run_chunk(payload_of(plan), [u for c in make_chunks(plan, set()) for u in c]).rows
    for row in rows:
        row["error_message"] = None
    rows[3]["error_message"] = "RuntimeError: stopped"  # in the second part only
    for n, chunk in enumerate((rows[:2], rows[2:])):
        table = pa.Table.from_pylist(chunk)
        table = table.replace_schema_metadata({STUDY_ID_KEY: ident.encode()})
        pq.write_table(table, out / EPISODES / f"part-old-{n:06d}.parquet")


def test_an_old_folder_is_read_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _old_folder(tmp_path)
    with pytest.raises(pa.ArrowException):  # what a user met before the declared schema
        ds.dataset(tmp_path / EPISODES).to_table()
    table = load(tmp_path)
    assert table.num_rows == 9
    assert table.schema.field("error_message").type == pa.string()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "older episode schema" in lines[0]


def test_the_column_reference_in_the_docs_is_current() -> None:
    text = (ROOT / "docs" / "studies.md").read_text()
    start, end = text.index(DOC_BEGIN) + len(DOC_BEGIN), text.index(DOC_END)
    assert text[start:end].strip() == markdown_reference(), (
        "regenerate with: python -m otmm_qp.studies.columns"
    )


def test_parts_are_read_into_buffers_sized_to_them(study: Path) -> None:
    """Under an address-space limit 1 GiB above the process's size, the study still reads.

    Before, every part was read into a 2 GiB buffer: ``MemoryError``. (One malloc arena, the
    system memory pool and one Arrow thread: the headroom does not depend on the core count.)
    """
    script = textwrap.dedent(
        f"""
        import resource
        from pathlib import Path
        import pyarrow as pa
        pa.set_cpu_count(1)
        pa.set_io_thread_count(1)
        from otmm_qp.studies import load
        from otmm_qp.studies.storage import read_episodes
        size = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status")
                    if l.startswith("VmSize:"))
        resource.setrlimit(resource.RLIMIT_AS, (size + 2**30, size + 2**30))
        print(read_episodes(Path({str(study)!r})).num_rows, load({str(study)!r}).num_rows)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={**os.environ, "MALLOC_ARENA_MAX": "1", "ARROW_DEFAULT_MEMORY_POOL": "system"},
    )
    assert done.returncode == 0, done.stderr[-500:]
    assert done.stdout.split() == ["9", "9"]


def test_a_column_without_values_is_never_stored_untyped(tmp_path: Path) -> None:
    writer = PartWriter(tmp_path, "abc")
    writer.write([{**_row("a" * 16, None), "task.shape": None, "task.size": 2}], [])
    writer.write([{**_row("b" * 16, None), "task.shape": "line", "task.size": 1.5}], [])
    writer.write([{**_row("c" * 16, None), "task.size": None}], [])
    schemas = [pq.read_schema(p) for p in _parts(tmp_path)]
    assert "task.shape" not in schemas[0].names
    assert schemas[1].field("task.shape").type == pa.string() == schemas[2].field("task.shape").type
    assert {s.field("task.size").type for s in schemas} == {pa.float64()}  # ints as float64
    table = ds.dataset(tmp_path / EPISODES).to_table()
    assert table.num_rows == 3

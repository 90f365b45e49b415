"""``migrate`` infers the schema of a file without ``version`` and never guesses it.

It reads the keys that exist in only one schema, never a plugin type otmm-qp does not ship
(a vendor's trajectory), and what ``run`` refuses as an older schema is exactly what
``migrate`` rewrites (one table, :data:`otmm_qp.migration.changes.CHANGES`). Stored old
files: ``tests/data/old_schema`` (a vendor trajectory with qp and pink ``damping`` = μ) and
0.1.0's arm configs in ``tests/data/configs_0.1.0``, whose migrated numbers are 5638e52's
golden rows (``tests/data/golden_5638e52_heads.json``).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from functools import partial
from importlib import metadata
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp import registry
from otmm_qp.cli import main
from otmm_qp.config.current_schema import CURRENT_SCHEMA
from otmm_qp.exceptions import FIRST_LINE_LIMIT, ConfigError
from otmm_qp.migration import versions
from otmm_qp.migration.changes import CURRENT_VERSION
from tests.migration.test_versions import GOLDEN, RELEASE_0_1, STEPS, _run, _shortened
from tests.test_plugins import patch_entry_points

check_schema = partial(versions.check_schema, current=CURRENT_SCHEMA)
migrate = partial(versions.migrate, current=CURRENT_SCHEMA)
read_schema = partial(versions.read_schema, current=CURRENT_SCHEMA)


OLD = Path(__file__).parents[1] / "data" / "old_schema"
VENDOR = {
    "vendor_quintic_line": "tests.vendor_trajectories:VendorQuinticLine",
    "vendor_pose_line": "tests.vendor_trajectories:VendorPoseLine",
}


@pytest.fixture
def vendor(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[None]:
    """The vendor's trajectory types registered as a third-party package's entry points;
    the test runs in ``tmp_path`` (short file names in the messages)."""
    monkeypatch.chdir(tmp_path)
    entries = [
        metadata.EntryPoint(name, value, registry.TRAJECTORIES) for name, value in VENDOR.items()
    ]
    patch_entry_points(monkeypatch, entries)
    yield
    registry.clear_cache()


def _refusal(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[str, list[str]]:
    """``run``'s refusal of ``path``: its first line and the per-key lines."""
    assert main(["run", str(path), "--out", str(path.parent / "never")]) == 2
    first, *details = capsys.readouterr().err.splitlines()
    assert len(first) <= FIRST_LINE_LIMIT and "Traceback" not in "".join(details)
    assert not (path.parent / "never").exists()
    return first, details


def _listed_blocks(details: list[str]) -> set[str]:
    """The blocks of the per-key lines that say what to write (``PATH.key: ... write ...``)."""
    return {
        line.strip().split(": ", 1)[0].rsplit(".", 1)[0] for line in details if " write " in line
    }


def _changed_blocks(err: str) -> set[str]:
    """The blocks ``migrate`` says it changed (``  PATH: old → new``)."""
    return {line.strip().split(": ", 1)[0] for line in err.splitlines() if " → " in line}


def test_vendor_trajectory_file_migrates_to_mu(
    vendor: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A vendor's trajectory type says nothing about the schema: read as schema 1, as run
    reads it, so qp's and pink's ``damping`` become ``regularization`` with the same μ; the
    migrated file runs to the golden qp rows and to the hand-written schema-2 file's pink."""
    source = Path("vendor_arm.yaml")
    source.write_text((OLD / "vendor_arm.yaml").read_text())
    first, details = _refusal(source, capsys)
    assert first.endswith(f"2 key(s) from an older schema; fix: otmm-qp migrate {source}")
    assert details[0].startswith("  read as schema 1 (otmm-qp 0.1.0): no key tells its schema")
    migrated = tmp_path / "migrated.yaml"
    assert main(["migrate", str(source), "-o", str(migrated)]) == 0
    out = capsys.readouterr().out
    assert "read as schema 1" in out and "no value changed" not in out
    assert _listed_blocks(details) == _changed_blocks(out)
    backends = [
        c["backend"] for c in yaml.safe_load(migrated.read_text())["experiments"][0]["controllers"]
    ]
    assert [b.get("regularization") for b in backends] == [1.0e-3, 1.0e-4]
    assert all("damping" not in b for b in backends)
    runs = _run(migrated, tmp_path / "runs")
    golden = GOLDEN["arms/ur5_elbow.yaml"]["ur5_elbow_position/clik/qp.csv"][: STEPS + 1]
    assert runs["ur5_vendor/clik/qp.csv"] == golden  # 0.1.0's qp with damping μ = 1e-3
    by_hand = _run(OLD / "vendor_arm_mu.yaml", tmp_path / "by_hand")
    assert runs == by_hand


def test_uninstalled_plugin_type_is_no_evidence() -> None:
    """Without the vendor's package the type is unknown: still schema 1, never schema 2."""
    data = yaml.safe_load((OLD / "vendor_arm.yaml").read_text())
    assert read_schema(data, "f")[::2] == (1, False)
    backends = [c["backend"] for c in migrate(data, "f").data["experiments"][0]["controllers"]]
    assert [b["regularization"] for b in backends] == [1.0e-3, 1.0e-4]


@pytest.mark.parametrize("name", ["ur5_elbow.yaml", "panda_reach.yaml"])
def test_release_0_1_arm_with_vendor_trajectories_reaches_its_numbers(
    name: str, vendor: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """0.1.0's arm files with every trajectory a vendor's: ``migrate FILE`` (no ``--from``)
    converts every key ``run`` lists, and the file runs to 0.1.0's numbers."""
    data = yaml.safe_load((RELEASE_0_1 / "arms" / name).read_text())
    for experiment in data["experiments"]:
        experiment["trajectory"]["type"] = "vendor_" + experiment["trajectory"]["type"]
    source = Path(name)
    source.write_text(yaml.safe_dump(_shortened(data), sort_keys=False))
    first, details = _refusal(source, capsys)
    assert first.endswith(f"fix: otmm-qp migrate {source}")
    migrated = tmp_path / "migrated.yaml"
    assert main(["migrate", str(source), "-o", str(migrated)]) == 0
    assert _listed_blocks(details) == _changed_blocks(capsys.readouterr().out)
    golden = {path: rows[: STEPS + 1] for path, rows in GOLDEN[f"arms/{name}"].items()}
    assert _run(migrated, tmp_path / "out") == golden


#: Backend blocks of every kind the table knows, and a vendor's (no evidence).
BACKENDS: list[dict[str, Any]] = [
    {"type": "qp", "damping": 1e-4},
    {"type": "qp", "regularization": 1e-4},
    {"type": "qp", "limit_gain": 0.3},
    {"type": "qp", "posture_weight": 0.1},
    {"type": "qp", "solver": "direct_daqp"},
    {"type": "pink", "damping": 4e-6},
    {"type": "mink"},
    {"type": "mink", "limits": [{"type": "velocity"}]},
    {"type": "drake"},
    {"type": "dls", "damping": 0.05},
    {"type": "sns", "max_speed": 1.0},
    {"type": "dls_error", "damping_floor": 1e-4},
    {"type": "vendor_backend", "damping": 3.0},
]
TRAJECTORIES: list[dict[str, Any]] = [
    {"type": "pose_circle", "centre": [0.0, 0.0, 0.4], "radius": 0.1},
    {"type": "pose_circle", "centre": [0.0, 0.0, 0.4], "radius": 0.1, "profile": "quintic"},
    {"type": "pose_line", "end": [0.5, 0.0, 0.4], "duration": 1.0},
    {"type": "vendor_pose_line", "end": [0.5, 0.0, 0.4], "duration": 1.0},
]


def _file(trajectory: int, backends: list[int], version: int | None) -> dict[str, Any]:
    controllers = [
        {"name": f"c{i}", "backend": json.loads(json.dumps(BACKENDS[b]))}
        for i, b in enumerate(backends)
    ]
    experiment = {
        "name": "e",
        "robot": {"type": "pinocchio", "name": "panda", "task": "pose"},
        "q0": [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8],
        "trajectory": json.loads(json.dumps(TRAJECTORIES[trajectory])),
        "controllers": controllers,
    }
    data: dict[str, Any] = {"name": "f", "experiments": [experiment]}
    return data if version is None else {"version": version, **data}


@settings(max_examples=120, deadline=None)
@given(
    st.integers(0, len(TRAJECTORIES) - 1),
    st.lists(st.integers(0, len(BACKENDS) - 1), min_size=1, max_size=4),
    st.sampled_from([None, None, 1, 2]),
)
def test_what_run_refuses_migrate_converts(
    trajectory: int, backends: list[int], version: int | None
) -> None:
    """For every file ``run`` refuses as an older schema, ``migrate`` (the command the refusal
    names) rewrites every key the refusal lists, keeps μ a μ, and the result is not refused;
    a file it cannot read unambiguously is refused by both in one line naming ``--from``."""
    data = _file(trajectory, backends, version)
    try:
        check_schema(json.loads(json.dumps(data)), "f.yaml")
    except ConfigError as error:
        refusal = error
    else:
        assert migrate(data, "f.yaml").changes == []  # nothing to refuse: nothing to rewrite
        return
    first = refusal.summary
    assert len("otmm-qp: error: " + first) <= FIRST_LINE_LIMIT
    if "cannot tell its schema" in first:
        assert first.endswith("fix: otmm-qp migrate f.yaml --from 1 (or --from 2)")
        with pytest.raises(ConfigError, match="cannot tell its schema"):
            migrate(data, "f.yaml")
        for chosen in (1, 2):
            check_schema(migrate(data, "f.yaml", chosen).data, "f.yaml")
        return
    assert first.endswith("otmm-qp migrate f.yaml") or "fix: add version: 2" in first
    migration = migrate(data, "f.yaml")
    listed = _listed_blocks(refusal.details)
    assert listed == {line.split(": ", 1)[0] for line in migration.changes}
    check_schema(migration.data, "migrated")  # nothing left to refuse
    assert migration.data["version"] == CURRENT_VERSION
    read_as = migration.source_version
    for before, after in zip(
        data["experiments"][0]["controllers"],
        migration.data["experiments"][0]["controllers"],
        strict=True,
    ):
        old, new = before["backend"], after["backend"]
        if old["type"] in ("qp", "pink") and "damping" in old:  # μ in schema 1, λ in 2
            assert (new.get("regularization"), new.get("damping")) == (
                (old["damping"], None) if read_as == 1 else (None, old["damping"])
            )

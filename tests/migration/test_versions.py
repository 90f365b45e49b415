"""Versioned configs: a changed meaning is refused in one line, ``otmm-qp migrate`` keeps numbers.

The shipped configs as of commit 5638e52 are kept in ``tests/data/configs_5638e52`` and the
first rows of their golden runs (made by 5638e52's code, timing column dropped) in
``tests/data/golden_5638e52_heads.json``.
"""

from __future__ import annotations

import json
import math
from functools import partial
from pathlib import Path
from typing import Any

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.config.current_schema import CURRENT_SCHEMA
from otmm_qp.config.load import load_config, parse_config
from otmm_qp.exceptions import ConfigError
from otmm_qp.migration import versions
from otmm_qp.migration.changes import CHANGES, CURRENT_VERSION
from otmm_qp.studies.spec import load_study, parse_study
from tests.factories import OLD_KEYWORD_EXAMPLES

check_schema = partial(versions.check_schema, current=CURRENT_SCHEMA)
migrate = partial(versions.migrate, current=CURRENT_SCHEMA)
read_schema = partial(versions.read_schema, current=CURRENT_SCHEMA)


DATA = Path(__file__).parents[1] / "data"
SNAPSHOT = DATA / "configs_5638e52"
GOLDEN = json.loads((DATA / "golden_5638e52_heads.json").read_text())
RUN_FILES = sorted(
    str(p.relative_to(SNAPSHOT)) for p in SNAPSHOT.rglob("*.yaml") if "studies" not in p.parts
)
STUDY_FILES = sorted(str(p.relative_to(SNAPSHOT)) for p in SNAPSHOT.glob("studies/*.yaml"))
#: The 5638e52 files with a key whose meaning changed since schema 1: pose_circle without
#: ``profile`` (constant speed in 0.1.0, quintic since).
CHANGED_MEANING = {"arms/joint_limits.yaml"}
#: Control steps each run is cut to (its first rows are compared).
STEPS = 3


def _shortened(data: dict[str, Any]) -> dict[str, Any]:
    """The run file with every experiment cut to :data:`STEPS` control steps."""
    for experiment in data["experiments"]:
        dt = experiment.get("dt", data.get("dt", 0.02))
        experiment["duration"] = STEPS * dt
    return data


def _run(config: Path, out: Path) -> dict[str, list[str]]:
    """Run ``config`` (no figures) and return the rows of every run CSV, timing column dropped."""
    status = main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet"])
    assert status == 0
    runs = {}
    for csv in sorted(out.rglob("*.csv")):
        if csv.name == "summary.csv":
            continue
        lines = csv.read_text().splitlines()
        keep = [i for i, name in enumerate(lines[0].split(",")) if name != "step_time_us"]
        runs[str(csv.relative_to(out))] = [
            ",".join(line.split(",")[i] for i in keep) for line in lines[: STEPS + 1]
        ]
    return runs


@pytest.mark.parametrize("name", RUN_FILES)
def test_shipped_run_config_runs_identically_after_migrate(name: str, tmp_path: Path) -> None:
    """Refused without ``version`` where a meaning changed; migrated, the 5638e52 numbers."""
    original = SNAPSHOT / name
    if name in CHANGED_MEANING:
        with pytest.raises(ConfigError, match="states no version and 1 key.*fix: add version: 2"):
            load_config(original)
    else:
        load_config(original)
    migrated = tmp_path / "migrated.yaml"
    assert main(["migrate", str(original), "-o", str(migrated)]) == 0
    data = yaml.safe_load(migrated.read_text())
    assert data["version"] == CURRENT_VERSION
    short = tmp_path / "short.yaml"
    short.write_text(yaml.safe_dump(_shortened(data), sort_keys=False))
    runs = _run(short, tmp_path / "out")
    if name in GOLDEN:  # the runs of 5638e52's code
        expected = {path: rows[: STEPS + 1] for path, rows in GOLDEN[name].items()}
        assert runs == expected
    else:  # no golden run: every value is the original's, so are the numbers
        assert name not in CHANGED_MEANING
        plain = _shortened(yaml.safe_load(original.read_text()))
        assert {k: v for k, v in data.items() if k != "version"} == plain
        assert runs and all(len(rows) == STEPS + 1 for rows in runs.values())


RELEASE_0_1 = DATA / "configs_0.1.0"


@pytest.mark.parametrize(
    "name",
    [f"arms/{p.name}" for p in sorted((RELEASE_0_1 / "arms").glob("*.yaml"))],
)
def test_release_0_1_configs_migrate_to_their_numbers(name: str, tmp_path: Path) -> None:
    """0.1.0's shipped files (qp ``damping`` = μ, pose_circle at constant speed) are refused
    unmigrated and, migrated, give the numbers 0.1.0 meant: 5638e52's (whose shipped files
    were converted by hand to ``regularization``), except the pose circle, now explicitly
    ``profile: constant`` where 5638e52's file ran the quintic default."""
    original = RELEASE_0_1 / name  # (0.1.0's paper.yaml is 5638e52's, tested above)
    with pytest.raises(ConfigError, match="meant"):
        load_config(original)
    migrated = tmp_path / "migrated.yaml"
    assert main(["migrate", str(original), "-o", str(migrated)]) == 0
    data = yaml.safe_load(migrated.read_text())
    short = tmp_path / "short.yaml"
    short.write_text(yaml.safe_dump(_shortened(data), sort_keys=False))
    runs = _run(short, tmp_path / "out")
    golden = {path: rows[: STEPS + 1] for path, rows in GOLDEN[name].items()}
    if name == "arms/joint_limits.yaml":
        assert data["experiments"][0]["trajectory"]["profile"] == "constant"
        assert runs.keys() == golden.keys() and runs != golden  # 0.1.0's circle, not 5638e52's
    else:
        assert runs == golden


@pytest.mark.parametrize("name", STUDY_FILES)
def test_shipped_study_file_is_unchanged_by_migrate(name: str, tmp_path: Path) -> None:
    """Study files came in schema 2: never refused, migrated to the same record (same study id)."""
    original = load_study(SNAPSHOT / name)
    migrated = tmp_path / "migrated.yaml"
    assert main(["migrate", str(SNAPSHOT / name), "-o", str(migrated)]) == 0
    assert load_study(migrated).model_dump() == original.model_dump()


OLD_RUN = {
    "name": "old",
    "experiments": [
        {
            "name": "e",
            "robot": {"type": "pinocchio", "name": "panda", "task": "pose"},
            "q0": [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8],
            "trajectory": {"type": "pose_circle", "centre": [0.0, 0.0, 0.4126], "radius": 0.484},
            "controllers": [
                {"name": "qp", "backend": {"type": "qp", "damping": 2.5e-5, "limit_gain": 0.3}},
                {"name": "pink", "backend": {"type": "pink", "damping": 4.0e-6}},
                {"name": "mink", "backend": {"type": "mink", "damping": 9.0e-6}},
            ],
        }
    ],
}


def test_refusal_lists_every_older_key_with_the_users_values() -> None:
    with pytest.raises(ConfigError) as info:
        check_schema(OLD_RUN, "old.yaml")
    summary, message = info.value.summary, str(info.value)
    assert summary == "old.yaml: 6 key(s) from an older schema; fix: otmm-qp migrate old.yaml"
    reading = "read as schema 1 (otmm-qp 0.1.0): experiments.0.controllers.0.backend.limit_gain"
    assert info.value.details[0] == f"{reading} exists only in schema 1"
    assert len(info.value.details) == 1 + 6  # the reading, one line per key
    controllers = "experiments.0.controllers"
    for key, value, sqrt in (("0", "2.5e-05", "0.005"), ("1", "4e-06", "0.002")):
        assert f"{controllers}.{key}.backend.damping: {value} meant μ" in message
        assert f"write regularization: {value} or damping: {sqrt} (λ = √μ)" in message
    assert f"{controllers}.2.backend.damping: 9e-06 meant μ" in message
    assert f"{controllers}.2.backend.limits: (absent) meant absent or true: mink's own" in message
    assert "write limits: [{type: velocity}, {type: position, gain: 0.95}]" in message
    assert f"{controllers}.0.backend.limit_gain: removed" in message
    assert "limits: [{type: position, gain: 0.3}]" in message and " G" not in message
    assert "experiments.0.trajectory.profile: (absent) meant constant speed" in message
    assert "write profile: constant or profile: quintic" in message


def test_stated_version_decides_what_damping_means() -> None:
    qp_only = json.loads(json.dumps(OLD_RUN))
    experiment = qp_only["experiments"][0]
    experiment["trajectory"]["profile"] = "quintic"
    experiment["controllers"] = [{"name": "qp", "backend": {"type": "qp", "damping": 0.01}}]
    # profile exists only in schema 2: read as schema 2, but it must say so (version: 2)
    with pytest.raises(ConfigError, match=r"^f: states no version.*fix: add version: 2") as info:
        check_schema(qp_only, "f")
    assert "backend.damping: 0.01 means λ" in info.value.details[1]
    assert info.value.details[1].endswith("if so, otmm-qp migrate f --from 1)")
    del experiment["trajectory"]["profile"]  # now nothing tells: read as schema 1, as migrate
    with pytest.raises(ConfigError, match="damping: 0.01 meant μ"):
        check_schema(qp_only, "f")
    experiment["trajectory"]["profile"] = "quintic"
    check_schema({**qp_only, "version": 2}, "f")  # schema 2: λ, nothing to refuse
    with pytest.raises(ConfigError, match=r"backend\.damping: 0\.01 meant μ"):
        check_schema({**qp_only, "version": 1}, "f")
    for bad in (0, 3, True, "2", 1.5):
        with pytest.raises(ConfigError, match=r"^f: version: must be an integer in \[1, 2\]"):
            check_schema({**qp_only, "version": bad}, "f")


def test_migrate_converts_value_by_value_and_the_result_loads() -> None:
    migration = migrate(json.loads(json.dumps(OLD_RUN)), "old.yaml")
    assert migration.source_version == 1
    experiment = migration.data["experiments"][0]
    assert experiment["trajectory"]["profile"] == "constant"
    backends = [c["backend"] for c in experiment["controllers"]]
    assert backends[0] == {
        "type": "qp",
        "regularization": 2.5e-5,
        "limits": [{"type": "position", "gain": 0.3}],
    }
    assert backends[1] == {"type": "pink", "regularization": 4.0e-6}
    assert backends[2] == {
        "type": "mink",
        "regularization": 9.0e-6,
        "limits": [{"type": "velocity"}, {"type": "position", "gain": 0.95}],
    }
    assert len(migration.changes) == 4
    suite = parse_config(migration.data, "migrated")
    assert suite.experiments[0].controllers[0].backend.params["regularization"] == 2.5e-5
    again = migrate(migration.data, "again")  # migrating a current file changes nothing
    assert again.changes == [] and again.data == migration.data


@pytest.mark.parametrize("damping", [1e-8, 1e-4, 0.25, 3.0])
def test_migrated_qp_damping_is_the_same_mu(damping: float) -> None:
    """μ of schema 1 and the migrated file's μ are one number: the QP the backend builds."""
    from otmm_qp import registry

    block = {"type": "qp", "damping": damping}
    migrated = migrate({"experiments": [{"controllers": [{"backend": block}]}]}, "f")
    new = migrated.data["experiments"][0]["controllers"][0]["backend"]
    params = {k: v for k, v in new.items() if k != "type"}
    backend = registry.create(registry.BACKENDS, "qp", params, "backend")
    assert backend.formulation.mu == damping
    lam = math.sqrt(damping)  # what the refusal offers instead
    other = registry.create(registry.BACKENDS, "qp", {"damping": lam}, "backend")
    assert math.isclose(other.formulation.mu, damping, rel_tol=1e-12)


def test_read_schema_reads_keys_that_exist_in_one_schema_only() -> None:
    newer = json.loads(json.dumps(OLD_RUN))
    newer["experiments"][0]["controllers"][1]["backend"] = {"type": "pink", "regularization": 1.0}
    with pytest.raises(ConfigError, match=r"cannot tell its schema.*--from 1 \(or --from 2\)"):
        read_schema(newer, "f")  # limit_gain is schema 1's, regularization schema 2's
    assert read_schema(newer, "f", from_version=1).version == 1
    del newer["experiments"][0]["controllers"][0]["backend"]["limit_gain"]
    version, reason, told = read_schema(newer, "f")
    assert (version, told) == (2, True) and "controllers.1.backend.regularization" in reason
    assert read_schema(OLD_RUN, "f")[::2] == (1, True)  # limit_gain: schema 1's
    plain = json.loads(json.dumps(OLD_RUN))
    del plain["experiments"][0]["controllers"][0]["backend"]["limit_gain"]
    assert read_schema(plain, "f")[::2] == (1, False)  # nothing says: as run reads it
    assert read_schema({"generators": []}, "f")[0] == 2


def test_migrate_cli_prints_what_it_changed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    source = Path("old.yaml")
    source.write_text(yaml.safe_dump(OLD_RUN))
    assert main(["run", str(source), "--out", str(tmp_path / "o")]) == 2
    first, *details = capsys.readouterr().err.strip().splitlines()
    assert len(first) <= 200 and first.endswith(f"fix: otmm-qp migrate {source}")
    assert len(details) == 7 and all(line.startswith("  ") for line in details)
    assert main(["migrate", str(source)]) == 0
    captured = capsys.readouterr()
    assert "read as schema 1" in captured.err
    assert "experiments.0.controllers.0.backend: damping: 2.5e-05, limit_gain: 0.3" in captured.err
    assert yaml.safe_load(captured.out)["version"] == CURRENT_VERSION
    assert main(["migrate", str(source), "--from", "7"]) == 2
    assert main(["migrate", str(source), "-o", str(tmp_path)]) == 2  # a folder
    assert main(["migrate", str(source), "-o", str(tmp_path / "no" / "x.yaml")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and all(line.startswith("otmm-qp: error: ") for line in lines)
    assert main(["migrate", str(tmp_path / "missing.yaml")]) == 2
    assert not (tmp_path / "o").exists()


def test_every_change_converts_to_a_block_it_no_longer_concerns() -> None:
    """Each converter removes what its change refuses (no migrate loop, no stale key)."""
    examples = {"damping": 1e-4, **OLD_KEYWORD_EXAMPLES, "solver": "direct_daqp"}
    for change in CHANGES:
        for kind in change.types:
            block = {"type": kind}
            if change.key in examples:
                block[change.key] = examples[change.key]
            assert change.concerns(change.group, block), (change.key, kind)
            assert not change.concerns(change.group, change.convert(dict(block))), change.key


def test_list_params_says_what_damping_means(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list", "--params", "qp"]) == 0
    out = capsys.readouterr().out
    assert "damping (meaning changed in schema 2): now λ" in out
    assert "it was μ" in out


def test_parse_study_accepts_version() -> None:
    data = yaml.safe_load((SNAPSHOT / "studies" / "planar.yaml").read_text())
    assert parse_study({**data, "version": 2}).model_dump() == parse_study(data).model_dump()
    with pytest.raises(ConfigError, match="starts at schema 2"):
        parse_study({**data, "version": 1})

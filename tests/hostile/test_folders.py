"""Folder kinds, locks and the study reader (issue 19): every folder the CLI writes says what
wrote it and has one writer; the study report and ``--resume`` read only this study's parts.
"""

from __future__ import annotations

import copy
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

from otmm_qp import paths as paths_module
from otmm_qp.cli import main
from otmm_qp.output.folders import KIND_NAME, folder_kind
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import EPISODES, read_episodes, read_study
from tests.cli_errors import refusal_text
from tests.factories import PINV, tiny_run, tiny_study

ROOT = Path(__file__).resolve().parents[2]
# The reference is off: these tests count controller episodes and parts.
TINY = tiny_study(
    "tiny",
    seed=3,
    chunk_size=1,
    reference={"enabled": False},
    generators=[{"type": "near_singular", "count": 3, "duration": [1.0, 1.5]}],
)
RUN = tiny_run([PINV], name="r", dt=0.05, radius=0.3, duration=0.3)


def _study_file(tmp_path: Path, data: dict, name: str = "study.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def _one_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    text = refusal_text(err)
    for needle in needles:
        assert needle in text, text
    return text


@pytest.fixture(scope="module")
def study_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tiny") / "tiny"
    outcome = run_study(plan_study(parse_study(TINY)), out, "tiny", workers=1)
    assert outcome.ran == 6
    return out


def test_folder_kinds_are_never_mixed_and_force_replaces_the_earlier_kind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], study_out: Path
) -> None:
    run_config = tmp_path / "run.yaml"
    run_config.write_text(RUN)
    study_file = _study_file(tmp_path, TINY)
    run_dir, study_dir = tmp_path / "run", tmp_path / "study"
    shutil.copytree(study_out, study_dir)
    assert (
        main(["run", str(run_config), "--out", str(run_dir), "--figures", "none", "--quiet"]) == 0
    )
    assert folder_kind(run_dir) == "run" and folder_kind(study_dir) == "study"
    capsys.readouterr()
    study = ["study", str(study_file), "--workers", "1", "--quiet"]
    # a study into a run folder, a run into a study folder, a bench into either: refused
    assert main([*study, "--out", str(run_dir)]) == 2
    _one_line(capsys, "is a run folder", "--force")
    assert main(["run", str(run_config), "--out", str(study_dir), "--figures", "none"]) == 2
    _one_line(capsys, "is a study folder")
    assert main(["bench", "--out", str(study_dir), "--steps", "10", "--planar-only"]) == 2
    _one_line(capsys, "is a study folder")
    assert (run_dir / "summary.csv").is_file() and len(read_episodes(study_dir) or []) == 6
    # --force removes everything the earlier kind wrote (also the study's report and figures)
    assert main(["report", str(study_dir)]) == 0
    assert (study_dir / "study_report.html").is_file()
    (study_dir / "notes.txt").write_text("mine")
    args = ["run", str(run_config), "--out", str(study_dir), "--figures", "none", "--quiet"]
    assert main([*args, "--force"]) == 0
    left = sorted(p.name for p in study_dir.iterdir())
    assert left == sorted([".otmm-qp.lock", KIND_NAME, "A", "notes.txt", "report.html",
                           "report.md", "summary.csv", "summary.md"]), left  # fmt: skip
    assert main([*study, "--out", str(run_dir), "--force", "--no-report"]) == 0
    assert not (run_dir / "summary.csv").exists() and not (run_dir / "A").exists()
    assert folder_kind(run_dir) == "study"


@pytest.mark.parametrize("command", ["study", "bench"])
def test_names_dot_dotdot_and_empty_out_never_write_the_cwd_or_results(
    command: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(tmp_path))
    if command == "study":
        for name in ("..", "."):
            path = _study_file(tmp_path, dict(TINY, name=name), f"s{len(name)}.yaml")
            before = sorted(os.listdir(tmp_path))
            assert main(["study", str(path), "--workers", "1", "--quiet", "--no-report"]) == 0
            assert sorted(os.listdir(tmp_path)) == sorted({*before, "results"})
            assert os.listdir(tmp_path / "results") == ["_"]  # safe_name('..') == '_'
            shutil.rmtree(tmp_path / "results")
        argv = ["study", str(path), "--out", ""]
    else:
        argv = ["bench", "--steps", "10", "--planar-only", "--out", ""]
    before = sorted(os.listdir(tmp_path))
    assert main(argv) == 2
    _one_line(capsys, "must not be empty")
    for out in (".", "results"):
        (tmp_path / "results").mkdir(exist_ok=True)
        assert main([*argv[:-1], out]) == 2
        _one_line(capsys, "choose a subfolder")
    assert sorted(os.listdir(tmp_path)) == sorted({*before, "results"})
    assert os.listdir(tmp_path / "results") == []


def test_two_concurrent_studies_into_one_folder_store_each_episode_once(tmp_path: Path) -> None:
    data = copy.deepcopy(TINY)
    data["generators"][0]["count"] = 40  # long enough (80 episodes) for both to overlap
    path = _study_file(tmp_path, data)
    out = tmp_path / "shared"
    argv = [sys.executable, "-m", "otmm_qp.cli", "study", str(path), "--out", str(out)]
    argv += ["--workers", "1", "--quiet", "--no-report"]
    first = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    second = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    results = [(p.wait(120), p.communicate()[1].decode()) for p in (first, second)]
    statuses = sorted(status for status, _ in results)
    refused = [err for status, err in results if status == 2]
    assert statuses in ([0, 2], [0, 0]), results
    for err in refused:
        assert err.count("\n") == 1 and "another otmm-qp command is writing" in err
    if statuses == [0, 0]:  # the second started after the first finished: it resumed
        assert any("0 episodes run" in err or "80 already stored" in err for _, err in results)
    table = read_episodes(out)
    assert table is not None
    keys = table.column("episode_key").to_pylist()
    raw = sum(pq.read_metadata(p).num_rows for p in (out / EPISODES).glob("part-*.parquet"))
    assert len(keys) == len(set(keys)) == raw == 80  # no episode stored twice


def test_report_and_resume_read_only_this_study_and_plan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], study_out: Path
) -> None:
    out = tmp_path / "tiny"
    shutil.copytree(study_out, out)
    episodes = out / EPISODES
    parts = sorted(episodes.glob("part-*.parquet"))
    # a part of another study, a duplicate of one of ours, a symlinked part, foreign and
    # mistyped Parquet files and a non-Parquet file, all named like parts
    other = tmp_path / "other"
    run_study(plan_study(parse_study(dict(TINY, name="tiny", dt=0.04))), other, "x", workers=1)
    shutil.copy(sorted((other / EPISODES).glob("part-*"))[0], episodes / "part-zz-other.parquet")
    shutil.copy(parts[0], episodes / "part-zz-copy.parquet")
    (episodes / "part-zz-link.parquet").symlink_to(parts[1])
    pq.write_table(pa.table({"x": [1, 2]}), episodes / "part-zz-foreign.parquet")
    mistyped = pq.read_table(parts[2]).to_pylist()
    for row in mistyped:
        row["steps"] = "many"
    pq.write_table(pa.Table.from_pylist(mistyped), episodes / "part-zz-types.parquet")
    (episodes / "part-zz-text.parquet").write_text("not parquet")
    data = read_study(out, EPISODES, *_scope(out))
    assert data.table is not None and data.table.num_rows == 6
    assert len(set(data.table.column("episode_key").to_pylist())) == 6
    reasons = " | ".join(data.ignored)
    for word in (
        "another study",
        "second copies",
        "symlinked",
        "episode_key",
        "clash",
        "non-Parquet",
    ):
        assert word in reasons, reasons
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("otmm-qp: report ignored") == len(data.ignored)
    # --resume with a changed setting reruns every episode and the report keeps only those
    changed = _study_file(tmp_path, dict(TINY, dt=0.04))
    assert main(["study", str(changed), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    outcome = capsys.readouterr()
    # the copied part of the dt = 0.04 study now is this study's: its 2 episodes count
    assert "4 episodes run (0 failed), 2 already stored" in outcome.out
    assert "resume ignored" in outcome.err
    table = read_episodes(out)
    assert table is not None and table.num_rows == 6
    assert set(table.column("dt").to_pylist()) == {0.04}


def _scope(out: Path) -> tuple[str, set[str]]:
    import json

    marker = json.loads((out / "study.json").read_text())
    return marker["study_id"], set(marker["episode_keys"])


def test_study_report_on_damaged_folders_is_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    study_out: Path,
) -> None:
    outside = tmp_path / "outside"
    shutil.copytree(study_out, outside)
    cases = {
        "episodes symlinked out": lambda d: (
            shutil.rmtree(d / EPISODES),
            (d / EPISODES).symlink_to(outside / EPISODES),
        ),
        "study.json symlinked out": lambda d: (
            (d / "study.json").unlink(),
            (d / "study.json").symlink_to(outside / "study.json"),
        ),
        "marker without config": lambda d: (d / "study.json").write_text('{"study": "tiny"}'),
        "marker with an invalid config": lambda d: (d / "study.json").write_text(
            '{"study": "tiny", "config": {"name": "tiny", "dt": "fast"}}'
        ),
        "marker not JSON": lambda d: (d / "study.json").write_bytes(b"\xff\x00{"),
    }
    expected = {
        "episodes symlinked out": "no stored episodes",
        "study.json symlinked out": "is a symlink",
        "marker without config": "holds no study config",
        "marker with an invalid config": "config.",
        "marker not JSON": "unreadable study marker",
    }
    for name, damage in cases.items():
        folder = tmp_path / name.replace(" ", "-")
        shutil.copytree(study_out, folder)
        damage(folder)
        capsys.readouterr()
        assert main(["report", str(folder)]) == 2, name
        err = capsys.readouterr().err
        assert expected[name] in err and "Traceback" not in err, (name, err)
        assert err.strip().count("otmm-qp: error") == 1, (name, err)
        if name == "episodes symlinked out":  # --resume refuses it before computing anything
            study = _study_file(tmp_path, TINY)
            argv = ["study", str(study), "--out", str(folder), "--workers", "1", "--quiet"]
            parts = sorted(p.name for p in (outside / EPISODES).iterdir())
            assert main(argv) == 2
            _one_line(capsys, "is a symlink")
            assert sorted(p.name for p in (outside / EPISODES).iterdir()) == parts
    # a read-only folder (root ignores modes: refuse where every write goes through)
    folder = tmp_path / "read-only"
    shutil.copytree(study_out, folder)

    def refuse(*args: object, **kwargs: object) -> tuple[int, str]:
        raise PermissionError(13, "Permission denied", str(folder))

    monkeypatch.setattr(paths_module.tempfile, "mkstemp", refuse)
    assert main(["report", str(folder)]) == 2
    _one_line(capsys, "Permission denied")

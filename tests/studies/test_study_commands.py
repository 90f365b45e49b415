"""The study command tree: ``otmm-qp study {run,show,report,verdict,tradeoff,plants}``.

Every bad input is one line ``otmm-qp: error: ...``, exit 2 (issue 31, items 5, 6, 7, 11, 12);
the old ``python -m`` entry points are aliases that say so in one line.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.exceptions import one_line
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import EPISODES
from tests.studies.conftest import SMALL


def _one_line(capsys: pytest.CaptureFixture[str], start: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and "usage:" not in err, err
    assert err.startswith(one_line(start)), err  # long values are cut the CLI's way
    return err


def _copy(study: Path, tmp_path: Path) -> Path:
    out = tmp_path / "study"
    shutil.copytree(study, out)
    return out


def test_study_file_still_runs_and_run_is_the_same(tmp_path: Path) -> None:
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({**SMALL, "generators": SMALL["generators"][1:]}))
    old = ["study", str(config), "--out", str(tmp_path / "a"), "--workers", "1", "--quiet"]
    new = ["study", "run", str(config), "--out", str(tmp_path / "b"), "--workers", "1", "--quiet"]
    assert main([*old, "--no-report"]) == 0
    assert main([*new, "--no-report"]) == 0
    keys = [json.loads((tmp_path / d / "study.json").read_text())["study_id"] for d in "ab"]
    assert keys[0] == keys[1]


@pytest.mark.parametrize(
    ("out", "start"),
    [
        ("", "otmm-qp: error: --out: must be a file name"),
        ("DIR", "otmm-qp: error: --out: "),
        ("missing/x.md", "otmm-qp: error: --out: folder 'missing' does not exist"),
        ("missing/", "otmm-qp: error: --out: 'missing/' is a folder; give a file name inside it"),
        ("/proc/x.md", "otmm-qp: error: --out: "),
    ],
)
def test_verdict_out_is_checked_in_one_line(
    small_study: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    out: str,
    start: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    out = str(tmp_path) if out == "DIR" else out
    assert main(["study", "verdict", str(small_study), "--ours", "dls", "--out", out]) == 2
    _one_line(capsys, start)


def test_verdict_writes_its_file(small_study: Path, tmp_path: Path) -> None:
    target = tmp_path / "verdict.md"
    assert main(["study", "verdict", str(small_study), "--ours", "dls", "--out", str(target)]) == 0
    assert "dls" in target.read_text()


def test_verdict_the_report_and_the_decision_say_the_same_for_the_arm(
    small_study: Path, tmp_path: Path
) -> None:
    from otmm_qp.studies.decide import judge

    target = tmp_path / "verdict.md"
    assert main(["study", "verdict", str(small_study), "--ours", "dls", "--kinds"] + [
        "--out", str(target)]) == 0  # fmt: skip
    decision = judge(small_study, 0, 0)  # what decision.md says of the stored rows
    lines = [f"- {decision.arm_line(robot)}" for robot in sorted(decision.arms)]
    text = target.read_text(encoding="utf-8")
    assert lines and text.startswith("Decision for the arm:")
    report = tmp_path / "report"
    shutil.copytree(small_study, report)
    assert main(["report", str(report)]) == 0
    markdown = (report / "study_report.md").read_text(encoding="utf-8")
    for line in lines:
        assert line in text and line in markdown
        assert markdown.index(line) < markdown.index("## Method")  # the first screen


def test_verdict_without_ours_is_the_trees_one_line_error(
    small_study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["study", "verdict", str(small_study)]) == 2  # --ours missing
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("otmm-qp: error: study verdict: ")


@pytest.mark.parametrize(
    "argv",
    [
        ["verdict", "STUDY", "--ours", "nobody"],
        ["verdict", "STUDY"],
        ["tradeoff", "STUDY", "--tasks", "x" * 10_000],
        ["tradeoff", "STUDY", "--bogus"],
        ["plants", "STUDY"],
        ["report", "NOWHERE"],
        ["show", "STUDY", "--episode", "zz"],
        [],
    ],
)
def test_every_bad_argument_is_one_short_line(
    small_study: Path, argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    where = {"STUDY": str(small_study), "NOWHERE": str(small_study / "nowhere")}
    assert main(["study", *[where.get(a, a) for a in argv]]) == 2
    err = _one_line(capsys, "otmm-qp: error: ")
    assert len(err) < 400


def test_show_refuses_a_drilldown_file(
    small_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(small_study, tmp_path)
    (out / "drilldown").write_text("not a folder")
    from otmm_qp.studies import load

    episode = next(r for r in load(out).to_pylist() if r["controller"] == "pinv")["episode_id"]
    capsys.readouterr()
    assert main(["study", "show", str(out), "--episode", episode]) == 2
    _one_line(capsys, f"otmm-qp: error: {out / 'drilldown'}: is not a folder")


def test_a_hand_edited_study_json_is_refused(
    small_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(small_study, tmp_path)
    marker = json.loads((out / "study.json").read_text())
    marker["config"]["dt"] = 0.01
    (out / "study.json").write_text(json.dumps(marker))
    for command in (["show", str(out), "--episode", "0123456789"], ["report", str(out)]):
        assert main(["study", *command]) == 2
        _one_line(capsys, f"otmm-qp: error: {out / 'study.json'}: its config does not hash")
    assert not (out / "drilldown").exists()


def test_a_folder_written_before_a_field_existed_is_still_read(
    small_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The id is checked against the config as stored, not as today's schema re-reads it."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from otmm_qp.studies.storage import study_id

    out = _copy(small_study, tmp_path)
    marker = json.loads((out / "study.json").read_text())
    del marker["config"]["reference"]["polish_iterations"]  # a field an older release lacked
    old, new = marker["study_id"], study_id(marker["config"])
    marker["study_id"] = new
    (out / "study.json").write_text(json.dumps(marker))
    for part in (out / EPISODES).glob("*.parquet"):  # the parts carry the id they were written with
        table = pq.read_table(part)
        column = pa.array([new if v == old else v for v in table["study"].to_pylist()])
        table = table.set_column(table.schema.get_field_index("study"), "study", column)
        metadata = {
            k: (new.encode() if v == old.encode() else v)
            for k, v in (table.schema.metadata or {}).items()
        }
        pq.write_table(table.replace_schema_metadata(metadata), part)
    assert main(["study", "report", str(out)]) == 0, capsys.readouterr().err


PLANTS = {
    **SMALL,
    "name": "plants",
    "generators": [{"type": "beyond_reach", "count": 2, "duration": [1.0, 1.5]}],
    "reference": {"enabled": False},
    "plants": [
        {"name": "lag", "plant": {"type": "lag", "tau": 0.05}},
        {"name": "delay", "plant": {"type": "delay", "steps": 1}},
    ],
}


@pytest.fixture(scope="module")
def plants_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plants")
    run_study(plan_study(parse_study(PLANTS)), out, "plants", workers=1)
    return out


def test_plants_without_the_reference_plant_is_one_line(
    plants_study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["study", "plants", str(plants_study)]) == 2  # no 'ideal' plant
    _one_line(capsys, "otmm-qp: error: --reference: no plant 'ideal' in the study; have: lag")
    assert main(["study", "plants", str(plants_study), "--reference", "lag"]) == 0
    assert "| delay | pinv |" in capsys.readouterr().out


def test_plants_says_what_it_left_out(
    plants_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(plants_study, tmp_path)
    part = sorted((out / EPISODES).glob("part-*.parquet"))[0]
    shutil.copy(part, part.with_name("part-zcopy.parquet"))  # a duplicated part
    (out / EPISODES / "part-zforeign.parquet").write_bytes(b"not parquet")
    assert main(["study", "plants", str(out), "--reference", "lag"]) == 0
    err = capsys.readouterr().err
    assert "second copies of an episode" in err and "unreadable or non-Parquet parts" in err


def test_plain_progress_prints_a_line_per_tenth_or_minute(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from otmm_qp.commands.study_run import PlainProgress

    now = [0.0]
    progress = PlainProgress(100)
    progress.clock = lambda: now[0]
    progress.shown = (0.0, 0)
    for _ in range(20):  # 5 episodes a chunk, one second apart
        now[0] += 1.0
        progress(5, 1)
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 10 and lines[-1].startswith("100 of 100 episodes (20 failed)")
    now[0] += 61.0  # a minute without a new tenth still prints
    progress(0, 0)
    assert capsys.readouterr().out.startswith("100 of 100 episodes")

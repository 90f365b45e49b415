"""Replay and bench meet the one-line, exit-2, before-compute rule (issue 19)."""

from __future__ import annotations

import csv
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from otmm_qp import paths as paths_module
from otmm_qp.bench import run as bench_run
from otmm_qp.cli import main
from otmm_qp.output.run_csv import thinned_rows
from otmm_qp.replay.stored_runs import MAX_ROWS, read_run
from tests.cli_errors import refusal_text
from tests.factories import DLS, PINV, tiny_run

RUN = tiny_run([PINV, DLS], name="r", dt=0.05, radius=0.3, duration=0.5)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("replay-run")
    (folder / "run.yaml").write_text(RUN)
    out = folder / "out"
    argv = ["run", str(folder / "run.yaml"), "--out", str(out), "--figures", "none", "--quiet"]
    assert main(argv) == 0
    return out


def _rewrite(path: Path, change: object) -> None:
    with path.open(newline="") as handle:
        rows = list(csv.reader(handle))
    change(rows)  # type: ignore[operator]
    with path.open("w", newline="") as handle:
        csv.writer(handle).writerows(rows)


def _huge_values(rows: list[list[str]]) -> None:
    header = rows[0]
    for row in rows[1:4]:
        row[header.index("q_joint1")] = "1e300"
        row[header.index("x")] = "-1e300"
    rows[5][header.index("t")] = "inf"


def _spatial(rows: list[list[str]]) -> None:
    rows[0] += ["z", "z_desired"]
    for row in rows[1:]:
        row += ["0", "0"]


#: damage to a copy of a run folder -> text the one error line holds (None: replay works)
CASES = {
    "a file where replays/ goes": (lambda d: (d / "replays").write_text("x"), "not a directory"),
    "1e300 values and an inf time": (lambda d: _rewrite(d / "A/clik/pinv.csv", _huge_values), None),
    "planar and spatial runs in one scenario": (
        lambda d: _rewrite(d / "A/clik/dls.csv", _spatial),
        "A/clik: mixes runs of different arms",
    ),
    "robot.json overflowing": (
        lambda d: (d / "A/robot.json").write_text(
            '{"type": "planar", "params": {"link_lengths": [1e308, 1e308]}}'
        ),
        "robot.json: robot: parameters out of range",
    ),
    "robot.json of another arm": (
        lambda d: (d / "A/robot.json").write_text(
            '{"type": "planar", "params": {"link_lengths": [2.0, 0.5]}}'
        ),
        "does not reproduce the stored end-effector positions",
    ),
    "robot.json nested deeply": (
        lambda d: (d / "A/robot.json").write_text("[" * 50_000 + "]" * 50_000),
        "larger than 65536 bytes",
    ),
    "robot.json not a robot block": (
        lambda d: (d / "A/robot.json").write_text("[1, 2]"),
        'expected {"type": NAME',
    ),
    "robot.json a string length": (
        lambda d: (d / "A/robot.json").write_text(
            '{"type": "planar", "params": {"link_lengths": ["a", 1]}}'
        ),
        "link_lengths[0]: input should be a valid number, got 'a'",
    ),
    "a study folder": (
        lambda d: (d / ".otmm-qp-kind").write_text('{"kind": "study"}'),
        "is a study folder",
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_replay_of_damaged_folders_is_one_line(
    case: str, run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "copy"
    shutil.copytree(run_dir, folder)
    damage, needle = CASES[case]
    damage(folder)
    capsys.readouterr()
    status = main(["replay", str(folder)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if needle is None:
        assert status == 0, err
        assert (folder / "replays" / "A-clik.gif").is_file()
        return
    assert status == 2 and needle in refusal_text(err), err
    assert not list(folder.rglob("*.tmp"))


def test_replay_into_read_only_folder_is_one_line(
    run_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    folder = tmp_path / "copy"
    shutil.copytree(run_dir, folder)

    def refuse(*args: object, **kwargs: object) -> tuple[int, str]:
        raise PermissionError(13, "Permission denied", str(folder))

    monkeypatch.setattr(paths_module.tempfile, "mkstemp", refuse)
    capsys.readouterr()
    assert main(["replay", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "Permission denied" in lines[0]


def test_long_time_series_are_thinned_while_read(run_dir: Path, tmp_path: Path) -> None:
    source = run_dir / "A/clik/pinv.csv"
    with source.open(newline="") as handle:
        rows = list(csv.reader(handle))
    header, row = rows[0], rows[1]
    t = header.index("t")
    path = tmp_path / "long.csv"
    n = 5 * MAX_ROWS + 7
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for k in range(n):
            row[t] = str(k)
            writer.writerow(row)
    run = read_run(path, "A", "clik", "pinv")
    assert MAX_ROWS // 2 <= run.steps <= MAX_ROWS + 1
    assert run.t[0] == 0 and run.t[-1] == n - 1  # first and last step kept
    gaps = np.diff(run.t[:-1])
    assert np.all(gaps == gaps[0])  # evenly thinned

    # memory stays bounded in one pass over any number of rows (a lazy 10^6-row source)
    width = 3
    peak = 0

    def source_rows() -> Iterator[list[str]]:
        nonlocal peak
        for k in range(1_000_000):
            yield [str(k), "0", "0"]

    kept = thinned_rows(source_rows(), width, 1000)
    peak = len(kept)
    assert peak <= 1001 and kept[0][0] == "0" and kept[-1][0] == "999999"


@pytest.mark.parametrize(
    ("out", "steps", "needle"),
    [
        ("FILE", "10", "exists and is not a directory"),
        ("/proc/otmm-bench", "10", "cannot create a results folder there"),
        ("READONLY", "10", "Permission denied"),
        ("OK", "1000000000000", "--steps: must be in [10, 100000]"),
    ],
)
def test_bench_refuses_before_any_timing(
    out: str,
    steps: str,
    needle: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def no_timing(*args: object, **kwargs: object) -> None:
        raise AssertionError("the timing started before the bad input was refused")

    monkeypatch.setattr(bench_run, "bench_scenario", no_timing)
    monkeypatch.setattr(bench_run, "machine", no_timing)
    if out == "FILE":
        out = str(tmp_path / "file")
        Path(out).write_text("x")
    elif out == "READONLY":
        out = str(tmp_path / "ro")

        def refuse(*args: object, **kwargs: object) -> tuple[int, str]:
            raise PermissionError(13, "Permission denied", out)

        monkeypatch.setattr(paths_module.tempfile, "mkstemp", refuse)
    elif out == "OK":
        out = str(tmp_path / "ok")
    assert main(["bench", "--out", out, "--steps", steps, "--planar-only"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], lines

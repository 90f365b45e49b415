"""Study execution: serial vs Dask identity, resume, interrupts, bad input (exit 2, one line)."""

from __future__ import annotations

import json
import math
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import dask
import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.studies.episodes import TIMING_METRICS
from otmm_qp.studies.execute import dask_client, run_study
from otmm_qp.studies.spec import load_study, parse_study, plan_study
from otmm_qp.studies.storage import read_episodes
from tests.cli_errors import refusal_text
from tests.factories import PINV_ROW, tiny_study

TINY = tiny_study(
    "tiny",
    seed=3,
    chunk_size=2,
    time_series={"tasks": 1, "stride": 4},
    generators=[
        {"type": "near_singular", "count": 3, "duration": [1.0, 1.5]},
        {"type": "beyond_reach", "count": 2, "duration": [1.0, 1.5]},
    ],
    controllers=[
        PINV_ROW,
        {
            "name": "otmm",
            "filters": [{"type": "otmm", "p": "linear"}],
            "backend": {"type": "pinv"},
            "grid": {"sigma_s": [0.02, 0.05]},
        },
    ],
)


def _write(tmp_path: Path, data: dict, name: str = "study.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def _rows(out: Path) -> dict[str, dict]:
    table = read_episodes(out)
    assert table is not None
    rows = table.to_pylist()
    keys = [r["episode_key"] for r in rows]
    assert len(keys) == len(set(keys)), "an episode was stored twice"
    for row in rows:
        for name in TIMING_METRICS:
            row.pop(name, None)
        for name, value in row.items():  # NaN != NaN: compare it as a marker
            if isinstance(value, float) and math.isnan(value):
                row[name] = "NaN"
    return {r["episode_key"]: r for r in rows}


@pytest.fixture(scope="module")
def serial_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("serial")
    plan = plan_study(parse_study(TINY))
    outcome = run_study(plan, out, "tiny", workers=1)
    assert outcome.ran == len(plan.episodes) == 5 * (3 + 1)  # + one oracle row per task
    return out


def test_grid_expands_to_named_controllers() -> None:
    plan = plan_study(parse_study(TINY))
    names = [c.name for c in plan.controllers]
    assert names == ["pinv", "otmm[sigma_s=0.02]", "otmm[sigma_s=0.05]"]
    assert plan.controllers[2].filters[0].params["sigma_s"] == 0.05


def test_serial_rows_are_complete(serial_out: Path) -> None:
    rows = _rows(serial_out)
    assert len(rows) == 20
    row = next(iter(rows.values()))
    assert {"max_error", "max_joint_speed", "status_ok", "task_seed", "controller_params"} <= set(
        row
    )
    near = [r for r in rows.values() if r["generator"] == "near_singular"]
    assert all(r["task.closest_distance"] is not None for r in near)
    marker = json.loads((serial_out / "study.json").read_text())
    assert marker["study"] == "tiny"
    assert (serial_out / "timeseries").is_dir()


def test_local_cluster_gives_identical_rows(serial_out: Path, tmp_path: Path) -> None:
    """Identical rows on a LocalCluster(2) — twice on one client (the same payload scattered
    again must not race the release of the first study's copy), with quiet workers."""
    plan = plan_study(parse_study(TINY))
    with dask_client(2, None) as client:
        quiet = client.run(lambda: dask.config.get("distributed.worker.profile.enabled"))
        assert set(quiet.values()) == {False}
        run_study(plan, tmp_path / "first", "tiny", workers=2, client=client)
        run_study(plan, tmp_path / "second", "tiny", workers=2, client=client)
    assert _rows(tmp_path / "first") == _rows(serial_out) == _rows(tmp_path / "second")


def test_resume_after_interrupt_adds_only_missing(serial_out: Path, tmp_path: Path) -> None:
    plan = plan_study(parse_study(TINY))
    calls = []

    def stop_after_first_chunk(done: int, failed: int) -> None:
        calls.append(done)
        raise KeyboardInterrupt

    first = run_study(plan, tmp_path, "tiny", workers=1, progress=stop_after_first_chunk)
    assert first.interrupted and 0 < first.ran < 20
    assert len(_rows(tmp_path)) == first.ran  # readable after the interrupt
    second = run_study(plan, tmp_path, "tiny", workers=1)
    assert second.skipped_stored == first.ran and second.ran == 20 - first.ran
    assert _rows(tmp_path) == _rows(serial_out)
    third = run_study(plan, tmp_path, "tiny", workers=1)
    assert third.ran == 0


def test_cli_study_and_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    small = dict(TINY, generators=[dict(TINY["generators"][0], count=2)])
    path = _write(tmp_path, small)
    assert (
        main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1", "--quiet"]) == 0
    )
    out = capsys.readouterr().out
    assert "8 episodes run (0 failed)" in out  # 2 tasks x (3 controllers + the oracle)
    report = (tmp_path / "out" / "study_report.md").read_text()
    assert "Wilcoxon" in report and "success" in report
    assert (tmp_path / "out" / "figures" / "pareto-planar2.png").is_file()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


BAD = [
    ({"generators": [{"type": "nope", "count": 1}]}, "generators.0: unknown task-generator 'nope'"),
    (
        {"generators": [{"type": "boundary", "count": 1, "wobble": 2}]},
        "generators.0.wobble: unknown parameter",
    ),
    ({"generators": [{"type": "boundary", "count": 0}]}, "generators.0.count"),
    (
        {"controllers": [{"name": "a", "backend": {"type": "dls"}, "grid": {"damping": []}}]},
        "zero controllers",
    ),
    (
        {
            "controllers": [
                {"name": "a", "backend": {"type": "dls"}, "grid": {"damping": [0.1, 0.1]}}
            ]
        },
        "duplicate names",
    ),
    (
        {"controllers": [{"name": "a", "backend": {"type": "pinv"}, "grid": {"wobble": [1]}}]},
        "grid.wobble",
    ),
    (
        {
            "robots": [
                {
                    "name": "stiff",
                    "robot": {
                        "type": "planar",
                        "link_lengths": [1.0, 0.8],
                        "limits": [[-1.0, 1.0], [0.5, 2.0]],
                    },
                }
            ],
            "generators": [{"type": "near_singular", "count": 1, "restarts": 2, "iterations": 3}],
        },
        "on robot 'planar2': no singular configuration",
    ),
]


@pytest.mark.parametrize(("change", "message"), BAD)
def test_bad_study_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: dict, message: str
) -> None:
    path = _write(tmp_path, {**TINY, **change})
    status = main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1", "--quiet"])
    err = capsys.readouterr().err
    assert status == 2
    assert message in refusal_text(err)  # a first line of at most 200 characters, details after


def test_same_name_of_another_arm_is_another_study(
    serial_out: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder belongs to one study: the same name on another arm is refused (no run holds
    the folder's lock any more), a changed setting of the same study is not."""
    target = tmp_path / "existing"
    shutil.copytree(serial_out, target)
    robots = [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.7]}}]
    other = _write(tmp_path, dict(TINY, robots=robots, generators=TINY["generators"][1:]))
    args = ["study", str(other), "--out", str(target), "--workers", "1", "--quiet", "--no-report"]
    assert main(args) == 2
    text = refusal_text(capsys.readouterr().err)
    assert "holds another study named 'tiny' (of other robots or another task)" in text
    assert "--force" in text and len(_rows(target)) == 20  # nothing lost, nothing added
    assert json.loads((target / "study.json").read_text())["config"]["robots"][0]["robot"][
        "link_lengths"
    ] == [1.0, 0.8]


def test_other_study_directory_is_refused_unless_forced(
    serial_out: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "existing"
    shutil.copytree(serial_out, target)
    other = _write(
        tmp_path, dict(TINY, name="other", generators=[dict(TINY["generators"][1], count=1)])
    )
    args = ["study", str(other), "--out", str(target), "--workers", "1", "--quiet", "--no-report"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "holds study 'tiny'" in err and err.count("\n") == 1
    assert len(_rows(target)) == 20  # nothing lost
    assert main([*args, "--force"]) == 0
    assert {r["study"] for r in _rows(target).values()} == {"other"}


def test_unreachable_scheduler_fails_fast(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from otmm_qp.studies import execute

    monkeypatch.setattr(execute, "CONNECT_TIMEOUT", 3.0)  # the default is 10 s
    path = _write(tmp_path, TINY)
    tic = time.monotonic()
    status = main(
        [
            "study",
            str(path),
            "--out",
            str(tmp_path / "o"),
            "--scheduler",
            f"tcp://127.0.0.1:{_free_port()}",
            "--quiet",
        ]
    )
    elapsed = time.monotonic() - tic
    err = capsys.readouterr().err
    assert status == 2 and "--scheduler: cannot reach" in err and err.count("\n") == 1
    assert elapsed < 10.0


def test_load_study_errors_name_the_file(tmp_path: Path) -> None:
    from otmm_qp.exceptions import ConfigError

    with pytest.raises(ConfigError, match="no such study file"):
        load_study(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [")
    with pytest.raises(ConfigError, match="malformed YAML"):
        load_study(bad)


def _spawn(args: list[str]) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )


def test_external_scheduler_with_a_worker_killed_midway(tmp_path: Path) -> None:
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    processes = [
        _spawn(
            [
                "distributed.cli.dask_scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--dashboard-address",
                ":0",
            ]
        )
    ]
    try:
        workers = [
            _spawn(
                [
                    "distributed.cli.dask_worker",
                    address,
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ]
            )
            for _ in range(2)
        ]
        processes += workers
        study = dict(
            TINY,
            name="external",
            chunk_size=1,
            generators=[
                {"type": "near_singular", "count": 8, "duration": [1.0, 1.5]},
                {"type": "random_reachable", "count": 8, "duration": [1.0, 1.5]},
            ],
        )
        path = _write(tmp_path, study)
        out = tmp_path / "out"
        driver = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "otmm_qp.cli",
                "study",
                str(path),
                "--out",
                str(out),
                "--scheduler",
                address,
                "--quiet",
                "--no-report",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and driver.poll() is None:
            parts = list((out / "episodes").glob("part-*.parquet")) if out.exists() else []
            if parts:
                break
            time.sleep(0.05)
        killed_midway = driver.poll() is None
        workers[0].kill()
        stdout, stderr = driver.communicate(timeout=120)
        assert driver.returncode == 0, stderr.decode()
        assert killed_midway
        rows = _rows(out)  # asserts each key stored once
        assert len(rows) == 16 * (3 + 1)  # + one oracle row per task
        assert set(rows) == {e.key for e in plan_study(parse_study(study)).episodes}
    finally:
        for process in processes:
            process.kill()
            process.wait(timeout=10)


SWALLOWED_STOP = """
import os, signal, sys
import otmm_qp.studies.execute as execute
from otmm_qp import interrupt

make_chunks = execute.make_chunks

def swallowing(*args, **kwargs):
    try:  # library code that catches KeyboardInterrupt and goes on
        os.kill(os.getpid(), signal.SIGTERM)
        while not interrupt.requested():
            pass
        for _ in range(10**6):  # the handler runs here, once the watcher hands the stop on
            pass
    except KeyboardInterrupt:
        print("swallowed", file=sys.stderr)
    return make_chunks(*args, **kwargs)

execute.make_chunks = swallowing
from otmm_qp.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_stop_that_study_code_swallows_still_stops_the_study(tmp_path: Path) -> None:
    """Held-out case: SIGTERM early in a study ended with exit 0 and no line (the private SIGTERM
    handler raised without recording the request; the KeyboardInterrupt was swallowed)."""
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    argv = ["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1", "--quiet"]
    done = subprocess.run(
        [sys.executable, "-c", SWALLOWED_STOP, *argv], capture_output=True, text=True, timeout=120
    )
    lines = [line for line in done.stderr.strip().splitlines() if line != "swallowed"]
    assert done.returncode == 130, done.stderr[-3000:]
    assert lines == ["otmm-qp: interrupted; every finished episode is stored (rerun to resume)"]

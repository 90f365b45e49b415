"""ResultsDir owns the run-folder layout: what it writes it finds and reads back (issue 17).

A run written through ``ResultsDir.write_run`` is found by ``run_files`` under its display
names and read back by ``read_run`` cell for cell; files outside the layout (``replays/``,
``figures/``, symlinks, other CSVs) are not runs; ``robot.json`` round-trips and is refused
when hostile; the streaming thinning keeps at most ``limit + 1`` evenly spaced rows with the
first and the last.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError
from otmm_qp.output.results import MAX_ROBOT_JSON_BYTES, ResultsDir
from otmm_qp.output.run_csv import thinned_rows
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.simulation import Episode, simulate
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp_controllers.pinv import PseudoInverseBackend


def _result(experiment: str, controller: str) -> RunResult:
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.927, -2.5])
    trajectory = CircleTrajectory(robot.forward(q0), [1.2, 0.0], 0.6, 10.0)
    episode = Episode(robot, trajectory, q0, 0.02, 0.1, name=experiment)
    return simulate(episode, Controller(controller, [], PseudoInverseBackend()))


def test_what_write_run_writes_run_files_finds_and_read_run_reads(tmp_path: Path) -> None:
    results = ResultsDir(tmp_path)
    names = ["pinv 1", "pinv_1", "PINV 1"]  # one safe form (pinv_1): slugs made unique
    written = [results.write_run(_result("E 1", name), names) for name in names]
    assert [p.stem for p in written] == ["pinv_1", "pinv_1-2", "PINV_1-3"]
    assert all(p.parent.parent.parent == tmp_path for p in written)
    (tmp_path / "replays" / "x").mkdir(parents=True)
    (tmp_path / "replays" / "x" / "a.csv").write_text(written[0].read_text())
    (tmp_path / "E_1" / "clik" / "other.csv").write_text("a,b\n1,2\n")  # not a time series
    (tmp_path / "E_1" / "clik" / "link.csv").symlink_to(written[0])
    found = results.run_files()
    assert sorted(r.path for r in found) == sorted(written)
    # without a summary the file-name forms are all there is: pinv_1-2 and PINV_1-3 stay so
    assert sorted(r.controller for r in found) == ["PINV_1-3", "pinv_1", "pinv_1-2"]
    (tmp_path / "summary.csv").write_text(
        "experiment,loop_mode,controller\n" + "".join(f"E 1,clik,{n}\n" for n in names)
    )
    found = results.run_files()  # the summary's display names, in its order
    assert [(r.experiment, r.loop_mode, r.controller, r.path) for r in found] == [
        ("E 1", "clik", name, path) for name, path in zip(names, written, strict=True)
    ]
    run = next(r for r in found if r.path == written[0])
    assert run.experiment_dir == written[0].parent.parent
    table = results.read_run(run)
    with written[0].open(newline="") as handle:
        rows = list(csv.reader(handle))
    assert list(table.header) == rows[0] and table.rows == rows[1:]


def test_run_names_are_the_summary_rows_and_lenient(tmp_path: Path) -> None:
    results = ResultsDir(tmp_path)
    assert results.run_names() == []  # no summary.csv: a replay still works
    (tmp_path / "summary.csv").write_text(
        "experiment,loop_mode,controller\nE 1,clik,p/inv 1\n,clik,x\nE 2,newton,dls\n"
    )
    assert results.run_names() == [("E 1", "clik", "p/inv 1"), ("E 2", "newton", "dls")]
    (tmp_path / "summary.csv").write_bytes(b"\xff\xfe not utf-8")
    assert results.run_names() == []
    with pytest.raises(ConfigError, match="RESULTS_DIR"):
        ResultsDir(tmp_path / "missing").run_files()


def test_robot_record_round_trips_and_hostile_records_are_refused(tmp_path: Path) -> None:
    results = ResultsDir(tmp_path)
    folder = tmp_path / "E"
    assert results.read_robot_record(folder) is None
    params = {"link_lengths": [1.0, 0.8]}
    path = results.write_robot_record(folder, "planar", params)
    assert path == folder / "robot.json"
    assert results.read_robot_record(folder) == {"type": "planar", "params": params}
    for text, message in [
        ("[1, 2]", "expected"),
        ('{"type": "planar", "params": {"type": "x"}}', "params"),
        ("{" * 50_000, "malformed robot record"),
        (" " * (MAX_ROBOT_JSON_BYTES + 1), f"larger than {MAX_ROBOT_JSON_BYTES} bytes"),
    ]:
        path.write_text(text)
        with pytest.raises(ConfigError, match=message):
            results.read_robot_record(folder)
    path.unlink()
    path.symlink_to(tmp_path / "elsewhere.json")
    with pytest.raises(ConfigError, match="symlink"):
        results.read_robot_record(folder)


@given(st.integers(0, 3000), st.integers(1, 200))
def test_thinning_keeps_first_last_and_even_spacing(n: int, limit: int) -> None:
    kept = thinned_rows(iter([[str(k), "x"] for k in range(n)] + [["short"]]), 2, limit)
    index = [int(row[0]) for row in kept]
    assert len(index) <= limit + 1
    if n == 0:
        assert index == []
        return
    assert index[0] == 0 and index[-1] == n - 1
    if n <= limit:
        assert index == list(range(n))  # nothing dropped below the cap
    gaps = np.diff(index[:-1])
    assert gaps.size == 0 or np.all(gaps == gaps[0])  # one stride, a power of two
    assert gaps.size == 0 or (int(gaps[0]) & (int(gaps[0]) - 1)) == 0

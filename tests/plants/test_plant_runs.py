"""Plants and conditioning through the CLI: runs, studies with a plants axis, bad input, bench."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from otmm_qp.cli import main
from otmm_qp.studies.spec import controller_record, expand_controllers, parse_study
from otmm_qp.studies.storage import read_episodes
from tests.cli_errors import refusal_text
from tests.factories import OTMM_PINV, run_script, tiny_run

ROOT = Path(__file__).resolve().parents[2]

RUN = tiny_run(
    [
        OTMM_PINV.replace("OTMM", "otmm", 1),
        "name: dls-conditioned\nbackend: {type: dls, damping: 0.05}\n"
        "conditioning: [{type: speed_scale, margin: 0.5}, {type: position_clip}]",
    ],
    duration=1.0,
    extra="    PLANT\n",
)


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _write(tmp_path: Path, plant: str) -> Path:
    config = tmp_path / "run.yaml"
    config.write_text(RUN.replace("PLANT", plant), encoding="utf-8")
    return config


def test_run_with_a_plant_per_experiment_records_the_true_motion(tmp_path: Path) -> None:
    config = _write(tmp_path, "plant: [{type: lag, tau: 0.05}, {type: sensor, noise: 1.0e-3}]")
    assert (
        main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"]) == 0
    )
    summary = _rows(tmp_path / "out" / "summary.csv")
    assert {r["controller"] for r in summary} == {"otmm", "dls-conditioned"}
    for row in summary:
        assert float(row["speed_gap_max"]) > 0.0  # the lag: commanded ≠ actual
    conditioned = next(r for r in summary if r["controller"] == "dls-conditioned")
    assert float(conditioned["max_joint_speed"]) <= 0.5 * np.pi + 1e-9  # PlanarArm: π rad/s
    series = next((tmp_path / "out").rglob("*otmm*.csv"))
    rows = _rows(series)
    assert "qdot_actual_joint1" in rows[0] and "torque_ratio" in rows[0]
    # The recorded q is the true state: its Euler differences are the actual velocities.
    q = np.array([[float(r["q_joint1"]), float(r["q_joint2"])] for r in rows])
    actual = np.array(
        [[float(r["qdot_actual_joint1"]), float(r["qdot_actual_joint2"])] for r in rows]
    )
    assert np.allclose(np.diff(q, axis=0) / 0.02, actual[:-1], atol=1e-6)


@pytest.mark.parametrize(
    ("plant", "field"),
    [
        ("plant: {type: lag, tau: 0.0}", "experiments.0.plant.tau"),
        ("plant: {type: lag, tau: -0.02}", "experiments.0.plant.tau"),
        ("plant: {type: delay, steps: -1}", "experiments.0.plant.steps"),
        (
            "plant: [{type: lag, tau: 0.1}, {type: sensor, noise: .nan}]",
            "experiments.0.plant.1.noise",
        ),
        ("plant: {type: mujoco}", "experiments.0.plant.effort_limit"),  # planar: no effort
        ("plant: {type: lagg}", "experiments.0.plant"),
    ],
)
def test_bad_plants_are_one_line_exit_2_before_compute(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], plant: str, field: str
) -> None:
    out = tmp_path / "out"
    assert (
        main(["run", str(_write(tmp_path, plant)), "--out", str(out), "--quiet", "--no-figures"])
        == 2
    )
    err = refusal_text(capsys.readouterr().err)  # first line <= 200 characters, details after
    assert f": {field}:" in err or f" {field}:" in err, err
    assert not (out / "summary.csv").exists()


STUDY = """
name: plants-tiny
seed: 3
dt: 0.02
robots:
  - name: planar3
    robot: {type: planar, link_lengths: [1.0, 0.8, 0.5]}
generators:
  - {type: near_singular, count: 2, duration: [1.0, 1.5]}
plants:
  - {name: ideal, plant: {type: ideal}}
  - {name: lag, plant: [{type: lag, tau: 0.02}, {type: delay, steps: 1}]}
  - {name: noise, plant: {type: sensor, noise: 1.0e-4}}
controllers:
  - name: pinv
    backend: {type: pinv}
  - name: dls
    backend: {type: dls, damping: 0.05}
  - name: otmm
    filters: [{type: otmm, sigma_s: 0.05, p: linear}]
    backend: {type: pinv}
"""


def test_plants_axis_names_rows_and_keeps_old_keys(tmp_path: Path) -> None:
    import yaml

    data = yaml.safe_load(STUDY)
    expanded = expand_controllers(parse_study(data))
    assert [c.name for c in expanded][:3] == ["pinv@ideal", "pinv@lag", "pinv@noise"]
    without = dict(data)
    without.pop("plants")
    plain = expand_controllers(parse_study(without))
    assert "plant" not in controller_record(plain[0])  # keys of plant-free studies unchanged
    config = tmp_path / "study.yaml"
    config.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "study"
    assert main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    table = read_episodes(out)
    assert table is not None
    rows = [r for r in table.to_pylist() if r["controller"] != "oracle"]
    assert {r["plant"] for r in rows} == {"ideal", "lag", "noise"}
    assert len(rows) == 2 * 3 * 3
    assert main(["study", "plants", str(out)]) == 0
    assert main(["study", "plants", str(tmp_path)]) == 2


def test_bad_plant_in_a_study_names_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "study.yaml"
    config.write_text(STUDY.replace("tau: 0.02", "tau: -1"), encoding="utf-8")
    assert main(["study", str(config), "--out", str(tmp_path / "s"), "--workers", "1"]) == 2
    assert "plants.1.plant.0.tau: must be a finite number > 0" in capsys.readouterr().err


def test_bench_plant_runs_tiny() -> None:
    done = run_script("benchmarks/bench_plant.py", "--steps", "10", "--rounds", "1", timeout=120)
    assert done.returncode == 0, done.stderr
    assert "plant mujoco (2 ms)" in done.stdout and "stage jerk_limit" in done.stdout


def test_shipped_plants_study_plans_and_runs_a_slice(tmp_path: Path) -> None:
    import yaml

    from otmm_qp.studies.spec import load_study

    shipped = load_study(ROOT / "configs/studies/plants.yaml")
    controllers = expand_controllers(shipped)
    assert len(controllers) == 8 * 18 and sum(g.count for g in shipped.generators) == 20
    sweep = {f"lag{t}ms-delay{d}" for t in (2, 10, 30) for d in (1, 2, 4)}
    assert {c.name.rsplit("@", 1)[1] for c in controllers} == {
        "ideal", "lag20ms-delay1", "noise1e-4", "mujoco", "encoder-1q", "encoder-3q",
        "franka_fci", "ur_e_series", "ur_cb3", *sweep,
    }  # fmt: skip
    data = yaml.safe_load((ROOT / "configs/studies/plants.yaml").read_text(encoding="utf-8"))
    data["robots"] = data["robots"][1:]  # Panda
    data["generators"] = [dict(data["generators"][0], count=1)]
    names = ("qp", "OTMM+pinv", "OTMM+qp")
    data["controllers"] = [c for c in data["controllers"] if c["name"] in names]
    data["plants"] = [p for p in data["plants"] if p["name"] in ("ideal", "mujoco", "franka_fci")]
    config = tmp_path / "slice.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    out = tmp_path / "slice"
    assert main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"]) in (0, 2)
    stored = read_episodes(out).to_pylist()  # type: ignore[union-attr]
    rows = [r for r in stored if r["controller"] != "oracle"]
    assert len(stored) == len(rows) + 1  # one offline reference for the one task
    assert len(rows) == 9 and all(r["status"] in ("ok", "stopped") for r in rows)
    mujoco = [r for r in rows if r["plant"] in ("mujoco", "franka_fci")]
    assert all(0.0 < r["peak_torque_ratio"] <= 1.0 for r in mujoco)


def test_limit_cost_pairs_qp_with_todays_box_per_plant() -> None:
    """Violations, success and the paired tests of qp against qp-box on the same tasks."""
    from otmm_qp.studies.plant_headline import limit_cost

    rows = []
    for i in range(12):
        task = {"robot": "ur5", "generator": "g", "task_index": i}
        # lag: qp keeps the limits and succeeds on 8 tasks the box fails; errors lower on all
        rows.append({**task, "controller": "qp@lag", "plant": "lag", "success": True,
                     "max_error": 0.01, "position_violations": 0})  # fmt: skip
        rows.append({**task, "controller": "qp-box@lag", "plant": "lag", "success": i >= 8,
                     "max_error": 0.02 + i, "position_violations": 3 if i < 5 else 0})  # fmt: skip
        rows.append({**task, "controller": "pinv@lag", "plant": "lag", "success": False,
                     "max_error": 1.0, "position_violations": 9})  # fmt: skip
    table = limit_cost(rows)
    line = next(x for x in table.splitlines() if x.startswith("| lag |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[1] == "0 / 5" and cells[2] == "100 / 33"
    assert cells[3].startswith("8 / 0, ") and float(cells[3].split(", ")[1]) < 0.01
    assert cells[4].startswith("12 / 0 / 0, ")
    assert limit_cost([r for r in rows if not r["controller"].startswith("qp-box")]) == ""

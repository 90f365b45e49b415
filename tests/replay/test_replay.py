"""Replays read back stored runs: GIF frames follow the stored path; bad input is one line."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from otmm_qp.cli import main
from otmm_qp.replay import find_replays, write_replays
from otmm_qp.replay.frames import plan_frames
from otmm_qp.replay.planar_animation import TIP_COLOR
from otmm_qp.replay.robot_model import fit_planar_arm, identify_urdf_arm, load_robot
from otmm_qp.replay.stored_runs import discover_runs, group_scenarios
from tests.cli_errors import refusal_text
from tests.factories import DLS_ITEM, OTMM_PINV, PINV_ITEM, tiny_run, ur5_wrist_run

PLANAR = tiny_run(
    ["name: RMRC\nbackend: {type: pinv}", OTMM_PINV.replace("OTMM", "OTMM/linear", 1)],
    experiment_name="E1.circle",
    duration=1.2,
    more=(
        "  - name: three-link\n"
        "    robot: {type: planar, link_lengths: [0.5, 0.4, 0.3]}\n"
        "    q0: [0.3, 0.5, 0.4]\n"
        "    trajectory: {type: quintic_line, end: [0.5, 0.6], duration: 0.4}\n"
        "    duration: 0.4\n"
        "    controllers:\n"
        "      - name: DLS\n"
        "        backend: {type: dls, damping: 0.05}\n"
    ),
)

ARM = ur5_wrist_run("arm", [PINV_ITEM, DLS_ITEM], motion=0.3)


def _run(tmp_path_factory: pytest.TempPathFactory, text: str, name: str) -> Path:
    folder = tmp_path_factory.mktemp(name)
    config = folder / "config.yaml"
    config.write_text(text)
    out = folder / "results"
    assert main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def planar_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory, PLANAR, "planar")


@pytest.fixture(scope="module")
def arm_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory, ARM, "arm")


def _copy(results: Path, tmp_path: Path) -> Path:
    target = tmp_path / "results"
    shutil.copytree(results, target)
    return target


def test_stored_runs_are_read_back_with_display_names(planar_results: Path) -> None:
    runs = discover_runs(planar_results)
    names = [(r.experiment, r.loop_mode, r.controller) for r in runs]
    assert names == [
        ("E1.circle", "clik", "RMRC"),
        ("E1.circle", "clik", "OTMM/linear"),
        ("three-link", "clik", "DLS"),
    ]
    assert runs[0].steps == 60 and runs[0].q.shape == (60, 2) and runs[0].dimension == 2


def test_planar_link_lengths_are_recovered_from_the_time_series(planar_results: Path) -> None:
    groups = group_scenarios(discover_runs(planar_results))
    two = fit_planar_arm(groups[("E1.circle", "clik")])
    three = fit_planar_arm(groups[("three-link", "clik")])
    np.testing.assert_allclose(two.link_lengths, [1.0, 0.8], atol=1e-7)
    np.testing.assert_allclose(three.link_lengths, [0.5, 0.4, 0.3], atol=1e-7)


def test_ur5_is_identified_among_arms_with_the_same_joint_names(arm_results: Path) -> None:
    robot = identify_urdf_arm(discover_runs(arm_results))
    assert robot.name == "ur5" and robot.frame_name == "tool0"


def _tip_centres(frame: Image.Image, maps: list[dict[str, float]]) -> list[np.ndarray | None]:
    """Centroid (in data coordinates [m]) of the tip colour inside each panel."""
    rgb = np.asarray(frame.convert("RGB")).astype(int)
    mask = (
        (np.abs(rgb[:, :, 0] - TIP_COLOR[0]) < 30)
        & (np.abs(rgb[:, :, 1] - TIP_COLOR[1]) < 30)
        & (np.abs(rgb[:, :, 2] - TIP_COLOR[2]) < 30)
    )
    rows, columns = np.nonzero(mask)
    x = (columns - np.array([[m["ox"]] for m in maps])) / np.array([[m["sx"]] for m in maps])
    y = (rows - np.array([[m["oy"]] for m in maps])) / np.array([[m["sy"]] for m in maps])
    centres: list[np.ndarray | None] = []
    for i in range(len(maps)):
        near = [j for j in range(columns.size) if abs(x[i, j]) < 2.0 and abs(y[i, j]) < 2.0]
        # panels are side by side: keep the pixels of panel i (closest panel origin)
        own = [
            j
            for j in near
            if min(range(len(maps)), key=lambda p: abs(columns[j] - maps[p]["ox"])) == i
        ]
        centres.append(np.array([x[i, own].mean(), y[i, own].mean()]) if own else None)
    return centres


def test_planar_gif_frames_and_the_drawn_tip_follow_the_stored_path(
    planar_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = _copy(planar_results, tmp_path)
    assert main(["replay", str(results), "--experiment", "E1.circle", "--max-frames", "12"]) == 0
    line = capsys.readouterr().out
    assert re.search(r"replay: .*E1.circle-clik\.gif \(\d+ kB, 2 controllers, 12 of 60 steps", line)
    gif = results / "replays" / "E1.circle-clik.gif"
    sidecar = json.loads(gif.with_suffix(".json").read_text())
    runs = group_scenarios(discover_runs(results))[("E1.circle", "clik")]
    pixel = 1.0 / sidecar["pixel_maps"][0]["sx"]  # [m] per pixel
    with Image.open(gif) as image:
        assert image.n_frames == sidecar["frames"] == 12
        assert sidecar["steps"] == plan_frames(60, 12).indices.tolist()
        for index, step in enumerate(sidecar["steps"]):
            image.seek(index)
            centres = _tip_centres(image, sidecar["pixel_maps"])
            for run, centre in zip(runs, centres, strict=True):
                assert centre is not None, f"no tip drawn in frame {index} for {run.controller}"
                error = float(np.linalg.norm(centre - run.position[step]))
                assert error < 2.5 * pixel, (run.controller, step, error / pixel)


def test_the_tip_check_detects_a_wrong_frame(planar_results: Path, tmp_path: Path) -> None:
    results = _copy(planar_results, tmp_path)
    write_replays(results, "E1.circle", max_frames=6, quiet=True)
    gif = results / "replays" / "E1.circle-clik.gif"
    sidecar = json.loads(gif.with_suffix(".json").read_text())
    with Image.open(gif) as image:
        image.seek(0)
        centre = _tip_centres(image, sidecar["pixel_maps"])[0]
    run = discover_runs(results)[0]
    pixel = 1.0 / sidecar["pixel_maps"][0]["sx"]
    assert centre is not None
    assert np.linalg.norm(centre - run.position[-1]) > 5 * pixel  # the last step is elsewhere


def test_gif_is_decimated_to_the_byte_budget(planar_results: Path, tmp_path: Path) -> None:
    results = _copy(planar_results, tmp_path)
    write_replays(results, "E1.circle", max_frames=16, max_bytes=30_000, quiet=True)
    gif = results / "replays" / "E1.circle-clik.gif"
    with Image.open(gif) as image:
        frames = image.n_frames
    assert gif.stat().st_size <= 30_000
    assert frames == 8  # 16 frames (~45 kB) halved once


def test_arm_page_is_self_contained_and_decimated(
    arm_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = _copy(arm_results, tmp_path)
    assert main(["replay", str(results), "--max-bytes", "20000"]) == 0
    line = capsys.readouterr().out
    assert re.search(
        r"replay: .*wrist-clik\.html \([\d.]+ MB, 2 controllers, \d+ of 30 steps", line
    )
    page = (results / "replays" / "wrist-clik.html").read_text()
    assert "MeshCat.Viewer" in page and "DecompressionStream" in page
    # offline: no external script, stylesheet or fetch target
    assert not re.search(r"<(script|link)[^>]+(src|href)=", page)
    assert find_replays(results) == [("wrist — clik", Path("replays/wrist-clik.html"))]


def test_missing_meshes_fall_back_to_simple_shapes_with_a_warning(
    arm_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from otmm_qp.robots.pinocchio_arm import PinocchioArm

    urdf = Path(PinocchioArm(name="ur5").urdf_path or "")
    broken = tmp_path / "ur5_no_meshes.urdf"
    broken.write_text(urdf.read_text().replace("package://", "package://missing_package/"))
    results = _copy(arm_results, tmp_path)
    (results / "wrist" / "robot.json").write_text(
        json.dumps({"type": "pinocchio", "params": {"urdf": str(broken), "frame": "tool0"}})
    )
    assert main(["replay", str(results)]) == 0
    captured = capsys.readouterr()
    warning = [line for line in captured.err.splitlines() if "warning" in line]
    assert (
        len(warning) == 1 and "meshes unavailable" in warning[0] and "simple shapes" in warning[0]
    )
    page = (results / "replays" / "wrist-clik.html").read_text()
    assert "simple shapes" in page


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (
            ["--experiment", "E9"],
            r"--experiment: unknown experiment 'E9'; available: E1.circle, three-link",
        ),
        (
            ["--controller", "SRI"],
            r"--controller: unknown controller 'SRI'; available: DLS, OTMM/linear, RMRC",
        ),
        (
            ["--experiment", "three-link", "--controller", "RMRC"],
            r"--controller: unknown controller 'RMRC' in experiment 'three-link'; available: DLS",
        ),
        (["--max-frames", "1"], r"--max-frames: must be >= 2, got 1"),
    ],
)
def test_unknown_names_are_one_line_errors_listing_what_is_available(
    planar_results: Path, arguments: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(planar_results), *arguments]) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, refusal_text(err)), err
    assert not (planar_results / "replays").exists()


def test_results_without_time_series_are_a_one_line_error(
    planar_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "only-summary"
    folder.mkdir()
    shutil.copy(planar_results / "summary.csv", folder / "summary.csv")
    for target in (folder, tmp_path / "missing"):
        assert main(["replay", str(target)]) == 2
        err = capsys.readouterr().err.strip()
        assert refusal_text(err).startswith("otmm-qp: error: RESULTS_DIR:"), err


def test_replays_are_written_only_inside_the_results_folder(
    planar_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = _copy(planar_results, tmp_path)
    outside = tmp_path / "outside"
    outside.mkdir()
    (results / "replays").symlink_to(outside, target_is_directory=True)
    assert main(["replay", str(results)]) == 2
    assert "outside" in capsys.readouterr().err
    assert list(outside.iterdir()) == []


def test_find_replays_ignores_sidecars_that_point_elsewhere(tmp_path: Path) -> None:
    folder = tmp_path / "replays"
    folder.mkdir()
    (folder / "a.gif").write_bytes(b"GIF89a")
    (folder / "a.json").write_text(json.dumps({"title": "A", "file": "a.gif"}))
    (folder / "b.json").write_text(json.dumps({"title": "B", "file": "../summary.csv"}))
    (folder / "c.json").write_text("{not json")
    (folder / "d.json").write_text(json.dumps({"title": "D", "file": "gone.html"}))
    assert find_replays(tmp_path) == [("A", Path("replays/a.gif"))]
    assert find_replays(tmp_path / "nothing") == []


def test_run_replay_records_the_robot_and_writes_every_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "config.yaml"
    config.write_text(PLANAR.replace("duration: 1.2", "duration: 0.3"))
    out = tmp_path / "out"
    assert (
        main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet", "--replay"])
        == 0
    )
    assert json.loads((out / "E1.circle" / "robot.json").read_text()) == {
        "type": "planar",
        "params": {"link_lengths": [1.0, 0.8]},
    }
    titles = [title for title, _ in find_replays(out)]
    assert titles == ["E1.circle — clik", "three-link — clik"]
    assert load_robot(discover_runs(out)[:1]).name == "planar2"

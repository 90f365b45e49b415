"""docs/your-own-arm.md, run verbatim on a user's URDF package; ``otmm-qp init study``; bad input.

The user's package is example-robot-data's Kinova Jaco 2 (j2s6s200, which no shipped config
uses by path) copied into a temporary folder as ``my_jaco_description/`` with its mesh URIs
rewritten to that package and its two finger joints made revolute (as in Kinova's own
description), so that they can be locked. The doc's commands run in that folder; the study
file ``init`` writes is run with every generator's count set to 1 (the only reduction).
"""

from __future__ import annotations

import csv
import json
import math
import re
import shlex
import shutil
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.commands.init import SHARES, generator_counts
from otmm_qp.exceptions import RobotLoadError
from otmm_qp.registry import check_parameters
from otmm_qp.robots.urdf_meshes import check_meshes
from otmm_qp.studies.limit_keeping import limit_breaks
from otmm_qp.studies.rows import load_rows
from otmm_qp.studies.spec import load_study
from otmm_qp.studies.storage import StudyDirectoryError, prepare_directory
from tests.cli_errors import refusal_text

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "your-own-arm.md"
URDF = "my_jaco_description/robots/kinova.urdf"
FINGERS = ("j2s6s200_joint_finger_1", "j2s6s200_joint_finger_2")


def doc_blocks(language: str) -> list[str]:
    """The fenced blocks of one language in the doc, in order."""
    text = DOC.read_text(encoding="utf-8")
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def make_package(folder: Path) -> Path:
    """The Jaco as a user's package ``folder/my_jaco_description``; returns the URDF path."""
    from example_robot_data.robots_loader import getModelPath

    source = Path(getModelPath("kinova_description/robots/kinova.urdf")) / "kinova_description"
    package = folder / "my_jaco_description"
    shutil.copytree(source, package)
    urdf = folder / URDF
    text = urdf.read_text(encoding="utf-8").replace(
        "package://example-robot-data/robots/kinova_description/", "package://my_jaco_description/"
    )
    for joint in FINGERS:
        found = re.search(rf'<joint name="{joint}" type="fixed">(.*?)</joint>', text, flags=re.S)
        assert found is not None, joint
        body = found.group(1) + '<axis xyz="0 0 1"/><limit lower="0" upper="1.51" velocity="1"/>'
        text = text.replace(found.group(0), f'<joint name="{joint}" type="revolute">{body}</joint>')
    urdf.write_text(text, encoding="utf-8")
    return urdf


@pytest.fixture
def user_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    make_package(tmp_path)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def urdf_limits(urdf: Path) -> dict[str, tuple[str, float]]:
    """Movable joints of the URDF file itself: (type, velocity limit), read independently."""
    limits = {}
    for joint in ElementTree.parse(urdf).getroot().iter("joint"):
        kind = joint.get("type", "")
        if kind in ("revolute", "continuous", "prismatic"):
            limit = joint.find("limit")
            speed = float(limit.get("velocity", 0.0)) if limit is not None else 0.0
            limits[str(joint.get("name"))] = (kind, speed)
    return limits


def one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    return refusal_text(capsys.readouterr().err)  # first line <= 200 characters, details after


def test_doc_steps_take_a_urdf_package_to_a_verdict(
    user_package: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    commands = [line.strip() for block in doc_blocks("bash") for line in block.splitlines()]
    init, run, study, verdict = commands
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    own = readme[readme.index("## Your own arm") :]
    own = own[: own.index("\n## ")]
    assert re.findall(r"```bash\n(.*?)```", own, flags=re.S)[0].splitlines() == [
        init,
        study,
        verdict,
    ]  # the README's section runs the doc's commands
    assert init.startswith("otmm-qp init study ") and run.startswith("otmm-qp run ")

    # 1. init, verbatim: the limits comment is the URDF's, the file is a valid study
    assert main(shlex.split(init)[1:]) == 0, capsys.readouterr().err
    study_file = user_package / "jaco-study.yaml"
    text = study_file.read_text(encoding="utf-8")
    limits = urdf_limits(user_package / URDF)
    arm_joints = [name for name in limits if name not in FINGERS]
    assert len(arm_joints) == 6 and all(f"#   {name}:" in text for name in arm_joints)
    assert not any(f"#   {name}:" in text for name in FINGERS)  # locked: not in the arm
    for name in arm_joints:
        kind, speed = limits[name]
        line = next(ln for ln in text.splitlines() if ln.startswith(f"#   {name}:"))
        assert f"speed {speed:.4g}" in line, line
        assert ("[-.inf, .inf]" in line) == (kind == "continuous"), line
    config = load_study(study_file)
    robot = config.robots[0].robot
    assert robot.params["frame"] == "j2s6s200_end_effector"
    assert robot.params["locked_joints"] == list(FINGERS)
    assert sum(g.count for g in config.generators) == 60
    assert config.decide is not None and (config.decide.budget_tasks, config.decide.batch) == (
        600,
        60,
    )

    # 2. the run config of the doc, verbatim, and its command
    (run_yaml,) = doc_blocks("yaml")
    (user_package / "jaco-run.yaml").write_text(run_yaml, encoding="utf-8")
    argv = shlex.split(run)[1:]
    assert main([*argv, "--figures", "none", "--quiet"]) == 0, capsys.readouterr().err
    with (user_package / "results/jaco-wrist/summary.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["outcome"] for r in rows] == ["completed", "completed"]
    assert all(float(r["initial_jump"]) < 1e-6 for r in rows)  # the first waypoint is q0
    assert all(float(r["min_sigma"]) < 0.05 for r in rows)  # it does pass near the wrist

    # 3. the study at tiny size: every generator's count set to 1, one batch of 6 tasks
    data = yaml.safe_load(text)
    for generator in data["generators"]:
        generator["count"] = 1
    data["decide"] = {"budget_tasks": 6, "batch": 6}
    study_file.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    argv = shlex.split(study)[1:]
    assert main([*argv, "--workers", "1", "--quiet"]) == 0, capsys.readouterr().err
    report = (user_package / "results/jaco-study/study_report.md").read_text(encoding="utf-8")
    assert "### Verdict" in report and "Singular crossings" in report
    accuracy = next(ln for ln in report.splitlines() if ln.startswith("- **Accuracy"))
    _, rows = load_rows(user_package / "results/jaco-study")
    for name in rows.controllers():  # every named row that broke the limits says so
        broken, total = limit_breaks(rows.rows, name)
        if f" {name} " in accuracy and broken:
            assert f"{name} " in accuracy and f"limits broken on {broken} of {total}" in accuracy
    decision = (user_package / "results/jaco-study/decision.md").read_text(encoding="utf-8")
    assert "Budget spent: 6 of 6 tasks per robot" in decision or "Decided every kind" in decision
    for line in report.splitlines():  # an undecided group says what a decision would need
        if "none is to be preferred" in line:
            assert "needs about" in line or "same tasks" in line or "not expected" in line, line

    # 4. the verdict per kind of task
    capsys.readouterr()
    assert main(shlex.split(verdict)[1:]) == 0
    printed = capsys.readouterr().out
    assert "| task kind (tasks) |" in printed and "singular crossings" in printed


def test_init_position_task_and_sizes(
    user_package: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["init", "study", "--urdf", URDF, "--package-dir", ".", "--frame", "j2s6s200_link_6"]
    assert (
        main([*argv, "--task", "position", "--tasks", "13", "--budget", "0", "-o", "p.yaml"]) == 0
    )
    config = load_study(user_package / "p.yaml")
    assert config.robots[0].robot.params["task"] == "position"
    assert config.robots[0].task_weight is None
    assert "max_orientation_error" not in (user_package / "p.yaml").read_text(encoding="utf-8")
    assert config.decide is None  # --budget 0: one batch of 13 tasks
    assert sum(g.count for g in config.generators) == 13
    # a URDF file name that is no study name gives a safe one
    spaced = user_package / "my jaco (v2).urdf"
    spaced.write_text((user_package / URDF).read_text(encoding="utf-8"), encoding="utf-8")
    argv2 = ["init", "study", "--urdf", str(spaced), "--frame", "j2s6s200_link_6", "-o", "q.yaml"]
    assert main(argv2) == 0
    assert load_study(user_package / "q.yaml").name == "my_jaco_v2"
    # an existing file is kept without --force
    assert main([*argv, "-o", "p.yaml"]) == 2
    assert "--force" in one_line_error(capsys)


@pytest.mark.parametrize("tasks", [6, 7, 13, 60, 61, 999, 100_000])
def test_generator_counts_split_the_tasks(tasks: int) -> None:
    counts = generator_counts(tasks)
    assert all(c >= 1 for c in counts)
    assert sum(counts) == tasks
    # in proportion to the shares beyond the one task each gets (within one task)
    shares = [share for _, share, _, _ in SHARES]
    assert all(abs(c - 1 - s * (tasks - 6)) < 1 for c, s in zip(counts, shares, strict=True))


def _break_mesh(urdf: Path, filename: str) -> None:
    text = urdf.read_text(encoding="utf-8")
    first = re.search(r'filename="([^"]+)"', text)
    assert first is not None
    urdf.write_text(text.replace(first.group(0), f'filename="{filename}"', 1), encoding="utf-8")


BAD_INIT = {
    "missing urdf": ({"--urdf": "nope/arm.urdf"}, None, "--urdf: file not found"),
    "package mesh outside": (
        {},
        "package://my_jaco_description/../../outside.dae",
        "lies outside its package 'my_jaco_description'",
    ),
    "relative mesh outside": ({}, "../../../outside.dae", "lies outside the package"),
    "mesh not found": ({}, "package://my_jaco_description/meshes/no.dae", "not found under"),
    "unknown frame": ({"--frame": "tool_tip"}, None, "unknown frame 'tool_tip'; valid frames:"),
    "unknown locked joint": (
        {"--locked-joints": "finger"},
        None,
        "locked_joints: unknown joint 'finger'",
    ),
    "package dir missing": ({"--package-dir": "nowhere"}, None, "--package-dir: not a folder"),
    "zero tasks": ({"--tasks": "0"}, None, "--tasks: must be an integer in [6, 100000]"),
    "five tasks": ({"--tasks": "5"}, None, "one task per generator at least"),
    "negative tasks": ({"--tasks": "-3"}, None, "--tasks: must be an integer"),
    "enormous tasks": ({"--tasks": "10000000000"}, None, "--tasks: must be an integer"),
    "budget below a batch": ({"--budget": "30"}, None, "--budget: must be 0 (one batch) or"),
    "negative budget": ({"--budget": "-1"}, None, "--budget: must be 0 (one batch) or"),
    "enormous budget": ({"--budget": "100000000"}, None, "--budget: must be 0 (one batch) or"),
}


@pytest.mark.parametrize("case", list(BAD_INIT))
def test_init_bad_input_is_one_line_before_anything_is_written(
    user_package: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    changes, mesh, message = BAD_INIT[case]
    if mesh is not None:
        _break_mesh(user_package / URDF, mesh)
    options = {"--urdf": URDF, "--package-dir": ".", "--frame": "j2s6s200_end_effector"}
    options.update(changes)
    argv = ["init", "study", *[part for item in options.items() for part in item], "-o", "s.yaml"]
    assert main(argv) == 2
    assert message in one_line_error(capsys)
    assert not (user_package / "s.yaml").exists()


def test_mesh_rules(tmp_path: Path) -> None:
    package = tmp_path / "pkg"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "meshes" / "a.stl").write_text("solid a\nendsolid a\n", encoding="utf-8")
    urdf = package / "urdf" / "arm.urdf"

    def with_mesh(filename: str) -> Path:
        urdf.write_text(
            f'<robot name="arm"><link name="l"><visual><geometry><mesh filename="{filename}"/>'
            "</geometry></visual></link></robot>",
            encoding="utf-8",
        )
        return urdf

    check_meshes(str(with_mesh("package://pkg/meshes/a.stl")), [str(tmp_path)])
    check_meshes(str(with_mesh("package://pkg/meshes/absent.stl")), [])  # no dirs: not looked up
    check_meshes(str(with_mesh("../meshes/a.stl")), [])
    for filename, message in (
        ("package://pkg/../other/a.stl", "outside its package 'pkg'"),
        ("package://pkg/meshes/absent.stl", "not found under package_dirs"),
        ("../../a.stl", "outside the package"),
        ("../meshes/absent.stl", "not found"),
        ("package://../a.stl", "names no package"),
    ):
        with pytest.raises(RobotLoadError, match=re.escape(message)):
            check_meshes(str(with_mesh(filename)), [str(tmp_path)])


PLANAR = """\
name: waypoints
dt: 0.02
loop_modes: [clik]
experiments:
  - name: e
    robot: {type: planar, link_lengths: [1.0, 0.8]}
    q0: [0.3, 0.5]
    trajectory: TRAJECTORY
    controllers:
      - name: dls
        backend: {type: dls, damping: 0.05}
"""


@pytest.mark.parametrize(
    ("trajectory", "message"),
    [
        (
            "{type: joint_waypoints, duration: 1.0}",
            "trajectory.waypoints: required parameter missing (give waypoints)",
        ),
        (
            "{type: joint_waypoints, waypoints: [[0.0, 0.5], [0.4, 0.6]], duration: 1.0}",
            "trajectory.waypoints.0: must be the start configuration q0 = [0.3, 0.5]",
        ),
        (
            "{type: joint_waypoints, waypoints: [[0.3, 0.5]], duration: 1.0}",
            "trajectory.waypoints: give at least two joint waypoints",
        ),
        (
            "{type: joint_waypoints, robot: {type: planar}, waypoints: [[0.3, 0.5], [0, 0]]}",
            "trajectory.robot: unknown parameter",
        ),
        (
            "{type: circle, centre: [1.5, 0.0], radius: 0.9, period: 4.0}",
            "(reach 1.8 m); to run a motion past the reach on purpose, set out_of_reach: true",
        ),
    ],
)
def test_trajectory_input_errors_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], trajectory: str, message: str
) -> None:
    config = tmp_path / "bad.yaml"
    config.write_text(PLANAR.replace("TRAJECTORY", trajectory), encoding="utf-8")
    assert main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert message in one_line_error(capsys)
    assert not (tmp_path / "out").exists()


def test_joint_waypoints_from_q0_run_without_an_initial_jump(tmp_path: Path) -> None:
    trajectory = "{type: joint_waypoints, waypoints: [[0.3, 0.5], [0.9, 1.4]], duration: 1.0}"
    config = tmp_path / "ok.yaml"
    config.write_text(PLANAR.replace("TRAJECTORY", trajectory), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet"]) == 0
    with (out / "summary.csv").open(encoding="utf-8") as handle:
        (row,) = list(csv.DictReader(handle))
    assert float(row["initial_jump"]) < 1e-9
    # the joint path's peak speed: quintic over |Δq|∞ = 0.9 rad in 1 s peaks at 1.875·0.9
    assert math.isclose(float(row["max_joint_speed"]), 1.875 * 0.9, rel_tol=0.05)


def test_missing_required_parameter_names_it() -> None:
    def factory(start: np.ndarray, waypoints: list, duration: float = 1.0) -> None:
        return None

    with pytest.raises(Exception, match=r"^t\.waypoints: required parameter missing"):
        check_parameters(factory, {"duration": 2.0}, "t", reserved=("start",))
    check_parameters(factory, {"waypoints": []}, "t", reserved=("start",))


def test_bare_command_accepts_run_options(capsys: pytest.CaptureFixture[str]) -> None:
    """``otmm-qp --force ...`` is ``otmm-qp run --force ...`` (the paper reproduction's options)."""
    assert main(["--force", "--out", ""]) == 2
    assert "--out" in one_line_error(capsys)  # refused by `run`, not an unknown argument


def _init(*extra: str) -> list[str]:
    return [
        "init",
        "study",
        "--urdf",
        URDF,
        "--package-dir",
        ".",
        "--frame",
        "j2s6s200_link_6",
        *extra,
    ]


def _run_line(out: str) -> str:
    return next(line for line in out.splitlines() if line.startswith("  run: ")).split()[-1]


def test_init_keeps_paths_as_given_and_a_folder_belongs_to_one_study(
    user_package: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Relative paths stay relative; ``--task position`` is another study (name, file, folder);
    the suggested folder is never another study's, and running into one is refused."""
    assert main(_init("--budget", "0")) == 0
    assert _run_line(capsys.readouterr().out) == "results/kinova-study"
    pose_file = Path("kinova-study.yaml")
    pose = load_study(pose_file)
    robot = pose.robots[0].robot.params
    assert (robot["urdf"], robot["package_dirs"]) == (URDF, ["."])  # as given
    assert f"urdf: {URDF}" in pose_file.read_text(encoding="utf-8")
    # the pose study has run: its folder holds its study.json
    pose_folder = Path("results/kinova-study")
    prepare_directory(pose_folder, pose.model_dump(mode="json"), force=False)
    (pose_folder / "study.json").write_text(
        json.dumps({"study": pose.name, "config": pose.model_dump(mode="json")})
    )
    assert main(_init("--budget", "0", "--task", "position")) == 0
    out = capsys.readouterr().out
    position = load_study(Path("kinova-position-study.yaml"))
    assert position.name == "kinova-position" and _run_line(out) == "results/kinova-position-study"
    # a folder of that name holding another study: the next free one is suggested
    taken = Path("results/kinova-position-study")
    taken.mkdir()
    (taken / "study.json").write_text((pose_folder / "study.json").read_text())
    assert main(_init("--budget", "0", "--task", "position", "--force")) == 0
    assert _run_line(capsys.readouterr().out) == "results/kinova-position-study-2"
    # the position study run into the pose study's folder: refused, study lock or not
    dumped = position.model_dump(mode="json")
    with pytest.raises(StudyDirectoryError, match="holds study 'kinova', not 'kinova-position'"):
        prepare_directory(pose_folder, dumped, force=False)
    same_name = {**dumped, "name": pose.name}  # renamed by hand: still of another task
    with pytest.raises(StudyDirectoryError, match="holds another study named 'kinova'"):
        prepare_directory(pose_folder, same_name, force=False)
    prepare_directory(pose_folder, {**pose.model_dump(mode="json"), "dt": 0.04}, force=False)


ARM_WITHOUT_VELOCITY = """<robot name="a"><link name="base"/><link name="l1"/><link name="tip"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="10"VELOCITY/></joint>
<joint name="j2" type="JOINT2"><parent link="l1"/><child link="tip"/><origin xyz="1 0 0"/>
<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="2"/></joint></robot>
"""


def _arm(folder: Path, velocity: str = "", joint2: str = "revolute") -> str:
    text = ARM_WITHOUT_VELOCITY.replace("VELOCITY", velocity).replace("JOINT2", joint2)
    if joint2 == "fixed":
        text = text.replace('<joint name="j1" type="revolute">', '<joint name="j1" type="fixed">')
    (folder / "arm.urdf").write_text(text, encoding="utf-8")
    return "arm.urdf"


@pytest.mark.parametrize(
    ("velocity", "joint2", "locked", "message"),
    [
        ("", "revolute", [], "urdf: cannot parse"),
        (' velocity="1"', "fixed", [], "arm has no movable joint (every joint is fixed)"),
        (' velocity="1"', "revolute", ["j1", "j2"], "no movable joint after locking j1, j2"),
    ],
)
def test_init_refuses_an_arm_urdfdom_refuses_or_without_movable_joint(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capfd: pytest.CaptureFixture[str],
    velocity: str,
    joint2: str,
    locked: list[str],
    message: str,
) -> None:
    """One refusal, urdfdom's own lines only as its details (never before it), no file."""
    monkeypatch.chdir(tmp_path)
    urdf = _arm(tmp_path, velocity, joint2)
    lock = ["--locked-joints", *locked] if locked else []
    assert main(["init", "study", "--urdf", urdf, "--frame", "tip", *lock, "-o", "s.yaml"]) == 2
    captured = capfd.readouterr()
    text = refusal_text(captured.err)
    assert message in text and captured.out == ""
    if not velocity:  # urdfdom's reason, after the first line
        assert "  urdfdom: joint [j1]: limit has no velocity" in captured.err.splitlines()
        assert "at line" not in captured.err
    assert not (tmp_path / "s.yaml").exists()


def test_init_names_a_zero_speed_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """``velocity="0"`` means no speed limit: said in the file and in a warning line."""
    monkeypatch.chdir(tmp_path)
    urdf = _arm(tmp_path, ' velocity="0"')
    assert main(["init", "study", "--urdf", urdf, "--frame", "tip", "-o", "s.yaml"]) == 0
    captured = capfd.readouterr()
    line = next(ln for ln in Path("s.yaml").read_text().splitlines() if ln.startswith("#   j1:"))
    assert 'velocity="0" in the URDF means no limit' in line
    assert "#   j2: [-1, 1] (range), speed 2" in Path("s.yaml").read_text()
    assert captured.err.startswith('otmm-qp: warning: j1: velocity="0" in the URDF means no')
    assert load_study(Path("s.yaml")).robots[0].robot.params["urdf"] == "arm.urdf"

"""Peer adapters (pink, mink, drake): models, skipping, and tracking against our ``qp``."""

from __future__ import annotations

import csv
from importlib import metadata
from typing import Any

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.config.load import parse_config
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ConfigError, ParameterError, PeerUnavailable, RobotLoadError
from otmm_qp.output.report import read_summary
from otmm_qp.output.run_writer import ResultsWriter
from otmm_qp.robots import peer_models as models
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.runner import run_suite
from otmm_qp.simulation import Episode, simulate
from otmm_qp.state import KinematicState

PEER_ENTRY_POINTS = {
    "pink": "otmm_qp_controllers.peers.pink_backend:PinkBackend",
    "mink": "otmm_qp_controllers.peers.mink_backend:MinkBackend",
    "drake": "otmm_qp_controllers.peers.drake_backend:DrakeBackend",
}
PEER_MODULES = {"pink": "pink", "mink": "mink", "drake": "pydrake"}
#: Stated tolerance: a peer's RMS / max position error may exceed qp's by at most this [m]
#: (measured: |Δ rms| ≤ 1.4e-5 m on both scenarios).
TRACKING_TOLERANCE = 2e-4
#: Largest joint-trajectory difference to qp [rad] (measured: ≤ 2.2e-4 rad, pink, planar).
JOINT_TOLERANCE = 1e-3

PLANAR_SCENARIO: dict[str, Any] = {
    "name": "planar3_circle",
    "robot": {"type": "planar", "link_lengths": [1.0, 0.8, 0.6]},
    "q0": [0.3, 0.9, 0.7],
    "trajectory": {"type": "circle", "centre": [0.9, 1.6], "radius": 0.2, "period": 4.0},
    "duration": 4.0,
}
PANDA_SCENARIO: dict[str, Any] = {
    "name": "panda_pose_line",
    "robot": {"type": "pinocchio", "name": "panda", "task": "pose"},
    "q0": [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8],
    "trajectory": {"type": "pose_line", "end": [0.45, 0.1, 0.45], "duration": 1.5},
    "duration": 2.0,
    "dt": 0.01,
}


@pytest.fixture
def peer_entry_points(monkeypatch: pytest.MonkeyPatch) -> None:
    """Register the peers as the pyproject entry points do (also when not yet installed)."""
    original = metadata.entry_points

    def patched(**params: Any) -> Any:
        found = original(**params)
        if params.get("group") != registry.BACKENDS:
            return found
        present = {e.name for e in found}
        extra = [
            metadata.EntryPoint(name, value, registry.BACKENDS)
            for name, value in PEER_ENTRY_POINTS.items()
            if name not in present
        ]
        return metadata.EntryPoints([*found, *extra])

    monkeypatch.setattr(metadata, "entry_points", patched)
    registry.clear_cache()
    yield
    registry.clear_cache()


def run(scenario: dict[str, Any], backends: dict[str, dict[str, Any]]) -> dict[str, Any]:
    experiment = dict(scenario)
    experiment["controllers"] = [{"name": name, "backend": spec} for name, spec in backends.items()]
    data = {"version": 2, "name": "peers", "loop_modes": ["clik"], "experiments": [experiment]}
    suite = parse_config(data)
    return run_suite(suite, None, progress=None)


# ------------------------------------------------------------------- models
def test_planar_mjcf_is_in_radians_and_matches_pinocchio() -> None:
    mujoco = pytest.importorskip("mujoco")
    arm = PlanarArm([1.0, 0.8, 0.5], limits=[[-2.0, 2.0], [-1.5, 1.5], [-1.0, 1.0]])
    model = mujoco.MjModel.from_xml_string(models.planar_mjcf(arm))
    np.testing.assert_allclose(model.jnt_range, [[-2.0, 2.0], [-1.5, 1.5], [-1.0, 1.0]])
    theta = np.array([0.4, -0.7, 1.1])
    position, orientation = models.pose_mismatch(arm, theta)
    assert position < 1e-12 and orientation < 1e-12
    data = mujoco.MjData(model)
    pose = models.mujoco_site_pose(model, data, models.PLANAR_FRAME, theta)
    np.testing.assert_allclose(pose[:2, 3], arm.forward(theta), atol=1e-12)


@pytest.mark.parametrize("name", ["panda", "ur5", "kinova"])
def test_urdf_arm_in_mujoco_agrees_with_pinocchio(name: str) -> None:
    pytest.importorskip("mujoco")
    from otmm_qp.robots.pinocchio_arm import PinocchioArm

    arm = PinocchioArm(name=name)
    lower, upper = arm.position_limits
    rng = np.random.default_rng(7)
    for _ in range(3):
        theta = rng.uniform(np.maximum(lower, -3.0), np.minimum(upper, 3.0))
        position, orientation = models.pose_mismatch(arm, theta)
        assert position < 1e-9 and orientation < 1e-9


def test_package_uris_are_rewritten_and_locked_joints_fixed() -> None:
    from otmm_qp.robots.pinocchio_arm import PinocchioArm

    arm = PinocchioArm(name="panda")
    text = models.peer_urdf(arm)
    assert "package://" not in text
    assert 'name="panda_finger_joint1" type="fixed"' in text
    assert 'name="panda_joint1" type="revolute"' in text
    assert "<collision>" not in models.peer_urdf(arm, keep_geometry=False)


def test_unresolvable_package_uri_names_the_uri() -> None:
    with pytest.raises(RobotLoadError, match=r"cannot resolve 'package://nope/a.stl'; searched /x"):
        models.resolve_package_uri("package://nope/a.stl", ["/x"])


# ------------------------------------------------------------------ skipping
def test_missing_peer_is_skipped_with_hint(
    peer_entry_points: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Any
) -> None:
    import otmm_qp_controllers.peers.peer_backend as peer_backend

    real_import = peer_backend.importlib.import_module

    def no_pink(name: str) -> Any:
        if name == "pink":
            raise ImportError("No module named 'pink'")
        return real_import(name)

    monkeypatch.setattr(peer_backend.importlib, "import_module", no_pink)
    with pytest.raises(PeerUnavailable, match=r"pip install \"otmm-qp\[peers\]\""):
        peer_backend.require("pink", ["pink"])
    experiment = dict(PLANAR_SCENARIO, duration=0.2)
    experiment["controllers"] = [
        {"name": "pink", "backend": {"type": "pink"}},
        {"name": "pinv", "backend": {"type": "pinv"}},
    ]
    suite = parse_config({"name": "skip", "loop_modes": ["clik"], "experiments": [experiment]})
    outcome = run_suite(suite, ResultsWriter(tmp_path), progress=None)
    assert [r.result.controller for r in outcome.records] == ["pinv"]
    assert [s.name for _, s in outcome.skipped] == ["pink"]
    with (tmp_path / "summary.csv").open(newline="") as handle:
        rows = {row["controller"]: row for row in csv.DictReader(handle)}
    assert rows["pink"]["outcome"] == "skipped" and rows["pinv"]["outcome"] == "completed"
    assert rows["pink"]["error_message"].startswith("peer 'pink' is not installed")
    report_rows = {r.controller: r for r in read_summary(tmp_path / "summary.csv")}
    assert report_rows["pink"].skipped and not report_rows["pinv"].skipped  # read from the column
    assert outcome.errors == []


# ------------------------------------------------------------------ tracking
@pytest.mark.parametrize("peer", sorted(PEER_ENTRY_POINTS))
@pytest.mark.parametrize("scenario", [PLANAR_SCENARIO, PANDA_SCENARIO], ids=["planar", "panda"])
def test_peer_tracks_like_qp(peer_entry_points: None, peer: str, scenario: dict[str, Any]) -> None:
    pytest.importorskip(PEER_MODULES[peer])
    if peer == "mink":
        pytest.importorskip("mujoco")
    outcome = run(scenario, {peer: {"type": peer}, "qp": {"type": "qp", "solver": "daqp"}})
    assert outcome.errors == [] and outcome.skipped == []
    ours = outcome.find(scenario["name"], "clik", "qp")
    theirs = outcome.find(scenario["name"], "clik", peer)
    assert ours is not None and theirs is not None
    m_ours, m_theirs = ours.metrics, theirs.metrics
    assert m_theirs["status_nonfinite"] == 0 and not m_theirs["blow_up"]
    assert m_theirs["rms_error"] <= m_ours["rms_error"] + TRACKING_TOLERANCE
    assert m_theirs["max_error"] <= m_ours["max_error"] + TRACKING_TOLERANCE
    assert float(np.max(np.abs(theirs.result.q - ours.result.q))) <= JOINT_TOLERANCE


# ------------------------------------------------------- the same problem as qp
def _weighted_limit_active_step(
    backends: dict[str, dict[str, Any]],
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """One UR5 pose step with joint 0 overridden to ±1 rad and sitting near its upper limit.

    The command drives joint 0 past the limit, so the box clips it and the five other joints
    cannot realise the 6-D twist: the weighted least-squares answer depends on W.
    """
    robot = registry.create(
        registry.ROBOTS, "pinocchio",
        {"name": "ur5", "task": "pose", "position_limits": [[-1.0, 1.0]] + [[-6.2, 6.2]] * 5},
        "robot",
    )  # fmt: skip
    theta = np.array([0.99, -1.2, 1.5, -1.8, 0.6, 0.3])
    weight = np.array([2.0, 1.0, 0.5, 0.3, 0.2, 0.4])
    state = KinematicState.compute(robot, robot.configuration(theta), weight)
    xdot = weight * np.array([-0.3, 0.2, 0.1, 0.2, -0.1, 0.3])  # weighted, as a filter passes it
    answers = {}
    for name, params in backends.items():
        backend = registry.create(registry.BACKENDS, params["type"], params["params"], name)
        backend.bind(robot, 0.01)
        backend.reset()
        answers[name] = backend.solve(state, xdot, np.zeros(robot.nv)).qdot
    upper = 0.5 * (1.0 - theta[0]) / 0.01  # qp's position bound on q̇_0, limit_gain 0.5
    return answers, np.array([upper])


@pytest.mark.usefixtures("peer_entry_points")
def test_pink_and_mink_solve_qps_weighted_limit_active_problem() -> None:
    pytest.importorskip("pink")
    pytest.importorskip("mink")
    weight = 1e-6  # μ
    answers, upper = _weighted_limit_active_step(
        {
            "qp": {"type": "qp", "params": {"solver": "daqp", "regularization": weight}},
            "pink": {"type": "pink", "params": {"regularization": weight}},
            "mink": {"type": "mink", "params": {"regularization": weight}},
        }
    )
    assert answers["qp"][0] == pytest.approx(upper[0], abs=1e-9)  # the limit is active
    for peer in ("pink", "mink"):
        np.testing.assert_allclose(answers[peer], answers["qp"], atol=1e-6, err_msg=peer)
        assert answers[peer][0] <= upper[0] + 1e-9  # zero violations


@pytest.mark.usefixtures("peer_entry_points")
def test_the_weight_changes_the_answer_so_the_agreement_test_can_fail() -> None:
    answers, _ = _weighted_limit_active_step(
        {"qp": {"type": "qp", "params": {"solver": "daqp", "regularization": 1e-6}}}
    )
    robot = PinocchioArm(name="ur5", position_limits=[[-1.0, 1.0]] + [[-6.2, 6.2]] * 5)
    theta = np.array([0.99, -1.2, 1.5, -1.8, 0.6, 0.3])
    state = KinematicState.compute(robot, robot.configuration(theta))
    backend = registry.create(
        registry.BACKENDS, "qp", {"solver": "daqp", "regularization": 1e-6}, "qp"
    )
    backend.bind(robot, 0.01)
    unweighted = backend.solve(state, np.array([-0.3, 0.2, 0.1, 0.2, -0.1, 0.3]), np.zeros(6))
    assert np.max(np.abs(unweighted.qdot - answers["qp"])) > 1e-2


@pytest.mark.usefixtures("peer_entry_points")
def test_drake_solves_the_direction_preserving_problem_of_qp_scaled() -> None:
    pytest.importorskip("pydrake")
    answers, upper = _weighted_limit_active_step(
        {
            "qp_scaled": {"type": "qp_scaled", "params": {}},
            "drake": {"type": "drake", "params": {}},
        }
    )
    np.testing.assert_allclose(answers["drake"], answers["qp_scaled"], atol=1e-5)
    assert answers["drake"][0] <= upper[0] + 1e-9


@pytest.mark.parametrize("peer", ["pink", "mink", "drake"])
def test_position_limit_override_reaches_the_peer_in_a_run(
    peer_entry_points: None, peer: str
) -> None:
    """The issue's reproduction: UR5, joint 0 limited to ±1 rad, driven past it."""
    pytest.importorskip(PEER_MODULES[peer])
    robot = PinocchioArm(
        name="ur5", task="position", position_limits=[[-1.0, 1.0]] + [[-6.2, 6.2]] * 5
    )
    q0 = robot.configuration(np.array([0.7, -1.2, 1.5, -1.8, 0.6, 0.3]))
    start = robot.forward(q0)
    turn = np.array([[np.cos(0.8), -np.sin(0.8), 0.0], [np.sin(0.8), np.cos(0.8), 0.0], [0, 0, 1]])
    trajectory = registry.create(
        registry.TRAJECTORIES, "quintic_line", {"end": (turn @ start).tolist(), "duration": 1.0},
        "trajectory", start=start,
    )  # fmt: skip
    backend = registry.create(registry.BACKENDS, peer, {}, peer)
    result = simulate(Episode(robot, trajectory, q0, 0.01, 1.5), Controller(peer, [], backend))
    assert result.error_message is None
    assert float(np.max(result.q[:, 0])) <= 1.0 + 1e-9
    assert float(np.max(result.q[:, 0])) > 0.95  # the limit was really approached


def test_pink_limit_warning_is_dropped_and_nothing_else(
    peer_entry_points: None, caplog: pytest.LogCaptureFixture
) -> None:
    """pink logs one root-logger line per step beyond a limit: the bound adapter drops it."""
    pytest.importorskip("pink")
    import logging

    from otmm_qp_controllers.peers.pink_backend import PINK_LIMIT_WARNING, PinkBackend

    PinkBackend(solver="daqp").bind(PlanarArm([1.0, 0.8]), 0.01)
    with caplog.at_level(logging.WARNING):
        logging.warning(PINK_LIMIT_WARNING, -3.141594, 2, -3.141593, 3.141593)
        logging.warning("another warning stays")
    assert [r.getMessage() for r in caplog.records] == ["another warning stays"]


@pytest.mark.usefixtures("peer_entry_points")
@pytest.mark.parametrize("peer", ["pink", "mink", "drake"])
def test_peers_take_qps_limit_objects(peer: str) -> None:
    """The same ``limits`` list: a velocity cap is honoured; a limit with no peer counterpart
    is one line naming what the peer allows."""
    pytest.importorskip({"pink": "pink", "mink": "mink", "drake": "pydrake"}[peer])
    robot = PinocchioArm(name="ur5", task="position")
    theta = np.array([0.3, -1.2, 1.5, -1.8, 0.6, 0.3])
    state = KinematicState.compute(robot, robot.configuration(theta))
    capped = {"limits": [{"type": "velocity", "max_speed": 0.2}, {"type": "position"}]}
    backend = registry.create(registry.BACKENDS, peer, capped, peer)
    backend.bind(robot, 0.01)
    assert backend.enforces_limits
    out = backend.solve(state, np.array([0.5, -0.4, 0.3]), np.zeros(6))
    assert np.all(np.abs(out.qdot) <= 0.2 + 1e-6), out.qdot
    refused = {"limits": [{"type": "acceleration", "a_max": 5.0}]}
    with pytest.raises(
        ConfigError,
        match=rf"^{peer}\.limits: {peer} has no counterpart of limit .acceleration.; allowed",
    ):
        registry.create(registry.BACKENDS, peer, refused, peer)


@pytest.mark.parametrize(
    ("key", "value"),
    [("delay", 1), ("tau", 0.01), ("deceleration", 5.0), ("ramp_start", 0.1), ("rate_limit", 7.5)],
)
def test_a_peer_refuses_the_predicted_position_parts_it_cannot_model(
    key: str, value: float
) -> None:
    """No peer models the commands in flight: an explicit model parameter is one line."""
    from otmm_qp_controllers.peers.peer_backend import peer_limit_set

    with pytest.raises(ParameterError, match=rf"^limits\.{key}: pink has no counterpart"):
        peer_limit_set([{"type": "predicted_position", key: value}], "pink")
    peer_limit_set([{"type": "predicted_position", "rate_limit": "plant"}], "pink")

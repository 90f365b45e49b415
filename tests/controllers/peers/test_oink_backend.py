"""The OInK peer (roboplan-oink): the same problem as ``qp``, limits kept, task tracked.

On the Panda and the UR5 (pose tasks, angular rows weighted 0.2):

* one step agrees with ``qp`` (same μ, same limits) to the SE(3) log of one period's motion;
* a closed loop driving a joint into a narrowed limit keeps every joint inside its limits,
  while without limits the same loop leaves them (so the check can fail);
* a free motion is tracked: the end effector follows the commanded twist;
* a missing install is :class:`PeerUnavailable` with the install hint; a limit or a weight OInK
  cannot express is a one-line :class:`ParameterError`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.exceptions import ParameterError, PeerUnavailable
from otmm_qp.robots.robot import Robot
from otmm_qp.state import KinematicState
from otmm_qp_controllers.qp import QpBackend

DT = 0.02  # [s]
WEIGHT = np.array([1.0, 1.0, 1.0, 0.2, 0.2, 0.2])
MU = 1e-4


def _oink(**params: Any) -> Any:
    pytest.importorskip("roboplan.optimal_ik")
    from otmm_qp_controllers.peers.oink_backend import OinkBackend

    return OinkBackend(**params)


def _robot(name: str, **extra: Any) -> Robot:
    robot: Robot = registry.create(
        registry.ROBOTS, "pinocchio", {"name": name, "task": "pose", **extra}, "robot"
    )
    return robot


def _middle(robot: Robot) -> np.ndarray:
    """A well-conditioned start [rad] (the UR5's elbow bent, the Panda's elbow at −1.5)."""
    if robot.nv == 6:
        return np.array([0.0, -1.2, 1.5, -1.8, 0.6, 0.3])
    lower, upper = robot.position_limits
    theta = 0.5 * (lower + upper)
    theta[1] += 0.3
    theta[3] = -1.5
    return theta


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_one_step_is_qps_answer(name: str) -> None:
    robot = _robot(name)
    state = KinematicState.compute(robot, robot.configuration(_middle(robot)), WEIGHT)
    xdot = WEIGHT * np.array([0.1, -0.05, 0.02, 0.1, 0.2, -0.1])
    answers = []
    for backend in (_oink(regularization=MU), QpBackend(regularization=MU)):
        backend.bind(robot, DT)
        answers.append(backend.solve(state, xdot, np.zeros(robot.nv)).qdot)
    ours, theirs = answers[1], answers[0]
    assert np.linalg.norm(theirs - ours) <= 2e-3 * np.linalg.norm(ours)


def _loop(robot: Robot, backend: Any, twist: np.ndarray, steps: int) -> tuple[np.ndarray, Any]:
    backend.bind(robot, DT)
    backend.reset()
    q = robot.configuration(_middle(robot))
    trace = [robot.joint_coordinates(q)]
    start = KinematicState.compute(robot, q, WEIGHT).x
    for _ in range(steps):
        state = KinematicState.compute(robot, q, WEIGHT)
        qdot = backend.solve(state, WEIGHT * twist, np.zeros(robot.nv)).qdot
        q = robot.integrate(q, qdot, DT)
        trace.append(robot.joint_coordinates(q))
    end = KinematicState.compute(robot, q, WEIGHT).x
    return np.array(trace), (start, end)


def _position(x: np.ndarray) -> np.ndarray:
    """The end-effector position [m], shape ``(3,)``, of a pose task's ``x``."""
    pose = np.asarray(x)
    return pose[:3, 3] if pose.ndim == 2 else pose[:3]


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_joint_limits_are_kept(name: str) -> None:
    """Joint 0 narrowed to ±0.15 rad around the start; the twist yaws the arm past it."""
    base = _robot(name)
    theta = _middle(base)
    lower, upper = (np.array(x, dtype=float) for x in base.position_limits)
    lower[0], upper[0] = theta[0] - 0.15, theta[0] + 0.15
    robot = _robot(name, position_limits=np.column_stack([lower, upper]).tolist())
    start = _position(KinematicState.compute(robot, robot.configuration(theta), WEIGHT).x)
    yaw = np.array([0.0, 0.0, 1.0])  # the whole arm about world z at 1 rad/s: joint 0's motion
    twist = np.concatenate([np.cross(yaw, start), yaw])
    kept, _ = _loop(robot, _oink(regularization=MU), twist, 60)
    free, _ = _loop(robot, _oink(regularization=MU, limits=False), twist, 60)
    excess = lambda t: float(np.max(np.maximum(t - upper, lower - t)))  # noqa: E731
    assert excess(free) > 0.05  # unlimited, the same loop leaves the narrowed limit
    assert excess(kept) <= 1e-8  # ProxQP stops at its tolerance (EPS_ABS = 1e-11)
    assert np.max(kept[:, 0]) > upper[0] - 0.01 or np.min(kept[:, 0]) < lower[0] + 0.01


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_a_free_motion_is_tracked(name: str) -> None:
    robot = _robot(name)
    twist = np.array([0.05, -0.03, 0.04, 0.0, 0.0, 0.0])  # [m/s], orientation held
    _, (start, end) = _loop(robot, _oink(regularization=1e-8), twist, 25)
    travelled = robot.task_error(end, start)[:3]  # end − start, position rows [m]
    np.testing.assert_allclose(travelled, twist[:3] * 25 * DT, atol=2e-3)
    assert np.linalg.norm(robot.task_error(end, start)[3:]) <= 5e-3


def test_missing_oink_is_unavailable_with_the_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    import otmm_qp_controllers.peers.peer_backend as peer_backend
    from otmm_qp_controllers.peers.oink_backend import OinkBackend

    real_import = peer_backend.importlib.import_module

    def no_oink(name: str) -> Any:
        if name.startswith("roboplan"):
            raise ImportError(f"No module named {name!r}")
        return real_import(name)

    monkeypatch.setattr(peer_backend.importlib, "import_module", no_oink)
    with pytest.raises(PeerUnavailable, match=r"pip install roboplan-oink"):
        OinkBackend()


def test_what_oink_cannot_express_is_one_line() -> None:
    with pytest.raises(ParameterError, match="singularity_barrier"):
        _oink(limits=[{"type": "singularity_barrier"}])
    with pytest.raises(ParameterError, match="deceleration"):
        _oink(limits=[{"type": "predicted_position", "deceleration": 5.0}])
    robot = _robot("ur5")
    backend = _oink()
    backend.bind(robot, DT)
    uneven = np.array([1.0, 2.0, 1.0, 0.2, 0.2, 0.2])
    state = KinematicState.compute(robot, robot.configuration(_middle(robot)), uneven)
    with pytest.raises(ParameterError, match="position rows' weights must be equal"):
        backend.solve(state, np.zeros(6), np.zeros(6))

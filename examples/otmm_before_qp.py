# /// script
# requires-python = ">=3.10"
# dependencies = ["otmm-qp"]
# ///
"""OTMM in front of the QP backend on a UR5 crossing its wrist singularity, through the API.

Run: ``python examples/otmm_before_qp.py`` (prints peak joint speed and tracking error of
the QP backend with and without the OTMM filter).
"""

from __future__ import annotations

import numpy as np

from otmm_qp import Controller
from otmm_qp.filters import OtmmFilter
from otmm_qp.metrics import compute_metrics
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.simulation import Episode, Loop, simulate
from otmm_qp.trajectories import PoseLineTrajectory
from otmm_qp_controllers.qp import QpBackend

DT = 0.01  # control period [s]


def main() -> dict[str, dict[str, object]]:
    robot = PinocchioArm(name="ur5", task="pose")
    q0 = robot.check_start(np.array([0.0, -1.2, 1.5, -1.8, 0.3, 0.0]))  # θ5 = 0.3 rad
    # Drive θ5 through 0 (wrist singularity): the pose at θ5 = −0.3 rad, reached in 4 s.
    goal = robot.forward(robot.configuration(np.array([0.0, -1.2, 1.5, -1.8, -0.3, 0.0])))
    weight = np.array([1.0, 1.0, 1.0, 0.2, 0.2, 0.2])  # 1 rad of orientation ~ 0.2 m
    results = {}
    for name, filters in [("qp", []), ("otmm+qp", [OtmmFilter(sigma_s=0.05, corank="all")])]:
        trajectory = PoseLineTrajectory(
            start=robot.forward(q0),
            end=goal[:3, 3].tolist(),
            end_quaternion=_quaternion(goal[:3, :3]),
            duration=4.0,
        )
        controller = Controller(name, filters, QpBackend(solver="daqp", regularization=1e-3))
        episode = Episode(robot, trajectory, q0, DT, 5.0, Loop("clik", 10.0), task_weight=weight)
        run = simulate(episode, controller)
        metrics = compute_metrics(run)
        results[name] = metrics
        print(
            f"{name:8s} peak |q̇| {metrics['max_joint_speed']:.3f} rad/s, "
            f"max position error {metrics['max_error']:.2e} m, min σ {metrics['min_sigma']:.1e}, "
            f"limit violations {metrics['position_violations']}"
        )
    return results


def _quaternion(rotation: np.ndarray) -> list[float]:
    """Unit quaternion [x, y, z, w] of a rotation matrix."""
    import pinocchio as pin

    return pin.Quaternion(rotation).coeffs().tolist()


if __name__ == "__main__":
    main()

"""Desired task trajectories."""

from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp.trajectories.line import ConstantVelocityLineTrajectory, QuinticLineTrajectory
from otmm_qp.trajectories.pose import PoseCircleTrajectory, PoseLineTrajectory
from otmm_qp.trajectories.trajectory import Trajectory

__all__ = [
    "CircleTrajectory",
    "ConstantVelocityLineTrajectory",
    "PoseCircleTrajectory",
    "PoseLineTrajectory",
    "QuinticLineTrajectory",
    "Trajectory",
]

"""Robot models: the :class:`Robot` interface and built-in arms."""

from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot, TaskKind

__all__ = ["FloatArray", "PeerDescription", "PlanarArm", "Robot", "TaskKind"]

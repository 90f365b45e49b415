"""A third-party trajectory package for the migrate tests: otmm-qp's lines under other names.

Registered by the tests through entry points whose module is this one, so otmm-qp does not
count them as its own (:mod:`otmm_qp.migration.evidence`).
"""

from __future__ import annotations

from otmm_qp.trajectories.line import QuinticLineTrajectory
from otmm_qp.trajectories.pose import PoseLineTrajectory


class VendorQuinticLine(QuinticLineTrajectory):
    """``quintic_line`` as a vendor ships it."""


class VendorPoseLine(PoseLineTrajectory):
    """``pose_line`` as a vendor ships it."""

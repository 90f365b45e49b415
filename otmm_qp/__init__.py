"""otmm-qp: velocity-level IK controllers compared near kinematic singularities.

The pipeline of one control step::

    state = KinematicState.compute(robot, q)      # J and its SVD, once
    out = controller.step(state, xdot_c, qdot)    # filters (e.g. OTMM) then a backend
"""

from otmm_qp.controller import Controller, ControllerOutput
from otmm_qp.exceptions import OtmmError
from otmm_qp.state import KinematicState

__all__ = ["Controller", "ControllerOutput", "KinematicState", "OtmmError"]
__version__ = "0.1.0"

r"""The QP differential IK with joint limits: formulation, backends and persistent solver sessions.

One concept, five files and a subpackage:

* :mod:`.formulation` — :class:`QpFormulation`, the pure problem
  ``min ½‖W(J q̇ − ẋ)‖² + ½μ‖q̇‖²`` subject to the limits' box, its closed-form minimiser from
  the step's shared SVD and ``build(out=)`` of the solver's matrices;
* :mod:`.posture` — :class:`QpPosture`, the posture cost (weight, gain, nominal posture);
* :mod:`.box_backend` — :class:`BoxQpBackend`, what every QP backend shares: the limits' box
  for the step, one persistent warm-started :class:`~.solvers.QpSession`, the infeasibility
  policy and the :class:`QpStep` record returned in ``BackendOutput.details``;
* :mod:`.backend` — :class:`QpBackend` (entry point ``qp``), the mink-style QP IK;
* :mod:`.scaled` — :class:`ScaledQpBackend` (``qp_scaled``), Drake-DiffIK-style
  direction-preserving task scaling;
* :mod:`.manipulability` — :class:`ManipulabilityQpBackend` (``qp_manipulability``), the QP
  with a linear manipulability-gradient cost term;
* :mod:`.solvers` — one :class:`~.solvers.QpSession` per solver (daqp, proxsuite, osqp,
  and any qpsolvers name through the stateless path).
"""

from .backend import DEFAULT_REGULARIZATION, POLICIES, QpBackend
from .box_backend import SOLVER_TOL, BoxQpBackend, QpStep
from .formulation import QpFormulation
from .manipulability import ManipulabilityQpBackend
from .posture import QpPosture
from .scaled import ScaledQpBackend
from .solvers import available_solvers

__all__ = [
    "DEFAULT_REGULARIZATION",
    "POLICIES",
    "SOLVER_TOL",
    "BoxQpBackend",
    "ManipulabilityQpBackend",
    "QpBackend",
    "QpFormulation",
    "QpPosture",
    "QpStep",
    "ScaledQpBackend",
    "available_solvers",
]

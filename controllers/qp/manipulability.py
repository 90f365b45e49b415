r"""Manipulability in the QP objective (Haviland & Corke 2021, NEO-style) on the QP with limits."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.backends.backend import BackendOutput, damping_weight
from otmm_qp.limits import LimitSpec
from otmm_qp.limits.options import LIMITS, removed_limit_keys
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState
from otmm_qp.validation import Boolean, Constraints, Interval, OneOf, check_params

from ..manipulability import manipulability_gradient
from .backend import DEFAULT_REGULARIZATION, POLICIES, POSITIVE_OR_NONE, QpBackend
from .box_backend import SOLVER
from .posture import QpPosture


class ManipulabilityQpBackend(QpBackend):
    r"""The ``qp`` backend with NEO's linear manipulability term in its objective.

    Haviland & Corke, "NEO: A novel expeditious optimisation algorithm for reactive motion
    control of manipulators", IEEE RA-L 6(2), 2021: the QP rewards the first-order change of
    Yoshikawa's manipulability :math:`w`, :math:`\dot w = \nabla_q w^\top\dot q` (their
    manipulability Jacobian :math:`J_m = \nabla_q w^\top`), through a *linear* cost term:

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
        - k\,\nabla_q w^\top\dot q
        \quad\text{s.t.}\quad lb \le \dot q \le ub

    with the box of the ``qp`` backend (velocity, position and acceleration limits) and
    :math:`\nabla_q w` of :func:`~otmm_qp_controllers.manipulability.manipulability_gradient`
    (the SVD form, defined at singularities). Unconstrained, the optimum is
    :math:`(J_w^\top J_w + \mu I)^{-1}(J_w^\top\dot x_w + k\nabla_q w)`: on a redundant arm the
    term moves the arm toward higher manipulability, on a square one it trades task accuracy
    for it (unlike the null-space ascent of ``manipulability``). k = 0 is the ``qp`` backend.

    Built on :class:`~otmm_qp_controllers.qp.QpBackend` with no change to it: its
    posture term :math:`\tfrac12 w_p\|\dot q - \dot q_p\|^2` is
    :math:`\tfrac12 w_p\|\dot q\|^2 - w_p\dot q_p^\top\dot q` + const, so with
    :math:`w_p = \mu/2`, the formulation's μ set to :math:`\mu/2` and
    :math:`\dot q_p = (k/w_p)\nabla_q w` the objective above is met exactly (fast path and QP
    alike).

    Args:
        manipulability_weight: k ≥ 0 [(task units)²/(rad/s) per unit of ∂w/∂q]. The
            null-space speed it asks for is about :math:`(k/\mu)\|\nabla_q w\|`, so k is
            to be read against μ (k = 1e-4 with μ = 1e-3: 0.1 rad/s per unit gradient).
            Default 0: the term is off (the backend is ``qp``) until a weight is given — so
            the conformance suite's reference set, which runs every built-in with its
            defaults, is unchanged (with k = 1e-4 it would have become the best built-in on
            paper E2, 0.56 vs 1.48 mm RMS, by pushing the singular start out of the
            singularity at the cost of the task).
        damping: λ > 0 [task units], μ = λ² (as ``qp``'s ``damping``).
        regularization: μ > 0, the weight of ½‖q̇‖², instead of ``damping`` (10⁻³ when
            neither is given).
        solver: As ``qp``.
        limits: As ``qp``.
        infeasible_policy: As ``qp``.
        fast_path: As ``qp``.
    """

    name = "qp_manipulability"
    parameter_constraints: ClassVar[Constraints] = {
        "manipulability_weight": Interval(Real, 0, None, closed="left"),
        "damping": POSITIVE_OR_NONE,
        "regularization": POSITIVE_OR_NONE,
        "solver": SOLVER,
        "limits": [LIMITS, None],
        "infeasible_policy": OneOf(*POLICIES),
        "fast_path": Boolean(),
    }
    removed_parameters: ClassVar[Mapping[str, str]] = removed_limit_keys(
        "limit_gain", "acceleration_limit"
    )

    def __init__(
        self,
        manipulability_weight: float = 0.0,
        damping: float | None = None,
        regularization: float | None = None,
        solver: str = "daqp",
        limits: Sequence[LimitSpec] | None = None,
        infeasible_policy: Literal["raise", "hold", "dls"] = "raise",
        fast_path: bool = True,
    ) -> None:
        check_params(self, locals())
        weight = float(manipulability_weight)
        mu = damping_weight(damping, regularization, DEFAULT_REGULARIZATION, positive=True)
        split = 0.5 * mu if weight > 0.0 else mu
        super().__init__(
            regularization=split,
            solver=solver,
            limits=limits,
            posture=QpPosture(weight=mu - split) if weight > 0.0 else None,
            infeasible_policy=infeasible_policy,
            fast_path=fast_path,
        )
        self.manipulability_weight = weight
        self.total_damping = mu
        self._factor = float(np.sqrt(self.total_damping))  # report λ = √μ as every DLS does
        self._gradient: FloatArray | None = None

    def _posture(self, theta: FloatArray) -> FloatArray:
        """``q̇_p = (k / w_p) ∇_q w`` [rad/s]: the linear term through the posture slot."""
        assert self._gradient is not None  # noqa: S101 - set by solve before the parent runs
        return (self.manipulability_weight / self.formulation.posture_weight) * self._gradient

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """Joint velocity [rad/s], shape ``(nv,)``, inside the box; ``damping`` is √μ."""
        if self.manipulability_weight > 0.0:
            self._gradient = manipulability_gradient(self.robot, state)
        return super().solve(state, xdot, qdot_prev)

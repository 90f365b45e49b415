r"""Saturation in the Null Space with greedy task scaling (Flacco, De Luca, Khatib 2012)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.exceptions import ParameterError
from otmm_qp.limits import LimitBox, LimitSpec, make_limits
from otmm_qp.limits.options import LIMITS, removed_limit_keys
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp.validation import Constraints, Interval, check_params


def task_scaling_factor(
    a: FloatArray, b: FloatArray, lower: FloatArray, upper: FloatArray
) -> tuple[float, int]:
    r"""Largest ``s ∈ [0, 1]`` with ``lower ≤ s·a + b ≤ upper``, and the joint that limits it.

    Flacco et al. 2012, *getTaskScalingFactor*: per joint the admissible interval of ``s``
    is :math:`[(lb_i - b_i)/a_i, (ub_i - b_i)/a_i]` (swapped for :math:`a_i < 0`); ``s_max``
    is the smallest upper end (its joint is the *most critical* one), ``s_min`` the largest
    lower end. The scale is 0 when the intervals do not intersect ``[0, ∞)``.

    Args:
        a: Joint velocity per unit task scale [rad/s], shape ``(nv,)``.
        b: Joint velocity at zero task scale [rad/s], shape ``(nv,)``.
        lower: Lower joint-velocity bounds [rad/s], shape ``(nv,)``.
        upper: Upper joint-velocity bounds [rad/s], shape ``(nv,)``.

    Returns:
        ``(s, j)``: the scale and the most critical joint (-1 when no joint limits it).
    """
    s_max, s_min, critical = math.inf, -math.inf, -1
    for i in range(a.size):
        if a[i] > 0.0:
            low, high = (lower[i] - b[i]) / a[i], (upper[i] - b[i]) / a[i]
        elif a[i] < 0.0:
            low, high = (upper[i] - b[i]) / a[i], (lower[i] - b[i]) / a[i]
        else:
            continue
        if high < s_max:
            s_max, critical = high, i
        s_min = max(s_min, low)
    if s_min > s_max or s_max < 0.0 or s_min > 1.0:
        return 0.0, critical
    return min(s_max, 1.0), critical


class SnsBackend(Backend):
    r"""SNS velocity IK, single task (Flacco, De Luca, Khatib, ICRA 2012, Algorithm 1).

    Joints that would exceed their bounds are saturated one at a time, most critical
    first, and removed from the task solution (``W_jj = 0``); their saturated velocity
    :math:`\dot q_N` is compensated by the remaining joints:

    .. math::
        \dot q = \dot q_N + (J W)^{+}\,(s\,\dot x - J\dot q_N)

    with ``s = 1`` while the remaining joints can realise the whole command. When they
    cannot (``rank(JW) < n``), the best scale found along the way, ``s* ∈ [0, 1]``
    (:func:`task_scaling_factor`), and its saturation set are used: then
    :math:`J\dot q = s^*\dot x` — the task *direction* is preserved, only its magnitude is
    scaled — and every bound is met (the saturated joints sit exactly on their bound).

    **The scale is greedy, not optimal.** Flacco et al. call this "optimal task scaling", but
    the saturation set is built one joint at a time (most critical first) and never revised,
    so on redundant Jacobians ``s*`` can be *smaller* than the largest feasible scale
    :math:`\max\{s \in [0,1] : \exists\dot q,\ J\dot q = s\dot x,\ \dot Q_{min} \le
    \dot q \le \dot Q_{max}\}` (a linear program). Example
    (``tests/controllers/test_strategy_backends.py``):
    3-link unit planar arm, q = (−1.0, −1.8, −0.2) rad, ẋ = (−1.0, −1.8) m/s, bound 1 rad/s:
    SNS 0.7309, LP 0.7464. In the test's 300 random redundant cases the greedy scale is below
    the LP optimum in 2 (ratio ≥ 0.991); it never exceeds it (it is always feasible).

    Bounds per joint: the box of the backend's limits (:mod:`otmm_qp.limits`), by default
    Flacco's shaping without the acceleration term,
    :math:`\dot Q_{max} = \min(\dot q_{max}, (\theta_{max} - \theta)/dt)`,
    :math:`\dot Q_{min} = \max(-\dot q_{max}, (\theta_{min} - \theta)/dt)` (``velocity`` and
    ``{type: position, gain: 1}``), with :math:`\dot q_{max}` the robot's speed limit,
    further capped by ``{type: velocity, max_speed: …}``; a soft ``command`` limit (the
    command's acceleration and jerk, :mod:`otmm_qp.limits.command_limit`) is given up braking
    first. Conflicting boxes (a joint outside
    its position limit) are relaxed by priority (:func:`otmm_qp.limits.box.relaxed`): the
    joint may return at its speed limit.

    SNS is not a singularity method: near a singularity :math:`(JW)^+` is large and the
    task is scaled down until the bounds hold (``rcond`` truncates the pseudoinverse).

    Args:
        limits: Box limits or ``{type: NAME, ...}`` entries (:mod:`otmm_qp.limits.options`);
            None: the robot's speed limit and ``{type: position, gain: 1}``.
        rcond: Relative truncation threshold of the pseudoinverses, in ``[0, 1)``.
    """

    name = "sns"
    parameter_constraints: ClassVar[Constraints] = {
        "limits": [LIMITS, None],
        "rcond": Interval(Real, 0, 1, closed="left"),
    }
    removed_parameters: ClassVar[Mapping[str, str]] = removed_limit_keys(
        "max_speed", default_gain=1.0
    )
    enforces_limits = True

    def __init__(
        self,
        limits: Sequence[LimitSpec] | None = None,
        rcond: float = 1e-10,
    ) -> None:
        check_params(self, locals())
        self.limits = make_limits(limits, default_gain=1.0)
        if self.limits.rows:
            names = ", ".join(row.name for row in self.limits.rows)
            raise ParameterError("limits", f"sns takes box limits only, not {names}")
        self.box = LimitBox(self.limits.boxes)
        self.rcond = float(rcond)

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Hand the plant's declaration to the limits (read at :meth:`bind`)."""
        self.box.declare_plant(declaration)

    def bind(self, robot: Robot, dt: float) -> None:
        """Bind the limits."""
        super().bind(robot, dt)
        self.box.bind(robot, dt)

    def reset(self) -> None:
        """Forget the limits' per-step state (a new run)."""
        self.box.reset()

    def bounds(
        self, state: KinematicState, qdot_prev: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Joint-velocity bounds ``(Q̇_min, Q̇_max)`` [rad/s], shapes ``(nv,)``, relaxed by priority.

        Args:
            state: The step's state.
            qdot_prev: Previous joint velocity [rad/s] (an acceleration limit's centre); zero
                when None.
        """
        theta = self.robot.joint_coordinates(state.q)
        previous = np.zeros(state.jacobian.shape[1]) if qdot_prev is None else qdot_prev
        self.box.compute(theta, previous)
        lower, upper = self.box.relaxed()
        return lower, upper

    def _pinv(self, jacobian: FloatArray, free: FloatArray) -> tuple[FloatArray, int]:
        """``(J W)⁺`` (nv, n) with zero rows for saturated joints, and its rank."""
        nv, n = jacobian.shape[1], jacobian.shape[0]
        result = np.zeros((nv, n))
        columns = jacobian[:, free]
        if columns.shape[1] == 0:
            return result, 0
        U, sigma, Vt = np.linalg.svd(columns, full_matrices=False)
        cutoff = max(self.rcond * float(sigma[0]) if sigma.size else 0.0, np.finfo(float).tiny)
        keep = sigma > cutoff
        result[free] = (Vt[keep].T / sigma[keep]) @ U[:, keep].T
        return result, int(np.count_nonzero(keep))

    def solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        """SNS joint velocity [rad/s], shape ``(nv,)``; ``scale`` is the task scale s.

        Status ``relaxed`` when a soft command limit was given up on the step (braking first).
        """
        output = self._solve(state, xdot, qdot_prev)
        if self.box.softened:
            return output._replace(status=Status.RELAXED)
        return output

    def _solve(
        self, state: KinematicState, xdot: FloatArray, qdot_prev: FloatArray
    ) -> BackendOutput:
        jacobian = state.task_jacobian
        n, nv = jacobian.shape
        lower, upper = self.bounds(state, qdot_prev)
        task_rank = self._pinv(jacobian, np.ones(nv, dtype=bool))[1]
        free = np.ones(nv, dtype=bool)
        qdot_n = np.zeros(nv)
        best = (0.0, free.copy(), qdot_n.copy())  # (s*, W*, q̇_N*)
        finite = np.abs(np.concatenate([lower, upper]))
        tolerance = 1e-12 * (1.0 + float(np.max(finite[np.isfinite(finite)], initial=0.0)))
        for _ in range(nv + 1):
            pinv = self._pinv(jacobian, free)[0]
            qdot = qdot_n + pinv @ (xdot - jacobian @ qdot_n)
            if np.all(qdot >= lower - tolerance) and np.all(qdot <= upper + tolerance):
                status = Status.OK if free.all() else Status.BOUNDED
                return BackendOutput(np.clip(qdot, lower, upper), status=status, scale=1.0)
            a = pinv @ xdot
            b = qdot - a
            scale, critical = task_scaling_factor(a, b, lower, upper)
            if scale > best[0]:
                best = (scale, free.copy(), qdot_n.copy())
            if critical < 0:
                break
            free[critical] = False
            qdot_n[critical] = upper[critical] if a[critical] > 0.0 else lower[critical]
            if self._pinv(jacobian, free)[1] < task_rank:  # the rest cannot do the task
                break
        scale, free, qdot_n = best
        pinv = self._pinv(jacobian, free)[0]
        qdot = qdot_n + pinv @ (scale * xdot - jacobian @ qdot_n)
        return BackendOutput(np.clip(qdot, lower, upper), status=Status.BOUNDED, scale=scale)

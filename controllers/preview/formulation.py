r"""The preview QP over a horizon of knots, pure: its weights and its data written in place.

Decision: the joint velocity ``v_i`` [rad/s] on each segment of the :class:`~.knots.KnotGrid`,
``x = (v_1, …, v_K)``, shape ``(K·nv,)``; the displacement of knot ``i`` from the present
joint coordinates θ₀ is :math:`\delta_i = \sum_{j \le i} h_j v_j` (the first knot, ``τ_0``, is
the state the robot is in). Linearised along the nominal knots
:math:`\bar\theta_i = \theta_0 + \bar d_i` (the previous plan shifted by one step) with the
weighted Jacobians :math:`\bar J_i = W J(\bar\theta_i)` and residuals :math:`\bar r_i`
[task units] (what knot ``i`` still misses, :mod:`.targets`):

.. math::
    \min_v\ &\tfrac12\sum_{i=1}^{K} \frac{h_i}{H\,dt^2}\Big(
        \|\bar J_i(\delta_i - \bar d_i) - \bar r_i\|^2 + \kappa\|\delta_i - \bar d_i\|^2\Big)
      + \tfrac12\mu\sum_{i=1}^{K}\frac{h_i}{H}\|v_i\|^2 \\
      &+ \tfrac12\rho_0\|v_1 - v_0\|^2
      + \tfrac12\rho\sum_{i=1}^{K}\frac{\tilde h_i}{H}\Big\|\frac{v_i - v_{i-1}}{\tilde h_i}
        \,dt\Big\|^2,\qquad \tilde h_i = \tfrac12(h_{i-1} + h_i),
        \ v_0 = \dot q_{prev},\ h_0 = dt \\
      &+ \omega\,s + \tfrac12\epsilon s^2 \quad\text{(only when } \omega > 0\text{)} \\
    \text{s.t.}\ &lb \le v_1 \le ub \quad\text{(the step's box of the project's limits)},\\
      &-\dot q_{max} \le v_i \le \dot q_{max},\quad
      \theta_{min} - \theta_0 \le \delta_i \le \theta_{max} - \theta_0,\quad
      |v_i - v_{i-1}| \le a_{max}\tilde h_i \quad (i \ge 2)
      \quad\text{and, when } \omega > 0:\quad |v_{i,j}| \le s\ (\text{every knot } i,
      \text{joint } j),\quad s \ge \hat s

The task term is the time average of the squared tracking error over the horizon, in units
of one step's velocity (÷ dt²); κ is a trust region keeping the plan near the nominal where
the linearisation holds (it keeps the Hessian well conditioned where ``J̄ᵀJ̄`` loses rank,
as the offline reference's Levenberg–Marquardt term does); ρ weights the second differences
of the knot positions (the plan's accelerations, the previous step's velocity ``v_0`` included,
so consecutive plans agree) and ρ₀ adds weight on the one-step jump of the executed velocity.
The peak-jump term (ω_a > 0) is the same for the plan's largest velocity change per step
``a`` [rad/s] (the study's max ‖Δq̇‖∞): :math:`|v_1 - \dot q_{prev}| \le a`,
:math:`|v_i - v_{i-1}|\,dt/\tilde h_i \le a`, cost :math:`\omega_a a`, ``a`` at least the
largest change already executed. The peak term (ω > 0) is the epigraph of the plan's peak
joint speed ``s`` [rad/s]
(:math:`\max_{i,j}|v_{i,j}|`, the study's max ‖q̇‖∞): one more variable, ``2·K·nv`` rows, a
linear cost; its floor :math:`\hat s` is the peak the episode has already executed, so speeds
below it are free (the metric counts the peak once) and only a new peak is paid for. The tiny
:math:`\epsilon` = :data:`PEAK_CURVATURE` keeps the Hessian positive definite.
The task error is soft — its slack is the residual itself — and every limit hard.
With ``K = 1`` (``H = dt``) and ρ = ρ₀ = κ = 0 the QP is the one-step QP
:math:`\min \tfrac12\|J_w v - \bar r_1/dt\|^2 + \tfrac12\mu\|v\|^2` in the box.

Assembly is structured: with :math:`G_i = \frac{h_i}{H dt^2}(\bar J_i^\top\bar J_i +
\kappa I)` and :math:`S_m = \sum_{i \ge m} G_i`, the task Hessian's block ``(j, l)`` is
:math:`h_j h_l S_{\max(j,l)}` (one suffix sum, no ``(Kn × K nv)`` product); the
regularisation and smoothness blocks and every constraint row are constant and set once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import linalg
from scipy.linalg import lapack

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray

from ..qp.solvers import BIG, QpProblem
from .knots import KnotGrid

__all__ = ["PEAK_CURVATURE", "BoolArray", "PreviewProblem", "PreviewWeights"]

#: ε of ``½ε s²`` on the peak variable [task units² / (rad/s)²] (keeps ``P`` definite).
PEAK_CURVATURE = 1e-6

#: A boolean mask, e.g. the variables held at a bound.
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class PreviewWeights:
    """The cost weights of the preview QP (module docstring).

    Attributes:
        regularization: μ > 0 [task units² / (rad/s)²], the weight of ``½‖v‖²``.
        smoothness: ρ ≥ 0 [task units² / (rad/s)²], the weight of the plan's second
            differences (its velocity changes per ``dt``).
        jump: ρ₀ ≥ 0 [task units² / (rad/s)²], the weight of ``‖v_1 − q̇_prev‖²``.
        trust_region: κ ≥ 0 [task units² / rad²], the weight of ``‖δ_i − d̄_i‖²``.
        peak: ω ≥ 0 [task units² / (rad/s)], the weight of the plan's peak joint speed
            ``s`` (0: no peak variable).
        peak_jump: ω_a ≥ 0 [task units² / (rad/s)], the weight of the plan's largest velocity
            change per step ``a`` (0: none).

    Raises:
        ParameterError: A weight out of range.
    """

    regularization: float = 1e-4
    smoothness: float = 0.001
    jump: float = 0.0
    trust_region: float = 1e-3
    peak: float = 0.0
    peak_jump: float = 0.0

    def __post_init__(self) -> None:
        """Validate the weights."""
        for field, value, positive in (
            ("regularization", self.regularization, True),
            ("smoothness", self.smoothness, False),
            ("jump", self.jump, False),
            ("trust_region", self.trust_region, False),
            ("peak", self.peak, False),
            ("peak_jump", self.peak_jump, False),
        ):
            if not math.isfinite(value) or value < 0.0 or (positive and value == 0.0):
                allowed = "> 0" if positive else ">= 0"
                raise ParameterError(field, f"must be a finite number {allowed}, got {value}")


class PreviewProblem:
    r"""The preview QP of one grid and arm, its data preallocated and rewritten each step.

    Args:
        grid: The horizon's knots.
        nv: Joints.
        weights: The cost weights.
        position: Whether the future knots keep ``θ_min ≤ θ ≤ θ_max`` (rows).
        acceleration: ``a_max`` [rad/s²], shape ``(nv,)``, for rows on the future knots'
            velocity changes, or None (none).

    Attributes:
        problem: The :class:`~otmm_qp_controllers.qp.solvers.QpProblem` handed to the solver
            (``K·nv`` variables; constant structure).
    """

    def __init__(
        self,
        grid: KnotGrid,
        nv: int,
        weights: PreviewWeights,
        position: bool,
        acceleration: FloatArray | None,
    ) -> None:
        h = grid.steps
        count, dt, horizon = grid.count, float(h[0]), grid.horizon
        self.grid, self.nv, self.weights = grid, nv, weights
        plan = count * nv
        # Epigraph variables after the plan: the peak speed s, then the peak jump a.
        self.peaked, self.jump_peaked = weights.peak > 0.0, weights.peak_jump > 0.0
        self._peak_index = plan if self.peaked else -1
        self._jump_index = plan + int(self.peaked) if self.jump_peaked else -1
        size = plan + int(self.peaked) + int(self.jump_peaked)
        future = count - 1
        rows = (future * nv if position else 0) + (future * nv if acceleration is not None else 0)
        epigraph_rows = 2 * plan * (int(self.peaked) + int(self.jump_peaked))
        self.problem = QpProblem.allocate(size, rows + epigraph_rows)
        self._plan_size = plan
        # The plan's block of P (a contiguous buffer when epigraph variables follow it).
        self._task_hessian = np.empty((plan, plan)) if size > plan else self.problem.P
        self._task_weight = h / (horizon * dt * dt)  # (K,)
        self._hh = np.multiply.outer(h, h)[:, :, None, None]  # (K, K, 1, 1)
        self._index = np.maximum.outer(np.arange(count), np.arange(count))
        self._blocks = np.empty((count, count, nv, nv))
        self._constant = self._constant_hessian(h, dt, horizon)
        self._first_jump = weights.jump
        eye = np.eye(nv)
        C = self.problem.C
        row = 0
        if position:
            for i in range(1, count):
                for j in range(i + 1):
                    C[row : row + nv, j * nv : (j + 1) * nv] = h[j] * eye
                row += nv
            self._position_rows = slice(0, row)
        else:
            self._position_rows = slice(0, 0)
        self._acceleration_rows = slice(row, rows)
        if acceleration is not None:
            mid = 0.5 * (h[:-1] + h[1:])  # h̃_i, i = 2..K
            for i in range(1, count):
                C[row : row + nv, i * nv : (i + 1) * nv] = eye
                C[row : row + nv, (i - 1) * nv : i * nv] = -eye
                row += nv
            change = np.minimum(np.outer(mid, acceleration).reshape(-1), BIG)
            self.problem.u[self._acceleration_rows] = change
            self.problem.l[self._acceleration_rows] = -change
        if size > plan:
            self._epigraphs(rows, h, dt)
        # The rows as groups of one block of nv rows per knot, in knot order (position and
        # acceleration rows: knots 2..K; each epigraph side: knots 1..K), for advance_rows.
        groups = [self._position_rows, self._acceleration_rows]
        groups += [slice(a, a + plan) for a in range(rows, rows + epigraph_rows, plan)]
        self._row_groups = [group for group in groups if group.stop > group.start]

    def _epigraphs(self, row: int, h: FloatArray, dt: float) -> None:
        r"""The epigraph rows from ``row`` on, their variables' cost and bounds (constant).

        Peak speed: :math:`\pm v_{ij} - s \le 0`. Peak jump, with :math:`c_1 = 1`,
        :math:`c_i = dt/\tilde h_i`: :math:`\pm c_i(v_i - v_{i-1}) - a \le 0` (``i ≥ 2``)
        and :math:`\pm v_1 - a \le \pm\dot q_{prev}` (its bounds written by :meth:`build`).
        Each variable: cost ``ω z + ½ε z²``, ``z ≥`` its floor (:meth:`build`).
        """
        problem, plan, nv = self.problem, self._plan_size, self.nv
        C, weights = problem.C, self.weights
        identity = np.arange(plan)
        problem.P[:] = 0.0
        problem.l[row:] = -BIG
        problem.u[row:] = 0.0
        for index in (self._peak_index, self._jump_index):
            if index < 0:
                continue
            problem.P[index, index] = PEAK_CURVATURE
            problem.ub[index] = BIG
            problem.lb[index] = 0.0
        if self.peaked:
            C[row + identity, identity] = 1.0
            C[row + plan + identity, identity] = -1.0
            C[row : row + 2 * plan, self._peak_index] = -1.0
            problem.q[self._peak_index] = weights.peak
            row += 2 * plan
        if self.jump_peaked:
            scale = np.repeat(np.concatenate([[1.0], dt / (0.5 * (h[:-1] + h[1:]))]), nv)
            self._jump_rows = slice(row, row + 2 * plan)
            for sign, start in ((1.0, row), (-1.0, row + plan)):
                C[start + identity, identity] = sign * scale
                C[start + identity[nv:], identity[:-nv]] = -sign * scale[nv:]
            C[row : row + 2 * plan, self._jump_index] = -1.0
            problem.q[self._jump_index] = weights.peak_jump

    def _constant_hessian(self, h: FloatArray, dt: float, horizon: float) -> FloatArray:
        """The regularisation and smoothness blocks, ``(K·nv, K·nv)`` (module docstring)."""
        count, nv, w = h.shape[0], self.nv, self.weights
        diagonal = w.regularization * h / horizon
        # Velocity-change weights: w_i = ρ dt²/(H h̃_i) (h̃_1 = dt: q̇_prev is segment 0 of
        # length dt), plus ρ₀ on the first.
        change = np.empty(count + 1)
        change[0] = w.smoothness * dt / horizon + w.jump
        change[1:count] = w.smoothness * dt * dt / (horizon * 0.5 * (h[:-1] + h[1:]))
        change[count] = 0.0
        diagonal = diagonal + change[:count] + change[1:]
        blocks = np.zeros((count, nv, count, nv))
        eye = np.eye(nv)
        for i in range(count):
            blocks[i, :, i, :] = diagonal[i] * eye
            if i:
                blocks[i, :, i - 1, :] = -change[i] * eye
                blocks[i - 1, :, i, :] = -change[i] * eye
        return blocks.reshape(count * nv, count * nv)

    def build(
        self,
        jacobians: FloatArray,
        residuals: FloatArray,
        nominal: FloatArray,
        qdot_prev: FloatArray,
        first_box: FloatArray,
        speed: FloatArray,
        position_room: FloatArray,
        peak_floor: float = 0.0,
        jump_floor: float = 0.0,
        peak_scale: float | None = None,
    ) -> QpProblem:
        r"""Write this step's QP into :attr:`problem` and return it.

        Args:
            jacobians: :math:`\bar J_i`, shape ``(K, n, nv)`` (weighted).
            residuals: :math:`\bar r_i` [task units], shape ``(K, n)`` (weighted).
            nominal: :math:`\bar d_i` [rad], shape ``(K, nv)``.
            qdot_prev: ``q̇_prev`` [rad/s], shape ``(nv,)``.
            first_box: ``[lb; ub]`` of ``v_1`` [rad/s], shape ``(2, nv)``.
            speed: ``q̇_max`` [rad/s] of the future segments, shape ``(nv,)`` (inf: none).
            position_room: ``[θ_min − θ₀; θ_max − θ₀]`` [rad], shape ``(2, nv)``.
            peak_floor: ŝ [rad/s], the peak joint speed already executed (peak term only).
            jump_floor: â [rad/s], the largest one-step velocity change already executed
                (peak-jump term only).
            peak_scale: None: the weights ω, ω_a as given; else their factor this step
                [task units² / s² / (rad/s)], :math:`\bar v^2/\dot q_{lim}` of the ``arm``
                rule (:mod:`.parameters`): the costs are ``peak·scale`` and
                ``peak_jump·scale``.
        """
        problem, count, nv = self.problem, self.grid.count, self.nv
        h, c = self.grid.steps, self._task_weight
        kappa = self.weights.trust_region
        transposed = jacobians.transpose(0, 2, 1)  # (K, nv, n)
        gram = np.matmul(transposed, jacobians)  # (K, nv, nv); batched matmul beats einsum
        if kappa > 0.0:
            gram.reshape(count, -1)[:, :: nv + 1] += kappa
        gram *= c[:, None, None]
        # g_i = c_i J̄_iᵀ r̄_i + G_i d̄_i, then suffix sums over i.
        pull = np.matmul(transposed, residuals[:, :, None])[:, :, 0]
        pull *= c[:, None]
        pull += np.matmul(gram, nominal[:, :, None])[:, :, 0]
        suffix = np.add.accumulate(gram[::-1])[::-1]  # cumsum over knots, no wrapper
        pull_suffix = np.add.accumulate(pull[::-1])[::-1]
        blocks = self._blocks
        np.take(suffix, self._index, axis=0, out=blocks)
        blocks *= self._hh
        hessian, plan = self._task_hessian, self._plan_size
        np.copyto(hessian.reshape(count, nv, count, nv), blocks.transpose(0, 2, 1, 3))
        np.add(hessian, self._constant, out=hessian)
        if problem.q.shape[0] > plan:
            problem.P[:plan, :plan] = hessian
        if peak_scale is not None:
            weights = self.weights
            if self.peaked:
                problem.q[self._peak_index] = weights.peak * peak_scale
            if self.jump_peaked:
                problem.q[self._jump_index] = weights.peak_jump * peak_scale
        if self.peaked:
            problem.lb[self._peak_index] = min(peak_floor, BIG)
        if self.jump_peaked:
            problem.lb[self._jump_index] = min(jump_floor, BIG)
            first = self._jump_rows.start
            np.copyto(problem.u[first : first + nv], qdot_prev)
            np.negative(qdot_prev, out=problem.u[first + plan : first + plan + nv])
        linear = problem.q[:plan].reshape(count, nv)
        np.multiply(pull_suffix, -h[:, None], out=linear)
        linear[0] -= self._first_jump * qdot_prev
        lb, ub = problem.lb[:plan].reshape(count, nv), problem.ub[:plan].reshape(count, nv)
        np.minimum(np.maximum(first_box[0], -BIG, out=lb[0]), BIG, out=lb[0])  # clip, no wrapper
        np.minimum(np.maximum(first_box[1], -BIG, out=ub[0]), BIG, out=ub[0])
        limit = np.minimum(speed, BIG)
        lb[1:] = -limit
        ub[1:] = limit
        rows = self._position_rows
        if rows.stop:
            room = np.minimum(np.maximum(position_room, -BIG), BIG)
            problem.l[rows].reshape(count - 1, nv)[:] = room[0]  # a view: every knot's rows
            problem.u[rows].reshape(count - 1, nv)[:] = room[1]
        return problem

    def unconstrained(self) -> FloatArray | None:
        r"""The minimiser of the built QP's cost without constraints, when it meets them all.

        :math:`x^* = -P^{-1}q` by one LAPACK Cholesky (``dpotrf``/``dpotrs``); returned only
        when :math:`lb \le x^* \le ub` and :math:`l \le Cx^* \le u` hold, where convexity makes
        it the QP's optimum (the fast path: no solver call). None otherwise (or when the
        factorisation fails).
        """
        none = np.zeros(self.problem.q.shape[0], dtype=bool)
        return self.with_active_bounds(none, none)

    def with_active_bounds(self, lower: BoolArray, upper: BoolArray) -> FloatArray | None:
        r"""The QP's optimum if the active constraints are exactly the given bounds, else None.

        With the variables in ``lower`` (``upper``) fixed at ``lb`` (``ub``), the free ones
        ``F`` solve :math:`P_{FF}x_F = -(q_F + P_{FB}x_B)` (one LAPACK Cholesky). The point is
        the optimum of the convex QP exactly when the KKT conditions hold: ``x_F`` within its
        bounds, every row satisfied, and the gradient :math:`g = Px + q` pushing each fixed
        variable against its bound (:math:`g_i \ge 0` at a lower, :math:`\le 0` at an upper
        bound; a tolerance of 1e-9 relative). The last step's active set is the usual guess.

        Args:
            lower: Variables held at ``lb``, shape ``(n,)`` (bool).
            upper: Variables held at ``ub``, shape ``(n,)`` (bool), disjoint from ``lower``.
        """
        problem = self.problem
        P, q, lb, ub = problem.P, problem.q, problem.lb, problem.ub
        fixed = lower | upper
        x = np.where(lower, lb, np.where(upper, ub, 0.0))
        free = ~fixed
        if free.any():
            if fixed.any():
                block = P[np.ix_(free, free)]
                rhs = q[free] + P[np.ix_(free, fixed)].dot(x[fixed])
            else:
                block, rhs = P, q
            factor, info = lapack.dpotrf(block, lower=False, clean=False, overwrite_a=False)
            if info != 0:
                return None
            solved, info = lapack.dpotrs(factor, rhs, lower=False)
            if info != 0:
                return None
            x[free] = -solved
        if not (np.all(x >= lb) and np.all(x <= ub)):
            return None  # also for NaN
        if problem.C.shape[0]:
            rows = problem.C.dot(x)
            if not (np.all(rows >= problem.l) and np.all(rows <= problem.u)):
                return None
        if fixed.any():
            gradient = P.dot(x) + q
            tolerance = 1e-9 * (1.0 + np.abs(gradient))
            if np.any(gradient[lower] < -tolerance[lower]) or np.any(
                gradient[upper] > tolerance[upper]
            ):
                return None
        return np.asarray(x, dtype=float)

    def with_active_set(
        self, lower: BoolArray, upper: BoolArray, rows_lower: BoolArray, rows_upper: BoolArray
    ) -> FloatArray | None:
        r"""The QP's optimum if the active constraints are exactly the given bounds and rows.

        The generalisation of :meth:`with_active_bounds` to active rows (the warm active set:
        no solver call when the last optimum's active set, or the same advanced by one
        segment, is still optimal). With the variables in ``lower`` (``upper``) fixed at
        ``lb`` (``ub``) and the rows ``W`` in ``rows_lower`` (``rows_upper``) held at ``l``
        (``u``), the free variables ``F`` solve the equality-constrained QP

        .. math::
            x_F = x_u - P_{FF}^{-1}A^\top\lambda,\quad
            (A P_{FF}^{-1} A^\top)\,\lambda = A x_u - b,\quad
            x_u = -P_{FF}^{-1}(q_F + P_{FB}x_B)

        with :math:`A = C_{WF}`, :math:`b = c_W - C_{WB}x_B` (``c_W`` the held sides); two
        LAPACK Cholesky factorisations (``P_FF``, then the ``|W| × |W|`` Schur complement).
        The point is the convex QP's optimum exactly when the KKT conditions hold: every bound
        and row met (the held rows within 1e-9 relative), :math:`\lambda \ge 0` on rows held
        at ``u``, :math:`\le 0` at ``l``, and :math:`g = Px + q + C_W^\top\lambda` pushing each
        fixed variable against its bound (tolerances 1e-9 relative). None otherwise, or when a
        factorisation fails (e.g. dependent active rows).

        Args:
            lower: Variables held at ``lb``, shape ``(n,)`` (bool).
            upper: Variables held at ``ub``, shape ``(n,)`` (bool), disjoint from ``lower``.
            rows_lower: Rows held at ``l``, shape ``(m,)`` (bool).
            rows_upper: Rows held at ``u``, shape ``(m,)`` (bool), disjoint from
                ``rows_lower``.
        """
        held = rows_lower | rows_upper
        if not held.any():
            return self.with_active_bounds(lower, upper)
        problem = self.problem
        P, q, lb, ub, C = problem.P, problem.q, problem.lb, problem.ub, problem.C
        fixed = lower | upper
        free = ~fixed
        if not free.any():
            return None
        x = np.where(lower, lb, np.where(upper, ub, 0.0))
        rows = C[held]
        A = rows[:, free]
        b = np.where(rows_lower, problem.l, problem.u)[held]
        if fixed.any():
            block = P[np.ix_(free, free)]
            rhs = q[free] + P[np.ix_(free, fixed)].dot(x[fixed])
            b = b - rows[:, fixed].dot(x[fixed])
        else:
            block, rhs = P, q
        # Rows that depend on others (a degenerate optimum: e.g. a peak row whose variable
        # sits at its bound) are dropped: a rank-revealing QR of A^T keeps a basis of them.
        _, triangle, pivots = linalg.qr(A.T, mode="economic", pivoting=True)
        diagonal = np.abs(np.diagonal(triangle))
        basis = pivots[: int(np.count_nonzero(diagonal > 1e-10 * max(1.0, diagonal[0])))]
        A, b, rows, at_lower = A[basis], b[basis], rows[basis], rows_lower[held][basis]
        if not basis.size:
            return self.with_active_bounds(lower, upper)
        factor, info = lapack.dpotrf(block, lower=False, clean=False, overwrite_a=False)
        if info != 0:
            return None
        unconstrained, info = lapack.dpotrs(factor, -rhs, lower=False)
        if info != 0:
            return None
        directions, info = lapack.dpotrs(factor, np.ascontiguousarray(A.T), lower=False)
        if info != 0:
            return None
        schur, info = lapack.dpotrf(A.dot(directions), lower=False, clean=False)
        if info != 0:
            return None
        multipliers, info = lapack.dpotrs(schur, A.dot(unconstrained) - b, lower=False)
        if info != 0:
            return None
        x[free] = unconstrained - directions.dot(multipliers)
        if not (np.all(x >= lb) and np.all(x <= ub)):
            return None  # also for NaN
        values = C.dot(x)
        slack = 1e-9 * (1.0 + np.abs(values))
        if not (np.all(values >= problem.l - slack) and np.all(values <= problem.u + slack)):
            return None
        signs = np.where(at_lower, -multipliers, multipliers)
        if np.any(signs < -1e-9 * (1.0 + np.abs(multipliers))):
            return None
        if fixed.any():
            gradient = P.dot(x) + q + rows.T.dot(multipliers)
            tolerance = 1e-9 * (1.0 + np.abs(gradient))
            if np.any(gradient[lower] < -tolerance[lower]) or np.any(
                gradient[upper] > tolerance[upper]
            ):
                return None
        return np.asarray(x, dtype=float)

    def active_rows(self, x: FloatArray, tol: float = 1e-9) -> tuple[BoolArray, BoolArray]:
        """The rows ``C x`` holds at a side (within ``tol·(1 + |side|)``): ``(at l, at u)``."""
        problem = self.problem
        values = problem.C.dot(x)
        lower = values <= problem.l + tol * (1.0 + np.abs(problem.l))
        upper = ~lower & (values >= problem.u - tol * (1.0 + np.abs(problem.u)))
        return lower, upper

    def violated_rows(self, x: FloatArray, tol: float = 1e-9) -> BoolArray:
        """The rows ``x`` breaks by more than ``tol·(1 + |side|)``, shape ``(m,)`` (bool)."""
        problem = self.problem
        values = problem.C.dot(x)
        return (values < problem.l - tol * (1.0 + np.abs(problem.l))) | (
            values > problem.u + tol * (1.0 + np.abs(problem.u))
        )

    @property
    def position_rows(self) -> slice:
        """The rows of the future knots' position box (empty without a position limit)."""
        return self._position_rows

    def advance_rows(self, mask: BoolArray) -> BoolArray:
        """A per-row mask advanced by one segment, as the plan is (the last knot's kept)."""
        moved = mask.copy()
        nv = self.nv
        for group in self._row_groups:
            moved[group.start : group.stop - nv] = mask[group.start + nv : group.stop]
        return moved

    def active_bounds(self, x: FloatArray, tol: float = 1e-9) -> tuple[BoolArray, BoolArray]:
        """The bounds ``x`` lies on (within ``tol·(1 + |bound|)``): ``(at lb, at ub)``."""
        problem = self.problem
        lower = x <= problem.lb + tol * (1.0 + np.abs(problem.lb))
        upper = ~lower & (x >= problem.ub - tol * (1.0 + np.abs(problem.ub)))
        return lower, upper

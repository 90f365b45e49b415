r"""The QP differential-IK formulation, pure: the closed-form minimiser and the QP data.

.. math::
    \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
    + \tfrac12 w_p\|\dot q - \dot q_p\|^2 \quad\text{s.t.}\quad lb \le \dot q \le ub,
    \quad c_j^\top\dot q \ge l_j

with ``μ = λ²`` (λ the DLS damping factor) and the box ``[lb; ub]`` of the step's limits
(:mod:`otmm_qp.limits`). :class:`QpFormulation` holds the cost; its
:meth:`~QpFormulation.unconstrained` is the minimiser without bounds from the shared SVD (the
fast path) and :meth:`~QpFormulation.build` writes the QP into preallocated arrays
(:func:`build_qp`). :func:`active_bound` and :func:`clip_into_box` read a solution against the
box. Solving lives in :mod:`otmm_qp_controllers.qp.solvers`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.state import KinematicState

from ..damping import damped_least_squares
from .solvers.problem import BIG, QpProblem

__all__ = [
    "BIG",
    "QpFormulation",
    "QpProblem",
    "active_bound",
    "build_qp",
    "clip_into_box",
    "diagonal_view",
]

_INF, _MINUS_INF = math.inf, -math.inf


@dataclass(frozen=True)
class QpFormulation:
    r"""The cost of the differential-IK QP (pure: no per-run or per-step state).

    .. math::
        f(\dot q) = \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - \dot q_p\|^2

    Attributes:
        mu: ``μ = λ² > 0``, the weight of ``½‖q̇‖²`` [task units² / (rad/s)²].
        posture_weight: ``w_p ≥ 0`` of the posture cost (0: none).

    Raises:
        ParameterError: ``mu`` not a finite number > 0, or ``posture_weight`` < 0.
    """

    mu: float
    posture_weight: float = 0.0

    def __post_init__(self) -> None:
        """Validate both weights."""
        if not (math.isfinite(self.mu) and self.mu > 0.0):
            raise ParameterError("damping", f"λ² must be a finite number > 0, got {self.mu}")
        if not (math.isfinite(self.posture_weight) and self.posture_weight >= 0.0):
            raise ParameterError("posture_weight", f"must be >= 0, got {self.posture_weight}")

    @property
    def damping(self) -> float:
        """The damping factor ``λ = √μ`` [task units] (``BackendOutput.damping``)."""
        return float(np.sqrt(self.mu))

    def unconstrained(
        self,
        state: KinematicState,
        xdot: FloatArray,
        posture: FloatArray | None,
        work: FloatArray | None = None,
    ) -> FloatArray:
        r"""The minimiser of :math:`f` without bounds, from the shared SVD [rad/s], ``(nv,)``.

        .. math::
            \dot q^* = V\,\mathrm{diag}\Big(\frac{1}{\sigma_i^2+\mu'}\Big)V^\top b
            + \frac{1}{\mu'}(I - VV^\top)b,\qquad b = J_w^\top\dot x_w + w_p\dot q_p,
            \ \mu' = \mu + w_p

        (without posture, DLS with ``λ² = μ``:
        :math:`\dot q^* = V\,\mathrm{diag}(\sigma_i/(\sigma_i^2+\mu))U^\top\dot x_w`).

        Args:
            state: The step's kinematic state (``U``, ``sigma``, ``Vt``).
            xdot: ``ẋ_w``, shape ``(n,)``.
            posture: ``q̇_p`` [rad/s], shape ``(nv,)``, or None (no posture cost).
            work: :func:`~otmm_qp.backends.backend.svd_work` buffers, shape ``(2, k)``, so
                that only the returned ``q̇*`` is allocated; None: temporaries.
        """
        if posture is None:  # DLS, from the shared SVD (μ > 0 is checked at construction)
            return damped_least_squares(state, xdot, self.mu, work)
        sigma, Vt = state.sigma, state.Vt
        mu = self.mu + self.posture_weight
        b = Vt.T @ (sigma * (state.U.T @ xdot)) + self.posture_weight * posture
        c = Vt @ b
        return np.asarray(Vt.T @ (c / (sigma * sigma + mu)) + (b - Vt.T @ c) / mu)

    def build(
        self,
        task_jacobian: FloatArray,
        xdot: FloatArray,
        posture: FloatArray | None,
        bounds: FloatArray | None,
        out: QpProblem,
        diagonal: FloatArray | None = None,
    ) -> QpProblem:
        """The QP of :math:`f` under the box ``bounds`` (2, nv) into ``out`` (:func:`build_qp`)."""
        return build_qp(
            task_jacobian, xdot, self.mu, bounds, self.posture_weight, posture, out, diagonal
        )


def active_bound(
    qdot: FloatArray,
    bounds: FloatArray,
    tol: float,
    lists: tuple[list[float], list[float]] | None = None,
) -> bool | None:
    r"""Whether some :math:`\dot q_i` is within ``tol·(1 + |bound|)`` of ``lb_i`` or ``ub_i``.

    .. math:: \exists i:\ \dot q_i - lb_i \le \tau(1 + |lb_i|)\ \lor\
              ub_i - \dot q_i \le \tau(1 + |ub_i|)

    for finite bounds (an infinite one is never active).

    Args:
        qdot: Joint velocity [rad/s], shape ``(nv,)``.
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``.
        tol: Relative tolerance τ [-].
        lists: ``bounds`` as two lists of Python floats when the caller has them
            (:attr:`~otmm_qp.limits.box.LimitBox.lists`); None: converted here.

    Returns:
        The answer, or None when ``qdot`` lies outside the box (or is NaN): one pass serves the
        QP's fast path (inside?) and the status (active?).
    """
    # A scalar loop: for an arm's nv ≤ ~10 joints it costs a third of the eight NumPy calls
    # (each ~1 µs) that the array form needs, and this runs on every QP step.
    active = False
    inf, minus_inf = _INF, _MINUS_INF  # locals: no global and attribute look-up per joint
    lower, upper = bounds.tolist() if lists is None else lists
    for value, low, high in zip(qdot.tolist(), lower, upper, strict=True):
        if not low <= value <= high:  # also for NaN
            return None
        # An infinite bound is never active (inf ≤ τ(1 + inf) would say it is).
        if not active and (
            (value - low <= tol * (1.0 + abs(low)) and low != minus_inf)
            or (high - value <= tol * (1.0 + abs(high)) and high != inf)
        ):
            active = True  # later joints need only the inside test
    return active


def clip_into_box(
    x: FloatArray,
    bounds: FloatArray,
    tol: float,
    lists: tuple[list[float], list[float]] | None = None,
    owned: bool = False,
) -> tuple[FloatArray, bool] | None:
    r"""A solver's answer clipped into the box, and whether a bound is then active.

    .. math:: \dot q = \min(\max(x, lb), ub),\qquad
              \text{active} = \text{active\_bound}(\dot q, [lb; ub], \tau)

    for a non-empty box (``lb ≤ ub``); clipping removes the solver's tolerance, so a returned
    ``q̇`` never violates a bound.

    Args:
        x: The solver's primal solution [rad/s], shape ``(nv,)``.
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``, ``lb ≤ ub``.
        tol: Relative tolerance τ [-] of :func:`active_bound`.
        lists: ``bounds`` as two lists of Python floats when the caller has them
            (:attr:`~otmm_qp.limits.box.LimitBox.lists`); None: converted here.
        owned: ``x`` is a fresh array the caller gives away (e.g. a solver's copy): returned
            as ``q̇`` itself when clipping changes none of its values.

    Returns:
        ``(q̇ (nv,), active)`` — a new array, or ``x`` itself when ``owned`` and nothing
        changed — or None when some ``x_i`` is NaN or ±inf.
    """
    # One scalar pass instead of isfinite/all, maximum/minimum and active_bound's pass (the
    # every-step QP path runs this on each step; see active_bound for why scalar).
    values = x.tolist()
    if not math.isfinite(sum(values)):  # NaN or ±inf somewhere (or entries beyond 1e308)
        return None
    active = changed = False
    inf, minus_inf = _INF, _MINUS_INF  # locals: no global and attribute look-up per joint
    lower, upper = bounds.tolist() if lists is None else lists
    for i, (value, low, high) in enumerate(zip(values, lower, upper, strict=True)):
        if value <= low:
            # Equal and non-zero: the same bits already (a zero may be -0.0 against 0.0).
            if value != low or low == 0.0:
                values[i], changed = low, True
            active = active or low != minus_inf
        elif value >= high:
            if value != high or high == 0.0:
                values[i], changed = high, True
            active = active or high != inf
        elif not active and (
            (value - low <= tol * (1.0 + abs(low)) and low != minus_inf)
            or (high - value <= tol * (1.0 + abs(high)) and high != inf)
        ):
            active = True
    if owned and not changed:
        return x, active
    return np.array(values), active


def diagonal_view(matrix: FloatArray) -> FloatArray:
    """A writeable view on the diagonal of a C-contiguous square ``matrix`` (n, n), shape (n,)."""
    return matrix.reshape(-1)[:: matrix.shape[0] + 1]


def build_qp(
    task_jacobian: FloatArray,
    xdot: FloatArray,
    damping: float,
    bounds: FloatArray | None,
    posture_weight: float = 0.0,
    posture_velocity: FloatArray | None = None,
    out: QpProblem | None = None,
    diagonal: FloatArray | None = None,
) -> QpProblem:
    r"""The differential-IK QP.

    .. math::
        \min_{\dot q}\ \tfrac12\|J_w\dot q - \dot x_w\|^2 + \tfrac12\mu\|\dot q\|^2
        + \tfrac12 w_p\|\dot q - \dot q_p\|^2 \quad\text{s.t.}\quad lb \le \dot q \le ub

    i.e. ``P = J_wᵀJ_w + (μ + w_p)I``, ``q = −(J_wᵀẋ_w + w_p q̇_p)``; ``±inf`` bounds are
    passed as ``±BIG``. The general-constraint rows of ``out`` (e.g. the singularity barrier)
    are left untouched.

    Args:
        task_jacobian: ``J_w``, shape ``(n, nv)``.
        xdot: ``ẋ_w``, shape ``(n,)``.
        damping: ``μ = λ² > 0`` [task units² per (rad/s)²].
        bounds: ``[lb; ub]`` [rad/s], shape ``(2, nv)``; None when ``out.lb``, ``out.ub``
            already hold the box within ``±BIG`` (a backend whose box is written into the
            problem, :meth:`QpProblem.allocate` with ``box=``).
        posture_weight: ``w_p ≥ 0``.
        posture_velocity: ``q̇_p = g_p(θ_nominal − θ)`` [rad/s], shape ``(nv,)``.
        out: Problem whose ``P``, ``q``, ``lb``, ``ub`` are overwritten; a new box-only
            problem when None.
        diagonal: A view on the diagonal of ``out.P``, shape ``(nv,)``
            (:func:`diagonal_view`, made once by a caller that reuses ``out``); None: made here.

    Raises:
        ParameterError: ``bounds`` is None without ``out``.
    """
    nv = task_jacobian.shape[1]
    if out is None:
        if bounds is None:
            raise ParameterError("bounds", "None needs out= holding the box")
        out = QpProblem.allocate(nv)
    hessian, linear = out.P, out.q
    # ndarray.dot rather than matmul or np.dot: the least call overhead on arm-sized arrays.
    task_jacobian.T.dot(task_jacobian, out=hessian)
    if diagonal is None:
        diagonal = diagonal_view(hessian)
    np.add(diagonal, damping + posture_weight, diagonal)
    xdot.dot(task_jacobian, out=linear)
    np.negative(linear, linear)
    if posture_weight > 0.0 and posture_velocity is not None:
        linear -= posture_weight * posture_velocity
    if bounds is not None:
        np.minimum(np.maximum(bounds[0], -BIG, out=out.lb), BIG, out=out.lb)
        np.minimum(np.maximum(bounds[1], -BIG, out=out.ub), BIG, out=out.ub)
    return out

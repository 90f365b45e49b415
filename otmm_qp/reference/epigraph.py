r"""The min-max solve in epigraph form: sequential QPs over the whole path (Clarabel).

The problem (:mod:`otmm_qp.reference.solve`) is

.. math::
    \min_{Q, t}\; t + \varepsilon\,\bar\ell(Q) \quad\text{s.t.}\quad
    m_{k,p}(q_k) \le t\ \ (k = 1..N-1,\ p \in \text{parts}),\quad
    l \le q_k \le u,\quad |q_k - q_{k-1}| \le s

with ``m_{k,p} = ‖e_{k,p}‖/tol_p`` (``p``: position, orientation), the mean least squares
``ℓ̄ = (1/(N−1)) Σ_k ½‖S e_k‖²`` as a small tie-break (``ε`` = :data:`TIE_BREAK`: it keeps
the samples that do not bind near their own best instead of letting them drift up to
``t``). Each iteration linearises the errors at the current path and solves, for the step
``δ`` and ``t``,

.. math::
    \min_{\delta, t}\; t + \varepsilon(\bar\ell + \bar g^\top\delta)
        + \tfrac12 \delta^\top B \delta
    \quad\text{s.t.}\quad m_{k,p} + a_{k,p}^\top \delta_k \le t,\quad
    \text{box}(l - q, u - q) \cap [-\Delta, \Delta],\quad
    |q_k + \delta_k - q_{k-1} - \delta_{k-1}| \le s

with ``a_{k,p} = −J_{k,p}^\top e_{k,p}/(‖e_{k,p}‖ tol_p)`` the gradient of ``m_{k,p}``,
``B = Σ y_{k,p} [∇²m_{k,p}]_GN + ε ∇²ℓ̄_GN + μI`` (the Gauss–Newton Hessian of the
Lagrangian with the previous QP's multipliers ``y``, eigenvalues clipped ``≥ 0``) and
``Δ`` a trust radius [rad]. A step is kept when the true
``φ = max m + ε ℓ̄`` decreases by at least a tenth of the model's prediction (every trial is
projected onto the limits exactly, so every iterate is feasible).

**Convergence test** (stored with the result): the step ``‖δ‖_∞`` [rad] and the KKT residual
of the epigraph problem at the current path with the QP's multipliers,

.. math:: r = \max\big(\|c + A^\top y\|_\infty,\ \max_i |y_i|\,\mathrm{slack}_i\big)

(stationarity of the linearised problem at ``δ = 0`` and complementarity; ``c`` the linear
cost). It stops when ``r ≤`` :data:`KKT_TOLERANCE` or ``‖δ‖_∞ ≤`` :data:`STEP_TOLERANCE`, at
the iteration cap, or at the deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import clarabel
import numpy as np
import scipy.sparse as sp

from otmm_qp.interrupt import sigint_held
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.projection import project_path
from otmm_qp.reference.sqp import SolverFailure
from otmm_qp.robots.robot import FloatArray

#: Weight ε of the mean least squares tie-break (merit units: squared tolerances).
TIE_BREAK = 1e-3
#: Proximal term μ on every block [merit units/rad²].
PROXIMAL = 1e-6
#: A part's error below this many tolerances has no direction: its gradient is left out.
TINY_MERIT = 1e-9
#: Floor of ``m`` in the Gauss–Newton Hessian ``J̃ᵀ(I − ûûᵀ)J̃ / m`` [tolerances].
CURVATURE_FLOOR = 1e-2
#: Convergence: KKT residual [merit units] and step [rad].
KKT_TOLERANCE = 1e-4
STEP_TOLERANCE = 1e-6
#: Initial, largest and smallest trust radius [rad].
INITIAL_RADIUS = 0.2
MAX_RADIUS = 2.0
MIN_RADIUS = 1e-10
#: Clarabel's gap and feasibility tolerances (the KKT test is at 1e-4, every step is checked).
QP_TOLERANCE = 1e-7
#: Clarabel statuses whose point is used (every step is checked on the true errors anyway).
ACCEPTED = ("Solved", "AlmostSolved", "MaxIterations", "MaxTime", "InsufficientProgress")


def _settings() -> Any:
    """Clarabel settings: quiet, :data:`QP_TOLERANCE`, at most 60 interior iterations."""
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_iter = 60
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = QP_TOLERANCE
    return settings


class TrialStep(NamedTuple):
    """The outcome of :func:`trust_region_trial`.

    Attributes:
        path: The accepted path ``(N, nv)``, or None when the step was rejected.
        merits: The trial path's merits.
        phi: The trial path's merit function.
        radius: The trust radius [rad] for the next subproblem.
    """

    path: FloatArray | None
    merits: FloatArray
    phi: float
    radius: float


def trust_region_trial(
    problem: TrackingProblem,
    evaluate: Callable[[FloatArray], tuple[FloatArray, FloatArray, float]],
    current: FloatArray,
    delta: FloatArray,
    phi: float,
    predicted: float,
    radius: float,
) -> TrialStep:
    r"""Try ``current`` moved by ``delta`` (projected into the limits) as the next iterate.

    Accepted when the actual decrease is more than a tenth of the model's ``predicted`` one,
    :math:`\rho = (\phi - \phi_{trial})/\text{predicted} > 0.1` with
    :math:`\phi_{trial} < \phi`; the radius then doubles (up to :data:`MAX_RADIUS`) when
    :math:`\rho > 0.75` and the step used 90 % of it. Rejected: the radius shrinks to a quarter
    of ``min(radius, ‖δ‖∞)``. ``delta`` has shape ``(N − 1, nv)`` (the first sample is fixed).
    """
    longest = float(np.max(np.abs(delta)))
    trial = current.copy()
    trial[1:] += delta
    trial = project_path(trial, problem.lower, problem.upper, problem.step)
    _, trial_merits, trial_phi = evaluate(trial)
    ratio = (phi - trial_phi) / predicted
    if ratio > 0.1 and trial_phi < phi:
        if ratio > 0.75 and longest > 0.9 * radius:
            radius = min(2.0 * radius, MAX_RADIUS)
        return TrialStep(trial, trial_merits, trial_phi, radius)
    return TrialStep(None, trial_merits, trial_phi, 0.25 * min(radius, longest))


@dataclass
class EpigraphOutcome:
    """What one epigraph solve reached.

    Attributes:
        path: Best path found, shape ``(N, nv)``, within every limit.
        merit: Its ``max_k m_k`` [tolerances] (of the solve's parts).
        step: ``‖δ‖_∞`` of the last QP [rad] (NaN when no QP ran).
        kkt: KKT residual of the last QP's point [merit units] (NaN when no QP ran).
        iterations: QPs solved.
        converged: Stopped by the convergence test (not the cap, the deadline or a stall).
    """

    path: FloatArray
    merit: float
    step: float = math.nan
    kkt: float = math.nan
    iterations: int = 0
    converged: bool = False


class _Layout:
    """Fixed sparsity of the epigraph QP (only the merit gradients change between iterations).

    Variables ``x = (δ_1, …, δ_{N−1}, t)``; constraint rows: the merit rows
    ``(k, p)`` (``a_{k,p}ᵀ δ_k − t ≤ −m_{k,p}``), the box rows ``δ`` and the rate rows
    ``D δ``.
    """

    def __init__(self, blocks: int, nv: int, parts: int) -> None:
        self.blocks, self.nv, self.parts = blocks, nv, parts
        size = blocks * nv
        self.size = size
        merit_rows = blocks * parts
        self.merit_rows = merit_rows
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        # merit rows: row k·parts + p, columns of block k, then t
        k, p, i = np.meshgrid(np.arange(blocks), np.arange(parts), np.arange(nv), indexing="ij")
        rows.append((k * parts + p).ravel())
        cols.append((k * nv + i).ravel())
        self.gradient_count = rows[0].size
        rows.append(np.arange(merit_rows))
        cols.append(np.full(merit_rows, size))
        # box rows
        rows.append(merit_rows + np.arange(size))
        cols.append(np.arange(size))
        # rate rows: (D δ)_j = δ_j − δ_{j−nv}
        rows.append(merit_rows + size + np.arange(size))
        cols.append(np.arange(size))
        rows.append(merit_rows + size + np.arange(nv, size))
        cols.append(np.arange(size - nv))
        row = np.concatenate(rows)
        col = np.concatenate(cols)
        ident = np.arange(1, row.size + 1, dtype=float)
        matrix = sp.csc_matrix((ident, (row, col)), shape=(merit_rows + 2 * size, size + 1))
        matrix.sort_indices()
        self.order = np.asarray(matrix.data, dtype=int) - 1  # data position → entry id
        self.matrix = matrix
        fixed = np.concatenate(
            [
                -np.ones(merit_rows),
                np.ones(size),
                np.ones(size),
                -np.ones(size - nv),
            ]
        )
        self._values = np.concatenate([np.zeros(self.gradient_count), fixed])

    def a_data(self, gradients: FloatArray) -> FloatArray:
        """CSC data of ``A`` with the merit gradients ``(blocks, parts, nv)``."""
        values = self._values.copy()
        values[: self.gradient_count] = gradients.ravel()
        return np.asarray(values[self.order], dtype=float)


class EpigraphSQP:
    """Epigraph min-max over one task's path (see the module docstring).

    Args:
        problem: The task (``N ≥ 2`` samples); its tolerances set the parts: position, and
            orientation when the task is a pose and ``settings.orientation_tolerance`` is
            set.
    """

    def __init__(self, problem: TrackingProblem) -> None:
        self.problem = problem
        settings = problem.settings
        self.parts: list[tuple[slice, float]] = []
        if settings.position_tolerance is not None:
            self.parts.append((slice(0, problem.linear), settings.position_tolerance))
        if problem.pose and settings.orientation_tolerance is not None:
            self.parts.append((slice(3, 6), settings.orientation_tolerance))
        self.blocks = problem.samples - 1
        self.layout = _Layout(self.blocks, problem.nv, max(1, len(self.parts)))
        nv = problem.nv
        rows = np.array([i for j in range(nv) for i in range(j + 1)])
        cols = np.array([j for j in range(nv) for _ in range(j + 1)])
        self._rows, self._cols = rows, cols
        per = rows.size
        indices = (np.arange(self.blocks)[:, None] * nv + rows[None, :]).ravel()
        counts = np.tile(np.arange(1, nv + 1), self.blocks)
        indptr = np.concatenate([[0], np.cumsum(counts), [self.blocks * per]])
        self._p_pattern = (indices, indptr)
        self._rows_kept: tuple[np.ndarray, np.ndarray] | None = None
        self._stacked_pattern: sp.csc_matrix | None = None
        self._stacked_order = np.zeros(0, dtype=int)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, path: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        """Errors ``(N, n)``, merits per part ``(N−1, parts)`` and ``φ`` of a path."""
        errors = self.problem.errors(path)
        merits = self._merits(errors)
        return errors, merits, self._phi(errors, merits)

    def _merits(self, errors: FloatArray) -> FloatArray:
        out = np.zeros((errors.shape[0] - 1, max(1, len(self.parts))))
        for p, (rows, tolerance) in enumerate(self.parts):
            out[:, p] = np.linalg.norm(errors[1:, rows], axis=1) / tolerance
        return out

    def _phi(self, errors: FloatArray, merits: FloatArray) -> float:
        scaled = errors[1:] * self.problem.scale
        mean = 0.5 * float(np.mean(np.sum(scaled * scaled, axis=1)))
        value = float(np.max(merits)) + TIE_BREAK * mean
        return value if math.isfinite(value) else math.inf

    def _linearise(
        self, path: FloatArray, multipliers: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Merit gradients ``(B, parts, nv)``, tie-break gradient ``(B·nv,)``, Hessian blocks."""
        problem, robot = self.problem, self.problem.robot
        nv, blocks = problem.nv, self.blocks
        gradients = np.zeros((blocks, self.layout.parts, nv))
        tie = np.zeros((blocks, nv))
        hessians = np.zeros((blocks, nv, nv))
        scale = problem.scale
        for b in range(blocks):
            k = b + 1
            x, jacobian = robot.kinematics(robot.configuration(path[k]))
            error = robot.task_error(problem.targets[k], x)
            scaled_j = scale[:, None] * jacobian
            tie[b] = -(scaled_j.T @ (scale * error)) * (TIE_BREAK / blocks)
            block = (TIE_BREAK / blocks) * (scaled_j.T @ scaled_j)
            for p, (rows, tolerance) in enumerate(self.parts):
                part = error[rows] / tolerance
                size = float(np.linalg.norm(part))
                if size <= TINY_MERIT:
                    continue
                unit = part / size
                jp = jacobian[rows] / tolerance  # d(part)/dq = −jp
                gradients[b, p] = -(jp.T @ unit)
                weight = float(multipliers[b, p])
                if weight > 0.0:
                    projected = jp - np.outer(unit, unit @ jp)
                    block += weight * (projected.T @ projected) / max(size, CURVATURE_FLOOR)
            hessians[b] = block
        return gradients, tie.ravel(), hessians, np.zeros(0)

    # ------------------------------------------------------------------ the QP
    def _p_data(self, hessians: FloatArray) -> tuple[FloatArray, FloatArray]:
        values, vectors = np.linalg.eigh(0.5 * (hessians + np.transpose(hessians, (0, 2, 1))))
        values = np.maximum(values, 0.0) + PROXIMAL
        fixed = np.einsum("bij,bj,bkj->bik", vectors, values, vectors)
        return fixed, np.asarray(fixed[:, self._rows, self._cols].ravel(), dtype=float)

    def _bounds(
        self, path: FloatArray, merits: FloatArray, radius: float
    ) -> tuple[FloatArray, FloatArray]:
        problem = self.problem
        current = path[1:]
        box_lo = np.maximum(problem.lower - current, -radius)
        box_hi = np.minimum(problem.upper - current, radius)
        moves = np.diff(path, axis=0)
        step = np.minimum(problem.step, BIG)
        lower = np.concatenate(
            [
                np.full(merits.size, -BIG),
                np.minimum(box_lo.ravel(), 0.0),
                np.minimum((-step - moves).ravel(), 0.0),
            ]
        )
        upper = np.concatenate(
            [
                -merits.ravel(),
                np.maximum(box_hi.ravel(), 0.0),
                np.maximum((step - moves).ravel(), 0.0),
            ]
        )
        return lower, upper

    def _sides(self, lower: FloatArray, upper: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        """Rows with a finite upper / lower bound (fixed per task: set on the first call)."""
        if self._rows_kept is None:
            self._rows_kept = (upper < BIG / 2, lower > -BIG / 2)
        return self._rows_kept

    def _stacked(self, up: np.ndarray, down: np.ndarray) -> sp.csc_matrix:
        """``[A_up; −A_down]`` with placeholder data, and its data order (built once)."""
        if self._stacked_pattern is None:
            matrix = self.layout.matrix.copy()
            count = matrix.data.size
            matrix.data = np.arange(1, count + 1, dtype=float)  # CSC position ids of A
            stacked = sp.vstack([matrix[up], -matrix[down]], format="csc")
            stacked.sort_indices()
            ids = np.asarray(stacked.data, dtype=int)
            # position in [A_data; −A_data]: a positive id is an upper row, negative a lower one
            self._stacked_order = np.where(ids > 0, ids - 1, count + (-ids) - 1)
            self._stacked_pattern = stacked
        return self._stacked_pattern.copy()

    def _solve(
        self,
        p_data: FloatArray,
        cost: FloatArray,
        a_data: FloatArray,
        lower: FloatArray,
        upper: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """One QP with Clarabel; ``(x, y)`` with ``y = z_upper − z_lower`` per row of ``A``.

        ``l ≤ A x ≤ u`` is passed as ``[A; −A] x + s = [u; −l]``, ``s ≥ 0`` (infinite rows
        dropped).

        Raises:
            SolverFailure: Clarabel returned no finite solution or a failure status.
        """
        layout = self.layout
        size = layout.size + 1
        indices, indptr = self._p_pattern
        hessian = sp.csc_matrix((p_data, indices, indptr), shape=(size, size))
        up, down = self._sides(lower, upper)
        stacked = self._stacked(up, down)
        values = np.concatenate([a_data, -a_data])  # ids index [A; −A] in CSC data order
        stacked.data = values[self._stacked_order]
        rhs = np.concatenate([upper[up], -lower[down]])
        try:
            solver = clarabel.DefaultSolver(
                hessian, cost, stacked, rhs, [clarabel.NonnegativeConeT(rhs.size)], _settings()
            )
            with sigint_held():  # a native solver's own SIGINT handler never takes Ctrl-C
                solution = solver.solve()
        except (ValueError, RuntimeError, TypeError) as error:
            raise SolverFailure(f"Clarabel: {' '.join(str(error).split())}") from None
        status = str(solution.status)
        x = np.asarray(solution.x, dtype=float)
        z = np.asarray(solution.z, dtype=float)
        if x.size != size or not np.all(np.isfinite(x)) or not np.all(np.isfinite(z)):
            raise SolverFailure(f"Clarabel returned no step ({status})")
        if status not in ACCEPTED:
            raise SolverFailure(f"Clarabel status {status}")
        y = np.zeros(lower.size)
        count = int(np.count_nonzero(up))
        y[up] += z[:count]
        y[down] -= z[count:]
        return x, y

    def _kkt(
        self,
        cost: FloatArray,
        a_data: FloatArray,
        y: FloatArray,
        lower: FloatArray,
        upper: FloatArray,
        top: float,
    ) -> float:
        """KKT residual at ``δ = 0, t = max m`` with the QP's multipliers ``y``."""
        A = self.layout.matrix.copy()
        A.data = a_data
        stationarity = float(np.max(np.abs(cost + A.T @ y)))
        point = np.zeros(self.layout.size + 1)
        point[-1] = top
        value = A @ point
        slack = np.where(y > 0.0, upper - value, value - lower)
        slack = np.where(np.abs(slack) >= BIG / 2, 0.0, np.abs(slack))
        complementarity = float(np.max(np.abs(y) * slack)) if y.size else 0.0
        return max(stationarity, complementarity)

    # ------------------------------------------------------------------ driver
    def solve(self, path: FloatArray, iterations: int, deadline: float) -> EpigraphOutcome:
        """Iterate from a feasible ``path`` (see the module docstring).

        Raises:
            SolverFailure: Clarabel failed on a subproblem.
        """
        problem = self.problem
        layout = self.layout
        current = path
        _, merits, phi = self.evaluate(current)
        top = float(np.max(merits))
        best = EpigraphOutcome(current, top)
        multipliers = np.where(merits >= top - 1e-12, 1.0, 0.0)
        multipliers /= max(float(np.sum(multipliers)), 1.0)
        radius = INITIAL_RADIUS
        linear = None
        while best.iterations < iterations and time.perf_counter() < deadline:
            if linear is None:
                linear = self._linearise(current, multipliers)
            gradients, tie, hessians, _ = linear
            blocks, p_data = self._p_data(hessians)
            cost = np.concatenate([tie, [1.0]])
            a_data = layout.a_data(gradients)
            lower, upper = self._bounds(current, merits, radius)
            x, y = self._solve(p_data, cost, a_data, lower, upper)
            best.iterations += 1
            delta = x[:-1].reshape(self.blocks, problem.nv)
            model_top = float(np.max(merits + np.einsum("bpi,bi->bp", gradients, delta)))
            model = (
                max(model_top, x[-1])
                + (phi - top)
                + float(tie @ x[:-1])
                + 0.5 * float(np.einsum("bi,bij,bj", delta, blocks, delta))
            )
            predicted = phi - model
            longest = float(np.max(np.abs(delta)))
            best.step = longest
            best.kkt = self._kkt(cost, a_data, y, lower, upper, top)
            if best.kkt <= KKT_TOLERANCE or longest <= STEP_TOLERANCE or predicted <= 0.0:
                best.converged = best.kkt <= KKT_TOLERANCE or longest <= STEP_TOLERANCE
                break
            step = trust_region_trial(
                problem, self.evaluate, current, delta, phi, predicted, radius
            )
            radius = step.radius
            if step.path is None:
                if radius < MIN_RADIUS:
                    break
                continue
            current, merits, phi = step.path, step.merits, step.phi
            top = float(np.max(merits))
            if top < best.merit:
                best.path, best.merit = current, top
            merit_y = y[: layout.merit_rows].reshape(self.blocks, layout.parts)
            multipliers = np.maximum(merit_y, 0.0)
            linear = None
        return best

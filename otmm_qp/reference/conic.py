r"""The min-max solve with second-order-cone subproblems: the norm kept exact, the error linearised.

The min-max problem in epigraph form (:mod:`otmm_qp.reference.solve`): ``min t + ε ℓ̄`` s.t.
every sample's ``m_{k,p} = ‖e_{k,p}‖/tol_p ≤ t``, the limits as constraints. Each iteration
linearises the *error* ``e_{k,p}(q_k + δ_k) ≈ e_{k,p} − J_{k,p} δ_k`` (Gauss–Newton), not
its norm:

.. math::
    \min_{\delta, t}\; t + \varepsilon(\bar\ell + \bar g^\top\delta) + \tfrac12 \delta^\top B\delta
    \quad\text{s.t.}\quad \big\|(e_{k,p} - J_{k,p}\delta_k)/tol_p\big\| \le t,\quad
    \text{box}(l - q, u - q) \cap [-\Delta, \Delta],\quad
    |q_k + \delta_k - q_{k-1} - \delta_{k-1}| \le s

(``B = ε ∇²ℓ̄_GN + μI``), a second-order cone program solved by Clarabel. The norm's kink at
``e = 0`` and its curvature ``1/‖e‖`` are in the model exactly, so the model stays good where
the errors are small (a linearised-norm model, the retired ``EpigraphSQP``, predicts
``t = 0`` one step away there and its steps are rejected until the trust radius is tiny).
Steps are kept by
the same ratio test on the true ``φ = max m + ε ℓ̄``, every trial projected onto the limits.

**Convergence test** (stored): the step ``‖δ‖_∞`` [rad] and the KKT residual of the cone
program at ``δ = 0, t = max m`` with its multipliers ``z``,
``r = max(‖c + Aᵀz‖_∞, max_cones |⟨z_c, s_c⟩|)`` (stationarity and complementarity, ``s`` the
slacks at that point). Those multipliers are the step's, so they certify ``δ = 0`` only when
the step gains nothing either: it stops as converged when ``r ≤`` :data:`KKT_TOLERANCE` *and*
the model's predicted decrease is ``≤`` :data:`KKT_TOLERANCE`, or ``‖δ‖_∞ ≤``
:data:`STEP_TOLERANCE`; otherwise when the model predicts no decrease, at the iteration cap or
the deadline, or when it stalls (:func:`~otmm_qp.reference.trust_region.stalled`: the last
accepted steps gain less than a hundredth of the merit and could not reach the tolerance
within the cap). The loop, the ratio test and the radius are the one trust-region driver's
(:func:`~otmm_qp.reference.trust_region.minimise`); this class is its subproblem, and the
merit ``φ`` is :class:`~otmm_qp.reference.merit.MinMaxMerit`'s.
"""

from __future__ import annotations

import math
from typing import Any

import clarabel
import numpy as np
import scipy.sparse as sp

from otmm_qp.exceptions import SolverFailure
from otmm_qp.interrupt import sigint_held
from otmm_qp.reference.merit import TIE_BREAK, MinMaxMerit
from otmm_qp.reference.problem import BIG, TrackingProblem
from otmm_qp.reference.trust_region import Iterate, Outcome, Radii, Step, Stopping, minimise
from otmm_qp.robots.robot import FloatArray

#: Proximal term μ on every block [merit units/rad²].
PROXIMAL = 1e-6
#: Convergence: KKT residual [merit units] and step [rad].
KKT_TOLERANCE = 1e-4
STEP_TOLERANCE = 1e-6
#: Trust radii [rad]: first, largest, smallest.
RADII = Radii(initial=0.2, largest=2.0, smallest=1e-10)
#: The stop tests besides the cap (module docstring).
STOPPING = Stopping(step_tolerance=STEP_TOLERANCE, stall=True)
#: Clarabel's gap and feasibility tolerances (the KKT test is at 1e-4, every step is checked).
QP_TOLERANCE = 1e-7
#: Clarabel statuses whose point is used (every step is checked on the true errors anyway).
ACCEPTED = ("Solved", "AlmostSolved", "MaxIterations", "MaxTime", "InsufficientProgress")


def _settings() -> Any:
    """Clarabel settings: quiet, :data:`QP_TOLERANCE`, at most 80 interior iterations."""
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_iter = 80
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = QP_TOLERANCE
    # Presolve only drops rows with an infinite bound (≥ 1e20), and no row here has one
    # (those rows are left out): off, it gives the same iterates, without its set-up cost.
    settings.presolve_enable = False
    return settings


class ConicEpigraph:
    """Epigraph min-max over one task's path with cone subproblems (module docstring).

    Args:
        problem: The task (``N ≥ 2`` samples); its tolerances set the parts
            (:func:`~otmm_qp.reference.merit.merit_parts`).
    """

    def __init__(self, problem: TrackingProblem) -> None:
        self.problem = problem
        self.evaluate = MinMaxMerit(problem)  # parts, errors, merits and φ: one definition
        self.parts = self.evaluate.parts
        self.blocks = problem.samples - 1
        nv = problem.nv
        size = self.blocks * nv
        self.size = size
        # Box and rate rows: C δ with C = [I; D] (D: δ_j − δ_{j−1} per joint).
        eye = sp.identity(size, format="csr")
        diff = eye - sp.eye(size, size, k=-nv, format="csr")
        self._linear = sp.vstack([eye, diff], format="csr")
        self._rows_key: tuple[bytes, bytes] | None = None
        self._rows = sp.csr_matrix((0, size + 1))
        self._stacked: tuple[sp.csc_matrix, sp.csc_matrix] | None = None
        self._at: FloatArray | None = None  # the path of the kept linearisation
        self._linear_at: tuple[Any, ...] = ()

    # ------------------------------------------------------------------ the cone program
    def _linearise(self, path: FloatArray) -> tuple[list[Any], FloatArray, FloatArray]:
        """Per block: its ``(error, jacobian)``; tie-break gradient ``(B·nv,)``, Hessian blocks."""
        problem = self.problem
        nv, blocks, scale = problem.nv, self.blocks, problem.scale
        errors, jacobians = problem.kinematics.errors_and_jacobians(path[1:], first=1)
        scaled = scale[None, :, None] * jacobians  # (B, n, nv)
        transposed = scaled.transpose(0, 2, 1)
        tie = -(transposed @ (scale * errors)[:, :, None])[:, :, 0] * (TIE_BREAK / blocks)
        hessians = (TIE_BREAK / blocks) * (transposed @ scaled) + PROXIMAL * np.eye(nv)
        local = list(zip(errors, jacobians, strict=True))
        return local, tie.ravel(), hessians

    def _cones(self, local: list[Any]) -> tuple[sp.csc_matrix, FloatArray, list[int]]:
        """Rows ``A x + s = b``, ``s ∈ SOC`` of every ``(k, p)``: ``s = (t, (e − Jδ)/tol)``.

        Per block ``b`` and part ``p`` (in that order) one cone of ``d_p + 1`` rows: the
        ``t`` row (``−1`` in the last column, ``b = 0``), then ``d_p`` rows
        ``J_{k,p}/tol_p`` in the block's columns with ``b = e_{k,p}/tol_p``.
        """
        nv, size, blocks = self.problem.nv, self.size, len(local)
        errors = np.array([error for error, _ in local])  # (B, n)
        jacobians = np.array([jacobian for _, jacobian in local])  # (B, n, nv)
        per_block = sum(rows_p.stop - rows_p.start + 1 for rows_p, _ in self.parts)
        first = np.arange(blocks) * per_block  # (B,) first row of each block
        columns = np.arange(blocks)[:, None] * nv + np.arange(nv)[None, :]  # (B, nv)
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []
        rhs = np.zeros(blocks * per_block)
        dims: list[int] = []
        offset = 0
        for rows_p, tolerance in self.parts:
            part_j = jacobians[:, rows_p] / tolerance  # (B, d, nv)
            d = part_j.shape[1]
            top = first + offset
            below = top[:, None] + 1 + np.arange(d)  # (B, d): the part's error rows
            rows.append(top)
            cols.append(np.full(blocks, size))
            vals.append(np.full(blocks, -1.0))
            rows.append(np.broadcast_to(below[:, :, None], part_j.shape).ravel())
            cols.append(np.broadcast_to(columns[:, None, :], part_j.shape).ravel())
            vals.append(part_j.ravel())
            rhs[below.ravel()] = (errors[:, rows_p] / tolerance).ravel()
            dims.append(d + 1)
            offset += d + 1
        matrix = sp.csc_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(blocks * per_block, size + 1),
        )
        return matrix, rhs, dims * blocks

    def _bounds(self, path: FloatArray, radius: float) -> tuple[FloatArray, FloatArray]:
        """Lower and upper ends of ``C δ`` (box ∩ trust radius, then the rate rows)."""
        problem = self.problem
        current = path[1:]
        box_lo = np.minimum(np.maximum(problem.lower - current, -radius), 0.0)
        box_hi = np.maximum(np.minimum(problem.upper - current, radius), 0.0)
        moves = np.diff(path, axis=0)
        step = np.minimum(problem.step, BIG)
        return (
            np.concatenate([box_lo.ravel(), np.minimum((-step - moves).ravel(), 0.0)]),
            np.concatenate([box_hi.ravel(), np.maximum((step - moves).ravel(), 0.0)]),
        )

    def _hessian(self, hessians: FloatArray) -> sp.csc_matrix:
        """Upper triangle of ``blockdiag(½(B_b + B_bᵀ), 0)``, shape ``(B·nv + 1, B·nv + 1)``.

        Every entry of each block's upper triangle is stored, zeros included (as
        ``scipy.sparse.block_diag`` of dense blocks, then ``triu``, store them): one pattern.
        """
        blocks, nv = hessians.shape[0], self.problem.nv
        symmetric = 0.5 * (hessians + hessians.transpose(0, 2, 1))
        i, j = np.triu_indices(nv)
        values = symmetric[:, i, j]  # (B, nv(nv+1)/2)
        shift = (np.arange(blocks) * nv)[:, None]
        rows, cols = (shift + i[None, :]).ravel(), (shift + j[None, :]).ravel()
        return sp.csc_matrix((values.ravel(), (rows, cols)), shape=(self.size + 1, self.size + 1))

    def _constraints(
        self, cone_a: sp.csc_matrix, up: np.ndarray, down: np.ndarray
    ) -> sp.csc_matrix:
        """``A = [cone rows; C[up]; −C[down]]`` (a zero column for ``t``), kept while the same."""
        key = (up.tobytes(), down.tobytes())
        if self._rows_key != key:
            linear = sp.hstack([self._linear, sp.csr_matrix((2 * self.size, 1))], format="csr")
            self._rows = sp.vstack([linear[up], -linear[down]], format="csr")
            self._rows_key = key
            self._stacked = None
        if self._stacked is None or self._stacked[0] is not cone_a:
            stacked = sp.vstack([cone_a.tocsr(), self._rows], format="csr").tocsc()
            self._stacked = (cone_a, stacked)
        return self._stacked[1]

    def _solve(
        self,
        hessian: sp.csc_matrix,
        cost: FloatArray,
        cones: tuple[sp.csc_matrix, FloatArray, list[int]],
        lower: FloatArray,
        upper: FloatArray,
    ) -> tuple[FloatArray, FloatArray, sp.csc_matrix, FloatArray, list[Any]]:
        """One cone program; ``(x, z, A, b, cone list)`` (``hessian``: :meth:`_hessian`).

        Raises:
            SolverFailure: Clarabel returned no finite solution or a failure status.
        """
        size = self.size
        cone_a, cone_b, dims = cones
        up = upper < BIG / 2
        down = lower > -BIG / 2
        a = self._constraints(cone_a, up, down)
        b = np.concatenate([cone_b, upper[up], -lower[down]])
        count = int(np.count_nonzero(up) + np.count_nonzero(down))
        kinds: list[Any] = [clarabel.SecondOrderConeT(d) for d in dims]
        kinds.append(clarabel.NonnegativeConeT(count))
        try:
            solver = clarabel.DefaultSolver(hessian, cost, a, b, kinds, _settings())
            with sigint_held():  # a native solver's own SIGINT handler never takes Ctrl-C
                solution = solver.solve()
        except (ValueError, RuntimeError, TypeError) as error:
            raise SolverFailure(f"Clarabel: {' '.join(str(error).split())}") from None
        status = str(solution.status)
        x = np.asarray(solution.x, dtype=float)
        z = np.asarray(solution.z, dtype=float)
        if x.size != size + 1 or not np.all(np.isfinite(x)) or not np.all(np.isfinite(z)):
            raise SolverFailure(f"Clarabel returned no step ({status})")
        if status not in ACCEPTED:
            raise SolverFailure(f"Clarabel status {status}")
        return x, z, a, b, [*dims, count]

    @staticmethod
    def _kkt(
        cost: FloatArray,
        a: sp.csc_matrix,
        b: FloatArray,
        z: FloatArray,
        dims: list[int],
        top: float,
    ) -> float:
        """KKT residual at ``δ = 0, t = top`` with the multipliers ``z`` (module docstring)."""
        stationarity = float(np.max(np.abs(cost + a.T @ z)))
        point = np.zeros(a.shape[1])
        point[-1] = top
        slack = b - a @ point
        complementarity = 0.0
        start = 0
        for d in dims[:-1]:
            part = slice(start, start + d)
            complementarity = max(complementarity, abs(float(z[part] @ slack[part])))
            start += d
        linear = np.abs(z[start:] * slack[start:])
        if linear.size:
            complementarity = max(complementarity, float(np.max(linear)))
        return max(stationarity, complementarity)

    # ------------------------------------------------------------------ the subproblem
    def start(self, path: FloatArray) -> Iterate:
        """The first iterate (:class:`~otmm_qp.reference.merit.MinMaxMerit`)."""
        return self.evaluate(path)

    def step(self, iterate: Iterate, radius: float) -> Step:
        r"""The cone program's step; ``pred = φ − (t + (φ − max m) + ε ḡᵀδ + ½ δᵀBδ)``.

        Stationary (converged) when the KKT residual and the predicted decrease are both
        ``≤`` :data:`KKT_TOLERANCE` (module docstring).

        Raises:
            SolverFailure: Clarabel failed.
        """
        if self._at is not iterate.path or not self._linear_at:
            local, tie, hessians = self._linearise(iterate.path)
            self._linear_at = (tie, hessians, self._hessian(hessians), self._cones(local))
            self._at = iterate.path
        tie, hessians, hessian, cones = self._linear_at
        phi, top = iterate.phi, iterate.top
        cost = np.concatenate([tie, [1.0]])
        lower, upper = self._bounds(iterate.path, radius)
        x, z, a, b, dims = self._solve(hessian, cost, cones, lower, upper)
        delta = x[:-1].reshape(self.blocks, self.problem.nv)
        quadratic = 0.5 * float(np.einsum("bi,bij,bj", delta, hessians, delta))
        model = x[-1] + (phi - top) + float(tie @ x[:-1]) + quadratic
        predicted = phi - model
        kkt = self._kkt(cost, a, b, z, dims, top)
        # the multipliers are the step's: they certify δ = 0 only when the model gains
        # nothing from the step either
        stationary = kkt <= KKT_TOLERANCE and predicted <= KKT_TOLERANCE
        return Step(delta, float(predicted), kkt, bool(stationary))

    def solve(self, path: FloatArray, iterations: int, deadline: float) -> Outcome:
        """Iterate from a feasible ``path`` by the trust-region driver (module docstring).

        Raises:
            SolverFailure: Clarabel failed on a subproblem, or no finite merit was reached.
        """
        self._at, self._linear_at = None, ()
        outcome = minimise(self, path, iterations, deadline, RADII, STOPPING)
        if not math.isfinite(outcome.merit):
            raise SolverFailure("no finite merit")
        return outcome

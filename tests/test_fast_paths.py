"""Every fast path returns the same q̇ as the plain reference path, on random states.

Fast paths checked against their references:

* QP fast path (unconstrained SVD solution when inside the box) vs ``fast_path=False``;
* direct solver paths (``direct_daqp``, ``direct_proxsuite``, ``direct_osqp``: persistent,
  updated in place, warm started) vs the qpsolvers ``quadprog`` path on the same QP;
* unmasked pseudoinverse (full rank) vs an explicitly masked one;
* vectorised OTMM vs a per-index loop written here from paper eq. (8);
* the allocation-free velocity box vs :func:`velocity_box`.

Tolerances: 1e-9 on q̇ [rad/s] for the exact paths (active-set solvers daqp and quadprog
are exact up to rounding). The iterative solvers run at ``eps_abs = 1e-10`` (proxsuite: on
the KKT residual; osqp: ADMM then polishing), which bounds the error on q̇ by about
``eps/λ`` = 1e-7 for ``λ = 1e-3`` (a little more when OSQP's polishing does not apply); both
are compared at 1e-6.
States include an exactly singular Jacobian (UR5 with θ5 = 0, a stretched planar arm) and
commands large enough to make bounds active. No timing assertions.
"""

from __future__ import annotations

import numpy as np
import pytest

from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp_controllers.pinv import PseudoInverseBackend
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp_problem import BoxBuffers, velocity_box

DT = 0.01  # [s]
PANDA = PinocchioArm(name="panda", task="pose")
UR5 = PinocchioArm(name="ur5", task="pose")
PLANAR = PlanarArm([1.0, 0.8, 0.6], limits=[[-2.5, 2.5]] * 3, velocity_limits=[2.0] * 3)
ROBOTS = {"panda": PANDA, "ur5": UR5, "planar": PLANAR}
#: Solver → tolerance on q̇ [rad/s] against the exact reference (see module docstring).
DIRECT = {"direct_daqp": 1e-9, "direct_proxsuite": 1e-6, "direct_osqp": 1e-6}


def random_theta(robot: Robot, rng: np.random.Generator) -> FloatArray:
    """Joint coordinates inside the limits (±π where unbounded), shape ``(nv,)``."""
    lower, upper = robot.position_limits
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    return lower + (upper - lower) * rng.uniform(0.02, 0.98, robot.nv)


def singular_theta(robot: Robot, rng: np.random.Generator) -> FloatArray:
    """A configuration with an exactly singular task Jacobian."""
    theta = random_theta(robot, rng)
    if robot is UR5:
        theta[4] = 0.0  # wrist singularity: axes 4 and 6 aligned
    else:
        theta[1:] = 0.0  # planar arm stretched
    return theta


def cases(robot: Robot, count: int, seed: int) -> list[tuple[KinematicState, FloatArray]]:
    """States (a third exactly singular where possible) and commands of mixed size."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        singular = robot is not PANDA and i % 3 == 0
        theta = singular_theta(robot, rng) if singular else random_theta(robot, rng)
        state = KinematicState.compute(robot, robot.configuration(theta))
        speed = rng.choice([1e-3, 0.1, 3.0])  # small: fast path; large: bounds active
        out.append((state, speed * rng.standard_normal(robot.task_dim)))
    return out


def test_singular_states_are_exactly_singular() -> None:
    rng = np.random.default_rng(0)
    for robot in (UR5, PLANAR):
        state = KinematicState.compute(robot, robot.configuration(singular_theta(robot, rng)))
        assert state.sigma_min < 1e-12 * state.sigma[0]


@pytest.mark.parametrize("name", sorted(ROBOTS))
@pytest.mark.parametrize("acceleration", [None, 20.0])
def test_qp_fast_path_equals_qp(name: str, acceleration: float | None) -> None:
    robot = ROBOTS[name]
    fast = QpBackend(solver="quadprog", acceleration_limit=acceleration, infeasible_policy="dls")
    slow = QpBackend(
        solver="quadprog", acceleration_limit=acceleration, infeasible_policy="dls",
        fast_path=False,
    )  # fmt: skip
    fast.bind(robot, DT)
    slow.bind(robot, DT)
    rng = np.random.default_rng(1)
    skipped = bounded = 0
    for state, xdot in cases(robot, 40, seed=2):
        prev = 0.05 * rng.standard_normal(robot.nv)
        a, b = fast.solve(state, xdot, prev), slow.solve(state, xdot, prev)
        np.testing.assert_allclose(a.qdot, b.qdot, rtol=0.0, atol=1e-9)
        assert a.status == b.status
        skipped += not fast.used_qp
        bounded += b.status == "bounded"
    assert skipped > 0 and bounded > 0  # both branches exercised


@pytest.mark.parametrize("name", sorted(ROBOTS))
@pytest.mark.parametrize("solver", sorted(DIRECT))
def test_direct_solver_equals_qpsolvers(name: str, solver: str) -> None:
    robot = ROBOTS[name]
    direct = QpBackend(solver=solver, fast_path=False, infeasible_policy="dls")
    reference = QpBackend(solver="quadprog", fast_path=False, infeasible_policy="dls")
    direct.bind(robot, DT)
    reference.bind(robot, DT)
    prev = np.zeros(robot.nv)
    bounded = 0
    for state, xdot in cases(robot, 30, seed=3):  # one run: warm starts carried across
        a, b = direct.solve(state, xdot, prev), reference.solve(state, xdot, prev)
        np.testing.assert_allclose(a.qdot, b.qdot, rtol=0.0, atol=DIRECT[solver])
        bounded += b.status == "bounded"
    assert bounded > 0


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_direct_qp_data_equals_build_qp(name: str) -> None:
    """The in-place P, q, lb, ub of the direct paths are the ones build_qp returns."""
    robot = ROBOTS[name]
    backend = QpBackend(solver="direct_daqp", fast_path=False, posture_weight=0.1)
    backend.bind(robot, DT)
    for state, xdot in cases(robot, 10, seed=4):
        backend.solve(state, xdot, np.zeros(robot.nv))
        problem = backend.problem
        assert problem is not None
        np.testing.assert_allclose(backend._hessian, problem.P, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(backend._linear, problem.q, rtol=1e-14, atol=1e-14)
        np.testing.assert_array_equal(backend._qp_lower, problem.lb)
        np.testing.assert_array_equal(backend._qp_upper, problem.ub)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_box_buffers_bit_identical(name: str) -> None:
    robot = ROBOTS[name]
    rng = np.random.default_rng(5)
    acceleration = np.full(robot.nv, 30.0)
    for acc in (None, acceleration):
        buffers = BoxBuffers(robot.position_limits, robot.velocity_limits, DT, 0.5, acc)
        for _ in range(20):
            theta = random_theta(robot, rng)
            theta[0] = robot.position_limits[1][0] + 0.3 if np.isfinite(theta[0]) else 0.0
            prev = 3.0 * rng.standard_normal(robot.nv)  # often an empty box with acc
            empty = buffers.update(theta, prev)
            box = velocity_box(
                theta, robot.position_limits, robot.velocity_limits, prev, DT, 0.5, acc
            )
            np.testing.assert_array_equal(buffers.lower, box.lower)
            np.testing.assert_array_equal(buffers.upper, box.upper)
            assert empty == box.empty


def masked_pinv(state: KinematicState, xdot: FloatArray, rcond: float) -> FloatArray:
    """Reference: the pseudoinverse with the singular-value mask always applied."""
    keep = state.sigma > max(rcond * state.sigma[0], np.finfo(float).tiny)
    coefficients = (state.U[:, keep].T @ xdot) / state.sigma[keep]
    return np.asarray(state.Vt[keep].T @ coefficients)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_pinv_unmasked_equals_masked(name: str) -> None:
    backend = PseudoInverseBackend()
    singular = 0
    for state, xdot in cases(ROBOTS[name], 30, seed=6):
        expected = masked_pinv(state, xdot, backend.rcond)
        got = backend.solve(state, xdot, np.zeros(state.Vt.shape[1])).qdot
        scale = max(1.0, float(np.abs(expected).max()))  # 1/σ_min can make q̇ large
        np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-9 * scale)
        singular += state.sigma_min < 1e-12
    assert name == "panda" or singular > 0


def otmm_reference(f: OtmmFilter, state: KinematicState, xdot: FloatArray) -> FloatArray:
    """Paper eq. (8), generalised, one singular direction at a time (no vectorisation).

    Every arm here has ``nv ≥ n``, so the thin SVD already holds all ``n`` directions.
    """
    n = state.task_dim
    sigma = state.sigma
    if sigma[n - 1] > f.sigma_s:
        return xdot.copy()
    indices = [n - 1] if f.corank == 1 else [i for i in range(n) if sigma[i] <= f.sigma_s]
    modified = xdot.copy()
    for i in indices:
        u = state.U[:, i]
        modified = modified - f.p(float(sigma[i])) * float(u @ xdot) * u
    return modified


@pytest.mark.parametrize("name", sorted(ROBOTS))
@pytest.mark.parametrize("corank", [1, "all"])
@pytest.mark.parametrize("p", ["linear", "sqrt"])
def test_vectorised_otmm_equals_loop(name: str, corank: int | str, p: str) -> None:
    f = OtmmFilter(sigma_s=0.3, p=p, corank=corank)
    active = 0
    for state, xdot in cases(ROBOTS[name], 30, seed=7):
        got = f.apply(state, xdot)
        np.testing.assert_allclose(
            got.xdot, otmm_reference(f, state, xdot), rtol=0.0, atol=1e-9 * (1 + abs(xdot).max())
        )
        active += got.report.active
    assert active > 0

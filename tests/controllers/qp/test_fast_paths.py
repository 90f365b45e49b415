"""Every fast path returns the same q̇ as the plain reference path, on random states.

Fast paths checked against their references:

* QP fast path (unconstrained SVD solution when inside the box) vs ``fast_path=False``;
* persistent solver sessions (``daqp``, ``proxsuite``, ``osqp``: set up once, updated in
  place, warm started) vs the stateless qpsolvers ``quadprog`` path on the same QP;
* :func:`build_qp` and :class:`~otmm_qp.limits.LimitBox` writing into reused ``out=`` arrays
  vs allocating references (and vs the QP a step returns in ``details``, solved from scratch);
* unmasked pseudoinverse (full rank) vs an explicitly masked one;
* vectorised OTMM vs a per-index loop written here from paper eq. (8);

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

from otmm_qp.exceptions import DimensionError, ParameterError
from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.limits import AccelerationLimit, LimitBox, PositionLimit, VelocityLimit
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.pinv import PseudoInverseBackend
from otmm_qp_controllers.qp import QpBackend, QpStep
from otmm_qp_controllers.qp.formulation import BIG, QpProblem, build_qp
from otmm_qp_controllers.qp.solvers import SESSIONS, make_session, solve_with_qpsolvers
from otmm_qp_controllers.qp.solvers.session import conflicting_bounds

DT = 0.01  # [s]
PANDA = PinocchioArm(name="panda", task="pose")
UR5 = PinocchioArm(name="ur5", task="pose")
PLANAR = PlanarArm([1.0, 0.8, 0.6], limits=[[-2.5, 2.5]] * 3, velocity_limits=[2.0] * 3)
ROBOTS = {"panda": PANDA, "ur5": UR5, "planar": PLANAR}
#: Session → tolerance on q̇ [rad/s] against the exact reference (see module docstring).
SESSION_TOL = {"daqp": 1e-9, "proxsuite": 1e-6, "osqp": 1e-6}


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
    limits = (
        None
        if acceleration is None
        else [{"type": "position", "gain": 0.5}, {"type": "acceleration", "a_max": acceleration}]
    )
    fast = QpBackend(solver="quadprog", limits=limits, infeasible_policy="dls")
    slow = QpBackend(
        solver="quadprog", limits=limits, infeasible_policy="dls",
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
        assert isinstance(a.details, QpStep)
        skipped += a.details.problem is None
        bounded += b.status == "bounded"
    assert skipped > 0 and bounded > 0  # both branches exercised


@pytest.mark.parametrize("name", sorted(ROBOTS))
@pytest.mark.parametrize("solver", sorted(SESSIONS))
def test_session_equals_qpsolvers(name: str, solver: str) -> None:
    """Persistent, warm-started sessions give the answer of a from-scratch quadprog solve."""
    robot = ROBOTS[name]
    persistent = QpBackend(solver=solver, fast_path=False, infeasible_policy="dls")
    reference = QpBackend(solver="quadprog", fast_path=False, infeasible_policy="dls")
    persistent.bind(robot, DT)
    reference.bind(robot, DT)
    prev = np.zeros(robot.nv)
    bounded = 0
    for state, xdot in cases(robot, 30, seed=3):  # one run: warm starts carried across
        a, b = persistent.solve(state, xdot, prev), reference.solve(state, xdot, prev)
        np.testing.assert_allclose(a.qdot, b.qdot, rtol=0.0, atol=SESSION_TOL[solver])
        assert a.status == b.status
        bounded += b.status == "bounded"
    assert bounded > 0


@pytest.mark.parametrize("name", sorted(ROBOTS))
@pytest.mark.parametrize("posture", [0.0, 0.1])
def test_build_qp_in_place_equals_fresh(name: str, posture: float) -> None:
    """build_qp writing into reused arrays equals build_qp allocating, bit for bit."""
    robot = ROBOTS[name]
    rng = np.random.default_rng(4)
    reused = QpProblem.allocate(robot.nv)
    for state, xdot in cases(robot, 10, seed=4):
        bounds = np.sort(rng.standard_normal((2, robot.nv)), axis=0)
        bounds[1, 0] = np.inf  # ±inf are passed as ±BIG
        velocity = rng.standard_normal(robot.nv)
        fresh = build_qp(state.task_jacobian, xdot, 1e-3, bounds, posture, velocity)
        build_qp(state.task_jacobian, xdot, 1e-3, bounds, posture, velocity, out=reused)
        for got, expected in zip(reused, fresh, strict=True):
            np.testing.assert_array_equal(got, expected)
        assert fresh.ub[0] == BIG


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_build_qp_into_shared_box_equals_copied_box(name: str) -> None:
    """A box written into the problem's own lb/ub (bounds=None) gives the same QP, bit for bit."""
    robot = ROBOTS[name]
    rng = np.random.default_rng(8)
    box = np.empty((2, robot.nv))
    shared = QpProblem.allocate(robot.nv, box=box)
    assert np.shares_memory(shared.lb, box) and np.shares_memory(shared.ub, box)
    for state, xdot in cases(robot, 10, seed=8):
        box[:] = np.sort(rng.standard_normal((2, robot.nv)), axis=0)
        copied = build_qp(state.task_jacobian, xdot, 1e-3, box.copy())
        build_qp(state.task_jacobian, xdot, 1e-3, None, out=shared)
        for got, expected in zip(shared, copied, strict=True):
            np.testing.assert_array_equal(got, expected)


def test_build_qp_without_bounds_needs_out() -> None:
    with pytest.raises(ParameterError, match="bounds"):
        build_qp(np.eye(2), np.zeros(2), 1e-3, None)
    with pytest.raises(DimensionError, match="box"):
        QpProblem.allocate(3, box=np.empty((2, 2)))


@pytest.mark.parametrize("fast_path", [True, False])
def test_unlimited_arm_qp_equals_dls(fast_path: bool) -> None:
    """Infinite speed and position limits (box not shared with the problem, ±inf → ±BIG)."""
    arm = PlanarArm([1.0, 0.8, 0.6])
    backend = QpBackend(solver="daqp", fast_path=fast_path)
    backend.bind(arm, DT)
    for state, xdot in cases(arm, 10, seed=9):
        out = backend.solve(state, xdot, np.zeros(arm.nv))
        J = state.task_jacobian
        mu = backend.formulation.mu
        dls = J.T @ np.linalg.solve(J @ J.T + mu * np.eye(arm.task_dim), xdot)
        np.testing.assert_allclose(out.qdot, dls, rtol=0.0, atol=1e-8 * (1 + abs(dls).max()))
        assert isinstance(out.details, QpStep)
        assert (out.details.problem is not None) is not fast_path
        assert out.status == Status.OK


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_problem_solved_from_scratch_equals_step(name: str) -> None:
    """The pure problem a step exposes, solved by quadprog, gives that step's q̇."""
    robot = ROBOTS[name]
    backend = QpBackend(solver="daqp", fast_path=False, posture={"weight": 0.1})
    backend.bind(robot, DT)
    for state, xdot in cases(robot, 10, seed=4):
        out = backend.solve(state, xdot, np.zeros(robot.nv))
        assert isinstance(out.details, QpStep)
        problem = out.details.problem
        assert problem is not None
        expected = solve_with_qpsolvers(problem.to_qpsolvers(), "quadprog")
        assert expected is not None
        np.testing.assert_allclose(out.qdot, expected, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_limit_box_in_place_bit_identical(name: str) -> None:
    """LimitBox.compute on reused arrays equals the three box formulas written out here."""
    robot = ROBOTS[name]
    rng = np.random.default_rng(5)
    a_max = np.full(robot.nv, 30.0)
    low, high = (np.asarray(side, dtype=float) for side in robot.position_limits)
    speed = np.asarray(robot.velocity_limits, dtype=float)
    for acc in (None, a_max):
        limits = [VelocityLimit(), PositionLimit(0.5)]
        limits += [] if acc is None else [AccelerationLimit(acc)]
        box = LimitBox(limits[::-1])  # any order: kept by priority
        box.bind(robot, DT)
        empties = 0
        for _ in range(20):
            theta = random_theta(robot, rng)
            theta[0] = high[0] + 0.3 if np.isfinite(theta[0]) else 0.0
            prev = 3.0 * rng.standard_normal(robot.nv)  # often an empty box with acc
            empty = box.compute(theta, prev)
            lower = np.maximum(-speed, (0.5 / DT) * (low - theta))
            upper = np.minimum(speed, (0.5 / DT) * (high - theta))
            if acc is not None:
                lower = np.maximum(lower, prev - acc * DT)
                upper = np.minimum(upper, prev + acc * DT)
            np.testing.assert_array_equal(box.bounds[0], lower)
            np.testing.assert_array_equal(box.bounds[1], upper)
            assert empty == bool(np.any(lower > upper))
            empties += empty
        assert acc is None or empties > 0


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


def _box_problem(lower: float, upper: float, hessian: float = 1.0) -> QpProblem:
    problem = QpProblem.allocate(3)
    problem.P[:] = hessian * np.eye(3)
    problem.q[:] = 1.0
    problem.lb[:], problem.ub[:] = lower, upper
    return problem


@pytest.mark.parametrize("solver", [*SESSIONS, "quadprog"])
@pytest.mark.parametrize("first", [True, False])
def test_session_refuses_an_empty_box_then_recovers(solver: str, first: bool) -> None:
    """lb > ub: not found with a reason (never the previous or a garbage x); then solves again.

    DAQP and OSQP used to report the previous solution as optimal after such an update (their
    Python update drops the C error code), and DAQP raised on a refused set-up.
    """
    session = make_session(solver)
    good = _box_problem(-1.0, 1.0)  # optimum x = -1 (q = 1, P = I)
    if not first:
        session.load(good)
        assert session.solve().found
    session.load(_box_problem(2.0, 1.0))
    refused = session.solve()
    assert not refused.found and refused.x is None and refused.detail
    session.load(good)
    solution = session.solve()
    assert solution.found and solution.x is not None
    np.testing.assert_allclose(solution.x, -1.0, atol=1e-6)


def test_daqp_session_refuses_a_hessian_it_cannot_factor() -> None:
    session = make_session("daqp")
    session.load(_box_problem(-1.0, 1.0))
    assert session.solve().found
    session.load(_box_problem(-1.0, 1.0, hessian=-1.0))
    refused = session.solve()
    assert not refused.found and "exitflag" in refused.detail


def test_conflicting_bounds_names_the_first_clash() -> None:
    problem = QpProblem.allocate(2, 1)
    problem.lb[:], problem.ub[:] = -1.0, 1.0
    assert conflicting_bounds(problem) is None
    problem.l[0], problem.u[0] = 0.5, 0.2
    assert conflicting_bounds(problem) == "infeasible: row 0 has lower bound 0.5 > upper 0.2"
    problem.lb[1] = 3.0
    assert conflicting_bounds(problem) == "infeasible: variable 1 has lower bound 3 > upper 1"


@pytest.mark.parametrize("solver", [*SESSIONS, "quadprog"])
def test_session_solve_before_load_is_not_found(solver: str) -> None:
    solution = make_session(solver).solve()
    assert not solution.found and solution.x is None and solution.detail


@pytest.mark.parametrize("solver", [*SESSIONS, "quadprog"])
def test_session_reads_a_reused_problem_written_in_place(solver: str) -> None:
    """One problem object rewritten in place each step (what the QP backend does).

    Every array the backend writes (P, q, lb, ub) is read again at each load, each one alone;
    an empty box is refused and the next valid data solves again. Optimum of
    ``½ h‖x‖² + qᵀx`` in a box: ``clip(−q/h, lb, ub)``.
    """
    session = make_session(solver)
    problem = _box_problem(-1.0, 1.0)  # P = I, q = 1: x = -1 (on the lower bound)

    def solved() -> np.ndarray:
        session.load(problem)
        solution = session.solve()
        assert solution.found and solution.x is not None, solution
        return solution.x

    np.testing.assert_allclose(solved(), -1.0, atol=1e-6)
    problem.lb[:] = -0.5  # the lower bound alone
    np.testing.assert_allclose(solved(), -0.5, atol=1e-6)
    problem.q[:] = -0.25  # the linear cost alone: x = 0.25, inside
    np.testing.assert_allclose(solved(), 0.25, atol=1e-6)
    problem.P[:] = 0.5 * np.eye(3)  # the Hessian alone: x = 0.5
    np.testing.assert_allclose(solved(), 0.5, atol=1e-6)
    problem.ub[:] = 0.3  # the upper bound alone
    np.testing.assert_allclose(solved(), 0.3, atol=1e-6)
    problem.lb[:] = 0.6  # lb > ub: refused, never the last x
    session.load(problem)
    refused = session.solve()
    assert not refused.found and refused.x is None and refused.detail
    problem.lb[:] = -0.5
    np.testing.assert_allclose(solved(), 0.3, atol=1e-6)

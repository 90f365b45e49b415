"""Status: one enum whose members carry their attributes, one classification (``classify``,
applied by the controller): `saturated` for every backend that does not enforce limits and
`diverging` for every controller, limits or not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.controller import Controller
from otmm_qp.exceptions import ParameterError
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp.status import (
    DIVERGENCE_SPEED,
    SpeedWork,
    Status,
    classify,
    exceeds_speed_limits,
    quiet_speed_squared,
    speed_limit_thresholds,
)
from otmm_qp_controllers.dls import DampedLeastSquaresBackend
from otmm_qp_controllers.dls_adaptive import AdaptiveDampedLeastSquaresBackend
from otmm_qp_controllers.dls_sigma import SigmaDampedLeastSquaresBackend
from otmm_qp_controllers.jparse import JParseBackend
from otmm_qp_controllers.manipulability import ManipulabilityBackend
from otmm_qp_controllers.pinv import PseudoInverseBackend
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.sdls import SelectiveDampedLeastSquaresBackend

DT = 0.02  # [s]
LIMITED = PlanarArm([1.0, 0.8], velocity_limits=[2.0, 2.0])
UNLIMITED = PlanarArm([1.0, 0.8])
NEAR_SINGULAR = np.array([0.3, 1e-3])  # σ_min ≈ 4e-4: pinv needs ~10³ rad/s along v_s

UNCONSTRAINED = {
    "pinv": PseudoInverseBackend,
    "dls": lambda: DampedLeastSquaresBackend(damping=1e-4),
    "dls_adaptive": lambda: AdaptiveDampedLeastSquaresBackend(alpha=1e-8, sigma_threshold=0.05),
    "dls_sigma": lambda: SigmaDampedLeastSquaresBackend(lambda_max=1e-4, epsilon=0.05),
    "sdls": lambda: SelectiveDampedLeastSquaresBackend(gamma_max=10.0),
    "jparse": JParseBackend,
    "manipulability": lambda: ManipulabilityBackend(gain=0.0),
}


def test_status_is_a_str_enum_whose_members_carry_their_attributes() -> None:
    assert Status.OK == "ok" and f"{Status.SATURATED}" == "saturated"
    assert str(Status.RELAXED) == "relaxed" and Status("bounded") is Status.BOUNDED
    assert {s for s in Status if s.relaxes_bound} == {Status.RELAXED, Status.INFEASIBLE}
    solved = {s for s in Status if s.claims_solution}
    assert solved == {Status.OK, Status.BOUNDED, Status.SATURATED, Status.STUCK}
    assert not solved & {s for s in Status if s.relaxes_bound}
    markers = [s.marker for s in Status if s is not Status.OK]
    assert Status.OK.marker is None and None not in markers
    assert len(set(markers)) == len(markers)  # every other status is marked, distinctly


def test_exceeds_speed_limits_boundary() -> None:
    limits = speed_limit_thresholds(np.array([2.0, np.inf]))
    assert not exceeds_speed_limits(np.array([2.0, 1e6]), limits)  # at the limit; inf: never
    assert not exceeds_speed_limits(np.array([-2.0 * (1 + 1e-10), 0.0]), limits)  # tolerance
    assert exceeds_speed_limits(np.array([-2.0 * (1 + 1e-8), 0.0]), limits)
    assert not exceeds_speed_limits(np.array([np.nan, 0.0]), limits)  # nonfinite's business


def step(controller: Controller, state: KinematicState, xdot: np.ndarray) -> BackendOutput:
    return controller.step(state, xdot, np.zeros(2)).backend


@pytest.mark.parametrize("name", sorted(UNCONSTRAINED))
def test_unconstrained_backend_beyond_speed_limit_is_saturated(name: str) -> None:
    """Every backend without limits, jparse and manipulability included (no opt-in)."""
    state = KinematicState.compute(LIMITED, NEAR_SINGULAR)
    along_weak = 0.5 * state.U[:, -1] + 20.0 * state.U[:, 0]  # [m/s]; sdls clamps v_s
    small = 1e-3 * state.U[:, 0]
    backend = UNCONSTRAINED[name]()
    assert not backend.enforces_limits
    controller = Controller(name, [], backend, divergence_speed=np.inf)  # not diverging
    controller.bind(LIMITED, DT)
    fast = step(controller, state, along_weak)
    assert np.abs(fast.qdot).max() > 2.0 and fast.status == Status.SATURATED
    slow = step(controller, state, small)
    assert np.abs(slow.qdot).max() <= 2.0 and slow.status == Status.OK
    unlimited = Controller(name, [], UNCONSTRAINED[name](), divergence_speed=np.inf)
    unlimited.bind(UNLIMITED, DT)  # no finite limit: nothing to saturate against
    assert step(unlimited, state, along_weak).status == Status.OK


def test_pinv_spinning_at_1e3_rad_s_is_not_ok() -> None:
    state = KinematicState.compute(LIMITED, NEAR_SINGULAR)
    controller = Controller("pinv", [], PseudoInverseBackend(), divergence_speed=np.inf)
    controller.bind(LIMITED, DT)
    out = step(controller, state, state.U[:, -1])
    assert np.abs(out.qdot).max() > 1e3 and out.status == "saturated"


def test_qp_never_saturates() -> None:
    """The QP's box holds the speed limits, so its steps are ok or bounded."""
    state = KinematicState.compute(LIMITED, NEAR_SINGULAR)
    controller = Controller("qp", [], QpBackend(solver="daqp"))
    controller.bind(LIMITED, DT)
    out = step(controller, state, 0.5 * state.U[:, -1] + 20.0 * state.U[:, 0])
    assert out.status == Status.BOUNDED and np.abs(out.qdot).max() <= 2.0


def test_unbound_backend_output_is_ok() -> None:
    class Raw(Backend):
        def solve(
            self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
        ) -> BackendOutput:
            return self.unconstrained_output(np.full(2, 1e3))

    state = KinematicState.compute(LIMITED, NEAR_SINGULAR)
    assert Raw().solve(state, np.zeros(2), np.zeros(2)).status == Status.OK


@pytest.mark.parametrize(
    ("backend", "expected"),
    [
        (DampedLeastSquaresBackend(damping=0.05), 0.05),
        (SigmaDampedLeastSquaresBackend(lambda_max=0.05, epsilon=0.05), None),
        (AdaptiveDampedLeastSquaresBackend(alpha=0.003, sigma_threshold=0.05), None),
    ],
)
def test_damping_is_the_factor_lambda(backend: Backend, expected: float | None) -> None:
    """BackendOutput.damping is λ [task units]: q̇ = Jᵀ(JJᵀ + λ²I)⁻¹ẋ, for every backend."""
    state = KinematicState.compute(UNLIMITED, np.array([0.3, 0.02]))
    xdot = np.array([0.1, -0.2])
    backend.bind(UNLIMITED, DT)
    out = backend.solve(state, xdot, np.zeros(2))
    jacobian = state.task_jacobian
    lam = out.damping
    assert lam > 0.0 and (expected is None or lam == pytest.approx(expected))
    reference = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + lam**2 * np.eye(2), xdot)
    np.testing.assert_allclose(out.qdot, reference, rtol=1e-9)


@pytest.mark.parametrize("name", sorted(UNCONSTRAINED))
def test_every_controller_reports_diverging_without_speed_limits(name: str) -> None:
    """A limitless arm spinning at > 100 rad/s is ``diverging``, not ``ok`` (E2's pinv)."""
    state = KinematicState.compute(UNLIMITED, NEAR_SINGULAR)
    controller = Controller(name, [], UNCONSTRAINED[name]())
    controller.bind(UNLIMITED, DT)
    fast = controller.step(state, 0.5 * state.U[:, -1] + 200.0 * state.U[:, 0], np.zeros(2))
    speed = float(np.abs(fast.qdot).max())
    assert (fast.backend.status == Status.DIVERGING) == (speed > DIVERGENCE_SPEED)
    if name not in ("sdls", "jparse"):  # both clamp the weak direction's share: 93 rad/s here
        assert speed > DIVERGENCE_SPEED
    slow = controller.step(state, 1e-3 * state.U[:, 0], np.zeros(2))
    assert slow.backend.status == Status.OK


def test_diverging_threshold_is_the_infinity_norm() -> None:
    """Just above/below q̇_div on one joint of many: the 2-norm pre-test never decides alone."""
    below = np.full(9, 99.0)  # ‖·‖₂ = 297 > 100 but ‖·‖∞ = 99
    assert classify(Status.OK, below, float(below @ below), None, 100.0) == Status.OK
    above = np.zeros(9)
    above[4] = -100.0 * (1 + 1e-12)
    assert classify(Status.BOUNDED, above, float(above @ above), None, 100.0) == "diverging"
    assert classify("ok", above, float(above @ above), None, 100.0) == "diverging"  # plain str
    # Statuses that already say the solution is not usable keep their word.
    for status in (Status.INFEASIBLE, Status.RELAXED):
        assert classify(status, above, float(above @ above), None, 100.0) == status


def test_classify_order() -> None:
    """nonfinite, then saturated (only for ok), then diverging (overriding saturated)."""
    thresholds = speed_limit_thresholds(np.array([2.0, 2.0]))
    fast, faster = np.array([3.0, 0.0]), np.array([300.0, 0.0])
    nan = np.array([np.nan, 0.0])
    assert classify(Status.OK, nan, float(nan @ nan), thresholds, 100.0) == Status.NONFINITE
    assert classify(Status.OK, fast, 9.0, thresholds, 100.0) == Status.SATURATED
    assert classify(Status.STUCK, fast, 9.0, thresholds, 100.0) == Status.STUCK
    assert classify(Status.OK, faster, 9e4, thresholds, 100.0) == Status.DIVERGING
    assert classify(Status.OK, fast, 9.0, None, 100.0) == Status.OK  # enforces limits
    inf = np.array([np.inf, 0.0])
    assert classify(Status.OK, inf, np.inf, None, np.inf) == Status.NONFINITE


def test_diverging_speed_is_configurable_and_validated() -> None:
    class Constant(Backend):
        def solve(
            self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
        ) -> BackendOutput:
            return BackendOutput(np.array([3.0, 0.0]))

    state = KinematicState.compute(UNLIMITED, NEAR_SINGULAR)
    strict = Controller("c", [], Constant(), divergence_speed=2.0)
    strict.bind(UNLIMITED, DT)
    assert strict.step(state, np.zeros(2), np.zeros(2)).backend.status == Status.DIVERGING
    for bad in (0.0, -1.0, float("nan"), "fast", None):
        with pytest.raises(ParameterError, match="divergence_speed"):
            Controller("c", [], Constant(), divergence_speed=bad)


def test_saturated_is_exceeds_speed_limits() -> None:
    """The controller's pre-scaled test equals the reference rule, at the tolerance edge too."""

    class Constant(Backend):
        qdot = np.zeros(2)

        def solve(
            self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
        ) -> BackendOutput:
            return self.unconstrained_output(self.qdot)

    backend = Constant()
    controller = Controller("c", [], backend)
    controller.bind(LIMITED, DT)
    state = KinematicState.compute(LIMITED, NEAR_SINGULAR)
    rng = np.random.default_rng(2)
    edges = [2.0 * (1 + 1e-10), 2.0 * (1 + 1e-8), 2.0, -2.0 * (1 + 1e-8)]
    samples = [rng.uniform(-2.5, 2.5, 2) for _ in range(200)] + [np.array([e, 0.0]) for e in edges]
    thresholds = speed_limit_thresholds(LIMITED.velocity_limits)
    for qdot in samples:
        backend.qdot = qdot
        saturated = step(controller, state, np.zeros(2)).status == Status.SATURATED
        assert saturated == exceeds_speed_limits(qdot, thresholds)


def test_config_blow_up_speed_is_the_diverging_threshold() -> None:
    """A config's metrics.blow_up_speed sets every controller's diverging threshold."""
    import yaml

    from otmm_qp.config.load import parse_config
    from otmm_qp.metrics import MetricSettings
    from otmm_qp.runner import prepare_experiment, run_experiment

    text = """
name: tiny
dt: 0.02
loop_modes: [feedforward]
metrics: {blow_up_speed: 1.5}
experiments:
  - name: A
    robot: {type: planar, link_lengths: [1.0, 0.8]}
    q0: [0.927, -2.5]
    trajectory: {type: circle, centre: [1.2, 0.0], radius: 0.6, period: 2.0}
    duration: 0.4
    controllers:
      - {name: RMRC, backend: {type: pinv}}
"""
    suite = parse_config(yaml.safe_load(text))
    prepared = prepare_experiment(suite, 0)
    assert [c.divergence_speed for c in prepared.controllers] == [1.5]
    run = run_experiment(prepared, MetricSettings(blow_up_speed=1.5))[0]
    speed = np.abs(run.result.qdot).max(axis=1)
    assert speed.max() > 1.5  # the circle needs more than 1.5 rad/s somewhere
    np.testing.assert_array_equal(run.result.status == Status.DIVERGING, speed > 1.5)
    assert run.metrics["blow_up"]


_speeds = st.floats(-1e3, 1e3, allow_nan=False)


@given(
    st.lists(st.floats(0.1, 10.0), min_size=1, max_size=8),
    st.lists(_speeds, min_size=8, max_size=8),
    st.sampled_from([1e-12, 1e-9, 1e-7, 1e-6, 1e-3, 0.5, 1.0]),
    st.floats(1.0, 200.0),
    st.booleans(),
)
def test_below_the_quiet_speed_classify_keeps_the_status(
    limits: list[float], raw: list[float], closeness: float, divergence: float, limited: bool
) -> None:
    """The controller skips classify when ‖q̇‖² < quiet_speed_squared: exact, never a miss.

    Speeds are drawn at and around the thresholds (relative offsets down to 1e-12), so a
    rounding slip of the 2-norm bound would show as a skipped ``saturated`` or ``diverging``.
    """
    thresholds = speed_limit_thresholds(np.array(limits)) if limited else None
    nv = len(limits)
    floor = min(limits) * (1.0 + 1e-9)
    qdot = np.array(raw[:nv]) * 1e-3
    qdot[0] = floor * (1.0 - closeness) if raw[0] >= 0 else -floor * (1.0 + closeness)
    speed_squared = float(qdot.dot(qdot))
    quiet = quiet_speed_squared(thresholds, divergence)
    work = SpeedWork(nv)
    for status in (Status.OK, Status.BOUNDED):
        classified = classify(status, qdot, speed_squared, thresholds, divergence, work)
        assert classified == classify(status, qdot, speed_squared, thresholds, divergence)
        if speed_squared < quiet:
            assert classified is status


def test_speed_work_gives_the_same_answers_as_temporaries() -> None:
    thresholds = speed_limit_thresholds(np.array([2.0, np.inf, 1.0]))
    work = SpeedWork(3)
    for qdot in ([2.0, 1e9, 1.0], [-2.0 * (1 + 1e-8), 0.0, 0.0], [0.0, 0.0, -1.1], [np.nan] * 3):
        array = np.array(qdot)
        assert exceeds_speed_limits(array, thresholds, work) == exceeds_speed_limits(
            array, thresholds
        )
    assert quiet_speed_squared(None, 100.0) == 1e4
    assert quiet_speed_squared(thresholds, math.inf) == pytest.approx(1.0, rel=1e-5)
    assert quiet_speed_squared(thresholds, math.inf) < 1.0  # strictly below the smallest limit


@pytest.mark.parametrize("enforces", [False, True])
def test_controller_status_is_classify_at_the_thresholds(enforces: bool) -> None:
    """Controller.step (which skips classify below the quiet speed) agrees with classify."""

    class Echo(Backend):
        enforces_limits = enforces
        given = np.zeros(2)

        def solve(
            self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
        ) -> BackendOutput:
            return BackendOutput(self.given.copy(), Status.OK)

    backend = Echo()
    controller = Controller("echo", [], backend, divergence_speed=3.0)
    controller.bind(LIMITED, DT)  # speed limits 2 rad/s
    state = KinematicState.compute(LIMITED, np.array([0.3, 1.2]))
    thresholds = None if enforces else speed_limit_thresholds(LIMITED.velocity_limits)
    edge = 2.0 * (1.0 + 1e-9)
    for first in (0.0, 1.0, 2.0, edge, np.nextafter(edge, 3.0), 2.9, 3.0, 3.0 + 1e-12, np.inf):
        for second in (0.0, -1.0, -2.5):
            backend.given = np.array([first, second])
            out = step(controller, state, np.zeros(2))
            qdot = backend.given
            expected = classify(Status.OK, qdot, float(qdot.dot(qdot)), thresholds, 3.0)
            assert out.status == expected, (first, second, out.status, expected)
            assert np.all(np.isfinite(out.qdot))

import numpy as np
import pytest

from otmm_qp.backends.backend import Backend, BackendOutput
from otmm_qp.controller import Controller
from otmm_qp.exceptions import NonFiniteState
from otmm_qp.filters import OtmmFilter
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp.status import Status


def test_svd_is_shared_and_correct() -> None:
    arm = PlanarArm([1.0, 0.8, 0.5])
    state = KinematicState.compute(arm, np.array([0.3, -0.4, 0.2]))
    np.testing.assert_allclose(
        state.U @ np.diag(state.sigma) @ state.Vt, state.jacobian, atol=1e-14
    )
    np.testing.assert_allclose(state.sigma, np.linalg.svd(state.jacobian)[1], atol=1e-14)
    assert state.sigma_min == state.sigma[-1]


def test_weighted_task_space() -> None:
    arm = PlanarArm([1.0, 0.8])
    weight = np.array([2.0, 0.5])
    state = KinematicState.compute(arm, np.array([0.3, 1.0]), weight)
    np.testing.assert_allclose(state.task_jacobian, np.diag(weight) @ state.jacobian)
    np.testing.assert_allclose(state.sigma, np.linalg.svd(np.diag(weight) @ state.jacobian)[1])


def test_non_finite_configuration_is_a_typed_error() -> None:
    with pytest.raises(NonFiniteState, match="jacobian: contains NaN or inf"):
        KinematicState.compute(PlanarArm([1.0, 0.8]), np.array([np.nan, 0.0]))


class NanBackend(Backend):
    def solve(
        self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
    ) -> BackendOutput:
        return BackendOutput(np.array([np.nan, np.inf]))


def test_controller_never_lets_nan_out() -> None:
    arm = PlanarArm([1.0, 0.8])
    controller = Controller("nan", [OtmmFilter()], NanBackend())
    controller.bind(arm, 0.02)
    out = controller.step(
        KinematicState.compute(arm, np.array([0.3, 0.0])), np.ones(2), np.zeros(2)
    )
    np.testing.assert_array_equal(out.qdot, [0.0, 0.0])
    assert out.backend.status == Status.NONFINITE
    assert np.all(np.isfinite(out.xdot_filtered))

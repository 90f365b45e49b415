import threading

import numpy as np
import pytest
from scipy.linalg import lapack

from otmm_qp.backends.backend import (
    Backend,
    BackendOutput,
    svd_work,
    truncated_pseudoinverse_apply,
)
from otmm_qp.controller import Controller
from otmm_qp.exceptions import DimensionError, NonFiniteState, ParameterError
from otmm_qp.filters import OtmmFilter
from otmm_qp.robots import PlanarArm
from otmm_qp.state import KinematicState, thin_svd
from otmm_qp.status import Status
from otmm_qp_controllers.damping import damped_least_squares


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


def test_a_weight_given_as_a_list_is_read_and_a_wrong_one_is_named() -> None:
    arm = PlanarArm([1.0, 0.8])
    q = np.array([0.3, 1.0])
    listed = KinematicState.compute(arm, q, [2.0, 0.5])  # type: ignore[arg-type]
    np.testing.assert_array_equal(
        listed.sigma, KinematicState.compute(arm, q, np.array([2.0, 0.5])).sigma
    )
    with pytest.raises(DimensionError, match=r"weight: expected shape \(2,\), got \(3,\)"):
        KinematicState.compute(arm, q, [1.0, 1.0, 1.0])  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="weight.*must be 2 numbers.*got list"):
        KinematicState.compute(arm, q, [object(), object()])  # type: ignore[arg-type]


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


@pytest.mark.parametrize("shape", [(2, 2), (2, 3), (3, 7), (6, 6), (6, 7), (7, 6)])
def test_thin_svd_through_the_workspace_is_lapacks_own(shape: tuple[int, int]) -> None:
    """The per-thread Fortran workspace gives dgesdd's exact answer; the input is untouched."""
    rng = np.random.default_rng(sum(shape))
    for matrix in (
        rng.standard_normal(shape),  # C order
        np.asfortranarray(rng.standard_normal(shape)),
        rng.standard_normal((shape[0], 2 * shape[1]))[:, ::2],  # strided view
        np.outer(rng.standard_normal(shape[0]), rng.standard_normal(shape[1])),  # rank 1
        np.zeros(shape),  # exactly singular
    ):
        kept = matrix.copy()
        U, sigma, Vt = thin_svd(matrix)
        np.testing.assert_array_equal(matrix, kept)
        expected = lapack.dgesdd(kept, compute_uv=1, full_matrices=0)
        for ours, theirs in zip((U, sigma, Vt), expected[:3], strict=True):
            np.testing.assert_array_equal(ours, theirs)
        np.testing.assert_allclose((U * sigma) @ Vt, kept, atol=1e-12)
    nan = np.full(shape, np.nan)
    assert np.isnan(thin_svd(nan)[1]).all()  # reported through σ, never raised


def test_thin_svd_workspaces_are_per_thread() -> None:
    """Threads stepping concurrently never see each other's scratch matrix."""
    rng = np.random.default_rng(3)
    matrices = [rng.standard_normal((6, 7)) for _ in range(8)]
    expected = [np.linalg.svd(m, compute_uv=False) for m in matrices]
    errors: list[float] = []

    def work(index: int) -> None:
        for _ in range(300):
            sigma = thin_svd(matrices[index])[1]
            errors.append(float(np.abs(sigma - expected[index]).max()))

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(matrices))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(errors) == 8 * 300 and max(errors) < 1e-12


@pytest.mark.parametrize("q", [[0.3, -0.4, 0.2], [0.3, 0.0, 0.0], [0.0, 1e-3, -1e-3]])
def test_pinv_and_dls_from_buffers_are_the_formulas(q: list[float]) -> None:
    """Into svd_work buffers or not, bit for bit; against the closed forms; exactly singular
    arms (elbow straight) give finite q̇ using only the achievable rows."""
    arm = PlanarArm([1.0, 0.8, 0.5])
    state = KinematicState.compute(arm, np.array(q))
    work = svd_work(arm)
    J = state.task_jacobian
    for xdot in (np.array([0.3, -0.2]), state.U[:, -1], np.zeros(2)):
        plain = truncated_pseudoinverse_apply(state, xdot)
        np.testing.assert_array_equal(truncated_pseudoinverse_apply(state, xdot, work=work), plain)
        assert np.all(np.isfinite(plain))
        np.testing.assert_allclose(plain, np.linalg.pinv(J, rcond=1e-10) @ xdot, atol=1e-9)
        for mu in (0.0, 1e-6, 2.5e-3):
            damped = damped_least_squares(state, xdot, mu, work)
            np.testing.assert_array_equal(damped, damped_least_squares(state, xdot, mu))
            if mu > 0.0:
                closed = J.T @ np.linalg.solve(J @ J.T + mu * np.eye(2), xdot)
                np.testing.assert_allclose(damped, closed, atol=1e-9)
        # the buffers are scratch: the results are new arrays, not views on them
        assert not np.shares_memory(plain, work)
        assert not np.shares_memory(damped_least_squares(state, xdot, 1e-3, work), work)

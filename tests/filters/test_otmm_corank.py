"""OTMM corank 'all' vs the paper's corank-1 filter, and per-component invariants."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.filters.otmm import OtmmFilter
from otmm_qp.state import KinematicState


def _state(sigma: np.ndarray, seed: int, nv: int = 6) -> KinematicState:
    rng = np.random.default_rng(seed)
    n = sigma.size
    U = np.linalg.qr(rng.standard_normal((n, n)))[0]
    V = np.linalg.qr(rng.standard_normal((nv, nv)))[0]
    jacobian = U @ np.diag(sigma) @ V[:, :n].T
    order = np.argsort(-sigma)
    return KinematicState(
        np.zeros(nv), np.zeros(n), jacobian, np.ones(n), jacobian,
        U[:, order], sigma[order], V[:, :n].T[order],
    )  # fmt: skip


sigmas = st.lists(st.floats(0.0, 2.0), min_size=6, max_size=6).map(np.array)


@settings(max_examples=80, deadline=None)
@given(sigmas, st.integers(0, 10_000), st.lists(st.floats(-1, 1), min_size=6, max_size=6))
def test_corank_all_equals_paper_with_one_small_sigma(sigma, seed, xdot) -> None:
    sigma = sigma.copy()
    sigma[:5] = np.maximum(sigma[:5], 0.06)  # only one σ below σ_S = 0.05 (maybe none)
    state = _state(sigma, seed)
    xdot = np.array(xdot)
    paper = OtmmFilter(0.05, corank=1).apply(state, xdot)
    general = OtmmFilter(0.05, corank="all").apply(state, xdot)
    np.testing.assert_allclose(paper.xdot, general.xdot, atol=1e-12)
    assert paper.report.p == general.report.p


@settings(max_examples=80, deadline=None)
@given(sigmas, st.integers(0, 10_000), st.lists(st.floats(-1, 1), min_size=6, max_size=6))
def test_each_component_scaled_by_one_minus_p(sigma, seed, xdot) -> None:
    state = _state(sigma, seed)
    xdot = np.array(xdot)
    otmm = OtmmFilter(0.05, corank="all")
    out = otmm.apply(state, xdot)
    before = state.U.T @ xdot
    after = state.U.T @ out.xdot
    for i, s in enumerate(state.sigma):
        factor = 1.0 - otmm.p(float(s)) if s <= 0.05 else 1.0
        assert abs(after[i] - factor * before[i]) <= 1e-12
    assert np.linalg.norm(out.xdot) <= np.linalg.norm(xdot) + 1e-12


def test_corank_one_filters_only_weakest() -> None:
    state = _state(np.array([1.0, 0.8, 0.5, 0.3, 0.02, 0.01]), 3)
    xdot = state.U @ np.ones(6)
    paper = OtmmFilter(0.05, corank=1).apply(state, xdot)
    general = OtmmFilter(0.05, corank="all").apply(state, xdot)
    np.testing.assert_allclose(state.U.T @ paper.xdot, [1, 1, 1, 1, 1, 0.2], atol=1e-12)
    np.testing.assert_allclose(state.U.T @ general.xdot, [1, 1, 1, 1, 0.4, 0.2], atol=1e-12)

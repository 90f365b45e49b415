"""``active_bound``, ``clip_into_box``: scalar loops equal the array forms; inf never active."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.state import KinematicState
from otmm_qp.status import Status
from otmm_qp_controllers.qp import QpBackend
from otmm_qp_controllers.qp.formulation import active_bound, clip_into_box

TOL = 1e-9
finite = st.floats(-5.0, 5.0, allow_nan=False)
bound = st.one_of(finite, st.just(np.inf), st.just(-np.inf))


def reference(qdot: np.ndarray, bounds: np.ndarray, tol: float) -> bool | None:
    """The array form: inside the box, then |margin| ≤ τ(1 + |bound|) on a finite bound."""
    margins = np.array([qdot - bounds[0], bounds[1] - qdot])
    if not (margins >= 0.0).all():
        return None
    near = (margins <= tol * (1.0 + np.abs(bounds))) & np.isfinite(bounds)
    return bool(near.any())


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(finite, bound, bound, st.booleans()), min_size=1, max_size=9))
def test_loop_equals_array_form(rows: list[tuple[float, float, float, bool]]) -> None:
    qdot = np.array([r[0] for r in rows])
    lower = np.array([min(r[1], r[2]) for r in rows])
    upper = np.array([max(r[1], r[2]) for r in rows])
    snap = np.array([r[3] for r in rows])  # put some q̇_i exactly on a finite bound
    on_lower = snap & np.isfinite(lower)
    qdot[on_lower] = lower[on_lower]
    bounds = np.array([lower, upper])
    assert active_bound(qdot, bounds, TOL) == reference(qdot, bounds, TOL)


def test_nan_is_outside() -> None:
    assert active_bound(np.array([np.nan, 0.0]), np.array([[-1.0, -1.0], [1.0, 1.0]]), TOL) is None


def test_qp_on_an_arm_without_limits_reports_ok() -> None:
    """Unlimited joints have ±inf bounds: never 'bounded' (they were, before the fix)."""
    arm = PlanarArm([1.0, 0.8])
    backend = QpBackend(solver="daqp")
    backend.bind(arm, 0.01)
    state = KinematicState.compute(arm, np.array([0.3, 0.5]))
    assert backend.solve(state, np.array([0.1, 0.0]), np.zeros(2)).status == Status.OK


def clip_reference(x: np.ndarray, bounds: np.ndarray, tol: float) -> tuple[np.ndarray, bool] | None:
    """The array form of clip_into_box: reject non-finite, clip, then active_bound's test."""
    if not np.isfinite(x).all():
        return None
    clipped = np.minimum(np.maximum(x, bounds[0]), bounds[1])
    active = reference(clipped, bounds, tol)
    assert active is not None  # clipped into a non-empty box: inside
    return clipped, active


solver_value = st.one_of(
    st.floats(-8.0, 8.0, allow_nan=False), st.just(np.inf), st.just(-np.inf), st.just(np.nan)
)


lower_bound = st.one_of(finite, st.just(-np.inf))
upper_bound = st.one_of(finite, st.just(np.inf))


@settings(max_examples=400, deadline=None)
@given(
    st.lists(
        st.tuples(solver_value, lower_bound, upper_bound, st.booleans()), min_size=1, max_size=9
    )
)
def test_clip_into_box_equals_array_form(rows: list[tuple[float, float, float, bool]]) -> None:
    """One scalar pass = isfinite + clip + active_bound on the clipped q̇ (bit for bit).

    Boxes are non-empty with ``lb < +inf`` and ``ub > −inf``, as every velocity box is.
    """
    x = np.array([r[0] for r in rows])
    lower = np.array([min(r[1], r[2]) for r in rows])
    upper = np.array([max(r[1], r[2]) for r in rows])
    snap = np.array([r[3] for r in rows]) & np.isfinite(upper)
    x[snap] = upper[snap] + 1e-12 * (1.0 + np.abs(upper[snap]))  # within the solver tolerance
    bounds = np.array([lower, upper])
    got, expected = clip_into_box(x, bounds, TOL), clip_reference(x, bounds, TOL)
    if expected is None:
        assert got is None
        return
    assert got is not None
    np.testing.assert_array_equal(got[0], expected[0])
    assert got[1] == expected[1]
    assert got[0] is not x  # a new array: the caller may keep it


def test_clip_into_box_rejects_nan_and_inf() -> None:
    bounds = np.array([[-1.0, -1.0], [1.0, 1.0]])
    assert clip_into_box(np.array([np.nan, 0.0]), bounds, TOL) is None
    assert clip_into_box(np.array([0.0, np.inf]), bounds, TOL) is None
    clipped = clip_into_box(np.array([1.0 + 1e-12, 0.0]), bounds, TOL)
    assert clipped is not None and clipped[0][0] == 1.0 and clipped[1]


zero_or_value = st.one_of(solver_value, st.just(0.0), st.just(-0.0))
zero_or_lower = st.one_of(lower_bound, st.just(0.0), st.just(-0.0))
zero_or_upper = st.one_of(upper_bound, st.just(0.0), st.just(-0.0))


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(zero_or_value, zero_or_lower, zero_or_upper, st.integers(0, 2)),
        min_size=1,
        max_size=9,
    )
)
def test_owned_answer_and_bound_lists_change_no_bit(
    rows: list[tuple[float, float, float, int]],
) -> None:
    """``owned=True`` and the box as lists give the same bits (signed zeros included).

    ``x`` is returned itself when strictly inside the box, never when clipping changed a bit
    (a value on a zero bound counts as clipped: its sign bit may differ from the bound's).
    """
    x = np.array([r[0] for r in rows])
    lower = np.array([min(r[1], r[2]) for r in rows])
    upper = np.array([max(r[1], r[2]) for r in rows])
    snap = np.array([r[3] for r in rows])  # 1: x on its lower bound, 2: on its upper bound
    x[snap == 1] = lower[snap == 1]
    x[snap == 2] = upper[snap == 2]
    x = np.where(np.isinf(x) & (snap > 0), 0.0, x)
    bounds = np.array([lower, upper])
    plain = clip_into_box(x, bounds, TOL)
    original = x.copy()
    owned = clip_into_box(x, bounds, TOL, lists=(lower.tolist(), upper.tolist()), owned=True)
    if plain is None:
        assert owned is None
        return
    assert owned is not None
    assert owned[0].tobytes() == plain[0].tobytes() and owned[1] == plain[1]
    if np.all((lower < original) & (original < upper)):
        assert owned[0] is x  # strictly inside: nothing to clip, the solver's array is kept
    if plain[0].tobytes() != original.tobytes():
        assert owned[0] is not x
    assert x.tobytes() == original.tobytes()  # never written in place


def test_active_bound_reads_the_lists_it_is_given() -> None:
    """With ``lists`` the array is not read: the lists are the box."""
    qdot = np.array([0.5, 0.0])
    stale = np.array([[-9.0, -9.0], [9.0, 9.0]])
    assert active_bound(qdot, stale, TOL, ([-1.0, -1.0], [0.5, 1.0])) is True
    assert active_bound(qdot, stale, TOL, ([-1.0, -1.0], [0.4, 1.0])) is None

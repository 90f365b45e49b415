"""The one trust-region driver of the reference (:mod:`otmm_qp.reference.trust_region`).

A toy subproblem with a known answer drives it: ``φ(Q) = Σ_k ½‖q_k − c‖²`` with the exact
model (the step ``δ_k = clip(c − q_k, −Δ, Δ)``, its decrease predicted exactly), or with a
model that over-promises twentyfold. The ratio test, the radius rules, the stop tests and the
deadline are checked against their definitions; the two real subproblems (least squares on
OSQP, the cone polish) keep their own contracts in ``test_reference*.py``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import OtmmError, SolverFailure, TimeBudgetExceeded
from otmm_qp.reference.trust_region import (
    GROW,
    SHRINK,
    Iterate,
    Radii,
    Step,
    Stopping,
    minimise,
)
from otmm_qp.robots.robot import FloatArray

RADII = Radii(initial=0.1, largest=0.4, smallest=1e-6)


class Bowl:
    """``φ(Q) = Σ_{k≥1} ½‖q_k − c‖²``, merits ``|q_k − c|_∞ / 0.01``; the model can lie."""

    def __init__(
        self, centre: FloatArray, lower: FloatArray, upper: FloatArray, lie: float
    ) -> None:
        nv = centre.size
        self.problem = SimpleNamespace(lower=lower, upper=upper, step=np.full(nv, np.inf))
        self.centre, self.lie = centre, lie
        self.radii_seen: list[float] = []
        self.phis: list[float] = []

    def evaluate(self, path: FloatArray) -> Iterate:
        gap = path[1:] - self.centre
        merits = np.max(np.abs(gap), axis=1) / 0.01
        phi = 0.5 * float(np.sum(gap * gap))
        self.phis.append(phi)
        return Iterate(path, gap, merits, phi)

    def start(self, path: FloatArray) -> Iterate:
        return self.evaluate(path)

    def step(self, iterate: Iterate, radius: float) -> Step:
        self.radii_seen.append(radius)
        target = np.clip(self.centre, self.problem.lower, self.problem.upper)
        delta = np.clip(target - iterate.path[1:], -radius, radius)
        gap = iterate.path[1:] - self.centre
        predicted = -float(np.sum(gap * delta) + 0.5 * np.sum(delta * delta))
        return Step(delta, self.lie * predicted)


def _start(rng: np.random.Generator, samples: int, nv: int) -> FloatArray:
    path = rng.uniform(-1.0, 1.0, (samples, nv))
    path[0] = 0.0
    return path


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), nv=st.integers(1, 4))
def test_an_exact_model_reaches_the_limited_optimum(seed: int, nv: int) -> None:
    """Exact model: every step is kept, ``φ`` decreases strictly, every iterate stays in
    the box, and the solve ends at ``c`` projected on the box (to the step tolerance)."""
    rng = np.random.default_rng(seed)
    lower, upper = np.full(nv, -0.8), np.full(nv, 0.8)
    centre = rng.uniform(-1.5, 1.5, nv)
    bowl = Bowl(centre, lower, upper, lie=1.0)
    start = np.clip(_start(rng, 5, nv), lower, upper)
    outcome = minimise(bowl, start, 200, math.inf, RADII, Stopping(step_tolerance=1e-9))
    assert outcome.converged and outcome.current is not None
    assert np.all(np.diff(bowl.phis) < 0.0)  # every trial was an improvement and was kept
    assert np.all(outcome.current >= lower) and np.all(outcome.current <= upper)
    optimum = np.broadcast_to(np.clip(centre, lower, upper), outcome.current[1:].shape)
    np.testing.assert_allclose(outcome.current[1:], optimum, atol=1e-9)
    # no step was rejected: the radius only grows, by GROW at a time, up to the largest
    for before, after in zip(bowl.radii_seen, bowl.radii_seen[1:], strict=False):
        assert after in (before, min(GROW * before, RADII.largest))
    assert bowl.radii_seen[0] == RADII.initial and max(bowl.radii_seen) <= RADII.largest


def test_an_over_promising_model_shrinks_the_radius_to_its_floor() -> None:
    """Every step is rejected (ratio 1/20 ≤ 0.1): the path never moves and the radius falls
    to ``¼·min(Δ, ‖δ‖∞)`` each time until it is below the smallest radius."""
    rng = np.random.default_rng(3)
    bowl = Bowl(np.full(2, 0.5), np.full(2, -1.0), np.full(2, 1.0), lie=20.0)
    start = _start(rng, 4, 2)
    outcome = minimise(bowl, start, 100, math.inf, RADII, Stopping())
    assert outcome.current is None and outcome.path is start
    seen = bowl.radii_seen
    expected = [RADII.initial]
    while expected[-1] * SHRINK >= RADII.smallest:
        expected.append(SHRINK * expected[-1])
    np.testing.assert_allclose(seen, expected, rtol=1e-12)
    assert outcome.radius < RADII.smallest and outcome.iterations == len(seen)
    assert not outcome.converged


def test_no_predicted_decrease_stops_before_any_trial() -> None:
    """At the optimum the model predicts nothing: the solve stops after one subproblem."""
    bowl = Bowl(np.zeros(2), np.full(2, -1.0), np.full(2, 1.0), lie=1.0)
    start = np.zeros((3, 2))
    outcome = minimise(bowl, start, 10, math.inf, RADII, Stopping(relative_decrease=1e-7))
    assert outcome.iterations == 1 and outcome.current is None and outcome.merit == 0.0


def test_settle_and_certificate_cut_the_iterations() -> None:
    """``settle``: the first accepted iterate with ``max m ≤ settle`` ends the solve; after a
    certificate (``max m ≤ 1``) only ``after_certificate`` more subproblems run."""
    rng = np.random.default_rng(5)
    start = _start(rng, 3, 2)
    free = Bowl(np.full(2, 0.3), np.full(2, -1.0), np.full(2, 1.0), lie=1.0)
    full = minimise(free, start, 50, math.inf, RADII, Stopping(step_tolerance=1e-12))
    settled = Bowl(np.full(2, 0.3), np.full(2, -1.0), np.full(2, 1.0), lie=1.0)
    short = minimise(settled, start, 50, math.inf, RADII, Stopping(settle=1.0))
    assert short.merit <= 1.0 < free.evaluate(start).top
    assert short.iterations < full.iterations
    capped = Bowl(np.full(2, 0.3), np.full(2, -1.0), np.full(2, 1.0), lie=1.0)
    after = minimise(capped, start, 50, math.inf, RADII, Stopping(after_certificate=1))
    assert after.iterations == short.iterations + 1


def test_the_deadline_stops_or_raises_a_typed_error() -> None:
    bowl = Bowl(np.full(2, 0.3), np.full(2, -1.0), np.full(2, 1.0), lie=1.0)
    start = _start(np.random.default_rng(0), 3, 2)
    quiet = minimise(bowl, start, 10, -math.inf, RADII, Stopping())
    assert quiet.iterations == 0 and quiet.path is start and math.isnan(quiet.step)
    with pytest.raises(TimeBudgetExceeded):
        minimise(bowl, start, 10, -math.inf, RADII, Stopping(raise_at_deadline=True))
    assert issubclass(TimeBudgetExceeded, OtmmError) and issubclass(SolverFailure, OtmmError)


@pytest.mark.parametrize("module", ["otmm_qp.reference.sqp", "otmm_qp.reference.conic"])
def test_one_loop_in_the_reference(module: str) -> None:
    """The subproblems hold no trust-region loop of their own: no ratio, no radius rule."""
    import ast
    import importlib
    import inspect

    tree = ast.parse(inspect.getsource(importlib.import_module(module)))
    assert not [node for node in ast.walk(tree) if isinstance(node, ast.While)]
    names = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
    assert not names & {"ratio", "radius_update", "trial"}

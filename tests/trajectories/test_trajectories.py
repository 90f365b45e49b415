import numpy as np
import pytest

from otmm_qp.exceptions import ParameterError
from otmm_qp.trajectories import (
    CircleTrajectory,
    ConstantVelocityLineTrajectory,
    QuinticLineTrajectory,
)

CASES = [
    CircleTrajectory(np.array([0.6, 0.0]), [1.2, 0.0], 0.6, 10.0),
    CircleTrajectory(
        np.array([0.6, 0.0, 0.3]), [1.2, 0.0, 0.3], 0.2, 4.0, "counterclockwise", normal=[1, 1, 0]
    ),
    QuinticLineTrajectory(np.zeros(2), [0.6, -1.0], 5.2, begin=[1.8, 0.0]),
    ConstantVelocityLineTrajectory(np.zeros(3), [0.3, 0.2, 0.1], 2.0),
]


@pytest.mark.parametrize("trajectory", CASES, ids=lambda t: t.name)
def test_velocity_is_the_derivative_of_position(trajectory) -> None:  # type: ignore[no-untyped-def]
    h = 1e-6
    for t in np.linspace(0.05, trajectory.duration - 0.05, 17):
        numeric = (trajectory.position(t + h) - trajectory.position(t - h)) / (2 * h)
        np.testing.assert_allclose(trajectory.sample(t)[1], numeric, atol=1e-6)


def test_paper_quintic_line_law() -> None:
    """Fig. 7: x = -1.2 s(τ) + 1.8, y = -s(τ), s = 10τ³ − 15τ⁴ + 6τ⁵."""
    line = QuinticLineTrajectory(np.zeros(2), [0.6, -1.0], 5.2, begin=[1.8, 0.0])
    for t in [0.0, 1.3, 2.6, 5.2]:
        tau = t / 5.2
        s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
        np.testing.assert_allclose(line.position(t), [-1.2 * s + 1.8, -s], atol=1e-14)
    assert np.all(line.sample(0.0)[1] == 0) and np.allclose(line.sample(5.2)[1], 0)


def test_circle_starts_nearest_the_start_and_turns_clockwise() -> None:
    circle = CircleTrajectory(np.array([0.5, 0.01]), [1.2, 0.0], 0.6, 10.0)
    np.testing.assert_allclose(
        circle.position(0.0), [0.6, 0.6 * np.sin(np.arctan2(0.01, -0.7))], atol=1e-3
    )
    # Clockwise from the leftmost point: y increases first (over the top).
    assert circle.sample(0.0)[1][1] > 0
    np.testing.assert_allclose(circle.position(5.0)[0], 1.8, atol=1e-3)


def test_bad_parameters() -> None:
    with pytest.raises(ParameterError, match=r"radius: must be (a finite number )?> 0"):
        CircleTrajectory(np.zeros(2), [0, 0], -1.0, 1.0)
    with pytest.raises(ParameterError, match="direction: must be .?clockwise.? or .?counter"):
        CircleTrajectory(np.zeros(2), [0, 0], 1.0, 1.0, "sideways")  # type: ignore[arg-type]

"""Held targets: piecewise-constant set-points, in runs and in studies."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from otmm_qp import registry
from otmm_qp.config.load import parse_config
from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots import PlanarArm
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.runner import run_suite
from otmm_qp.scenarios.held_target import HeldTargetGenerator
from otmm_qp.trajectories.held_targets import HeldTargetsTrajectory


def test_targets_are_held_for_their_times_with_zero_velocity() -> None:
    traj = HeldTargetsTrajectory(
        np.array([1.8, 0.0]), [[1.0, 0.5], [0.2, 1.2]], hold=[0.5, 1.0], initial_hold=0.25
    )
    assert traj.duration == pytest.approx(1.75)
    for t, expected in [
        (-1.0, [1.8, 0.0]),
        (0.0, [1.8, 0.0]),
        (0.2499, [1.8, 0.0]),
        (0.25, [1.0, 0.5]),
        (0.7499, [1.0, 0.5]),
        (0.75, [0.2, 1.2]),
        (99.0, [0.2, 1.2]),
    ]:
        x, v = traj.sample(t)
        np.testing.assert_array_equal(x, expected)
        np.testing.assert_array_equal(v, 0.0)
    x, _ = traj.sample(0.3)
    x[0] = 7.0  # samples are copies: the trajectory cannot be changed through them
    np.testing.assert_array_equal(traj.sample(0.3)[0], [1.0, 0.5])


def test_pose_targets_keep_or_set_the_orientation() -> None:
    start = np.eye(4)
    traj = HeldTargetsTrajectory(start, [[0.3, 0.0, 0.5], [0.3, 0.1, 0.5, 0.0, 0.0, np.pi / 2]])
    first, twist = traj.sample(0.5)
    np.testing.assert_array_equal(first[:3, :3], np.eye(3))
    np.testing.assert_array_equal(first[:3, 3], [0.3, 0.0, 0.5])
    assert twist.shape == (6,) and not twist.any()
    second, _ = traj.sample(1.5)
    np.testing.assert_allclose(second[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)


@pytest.mark.parametrize(
    ("params", "error", "message"),
    [
        ({"targets": []}, ConfigError, "targets: give at least one target"),
        ({"targets": [[1.0]]}, DimensionError, "targets.0: expected shape (2,)"),
        ({"targets": [[1.0, float("nan")]]}, ParameterError, "targets.0: must be finite"),
        ({"targets": [[1.0, 0.0]], "hold": 0.0}, ParameterError, "hold: every hold time"),
        ({"targets": [[1.0, 0.0]], "hold": [1.0, 2.0]}, DimensionError, "hold: expected shape"),
        ({"targets": [[1.0, 0.0]], "hold": "long"}, ParameterError, "hold: must be a number"),
        ({"targets": [[1.0, 0.0]], "initial_hold": -1.0}, ParameterError, "initial_hold: must"),
    ],
)
def test_bad_parameters_name_the_field(
    params: dict[str, object], error: type[Exception], message: str
) -> None:
    with pytest.raises(error) as info:
        HeldTargetsTrajectory(np.zeros(2), **params)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)


def test_a_run_from_yaml_converges_to_each_target() -> None:
    suite = parse_config(
        yaml.safe_load(
            """
name: held
dt: 0.01
loop_modes: [clik]
experiments:
  - name: teleop
    robot: {type: planar, link_lengths: [1.0, 0.8]}
    q0: [0.3, 1.2]
    trajectory: {type: held_targets, targets: [[1.2, 0.6], [0.4, 1.3]], hold: 1.0}
    controllers:
      - name: dls_error
        backend: {type: dls_error, error_weight: 10.0, error_horizon: 0.1}
"""
        )
    )
    result = run_suite(suite, None, progress=None).records[0].result
    arm = PlanarArm([1.0, 0.8])
    for t_end, target in ((0.99, [1.2, 0.6]), (1.99, [0.4, 1.3])):
        k = int(np.searchsorted(result.t, t_end))
        np.testing.assert_allclose(arm.forward(result.q[k]), target, atol=5e-3)


def test_the_generator_draws_reachable_held_targets_reproducibly() -> None:
    assert "held_target" in registry.available(registry.TASK_GENERATORS)
    generator = HeldTargetGenerator(targets=3, hold=0.8)
    arm = PlanarArm([1.0, 0.8, 0.5])
    task = generator.generate(arm, 123)
    again = generator.generate(arm, 123)
    assert task.duration == pytest.approx(2.4)
    np.testing.assert_array_equal(task.q0, again.q0)
    for t in (0.1, 0.9, 1.7):
        x, v = task.trajectory.sample(t)
        np.testing.assert_array_equal(x, again.trajectory.sample(t)[0])
        assert np.linalg.norm(x) <= 2.3 + 1e-12 and not v.any()
    panda = PinocchioArm(name="panda", task="pose")
    pose_task = HeldTargetGenerator(targets=1).generate(panda, 7)
    assert pose_task.trajectory.sample(0.5)[0].shape == (4, 4)
    with pytest.raises(ParameterError, match="targets: must be an integer"):
        HeldTargetGenerator(targets=0)
    with pytest.raises(ParameterError, match="hold: must be a finite number > 0"):
        HeldTargetGenerator(hold=float("inf"))

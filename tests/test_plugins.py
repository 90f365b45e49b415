"""Plugin API: discovery of a third-party package, rejection, name clashes, and a run."""

from __future__ import annotations

import importlib
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from otmm_qp import registry
from otmm_qp.backends.backend import Backend
from otmm_qp.config.load import parse_config
from otmm_qp.exceptions import PluginValidationError
from otmm_qp.runner import run_suite
from tests.plugin_install import install_example_plugin


@pytest.fixture
def example_plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for folder in install_example_plugin(tmp_path):
        monkeypatch.syspath_prepend(str(folder))
    importlib.invalidate_caches()
    registry.clear_cache()
    yield
    registry.clear_cache()
    for name in [m for m in sys.modules if m.startswith("otmm_qp_example_plugin")]:
        del sys.modules[name]


def patch_entry_points(monkeypatch: pytest.MonkeyPatch, extra: list[metadata.EntryPoint]) -> None:
    """Add entry points (as if from other installed distributions)."""
    original = metadata.entry_points

    def patched(**params: Any) -> Any:
        found = original(**params)
        group = params.get("group")
        return metadata.EntryPoints([*found, *(e for e in extra if e.group == group)])

    monkeypatch.setattr(metadata, "entry_points", patched)
    registry.clear_cache()


class NotABackend:
    """Lacks the Backend base class."""


class HalfBackend(Backend):
    """Subclasses Backend but does not implement solve."""


def test_example_plugin_is_discovered(example_plugin: None) -> None:
    assert "example_clipped_pinv" in registry.available(registry.BACKENDS)
    assert "example_smoothstep" in registry.available(registry.P_FUNCTIONS)
    spec = registry.specs(registry.BACKENDS)["example_clipped_pinv"]
    assert spec.distribution == "otmm-qp-example-plugin"
    p = registry.load(registry.P_FUNCTIONS, "example_smoothstep")
    assert (p(0.0, 0.05), p(0.05, 0.05), p(0.025, 0.05)) == (1.0, 0.0, 0.5)


def test_experiment_runs_with_the_example_plugin(example_plugin: None) -> None:
    suite = parse_config(
        {
            "name": "plugin",
            "loop_modes": ["clik"],
            "experiments": [
                {
                    "name": "E2",
                    "robot": {"type": "planar", "link_lengths": [1.0, 0.8]},
                    "q0": [0.0, 0.0],
                    "trajectory": {
                        "type": "quintic_line",
                        "begin": [1.8, 0.0],
                        "end": [0.6, -1.0],
                        "duration": 5.2,
                    },
                    "controllers": [
                        {
                            "name": "clipped",
                            "backend": {"type": "example_clipped_pinv", "max_speed": 1.5},
                        },
                        {
                            "name": "otmm-smooth",
                            "filters": [
                                {"type": "otmm", "sigma_s": 0.05, "p": "example_smoothstep"}
                            ],
                            "backend": {"type": "example_clipped_pinv"},
                        },
                    ],
                }
            ],
        }
    )
    outcome = run_suite(suite, None, progress=None)
    assert outcome.errors == []
    clipped = outcome.records[0]
    assert float(np.max(np.abs(clipped.result.qdot))) <= 1.5 + 1e-12
    assert clipped.metrics["rms_error"] < 0.01
    assert outcome.records[1].metrics["completed"]


def test_backend_without_base_class_is_rejected(monkeypatch: pytest.MonkeyPatch) -> None:
    patch_entry_points(
        monkeypatch, [metadata.EntryPoint("bad", f"{__name__}:NotABackend", registry.BACKENDS)]
    )
    with pytest.raises(PluginValidationError) as info:
        registry.load(registry.BACKENDS, "bad")
    assert str(info.value) == (
        "plugin 'bad': must be a subclass of otmm_qp.backends.backend.Backend"
    )


def test_backend_missing_solve_is_rejected(monkeypatch: pytest.MonkeyPatch) -> None:
    patch_entry_points(
        monkeypatch, [metadata.EntryPoint("half", f"{__name__}:HalfBackend", registry.BACKENDS)]
    )
    with pytest.raises(PluginValidationError) as info:
        registry.load(registry.BACKENDS, "half")
    assert str(info.value) == "plugin 'half': does not implement solve"


def test_p_function_with_wrong_signature_is_rejected(monkeypatch: pytest.MonkeyPatch) -> None:
    patch_entry_points(
        monkeypatch, [metadata.EntryPoint("one_arg", "math:sqrt", registry.P_FUNCTIONS)]
    )
    with pytest.raises(PluginValidationError, match="plugin 'one_arg': p-function must accept"):
        registry.load(registry.P_FUNCTIONS, "one_arg")


def test_two_plugins_claiming_one_name_are_both_named(
    example_plugin: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    clash = metadata.EntryPoint(
        "example_clipped_pinv", f"{__name__}:HalfBackend", registry.BACKENDS
    )
    patch_entry_points(monkeypatch, [clash])
    with pytest.raises(PluginValidationError) as info:
        registry.available(registry.BACKENDS)
    message = str(info.value)
    assert "otmm_qp_example_plugin.clipped_pinv:ClippedPseudoInverseBackend" in message
    assert f"{__name__}:HalfBackend" in message
    assert message.startswith("plugin 'example_clipped_pinv': name registered twice")


class UnnamedPinv(Backend):
    """A third-party backend that declares no ``name`` of its own."""

    def solve(self, state: Any, xdot: np.ndarray, qdot_prev: np.ndarray) -> Any:
        from otmm_qp.backends.backend import BackendOutput
        from otmm_qp_controllers.pinv import truncated_pseudoinverse_apply

        return BackendOutput(truncated_pseudoinverse_apply(state, xdot))


def test_the_registered_name_is_kept_beside_the_object_not_written_into_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """One class under two registered names: each run is labelled by its own name."""
    from otmm_qp.config.schema import ControllerConfig
    from otmm_qp.runner.build import build_controller
    from otmm_qp_controllers.pinv import PseudoInverseBackend

    for name in ("pinv_a", "pinv_b"):
        monkeypatch.setitem(registry._cache, (registry.BACKENDS, name), PseudoInverseBackend)
    monkeypatch.setitem(registry._cache, (registry.BACKENDS, "unnamed"), UnnamedPinv)
    built = {
        name: build_controller(
            ControllerConfig.model_validate(
                {"name": name, "filters": [{"type": "identity"}], "backend": {"type": name}}
            ),
            "c",
        )
        for name in ("pinv_a", "pinv_b", "unnamed")
    }
    assert {n: c.backend_name for n, c in built.items()} == {
        "pinv_a": "pinv_a", "pinv_b": "pinv_b", "unnamed": "unnamed"
    }  # fmt: skip
    assert all(c.filter_names == ("identity",) for c in built.values())
    # the objects keep their class's own name: nothing was assigned on them
    assert [c.backend.name for c in built.values()] == ["pinv", "pinv", "backend"]
    assert all("name" not in vars(c.backend) for c in built.values())
    # and the run's result (the summary's filters/backend columns) carries the registered names
    from otmm_qp.robots.planar_arm import PlanarArm
    from otmm_qp.simulation import Episode, simulate
    from otmm_qp.trajectories.circle import CircleTrajectory

    robot, q0 = PlanarArm([1.0, 0.8]), np.array([0.927, -2.5])
    trajectory = CircleTrajectory(robot.forward(q0), [1.2, 0.0], 0.6, 10.0)
    result = simulate(Episode(robot, trajectory, q0, 0.02, 0.1), built["unnamed"])
    assert (result.filters, result.backend, result.error_message) == ("identity", "unnamed", None)

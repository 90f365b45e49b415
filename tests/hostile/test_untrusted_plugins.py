"""Plugins are untrusted code: an exception or a malformed q̇ fails that run only (issue 19).

A backend that raises (any exception, ``SystemExit`` included) or returns a q̇ of the wrong
type/shape at step k stops its run after k recorded steps; the other runs of the suite or
study are kept and stored, and the CLI exits 2. ``KeyboardInterrupt`` stays an interrupt.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from otmm_qp import registry
from otmm_qp.backends import Backend, BackendOutput
from otmm_qp.cli import main
from otmm_qp.controller import Controller
from otmm_qp.filters.task_filter import TaskFilter
from otmm_qp.plants import IdealPlant, PlantChain, PlantStep
from otmm_qp.robots.planar_arm import PlanarArm
from otmm_qp.simulation import Episode, simulate
from otmm_qp.state import KinematicState
from otmm_qp.studies.storage import read_episodes
from otmm_qp.trajectories.circle import CircleTrajectory
from otmm_qp_controllers.pinv import PseudoInverseBackend, truncated_pseudoinverse_apply
from tests.factories import experiment, tiny_run

FAIL_AT = 3

#: What the plugin does at step FAIL_AT, and the message the run keeps.
FAILURES: dict[str, tuple[Any, str]] = {
    "RuntimeError": (
        RuntimeError("solver crashed"),
        "a plugin raised RuntimeError: solver crashed",
    ),
    "SystemExit": (SystemExit(3), "a plugin raised SystemExit: 3"),
    "ZeroDivisionError": (ZeroDivisionError("x"), "a plugin raised ZeroDivisionError: x"),
    "wrong shape": (np.zeros(5), r"returned q̇ of type ndarray and shape \(5,\); expected"),
    # Controller.step reads q̇.dot first: a list fails there, as a plugin error of that run.
    "wrong type": ([0.0, 0.0], "'list' object"),
    "integer array": (np.zeros(2, dtype=int), r"shape \(2,\); expected a float array"),
}


class Misbehaving(Backend):
    """pinv for FAIL_AT steps, then raises or returns ``Misbehaving.outcome``."""

    outcome: Any = None

    def reset(self) -> None:
        self.calls = 0

    def solve(
        self, state: KinematicState, xdot: np.ndarray, qdot_prev: np.ndarray
    ) -> BackendOutput:
        self.calls += 1
        if self.calls > FAIL_AT:
            if isinstance(self.outcome, BaseException):
                raise self.outcome
            return BackendOutput(self.outcome)
        return BackendOutput(truncated_pseudoinverse_apply(state, xdot))


def _episode(duration: float = 0.2) -> Episode:
    robot = PlanarArm([1.0, 0.8])
    q0 = np.array([0.927, -2.5])
    trajectory = CircleTrajectory(robot.forward(q0), [1.2, 0.0], 0.6, 10.0)
    return Episode(robot, trajectory, q0, 0.02, duration)


@pytest.mark.parametrize("case", sorted(FAILURES))
def test_a_failing_backend_stops_its_run_after_k_steps(case: str) -> None:
    outcome, message = FAILURES[case]
    backend = Misbehaving()
    backend.outcome = outcome
    result = simulate(_episode(), Controller("bad", [], backend))
    assert result.steps == FAIL_AT
    assert result.error_message is not None
    assert result.error_message.startswith(f"step {FAIL_AT}: ")
    assert re.search(message, result.error_message), result.error_message
    assert np.all(np.isfinite(result.q)) and np.all(np.isfinite(result.qdot))
    assert "\n" not in result.error_message


def test_keyboard_interrupt_from_a_plugin_stays_an_interrupt() -> None:
    backend = Misbehaving()
    backend.outcome = KeyboardInterrupt()
    with pytest.raises(KeyboardInterrupt):
        simulate(_episode(), Controller("bad", [], backend))


class RaisingFilter(TaskFilter):
    """Raises at its FAIL_AT-th call."""

    def __init__(self) -> None:
        self.calls = 0

    def apply(self, state: KinematicState, xdot: np.ndarray) -> Any:
        self.calls += 1
        if self.calls > FAIL_AT:
            raise MemoryError("filter")
        return xdot, type("Report", (), {"p": 0.0, "active": False})()


def test_a_raising_filter_stops_the_run() -> None:
    result = simulate(_episode(), Controller("f", [RaisingFilter()], PseudoInverseBackend()))
    assert result.steps == FAIL_AT and "a plugin raised MemoryError: filter" in str(
        result.error_message
    )


class BrokenBody(IdealPlant):
    """The ideal body for FAIL_AT periods, then raises or returns ``BrokenBody.outcome``."""

    outcome: Any = None

    def reset(self, robot: Any, q0: np.ndarray, dt: float) -> None:
        super().reset(robot, q0, dt)
        self.calls = 0

    def advance(self, q: np.ndarray, qdot: np.ndarray) -> PlantStep:
        self.calls += 1
        step = super().advance(q, qdot)
        if self.calls <= FAIL_AT:
            return step
        if isinstance(self.outcome, BaseException):
            raise self.outcome
        field, value = self.outcome
        return step._replace(**{field: value})


#: What the plant's body does after FAIL_AT periods, and the message the run keeps.
PLANT_FAILURES: dict[str, tuple[Any, str]] = {
    "ValueError": (ValueError("integration"), "a plugin raised ValueError: integration"),
    "SystemExit": (SystemExit(4), "a plugin raised SystemExit: 4"),
    "NaN q": (("q", np.array([0.1, np.nan])), "the plant returned q containing NaN or inf"),
    "inf qdot": (("qdot", np.array([np.inf, 0.0])), "the plant returned qdot containing NaN"),
    "wrong shape q": (("q", np.zeros(3)), r"returned q of type ndarray and shape \(3,\); expected"),
    "list qdot": (("qdot", [0.0, 0.0]), r"returned qdot of type list; expected a float array"),
}


@pytest.mark.parametrize("case", sorted(PLANT_FAILURES))
def test_a_failing_plant_stops_its_run_with_its_steps_kept(case: str) -> None:
    outcome, message = PLANT_FAILURES[case]
    body = BrokenBody()
    body.outcome = outcome
    episode = _episode()
    plain = simulate(episode, Controller("p", [], PseudoInverseBackend()))
    result = simulate(
        episode, Controller("p", [], PseudoInverseBackend()), plant=PlantChain([body])
    )
    # The period after step FAIL_AT fails: FAIL_AT + 1 steps recorded, as the ideal plant's.
    assert result.steps == FAIL_AT + 1
    assert result.error_message is not None and "\n" not in result.error_message
    assert result.error_message.startswith(f"step {FAIL_AT + 1}: ")
    assert re.search(message, result.error_message), result.error_message
    np.testing.assert_array_equal(result.q, plain.q[: FAIL_AT + 1])
    np.testing.assert_array_equal(result.qdot, plain.qdot[: FAIL_AT + 1])
    assert np.all(np.isfinite(result.q)) and np.all(np.isfinite(result.qdot_actual))


def test_a_plant_interrupt_stays_an_interrupt() -> None:
    body = BrokenBody()
    body.outcome = KeyboardInterrupt()
    with pytest.raises(KeyboardInterrupt):
        simulate(_episode(), Controller("p", [], PseudoInverseBackend()), plant=PlantChain([body]))


def test_the_default_plant_is_the_euler_step_of_the_robot() -> None:
    episode = _episode()
    plain = simulate(episode, Controller("p", [], PseudoInverseBackend()))
    again = simulate(
        episode, Controller("p", [], PseudoInverseBackend()), plant=PlantChain([IdealPlant()])
    )
    np.testing.assert_array_equal(plain.q, again.q)
    # q_{k+1} = q_k + q̇_k dt, exactly
    np.testing.assert_array_equal(plain.q[1:], plain.q[:-1] + plain.qdot[:-1] * episode.dt)


GOOD = tiny_run(
    ["name: bad\nbackend: {type: misbehaving}", "name: good\nbackend: {type: pinv}"],
    more=experiment(["name: good\nbackend: {type: pinv}"], name="B"),
)


@pytest.mark.parametrize("case", ["RuntimeError", "SystemExit", "wrong shape"])
def test_run_keeps_every_other_run_and_exits_2(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(registry._cache, (registry.BACKENDS, "misbehaving"), Misbehaving)
    monkeypatch.setattr(Misbehaving, "outcome", FAILURES[case][0])
    config = tmp_path / "c.yaml"
    config.write_text(GOOD)
    out = tmp_path / "out"
    status = main(["run", str(config), "--out", str(out), "--quiet", "--no-figures"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and err[0].startswith(f"otmm-qp: error: A/clik/bad: step {FAIL_AT}: ")
    rows = list(csv.DictReader((out / "summary.csv").read_text().splitlines()))
    assert [(r["experiment"], r["controller"], r["steps"], r["completed"]) for r in rows] == [
        ("A", "bad", str(FAIL_AT), "False"),
        ("A", "good", "20", "True"),
        ("B", "good", "20", "True"),
    ]
    assert (out / "A" / "clik" / "bad.csv").is_file() and (out / "report.html").is_file()


def test_a_failing_plant_keeps_every_other_run_and_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(registry._cache, (registry.PLANTS, "broken"), BrokenBody)
    monkeypatch.setattr(BrokenBody, "outcome", RuntimeError("servo bus"))
    config = tmp_path / "c.yaml"
    config.write_text(
        GOOD.replace(
            "backend: {type: misbehaving}", "backend: {type: pinv}\n        plant: {type: broken}"
        )
    )
    out = tmp_path / "out"
    status = main(["run", str(config), "--out", str(out), "--quiet", "--no-figures"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1, err
    message = f"step {FAIL_AT + 1}: a plugin raised RuntimeError: servo bus"
    assert err[0] == f"otmm-qp: error: A/clik/bad: {message}"
    rows = list(csv.DictReader((out / "summary.csv").read_text().splitlines()))
    assert [(r["experiment"], r["controller"], r["steps"], r["completed"]) for r in rows] == [
        ("A", "bad", str(FAIL_AT + 1), "False"),
        ("A", "good", "20", "True"),
        ("B", "good", "20", "True"),
    ]


def test_study_stores_every_episode_and_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(registry._cache, (registry.BACKENDS, "misbehaving"), Misbehaving)
    monkeypatch.setattr(Misbehaving, "outcome", RuntimeError("boom"))
    study = {
        "name": "bad",
        "dt": 0.05,
        "duration": {"extra": 0.2},
        "reference": {"enabled": False},  # counts the controllers' episodes only
        "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
        "generators": [{"type": "near_singular", "count": 2, "duration": [1.0, 1.5]}],
        "controllers": [
            {"name": "bad", "backend": {"type": "misbehaving"}},
            {"name": "good", "backend": {"type": "pinv"}},
        ],
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(study))
    out = tmp_path / "out"
    status = main(["study", str(path), "--out", str(out), "--quiet", "--workers", "1"])
    err = capsys.readouterr().err
    assert status == 2, err
    assert "2 of 4 episodes failed" in err
    table = read_episodes(out)
    assert table is not None
    rows = sorted(table.to_pylist(), key=lambda r: (r["controller"], r["task_index"]))
    assert [(r["controller"], r["status"]) for r in rows] == [
        ("bad", "stopped"), ("bad", "stopped"), ("good", "ok"), ("good", "ok")
    ]  # fmt: skip
    assert all(
        str(r["error_message"]).startswith(f"step {FAIL_AT}: a plugin raised") for r in rows[:2]
    )

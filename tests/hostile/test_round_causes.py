"""Root causes of the held-out hostile rounds (issue 41), each through the CLI: one line, exit 2
(or a clean run), no traceback, no warning; and the preview QP's size bound."""

from __future__ import annotations

import math
import sys
import warnings
from importlib import metadata
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from otmm_qp.cli import main
from otmm_qp.exceptions import ParameterError
from otmm_qp.plants.declaration import PlantDeclaration, combine
from otmm_qp_controllers.preview.knots import BYTES_PER_ENTRY, MAX_QP_BYTES, KnotGrid
from tests.cli_errors import refusal_text
from tests.factories import tiny_run
from tests.test_plugins import patch_entry_points

CONFIG = tiny_run(["name: C\nbackend: {type: pinv}"], duration=0.1)


def _cli(
    tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str]
) -> tuple[int, list[str], list[warnings.WarningMessage]]:
    """Run ``text`` as a config: (status, stderr lines, warnings raised).

    A refusal (status 2) is checked by the refusal rule and given as one line (its text).
    """
    config = tmp_path / "c.yaml"
    config.write_text(text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status = main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    if status == 2:
        return status, [refusal_text(err)], caught
    return status, err.strip().splitlines(), caught


@given(st.lists(st.floats(0.0, 1e300), min_size=1, max_size=4))
def test_declared_noise_is_the_root_sum_of_squares_without_overflow(noises: list[float]) -> None:
    declared = combine(PlantDeclaration(noise=n) for n in noises).noise
    assert math.isfinite(declared)
    assert max(noises) <= declared <= math.fsum(noises)  # ‖σ‖∞ ≤ ‖σ‖₂ ≤ ‖σ‖₁
    if max(noises) < 1e150:  # where the squares are finite: the plain formula
        assert declared == pytest.approx(math.sqrt(math.fsum(n * n for n in noises)), rel=1e-12)


def test_large_finite_sensor_noise_behind_a_rate_limit_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: ``noise**2`` overflowed in Python floats (OverflowError traceback)."""
    plant = (
        "    plant: [{type: rate_limit, acceleration: 10.0}, {type: sensor, noise: 1.0e+200},"
        " {type: sensor, noise: 1.0e+200}]\n    controllers:"
    )
    status, err, _ = _cli(tmp_path, CONFIG.replace("    controllers:", plant), capsys)
    assert status == 0, err


def test_a_plugin_whose_import_calls_sys_exit_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: SystemExit escaped the registry's ``except Exception`` (status 3, no line)."""
    (tmp_path / "exiting_plugin.py").write_text("import sys\nsys.exit(3)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "exiting_plugin", raising=False)
    entry = metadata.EntryPoint("exiting", "exiting_plugin:Backend", "otmm_qp.backends")
    patch_entry_points(monkeypatch, [entry])
    text = CONFIG.replace("backend: {type: pinv}", "backend: {type: exiting}")
    status, err, _ = _cli(tmp_path, text, capsys)
    assert status == 2
    assert len(err) == 1 and "exiting" in err[0] and "sys.exit(3)" in err[0], err


def test_huge_q0_on_a_planar_arm_is_one_line_without_warnings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: six RuntimeWarning lines (overflow in the forward kinematics) before the line."""
    text = CONFIG.replace("q0: [0.927, -2.5]", "q0: [1e308, 1e308]")
    status, err, caught = _cli(tmp_path, text, capsys)
    assert status == 2 and len(err) == 1 and "experiments.0.q0" in err[0], err
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


def test_a_3d_circle_centre_on_a_planar_arm_names_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: "operands could not be broadcast together with shapes (2,) (3,)"."""
    text = CONFIG.replace("centre: [1.2, 0.0]", "centre: [1.2, 0.0, 0.3]")
    status, err, _ = _cli(tmp_path, text, capsys)
    assert status == 2 and len(err) == 1, err
    assert "trajectory.centre" in err[0] and "2 coordinates" in err[0]
    assert "broadcast" not in err[0]


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        # the case: an ArrayMemoryError traceback (17.8 PiB) or no answer in 60 s
        ("horizon: 1.0e+6, knots: 1000000000, fine_steps: 1000000", "knots: must be an integer"),
        ("horizon: 1000, knots: 5000, fine_steps: 4", r"knots: 5000 segments × 2 joints need"),
    ],
    ids=["issue", "memory"],
)
def test_an_oversized_preview_qp_is_one_line_before_compute(
    params: str, pattern: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = CONFIG.replace("backend: {type: pinv}", f"backend: {{type: preview, {params}}}")
    text = text.replace("period: 10.0}", "period: 10.0, turns: 200}")  # known far enough ahead
    status, err, _ = _cli(tmp_path, text, capsys)
    assert status == 2 and len(err) == 1, err
    assert pattern in err[0] and ("MiB" in err[0] or "memory" not in err[0]), err
    assert not (tmp_path / "out" / "summary.csv").exists()


@pytest.mark.parametrize("joints", [1, 2, 7, 30])
def test_preview_memory_bound_is_exact_at_its_edge(joints: int) -> None:
    """The largest K that fits is accepted, K + 1 refused (the bound of the docstring)."""
    largest = math.isqrt(MAX_QP_BYTES // BYTES_PER_ENTRY) // joints
    KnotGrid.check_memory(largest, joints)
    with pytest.raises(ParameterError, match=r"knots: .*GiB|knots: .*MiB") as refused:
        KnotGrid.check_memory(largest + 1, joints)
    assert f"at most {largest} segments on {joints} joints" in str(refused.value)

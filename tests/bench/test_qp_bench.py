"""benchmarks/bench_qp_session.py runs at a tiny size and prints every row (no timing asserted)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

from tests.factories import ROOT, load_script

SCRIPT = ROOT / "benchmarks" / "bench_qp_session.py"


def _script(path: Path) -> ModuleType:
    """The benchmark script at ``path`` imported as a module."""
    return load_script(str(path.relative_to(ROOT)))


def test_bench_qp_session_prints_every_row(capsys: pytest.CaptureFixture[str]) -> None:
    module = _script(SCRIPT)
    assert module.main(["--steps", "4", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    for row in (
        "qp (default: daqp session, fast path)",
        "qp (daqp session, QP every step)",
        "otmm+qp (default)",
        "otmm+qp (daqp session, QP every step)",
        "qp+barrier (default)",
        "qp+barrier (QP every step)",
    ):
        assert row in out
    if importlib.util.find_spec("pink") is not None:
        assert "pink (daqp)" in out and "skipped" not in out


def test_bench_preview_cpu_prints_every_preview_row(capsys: pytest.CaptureFixture[str]) -> None:
    from otmm_qp.bench.pipelines import PREVIEWS, REFERENCE

    module = _script(SCRIPT.with_name("bench_preview_cpu.py"))
    assert module.main(["--steps", "6", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    for row in (REFERENCE, *(label for label, _, _ in PREVIEWS)):
        assert f"| {row} |" in out
    rows = [line for line in out.splitlines() if line.startswith("| ") and "µs" not in line]
    assert len(rows) == 1 + len(PREVIEWS)
    for line in rows:
        median, p99, worst, wall_median, wall_p99 = (float(c) for c in line.split("|")[2:7])
        assert 0 < median <= p99 <= worst
        assert 0 < wall_median <= wall_p99
    from otmm_qp.bench.pipelines import DEPLOYABLE

    assert f"{DEPLOYABLE}: CPU median" in out


def test_bench_preview_cpu_deployable_times_pink_and_the_deployable_row_only(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from otmm_qp.bench.pipelines import DEPLOYABLE, REFERENCE

    module = _script(SCRIPT.with_name("bench_preview_cpu.py"))
    assert module.main(["--deployable", "--steps", "6", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| ") and "µs" not in line]
    assert [row.split("|")[1].strip() for row in rows] == [REFERENCE, DEPLOYABLE]
    assert f"{DEPLOYABLE}: CPU median" in out


def test_profile_preview_charges_every_phase_once(capsys: pytest.CaptureFixture[str]) -> None:
    """The phases' times are disjoint: with what is left they make up the step's CPU time."""
    from otmm_qp.bench.pipelines import DEPLOYABLE

    module = _script(SCRIPT.with_name("profile_preview.py"))
    assert module.main(["--row", DEPLOYABLE, "--steps", "12", "--rounds", "1"]) == 0
    out = capsys.readouterr().out
    head, *lines = out.splitlines()
    per_step = float(head.split(" steps, ")[1].split(" µs")[0])
    cells = {
        line.split("|")[1].strip(): float(line.split("|")[2])
        for line in lines
        if line.startswith("| ") and "µs" not in line
    }
    for phase in ("knots' FK + Jacobians", "QP assembly (Hessian, gradient)", "solver solve"):
        assert cells[phase] > 0, phase
    rest = cells.pop("the rest (state, filters, shift, clip, Python)")
    assert rest >= -1  # rounding of the printed µs
    assert abs(sum(cells.values()) + rest - per_step) <= len(cells) + 1

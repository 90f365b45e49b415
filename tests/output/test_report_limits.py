"""The run report judges every run against the arm's own joint limits; ties are ties."""

from __future__ import annotations

import math
from pathlib import Path

from otmm_qp.cli import main
from otmm_qp.output.report import REPORT_COLUMNS, Row, best_values, limit_note, ranking
from tests.factories import DLS_ITEM, PINV_ITEM, ur5_wrist_run


def _row(controller: str, experiment: str = "e", **values: float) -> Row:
    full = {key: 1.0 for key, _, _ in REPORT_COLUMNS}
    full.update({"position_violations": 0.0, "velocity_violations": 0.0})
    full.update(values)
    return Row(experiment, "clik", controller, full, "", False, steps=500)


def test_a_limit_breaking_run_is_never_best_and_ranks_after_the_keepers() -> None:
    rows = [
        _row("pinv", rms_error=0.001, max_error_window=0.001, velocity_violations=246),
        _row("qp", rms_error=0.01, max_error_window=0.02),
        _row("dls", rms_error=0.02, max_error_window=0.01),
    ]
    best = best_values(rows)
    assert best["rms_error"] == 0.01  # pinv's 0.001 breaks the speed limit: not eligible
    order = [name for name, _, _ in ranking(rows)]
    assert order[-1] == "pinv" and set(order[:2]) == {"qp", "dls"}
    assert limit_note(rows, "pinv") == "broken: speed on 246 of 500 steps in 1 of 1 scenarios"
    assert limit_note(rows, "qp") == "kept"
    assert not rows[0].eligible and rows[0].breaks_limits


def test_a_shared_best_value_is_a_tie_not_best() -> None:
    rows = [_row("a", rms_error=0.5), _row("b", rms_error=0.5), _row("c", rms_error=0.7)]
    assert math.isnan(best_values(rows)["rms_error"])
    rows.append(_row("d", rms_error=0.4))
    assert best_values(rows)["rms_error"] == 0.4


ARM = ur5_wrist_run("limits", [PINV_ITEM, DLS_ITEM], motion=4.0, duration=5.0)


def test_run_report_flags_the_unfiltered_wrist_crossing(tmp_path: Path) -> None:
    """The UR5 wrist crossing: pinv passes its joints' speed limits; the report says so."""
    config = tmp_path / "limits.yaml"
    config.write_text(ARM, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet"]) == 0
    report = (out / "report.md").read_text(encoding="utf-8")
    line = next(ln for ln in report.splitlines() if ln.startswith("| pinv (breaks the speed"))
    assert "**" not in line  # no best mark on a limit-breaking run
    ranking_lines = report[report.index("## Ranking") :].splitlines()
    ranked = [
        ln.split("|")[2].strip() for ln in ranking_lines if ln.startswith("| ") and "rank" not in ln
    ]
    assert ranked[-1] == "pinv"
    assert (
        "broken: speed on"
        in ranking_lines[[i for i, ln in enumerate(ranking_lines) if "| pinv |" in ln][0]]
    )

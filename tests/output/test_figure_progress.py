"""``otmm-qp run`` says when each experiment's figures are drawn (and nothing with --quiet)."""

from __future__ import annotations

from pathlib import Path

import pytest

from otmm_qp.cli import main

CONFIG = """\
name: progress
dt: 0.05
loop_modes: [clik, newton]
experiments:
  - name: arc
    robot: {type: planar, link_lengths: [1.0, 0.8]}
    q0: [0.3, 0.5]
    trajectory: {type: circle, centre: [1.0, 0.6], radius: 0.2, period: 2.0}
    controllers:
      - name: dls
        backend: {type: dls, damping: 0.05}
"""


@pytest.mark.parametrize("quiet", [False, True])
def test_one_progress_line_per_experiment_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], quiet: bool
) -> None:
    config = tmp_path / "p.yaml"
    config.write_text(CONFIG, encoding="utf-8")
    argv = ["run", str(config), "--out", str(tmp_path / "out"), "--figures", "all"]
    assert main(argv + ["--quiet"] * quiet) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "figures:" in ln]
    assert lines == [] if quiet else (len(lines) == 1 and "arc: 2 comparisons + 2 runs" in lines[0])
    assert len(list((tmp_path / "out").rglob("*.png"))) == 4

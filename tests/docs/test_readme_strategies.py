"""The "Which strategy for which task" table is what the shipped commands print.

The README names the two commands and links the table, which with its sentences is the section
"Which strategy for which task" of docs/strategies.md (``SOURCE``). Runs the two commands on the
shipped reduced study (``strategies_readme.yaml``) and checks the table line by line, and the
claims of the sentences around it against the fronts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from otmm_qp.cli import main
from otmm_qp.studies.group_verdict import kind_fronts, kind_rows, kinds_table
from otmm_qp.studies.limit_keeping import limit_breaks
from otmm_qp.studies.report import load_rows
from otmm_qp.studies.spec import load_study, plan_study

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "configs" / "studies"
SOURCE = ROOT / "docs" / "strategies.md"  # the section the README links


def _readme_section() -> str:
    text = SOURCE.read_text(encoding="utf-8")
    start = text.index("\n## Which strategy for which task\n")
    return text[start : text.index("\n## ", start + 1)]


def _readme_table(section: str) -> list[str]:
    start = section.index("| task kind (tasks) |")
    return f"{section}\n\n"[start : f"{section}\n\n".index("\n\n", start)].splitlines()


def test_readme_strategies_table_is_regenerated(tmp_path: Path, capsys) -> None:
    section = _readme_section()
    readme_file = "configs/studies/strategies_readme.yaml"
    assert f"otmm-qp study {readme_file} --out results/strategies-readme --highlight sigma_lm" in (
        section
    )
    assert "otmm-qp study verdict results/strategies-readme --ours sigma_lm --kinds" in section
    out = tmp_path / "strategies-readme"
    command = ["study", str(ROOT / readme_file), "--out", str(out), "--highlight", "sigma_lm"]
    assert main([*command, "--workers", "1", "--quiet"]) == 0, capsys.readouterr().err
    assert "**sigma_lm** (ours)" in (out / "study_report.md").read_text(encoding="utf-8")
    printed = tmp_path / "kinds.md"
    verdict = ["study", "verdict", str(out), "--ours", "sigma_lm", "--kinds"]
    assert main([*verdict, "--out", str(printed)]) == 0
    table = _readme_table(printed.read_text(encoding="utf-8"))
    assert _readme_table(section) == table

    # The sentences: sizes, and what the fronts say.
    config = load_study(STUDIES / "strategies_readme.yaml")
    tasks = len({(e.robot, e.generator, e.task_index) for e in plan_study(config).episodes})
    flat = " ".join(section.split())
    assert f"({tasks} tasks × {len(config.controllers)} rows" in flat
    counts = {g.type: g.count for g in config.generators}
    assert counts["held_target"] == counts["random_reachable"] == 4
    assert "(4 tasks per arm for held and random targets)" in flat
    for name, size in (("strategies_arms.yaml", 192), ("strategies_planar.yaml", 136)):
        plan = plan_study(load_study(STUDIES / name))
        assert len({(e.robot, e.generator, e.task_index) for e in plan.episodes}) == size
    rows = load_rows(out)[1]
    fronts = {g.group: g for g in kind_fronts(rows)}
    assert kinds_table(list(fronts.values()), "sigma_lm", kind_rows(rows)) == table
    broken, total = limit_breaks(kind_rows(rows)["singular crossings"], "OTMM-directional+pinv")
    assert (
        f"OTMM-directional + pinv is the most accurate but breaks the arm's speed or position "
        f"limits on {broken} of the {total} tasks" in flat
    )
    # every pick that failed the arm's speed or position limits says so in its cell
    for line in table[2:]:
        kind = line.split("|")[1].strip().rsplit(" (", 1)[0]
        accurate = line.split("|")[2].strip().split(" (", 1)[0]
        broken, total = limit_breaks(kind_rows(rows)[kind], accurate)
        assert (f"(limits broken on {broken} of {total} tasks)" in line) == (broken > 0), line
    assert all(g.best_on_all is None for g in fronts.values())  # none on top of all three
    assert all("sigma_lm" not in (g.best_on(0), g.best_on(1)) for g in fronts.values())
    assert all(g.best_on(1) == "dls_error" for g in fronts.values())  # the calm end
    assert fronts["singular crossings"].best_on(0) == "OTMM-directional+pinv"
    assert fronts["reachable random"].best_on(0) == "sns"
    for kind, factor in (
        ("undecided", 2.0),
        ("unachievable (certified)", 2.0),
        ("limit-bound motion", 3.0),
        ("held targets", 3.0),
    ):
        g = fronts[kind]
        accurate, calm = g.row(str(g.best_on(0))), g.row("dls_error")
        assert accurate is not None and calm is not None
        assert accurate.medians[1] >= factor * calm.medians[1]  # "2.3 ×", "several times"
    for kind, text in (
        ("unachievable (certified)", "qp, which kept the limits on every task"),
        ("undecided", "OTMM-directional + pinv, which breaks the limits on"),
    ):
        accurate = fronts[kind].best_on(0)
        assert accurate == text.split(",")[0].replace(" + ", "+") and text in flat
        broken, total = limit_breaks(kind_rows(rows)[kind], accurate)
        assert (broken == 0) == ("kept the limits" in text)
        if broken:
            assert f"{text} {broken} of the {total}" in flat
        speeds = fronts[kind].row(accurate), fronts[kind].row("dls_error")
        assert f"at {speeds[0].medians[1] / speeds[1].medians[1]:.1f} × `dls_error`" in flat
    accurate = fronts["limit-bound motion"].best_on(0)
    broken, total = limit_breaks(kind_rows(rows)["limit-bound motion"], accurate)
    assert f"on limit-bound motion {total - broken} of {total})" in flat
    from otmm_qp.robots.pinocchio_arm import PinocchioArm

    limits = PinocchioArm(name="panda", task="pose").velocity_limits
    assert (round(float(np.min(limits)), 1), round(float(np.max(limits)), 1)) == (2.2, 2.6)
    assert "are 2.2–2.6 rad/s" in flat

"""The README's run commands that no other test ran, and the strategies table they print.

``otmm-qp run configs/strategies/paper.yaml`` (with its comparison figures, where the symlog note
once divided by zero) and ``configs/strategies/arms.yaml`` run once per module through the CLI's
``main``; every cell of the table the README links to (docs/strategies.md, "The four scenarios
in short": ``TABLE_SOURCE``) is checked against their ``summary.csv`` at the precision it
prints, and so are the numbers of the paragraph below it. An arm
cell's numbers must also hold on another machine: the table's arm experiments run again with
another OpenBLAS kernel (other floating-point rounding in every SVD and product) and with q0
moved by ±1e-13 rad, and each printed number must match every run (a chaotic run's numbers are
printed as the range ``a–b`` they span). The other
tests run the UR5 wrist replay command and a reduced ``configs/studies/arms.yaml`` (the bare
``otmm-qp`` runs in ``tests/docs/test_readme_paper_numbers.py``).
"""

from __future__ import annotations

import csv
import os
import re
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import pytest
import yaml

from otmm_qp.cli import main

ROOT = Path(__file__).resolve().parents[2]
STRATEGIES = ROOT / "configs" / "strategies"
TABLE_SOURCE = ROOT / "docs" / "strategies.md"  # the four scenarios' table and its paragraph

# README column → (config, experiment); every cell is the CLIK run.
COLUMNS = {
    "E1": ("paper", "E1"),
    "E2 (singular start)": ("paper", "E2"),
    "UR5 wrist crossing": ("arms", "ur5_wrist_pose"),
    "UR5 elbow, beyond reach": ("arms", "ur5_elbow_beyond_pose"),
}
# README row → controller name in both configs.
ROWS = {
    "RMRC (pinv)": "RMRC",
    "OTMM-cbrt (paper)": "OTMM-cbrt",
    "OTMM-bounded": "OTMM-bounded",
    "OTMM-directional": "OTMM-directional",
    "J-PARSE": "J-PARSE",
    "SNS": "SNS",
}
# The three numbers of a cell, in the README's order.
CELL_METRICS = ("max_error_window", "max_joint_speed", "max_jump")

Summary = dict[tuple[str, str, str], dict[str, str]]


def _summary(folder: Path) -> Summary:
    with (folder / "summary.csv").open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {(r["experiment"], r["loop_mode"], r["controller"]): r for r in rows}


@pytest.fixture(scope="module")
def strategies(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Summary]:
    """Both README commands, run once: ``paper`` with comparison figures, ``arms`` without.

    Reduced only in figures: the per-run PNGs of ``paper.yaml`` (108 of them, ~50 s) are drawn by
    the same code the comparison figures use and are covered by ``tests/output/test_figures.py``.
    """
    base = tmp_path_factory.mktemp("strategies")
    out: dict[str, Summary] = {}
    for name, figures in (("paper", "comparison"), ("arms", "none")):
        folder = base / name
        argv = ["run", str(STRATEGIES / f"{name}.yaml"), "--out", str(folder), "--quiet"]
        assert main([*argv, "--figures", figures]) == 0, name
        assert (folder / "summary.md").is_file() and (folder / "report.html").is_file()
        out[name] = _summary(folder)
        if name == "paper":  # one comparison figure per experiment and loop mode
            for experiment in ("E1", "E2", "E3"):
                pngs = sorted((folder / experiment).rglob("*.png"))
                assert len(pngs) >= 3, (experiment, pngs)
    return out


def _readme_table() -> dict[str, list[str]]:
    text = TABLE_SOURCE.read_text(encoding="utf-8")
    start = text.index("| strategy | E1 | E2 (singular start)")
    lines = text[start : text.index("\n\n", start)].splitlines()
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    assert header[1:] == list(COLUMNS), header
    rows = {}
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return rows


def matches_printed(value: float, printed: str) -> bool:
    """Whether ``value`` rounds to ``printed`` at the precision ``printed`` shows.

    The printed number's last digit sets the resolution: ``0.09`` means |v − 0.09| ≤ 0.005,
    ``2.3e-4`` means |v − 2.3·10⁻⁴| ≤ 0.05·10⁻⁴, ``11`` means |v − 11| ≤ 0.5. A range
    ``a–b`` (a chaotic run's: its value differs between machines) means a − ½ unit ≤ v ≤ b + ½
    unit, each end at its own resolution.
    """
    if "–" in printed:
        low, high = (Decimal(part) for part in printed.split("–"))
        slack = [Decimal(5).scaleb(n.as_tuple().exponent - 1) for n in (low, high)]  # type: ignore[operator]
        v = Decimal(repr(value))
        return low - slack[0] * Decimal("1.000001") <= v <= high + slack[1] * Decimal("1.000001")
    number = Decimal(printed)
    half_unit = Decimal(5).scaleb(number.as_tuple().exponent - 1)  # type: ignore[operator]
    return abs(Decimal(repr(value)) - number) <= half_unit * Decimal("1.000001")


@pytest.mark.parametrize(
    ("value", "printed", "expected"),
    [(0.0926, "0.09", True), (0.000233, "2.3e-4", True), (10.504, "11", True),
     (1.0, "1.0", True), (0.0101, "0.010", True), (0.0926, "0.093", True),
     (0.0926, "0.092", False), (0.000238, "2.3e-4", False), (11.6, "11", False),
     (58.44, "58–59", True), (57.5, "58–59", True), (59.49, "58–59", True),
     (57.4, "58–59", False), (59.6, "58–59", False), (0.1016, "0.10–0.11", True),
     (0.094, "0.10–0.11", False)],
)  # fmt: skip
def test_printed_precision_rule(value: float, printed: str, expected: bool) -> None:
    assert matches_printed(value, printed) is expected


def _check_table(strategies: dict[str, Summary], configs: tuple[str, ...]) -> None:
    """Every cell of the README table whose column comes from one of ``configs``."""
    table = _readme_table()
    assert set(table) == set(ROWS), set(table) ^ set(ROWS)
    for row, cells in table.items():
        for cell, (config, experiment) in zip(cells, COLUMNS.values(), strict=True):
            if config not in configs:
                continue
            record = strategies[config][(experiment, "clik", ROWS[row])]
            where = (row, experiment, cell)
            assert record["outcome"] == "completed", where
            if cell == "blow-up":
                assert record["blow_up"] == "True", where
                continue
            assert record["blow_up"] == "False", where
            printed = [part.strip() for part in cell.split("/")]
            assert len(printed) == len(CELL_METRICS), where
            for metric, text in zip(CELL_METRICS, printed, strict=True):
                value = float(record[metric])
                assert matches_printed(value, text), (*where, metric, value)


def test_readme_strategies_table_is_regenerated(strategies: dict[str, Summary]) -> None:
    _check_table(strategies, ("paper", "arms"))


#: Rounding-level changes another machine makes: (OPENBLAS_CORETYPE or "", q0 offset [rad]).
#: Prescott's kernels round differently from the Haswell/Zen and Sandybridge ones on x86-64
#: (ignored where OpenBLAS is not the dynamic-architecture build: the run is then repeated).
VARIANTS = (("Prescott", 0.0), ("", 1e-13), ("", -1e-13))


def _table_config(name: str, offset: float, folder: Path) -> Path:
    """The README table's CLIK experiments of ``configs/strategies/NAME.yaml``, q0 + offset."""
    data = yaml.safe_load((STRATEGIES / f"{name}.yaml").read_text(encoding="utf-8"))
    wanted = {experiment for config, experiment in COLUMNS.values() if config == name}
    data["experiments"] = [e for e in data["experiments"] if e["name"] in wanted]
    data["loop_modes"] = ["clik"]
    for experiment in data["experiments"]:
        experiment.pop("loop_modes", None)
        experiment["q0"] = [q + offset for q in experiment["q0"]]
        experiment["controllers"] = [
            c for c in experiment["controllers"] if c["name"] in ROWS.values()
        ]
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize(("kernel", "offset"), VARIANTS)
def test_readme_strategies_table_holds_on_another_machine(
    tmp_path: Path, kernel: str, offset: float
) -> None:
    """Each printed arm number holds under another BLAS kernel and a 1e-13 rad move of q0.

    The planar columns (E1, E2) are left out: the planar arms' runs are bit-identical under
    every OpenBLAS kernel and with numpy's SIMD limited to x86-64-v2, and E2 starts at the
    exact singularity q0 = [0, 0], which every machine holds exactly (moving it by 1e-13 rad
    is another task: J-PARSE's window error becomes 0.0103 m).
    """
    runs: dict[str, Summary] = {}
    for name in ("arms",):
        config, folder = _table_config(name, offset, tmp_path), tmp_path / f"{name}-out"
        argv = ["run", str(config), "--out", str(folder), "--figures", "none", "--quiet"]
        if kernel:  # the kernel is chosen when OpenBLAS loads: a fresh process
            env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
            code = "import sys; from otmm_qp.cli import main; sys.exit(main(sys.argv[1:]))"
            done = subprocess.run([sys.executable, "-c", code, *argv], env=env, check=False)
            assert done.returncode == 0
        else:
            assert main(argv) == 0
        runs[name] = _summary(folder)
    _check_table(runs, tuple(runs))


def test_readme_no_strategy_dominates_paragraph(strategies: dict[str, Summary]) -> None:
    """The numbers of "No strategy dominates" (all but the µs timings of the benchmark)."""
    text = " ".join(TABLE_SOURCE.read_text(encoding="utf-8").split())
    found = re.search(
        r"removes the E2 spike \(([0-9.]+) rad/s in every loop mode\) and keeps cbrt's E1 window "
        r"error \(([0-9.]+) ×\).*?UR5 wrist peak ([0-9.]+) rad/s, beyond-reach jump ([0-9.]+) "
        r"rad/s\), paying about ([0-9.]+) × cbrt's window error on E1",
        text,
    )
    assert found, "docs/strategies.md's 'No strategy dominates' paragraph changed its form"
    e2_peak, ratio, wrist, jump, directional = found.groups()
    paper, arms = strategies["paper"], strategies["arms"]
    for mode in ("feedforward", "clik", "newton"):
        peak = float(paper[("E2", mode, "OTMM-bounded")]["max_joint_speed"])
        assert matches_printed(peak, e2_peak), (mode, peak)

    def window(controller: str) -> float:
        return float(paper[("E1", "clik", controller)]["max_error_window"])

    assert matches_printed(window("OTMM-bounded") / window("OTMM-cbrt"), ratio)
    assert matches_printed(window("OTMM-directional") / window("OTMM-cbrt"), directional)
    record = arms[("ur5_wrist_pose", "clik", "OTMM-directional")]
    assert matches_printed(float(record["max_joint_speed"]), wrist)
    record = arms[("ur5_elbow_beyond_pose", "clik", "OTMM-directional")]
    assert matches_printed(float(record["max_jump"]), jump)


def test_ur5_wrist_replay_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``otmm-qp run configs/arms/ur5_wrist.yaml --replay`` writes the page the README names."""
    out = tmp_path / "ur5_wrist"
    argv = ["run", str(ROOT / "configs/arms/ur5_wrist.yaml"), "--replay", "--out", str(out)]
    assert main([*argv, "--figures", "none", "--quiet"]) == 0, capsys.readouterr().err
    page = out / "replays" / "ur5_wrist_pose-clik.html"
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "`results/ur5_wrist/replays/ur5_wrist_pose-clik.html`" in text
    assert page.is_file() and page.stat().st_size > 10_000
    assert "replays/ur5_wrist_pose-clik.html" in (out / "report.html").read_text(encoding="utf-8")


def test_arms_study_command_reduced(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``otmm-qp study configs/studies/arms.yaml`` on a reduced copy: one task per generator.

    The shipped file is copied with every generator's ``count`` set to 1 (22,000 → 110
    episodes: 2 robots × 5 tasks × (10 controllers after grid expansion + the reference, the
    count the README states next to the command)); nothing else changes.
    """
    data = yaml.safe_load((ROOT / "configs/studies/arms.yaml").read_text(encoding="utf-8"))
    for generator in data["generators"]:
        generator["count"] = 1
    config = tmp_path / "arms.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    out = tmp_path / "arms-study"
    status = main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"])
    assert status in (0, 2), capsys.readouterr().err  # 2: an episode stored as an error row
    from otmm_qp.studies.storage import read_episodes

    table = read_episodes(out)
    assert table is not None
    rows = table.to_pylist()
    assert len({r["task_id"] for r in rows}) == 2 * 5
    controllers = {r["controller"] for r in rows}
    stated = re.search(
        r"UR5 \+ Panda, [\d,]+ tasks x \((\d+) controllers \+ oracle\)",
        (ROOT / "README.md").read_text(encoding="utf-8"),
    )
    assert stated, "the README's arms study comment changed its form"
    assert "oracle" in controllers and len(controllers) == int(stated.group(1)) + 1
    assert len(rows) == 10 * len(controllers)
    assert (out / "study_report.md").is_file() and (out / "study_report.html").is_file()
    assert main(["report", str(out)]) == 0  # `otmm-qp report DIR` on a study folder

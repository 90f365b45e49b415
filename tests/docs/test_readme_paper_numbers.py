"""The numbers in the README's "What the paper reproduction finds", from the embedded config.

The module runs the README's first command, the bare ``otmm-qp`` (no command = ``run`` of the
embedded ``paper.yaml`` into ``results/paper``), once in a temporary working directory, reduced
by ``--figures none`` (the comparison figures are drawn in ``tests/docs/test_readme_runs.py``), and
reads its ``summary.csv``. ``tests/docs/test_paper_claims.py`` asserts the claims (who spikes, what
orders, which verdicts) with loose bounds; this file checks each number the section prints
against the metric it comes from, at the README's printed precision (``matches_printed``: the
last printed digit is the resolution) or, for "under X" / "> X", as the bound it states. Each
entry is found in the whitespace-normalised section by a regex with one group per number, so a
reworded sentence fails loudly instead of going unchecked.
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from otmm_qp.cli import main
from tests.docs.test_readme_runs import matches_printed

ROOT = Path(__file__).resolve().parents[2]
MODES = ("feedforward", "clik", "newton")


Summary = dict[str, dict[str, str]]  # "experiment/loop_mode/controller" → summary.csv row


@pytest.fixture(scope="module")
def paper(tmp_path_factory: pytest.TempPathFactory) -> Summary:
    """``otmm-qp`` (as ``run --figures none --quiet``) in a fresh directory: ``results/paper``."""
    cwd = tmp_path_factory.mktemp("bare")
    before = Path.cwd()
    os.chdir(cwd)
    try:
        assert main(["run", "--figures", "none", "--quiet"]) == 0
    finally:
        os.chdir(before)
    out = cwd / "results" / "paper"
    for name in ("summary.csv", "summary.md", "claims.md", "report.html"):
        assert (out / name).is_file(), name
    with (out / "summary.csv").open(encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {f"{r['experiment']}/{r['loop_mode']}/{r['controller']}": r for r in rows}


def test_bare_command_reproduces_the_paper_into_results_paper(paper: Summary) -> None:
    assert {run.split("/")[0] for run in paper} >= {"E1", "E2", "E3"}
    assert {run.split("/")[1] for run in paper} == set(MODES)
    assert all(row["outcome"] == "completed" for row in paper.values())


def _section() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("## What the paper reproduction finds")
    return " ".join(text[start : text.index("\n## ", start + 5)].split())


def _metric(paper: Summary, run: str, name: str) -> float:
    assert run in paper, run
    return float(paper[run][name])


def _exponent(text: str) -> str:
    """``2·10⁻⁵`` → ``2e-5`` (the README's typeset powers of ten)."""
    superscripts = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
    mantissa, _, power = text.partition("·10")
    return f"{mantissa}e{power.translate(superscripts)}" if power else text


Value = Callable[[Summary], list[float]]


def _runs(name: str, *runs: str) -> Value:
    return lambda paper: [_metric(paper, run, name) for run in runs]


_E1_OTMM = [f"E1/clik/OTMM-{p}" for p in ("linear", "sqrt", "cbrt")]
_NUMBER = r"([0-9.]+(?:·10[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+)?)"

# (regex with one group per number, per group: (comparison, values the number must describe))
# comparison "=": every value matches the printed number; "<" / ">": every value is below / above
# it; "min" / "max": the smallest / largest value matches it.
CLAIMS: list[tuple[str, list[tuple[str, Value]]]] = [
    (
        rf"RMRC passes σ_min ≈ {_NUMBER} at t = {_NUMBER} s and its joint speed peaks at ≈ "
        rf"{_NUMBER} rad/s; OTMM with linear, sqrt and cbrt p stays under {_NUMBER} rad/s",
        [
            ("=", _runs("min_sigma", "E1/clik/RMRC")),
            ("=", _runs("t_min_sigma", "E1/clik/RMRC")),
            ("=", _runs("max_joint_speed", "E1/clik/RMRC")),
            ("<", _runs("max_joint_speed", *_E1_OTMM)),
        ],
    ),
    (
        rf"σ_min never drops below σ_S \(min {_NUMBER}\)",
        [
            (
                "min",
                lambda paper: [
                    float(row["min_sigma"])
                    for run, row in paper.items()
                    if run.startswith("E1/feedforward/")
                ],
            )
        ],
    ),
    (
        rf"RMRC never spikes \(peak {_NUMBER} rad/s\) but changes speed by {_NUMBER} rad/s in one "
        rf"step .*? OTMM with cbrt p \({_NUMBER} rad/s\)",
        [
            ("=", _runs("max_joint_speed", "E1/newton/RMRC")),
            ("=", _runs("max_jump", "E1/newton/RMRC")),
            ("=", _runs("max_jump", "E1/newton/OTMM-cbrt")),
        ],
    ),
    (
        rf"\(E1, CLIK, cbrt: {_NUMBER} m at σ_S = 0.01 up to {_NUMBER} m at 0.1\), but the "
        rf"largest one-step joint-speed change grows from {_NUMBER} to {_NUMBER} rad/s",
        [
            ("=", _runs("max_error_window", "E1_sigma_s/clik/OTMM-cbrt-0.01")),
            ("=", _runs("max_error_window", "E1_sigma_s/clik/OTMM-cbrt-0.1")),
            ("=", _runs("max_jump", "E1_sigma_s/clik/OTMM-cbrt-0.1")),
            ("=", _runs("max_jump", "E1_sigma_s/clik/OTMM-cbrt-0.01")),
        ],
    ),
    (
        rf"\(peak {_NUMBER} rad/s in CLIK\), unlike the paper's figure",
        [("=", _runs("max_joint_speed", "E1/clik/SRI"))],
    ),
    (
        rf"spikes to {_NUMBER}–{_NUMBER} rad/s just after the start in every loop mode\. Linear p "
        rf"\(gain bounded by 1/σ_S\) stays under {_NUMBER} rad/s\. RMRC blows up \(> "
        rf"{_NUMBER} rad/s\)",
        [
            ("min", _runs("max_joint_speed", *(f"E2/{m}/OTMM-cbrt" for m in MODES))),
            ("max", _runs("max_joint_speed", *(f"E2/{m}/OTMM-cbrt" for m in MODES))),
            ("<", _runs("max_joint_speed", *(f"E2/{m}/OTMM-linear" for m in MODES))),
            (">", _runs("max_joint_speed", *(f"E2/{m}/RMRC" for m in MODES))),
        ],
    ),
    (
        rf"\({_NUMBER} vs {_NUMBER} rad/s in CLIK\), but its largest one-step speed change near "
        rf"the singularity \({_NUMBER} rad/s\)",
        [
            ("=", _runs("max_joint_speed", "E3/clik/OTMM-cbrt")),
            ("=", _runs("max_joint_speed", "E3/clik/RMRC")),
            ("=", _runs("max_jump", "E3/clik/OTMM-cbrt")),
        ],
    ),
]


def _holds(comparison: str, printed: str, values: list[float]) -> bool:
    number = float(_exponent(printed))
    if comparison == "=":
        return all(matches_printed(v, _exponent(printed)) for v in values)
    if comparison in ("min", "max"):
        chosen = min(values) if comparison == "min" else max(values)
        return matches_printed(chosen, _exponent(printed))
    if comparison == "<":
        return all(v < number for v in values)
    return all(v > number for v in values)


@pytest.mark.parametrize("index", range(len(CLAIMS)))
def test_paper_reproduction_numbers_in_readme(paper: Summary, index: int) -> None:
    pattern, checks = CLAIMS[index]
    found = re.search(pattern, _section())
    assert found, f"the README sentence changed its form: {pattern}"
    assert len(found.groups()) == len(checks)
    for printed, (comparison, value) in zip(found.groups(), checks, strict=True):
        values = value(paper)
        assert _holds(comparison, printed, values), (pattern[:40], printed, comparison, values)


def test_conformance_pinv_speed_in_readme(paper: Summary) -> None:
    """ "`pinv` fails E2 (N rad/s from the singular start)": the conformance suite runs paper E2 in
    CLIK with the embedded config's settings, so N is the CLIK RMRC peak of that run."""
    text = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    found = re.search(r"`pinv` fails E2 \((\d+) rad/s from the singular start", text)
    assert found, "the README's conformance sentence changed its form"
    assert matches_printed(_metric(paper, "E2/clik/RMRC", "max_joint_speed"), found.group(1))

"""The paper report leads with the answer: its first screen in Chromium shows the claims verdict.

``otmm-qp run configs/paper.yaml --figures none`` (the embedded paper config) writes
``report.html``; opened in headless Chromium at 1400 × 900 the claims verdict's heading and the
first rows of its table are inside the first screen, the evidence column wraps (no horizontal
scrolling), the claims carry no raw LaTeX, and the report stays small.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from otmm_qp.cli import main
from otmm_qp.replay.browser import Page
from tests.factories import browser_page

ROOT = Path(__file__).resolve().parents[2]
WIDTH, HEIGHT = 1400, 900


@pytest.fixture(scope="module")
def paper(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("paper") / "paper"
    argv = ["run", str(ROOT / "configs/paper.yaml"), "--out", str(out), "--figures", "none"]
    assert main([*argv, "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def browser() -> Iterator[Page]:
    with browser_page(WIDTH, HEIGHT) as page:
        yield page


def test_claims_come_first_as_text(paper: Path) -> None:
    markdown = (paper / "report.md").read_text(encoding="utf-8")
    assert markdown.index("## Claims verdict") < markdown.index("## Comparison per scenario")
    claims = (paper / "claims.md").read_text(encoding="utf-8")
    assert "\\" not in claims and "{" not in claims, "raw LaTeX in claims.md"
    assert "max ‖q̇‖∞" in claims and "5 v_nom" in claims
    html = (paper / "report.html").read_text(encoding="utf-8")
    assert html.index('id="claims"') < html.index('id="tables"')


def test_first_screen_shows_the_claims_verdict(browser: Page, paper: Path) -> None:
    browser.open((paper / "report.html").resolve().as_uri())
    geometry = browser.evaluate(
        "(() => { const h = document.getElementById('claims');"
        " const rows = document.querySelectorAll('.claims table tr');"
        " const r = rows.length > 2 ? rows[2].getBoundingClientRect() : null;"
        " return {heading: h.getBoundingClientRect().top, rows: rows.length,"
        " row_bottom: r ? r.bottom : 1e9, row_right: r ? r.right : 1e9,"
        " page_width: document.documentElement.scrollWidth, view: window.innerWidth}; })()"
    )
    assert 0 <= geometry["heading"] < HEIGHT / 3, geometry
    assert geometry["rows"] > 10, geometry  # the claims table itself, not a placeholder
    assert geometry["row_bottom"] <= HEIGHT, geometry  # its first verdicts are on screen
    assert geometry["row_right"] <= geometry["view"], geometry  # evidence readable in place
    assert geometry["page_width"] <= geometry["view"], geometry  # no horizontal scroll


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny planar study with its reference: two rows, every generator once."""
    folder = tmp_path_factory.mktemp("study")
    config = folder / "s.yaml"
    config.write_text(
        "name: first-screen\nseed: 1\ndt: 0.02\nloop_modes: [clik]\nduration: {extra: 0.2}\n"
        "success: {max_position_error: 0.02, max_joint_speed: 10.0}\n"
        "robots:\n  - {name: planar2, robot: {type: planar, link_lengths: [1.0, 0.8]}}\n"
        "generators:\n  - {type: near_singular, count: 2}\n  - {type: beyond_reach, count: 2}\n"
        "controllers:\n  - {name: dls, backend: {type: dls, damping: 0.05}}\n"
        "  - {name: qp, backend: {type: qp, solver: daqp}}\n",
        encoding="utf-8",
    )
    out = folder / "out"
    assert main(["study", str(config), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    return out


def test_study_report_first_screen_shows_the_decision(browser: Page, study: Path) -> None:
    markdown = (study / "study_report.md").read_text(encoding="utf-8")
    assert markdown.index("## Decision for the arm") < markdown.index("## Method")
    browser.open((study / "study_report.html").resolve().as_uri())
    geometry = browser.evaluate(
        "(() => { const box = document.querySelector('.verdict');"
        " const items = document.querySelectorAll('.verdict li');"
        " const last = items.length ? items[items.length - 1].getBoundingClientRect() : null;"
        " return {items: items.length, top: box ? box.getBoundingClientRect().top : 1e9,"
        " bottom: last ? last.bottom : 1e9,"
        " text: Array.from(items).map(i => i.innerText).join(' ')}; })()"
    )
    assert geometry["items"] >= 3, geometry  # the kinds of task and the accuracy line
    assert geometry["top"] < HEIGHT / 3 and geometry["bottom"] <= HEIGHT, geometry
    assert "Singular crossings" in geometry["text"], geometry

"""The replay page and report.html in a real headless Chromium, used as a person would.

Skipped only when Chromium is absent and CI is not set; in CI a missing browser fails.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from otmm_qp.cli import main
from otmm_qp.replay.browser import Page
from tests.factories import PINV_ITEM, browser_page, ur5_wrist_run

ARM = ur5_wrist_run(
    "arm",
    [
        PINV_ITEM,
        "name: otmm+dls\nfilters: [{type: otmm, sigma_s: 0.05, p: linear, corank: all}]\n"
        "backend: {type: dls, damping: 0.05}",
    ],
    motion=0.4,
)
WIDTH, HEIGHT, PANEL = 900, 640, 118  # viewport and the control panel height [px]


@pytest.fixture(scope="module")
def browser() -> Iterator[Page]:
    with browser_page(WIDTH, HEIGHT) as page:
        yield page


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("browser")
    config = folder / "arm.yaml"
    config.write_text(ARM)
    out = folder / "results"
    assert (
        main(["run", str(config), "--out", str(out), "--figures", "none", "--quiet", "--replay"])
        == 0
    )
    return out


def _image(png: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(png)) as image:
        return np.asarray(image.convert("RGB")).astype(int)


def _scene(pixels: np.ndarray) -> np.ndarray:
    """The 3-D view: above the control panel, below the title box."""
    return pixels[90 : HEIGHT - PANEL, :]


def test_replay_page_plays_in_chromium(browser: Page, results: Path) -> None:
    page = results / "replays" / "wrist-clik.html"
    browser.open(page.resolve().as_uri(), ready="window.replayReady === true")
    browser.settle(5)
    first = _image(browser.screenshot())
    assert browser.evaluate("document.querySelector('#meshcat-pane canvas').width") > 0
    scene = _scene(first)
    colours = np.unique(scene.reshape(-1, 3), axis=0).shape[0]
    assert colours > 500 and scene.std() > 10, "the 3-D canvas looks blank"
    label = browser.evaluate("document.getElementById('tlabel').textContent")
    assert label.startswith("t = 0.00 s")

    # drag the slider the way a person does: click near its right end
    box = browser.evaluate(
        "(() => { const r = document.getElementById('time').getBoundingClientRect();"
        " return [r.left, r.top, r.width, r.height]; })()"
    )
    browser.click(box[0] + 0.9 * box[2], box[1] + box[3] / 2)
    browser.settle(5)
    assert int(browser.evaluate("document.getElementById('time').value")) > 0
    assert browser.evaluate("document.getElementById('tlabel').textContent") != label
    second = _image(browser.screenshot())
    changed = np.abs(_scene(second) - scene).sum(axis=2) > 30
    assert changed.sum() > 300, f"moving the slider changed only {changed.sum()} pixels"

    # switch controller: the page keeps working
    browser.evaluate(
        "(() => { const s = document.getElementById('controller'); s.value = '1';"
        " s.dispatchEvent(new Event('change')); return true; })()"
    )
    browser.settle(3)
    assert (
        browser.evaluate("document.getElementById('controller').selectedOptions[0].text")
        == "otmm+dls"
    )
    assert browser.console_errors == []


def test_url_hash_sets_the_frame(browser: Page, results: Path) -> None:
    page = (results / "replays" / "wrist-clik.html").resolve().as_uri()
    browser.open(page + "#frame=20&controller=otmm%2Bdls", ready="window.replayReady === true")
    assert int(browser.evaluate("document.getElementById('time').value")) == 20
    assert browser.evaluate("document.getElementById('controller').value") == "1"
    assert browser.console_errors == []


def test_report_opens_without_errors(browser: Page, results: Path) -> None:
    assert main(["report", str(results)]) == 0
    browser.open((results / "report.html").resolve().as_uri())
    pixels = _image(browser.screenshot())
    assert (np.abs(pixels - 255).sum(axis=2) > 60).mean() > 0.01, "report.html renders blank"
    assert browser.evaluate("document.querySelectorAll('table').length") >= 1
    assert browser.console_errors == []

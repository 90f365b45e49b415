"""Hostile names in real headless Chromium: the replay page and report.html run no injected
script and still work (issue 19, "Script injection").

Names travel into three HTML contexts (text, attribute, inline ``<script>`` JSON) through
:func:`otmm_qp.output.escape.escape`; the experiment name ``w__META__x__SCENE__`` checks that
the page template is filled in one pass (the escaped title was once replaced again by the
page data, unescaped). Skipped only when Chromium is absent and CI is not set.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from otmm_qp.cli import main
from otmm_qp.output.escape import escape, fill_template
from otmm_qp.replay.browser import Page
from tests.factories import browser_page, ur5_wrist_run

#: Controller names that break out of each context if not escaped (``window.pwned`` is set
#: by any script that runs).
HOSTILE = [
    "</script><script>window.pwned=1</script>",
    "<!--<script>\u2028\u2029__TITLE__\"'><img src=x onerror=window.pwned=2>",
]
EXPERIMENT = "w__META__x__SCENE__"


def _config() -> str:
    controllers = [
        f"name: {json.dumps(name)}\nbackend: {{type: dls, damping: 0.05}}" for name in HOSTILE
    ]
    title = json.dumps("s</title><script>window.pwned=3</script>")
    return ur5_wrist_run(title, controllers, motion=0.2, experiment=EXPERIMENT)


@pytest.fixture(scope="module")
def browser() -> Iterator[Page]:
    with browser_page(900, 640) as page:
        yield page


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("hostile-browser")
    config = folder / "hostile.yaml"
    config.write_text(_config())
    out = folder / "results"
    argv = ["run", str(config), "--out", str(out), "--figures", "none", "--quiet", "--replay"]
    assert main(argv) == 0
    return out


def test_escape_contexts_never_leave_markup_or_end_a_script() -> None:
    for name in HOSTILE:
        for context in ("text", "attr"):
            assert not set("<>\"'") & set(escape(name, context))  # type: ignore[arg-type]
        script = escape({"name": name, "x": float("nan")}, "script")
        for forbidden in ("<", ">", "\u2028", "\u2029"):
            assert forbidden not in script
        assert json.loads(script) == {"name": name, "x": None}
    filled = fill_template("__A__|__B__", {"A": "__B__", "B": "b"})
    assert filled == "__B__|b"  # inserted text is not searched again


def test_hostile_names_run_no_script_in_replay_page(browser: Page, results: Path) -> None:
    page = results / "replays" / f"{EXPERIMENT}-clik.html"
    browser.open(page.resolve().as_uri(), ready="window.replayReady === true")
    browser.settle(3)
    assert browser.evaluate("typeof window.pwned") == "undefined"
    names = browser.evaluate(
        "Array.from(document.getElementById('controller').options).map(o => o.text)"
    )
    assert names == HOSTILE  # shown verbatim as text
    assert EXPERIMENT in browser.evaluate("document.title")
    browser.evaluate(
        "(() => { const s = document.getElementById('controller'); s.value = '1';"
        " s.dispatchEvent(new Event('change')); return true; })()"
    )
    browser.settle(2)
    assert browser.evaluate("document.getElementById('tlabel').textContent").startswith("t = ")
    assert browser.evaluate("typeof window.pwned") == "undefined"
    assert browser.console_errors == []


def test_hostile_names_run_no_script_in_report(browser: Page, results: Path) -> None:
    browser.open((results / "report.html").resolve().as_uri())
    browser.settle(2)
    assert browser.evaluate("typeof window.pwned") == "undefined"
    assert browser.evaluate("document.querySelectorAll('img[src=x]').length") == 0
    text = browser.evaluate("document.body.innerText")
    for name in HOSTILE:
        assert name.replace("\u2028", "").replace("\u2029", "")[:20] in text.replace(
            "\u2028", ""
        ).replace("\u2029", "")
    assert browser.evaluate("document.querySelectorAll('a[href^=\"replays/\"]').length") == 1
    assert browser.console_errors == []

"""The comparison report agrees with summary.csv and is self-contained."""

from __future__ import annotations

import csv
from html.parser import HTMLParser
from pathlib import Path

import pytest

from otmm_qp.config.load import parse_config
from otmm_qp.exceptions import ConfigError
from otmm_qp.output.report import REPORT_COLUMNS, write_report
from otmm_qp.output.run_writer import ResultsWriter
from otmm_qp.runner import run_suite

PNG = bytes.fromhex(
    "89504e470d0a1a0a0000000d4948445200000001000000010806000000"
    "1f15c4890000000d49444154789c6360000002000154a24f5d0000000049454e44ae426082"
)


class TableParser(HTMLParser):
    """Collect scenario tables: {scenario: {controller: {key: (text, classes)}}}."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, dict[str, dict[str, tuple[str, str]]]] = {}
        self.scenario = self.controller = self.key = ""
        self.classes = ""
        self.text = ""
        self.external: list[str] = []
        self.images = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if tag == "table" and "data-scenario" in a:
            self.scenario = a["data-scenario"]
            self.tables[self.scenario] = {}
        elif tag == "tr" and "data-controller" in a and self.scenario:
            self.controller = a["data-controller"]
            self.tables[self.scenario][self.controller] = {}
        elif tag == "td" and "data-key" in a:
            self.key, self.classes, self.text = a["data-key"], a.get("class", ""), ""
        elif tag in ("img", "link", "script"):
            source = a.get("src", a.get("href", ""))
            if tag == "img":
                self.images += 1
            if source and not source.startswith("data:"):
                self.external.append(source)

    def handle_data(self, data: str) -> None:
        if self.key:
            self.text += data

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self.key:
            self.tables[self.scenario][self.controller][self.key] = (self.text, self.classes)
            self.key = ""
        elif tag == "table":
            self.scenario = ""


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("results")
    suite = parse_config(
        {
            "name": "report",
            "loop_modes": ["clik", "feedforward"],
            "experiments": [
                {
                    "name": "E2",
                    "robot": {"type": "planar", "link_lengths": [1.0, 0.8]},
                    "q0": [0.0, 0.0],
                    "trajectory": {
                        "type": "quintic_line",
                        "begin": [1.8, 0.0],
                        "end": [0.6, -1.0],
                        "duration": 2.0,
                    },
                    "controllers": [
                        {"name": "RMRC", "backend": {"type": "pinv"}},
                        {"name": "DLS", "backend": {"type": "dls", "damping": 0.05}},
                        {"name": "SDLS", "backend": {"type": "sdls"}},
                    ],
                }
            ],
        }
    )
    run_suite(suite, ResultsWriter(out), progress=None)
    (out / "E2" / "fig.png").write_bytes(PNG)
    (out / "claims.md").write_text("# Claims\n\n| claim | verdict |\n|---|---|\n| x | holds |\n")
    return out


def test_html_tables_agree_with_summary_csv(results: Path) -> None:
    html_path, md_path = write_report(results)
    parser = TableParser()
    parser.feed(html_path.read_text())
    with (results / "summary.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6
    for row in rows:
        cells = parser.tables[f"{row['experiment']}/{row['loop_mode']}"][row["controller"]]
        for key, _, _spec in REPORT_COLUMNS:
            assert float(cells[key][0]) == pytest.approx(float(row[key]), rel=6e-3, abs=1e-12)
    for scenario, table in parser.tables.items():
        mode = scenario.split("/")[1]
        group = [r for r in rows if r["loop_mode"] == mode and r["blow_up"] == "False"]
        for key in ("rms_error", "max_joint_speed"):
            best = min(group, key=lambda r: float(r[key]))["controller"]
            marked = [c for c, cells in table.items() if "best" in cells[key][1]]
            assert marked == [best], (scenario, key)
    assert parser.external == [] and parser.images == 1
    text = md_path.read_text()
    assert "## Ranking across scenarios" in text and "| x | holds |" in text
    assert "![E2/fig.png](E2/fig.png)" in text


def test_missing_summary_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no summary.csv here"):
        write_report(tmp_path)

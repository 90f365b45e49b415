"""Refusals a person reads: a first line of at most 200 characters, details after it.

docs/guarantees.md ("one line"): what, where and what fixes it on the first line (the
``otmm-qp: error:`` prefix included), any further line indented, never a traceback. The long
cases: an old file with many keys to rewrite, a list of every available name, a 10,000-character
value, a deep file path, an ambiguous schema.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.exceptions import FIRST_LINE_LIMIT, ConfigError, error_lines
from tests.cli_errors import refusal_text


def _old_file(controllers: int) -> dict[str, Any]:
    """A schema-1 run file with ``controllers`` qp controllers, each with damping and limit_gain."""
    return {
        "name": "old",
        "experiments": [
            {
                "name": "e",
                "robot": {"type": "planar", "link_lengths": [1.0, 0.8]},
                "q0": [0.3, 0.5],
                "trajectory": {"type": "circle", "centre": [1.0, 0.0], "radius": 0.2, "period": 4},
                "controllers": [
                    {
                        "name": f"qp{i}",
                        "backend": {"type": "qp", "damping": 1e-4, "limit_gain": 0.3},
                    }
                    for i in range(controllers)
                ],
            }
        ],
    }


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[str, list[str], str]:
    """The refusal of ``argv``: its first line, the lines after it, all of it as one string."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    text = refusal_text(err)
    first, *rest = err.strip().splitlines()
    return first, rest, text


def test_many_old_keys_are_one_short_line_and_one_line_each(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("old.yaml").write_text(yaml.safe_dump(_old_file(40)))
    first, details, _ = _refused(["run", "old.yaml", "--out", "o"], capsys)
    assert first == (
        "otmm-qp: error: old.yaml: 80 key(s) from an older schema; fix: otmm-qp migrate old.yaml"
    )
    assert len(details) == 1 + 80  # how it was read, then one line per key
    assert sum("backend.damping: 0.0001 meant μ" in line for line in details) == 40
    assert not Path("o").exists()


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["list", "--params", "x" * 10_000], "xxx"),
        (["run", "DEEP", "--out", "o"], "run.yaml: no such config file"),
        (["run", "UNKNOWN", "--out", "o"], "unknown backend 'nope'; available:"),
        (["migrate", "AMBIGUOUS"], "cannot tell its schema"),
    ],
)
def test_long_refusals_keep_the_first_line_short(
    argv: list[str],
    needle: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    deep = Path(*(["a-rather-long-folder-name"] * 12), "run.yaml")
    unknown = _old_file(1)
    unknown["experiments"][0]["controllers"][0]["backend"] = {"type": "nope"}
    Path("unknown.yaml").write_text(yaml.safe_dump({"version": 2, **unknown}))
    ambiguous = _old_file(1)
    ambiguous["experiments"][0]["controllers"].append(
        {"name": "pink", "backend": {"type": "qp", "regularization": 1e-4}}
    )
    Path("ambiguous.yaml").write_text(yaml.safe_dump(ambiguous))
    names = {"DEEP": str(deep), "UNKNOWN": "unknown.yaml", "AMBIGUOUS": "ambiguous.yaml"}
    first, _, text = _refused([names.get(a, a) for a in argv], capsys)
    assert needle in text, text
    if needle == "cannot tell its schema":
        assert first.endswith("fix: otmm-qp migrate ambiguous.yaml --from 1 (or --from 2)")


def test_error_lines_break_a_long_summary_at_a_space_and_keep_every_word() -> None:
    words = [f"w{i:03d}" for i in range(200)]
    error = ConfigError("field", " ".join(words), ["one detail", "another"])
    lines = error_lines(error)
    assert all(len(line) <= FIRST_LINE_LIMIT for line in lines)
    assert lines[0].startswith("otmm-qp: error: field: w000 ")
    assert all(line.startswith("    ") for line in lines[1:-2])
    assert lines[-2:] == ["  one detail", "  another"]
    assert " ".join(line.strip() for line in lines[:-2]).split()[3:] == words
    assert str(error) == "field: " + " ".join(words) + "\n  one detail\n  another"
    assert error.summary == "field: " + " ".join(words)

"""What the CLI's refusal looks like (docs/guarantees.md, "one line")."""

from __future__ import annotations

from otmm_qp.exceptions import FIRST_LINE_LIMIT


def refusal_text(err: str) -> str:
    """Check ``err`` (a command's stderr) is one refusal; return its text as one string.

    The rule: a first line ``otmm-qp: error: ...`` of at most :data:`FIRST_LINE_LIMIT`
    characters, then only indented lines (a long summary's continuation, or details), and no
    traceback. The text returned joins them with spaces (a pattern can span the break).
    """
    lines = err.strip().splitlines()
    assert lines and lines[0].startswith("otmm-qp: error: "), err
    assert len(lines[0]) <= FIRST_LINE_LIMIT, lines[0]
    assert all(line.startswith("  ") for line in lines[1:]), err
    assert "Traceback" not in err, err
    return " ".join(line.strip() for line in lines)

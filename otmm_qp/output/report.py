r"""``otmm-qp report RESULTS_DIR``: one self-contained HTML page and its Markdown twin.

Reads ``summary.csv`` (required), ``claims.md`` (optional) and every ``*.png`` under the
results folder, and writes ``report.html`` (inline CSS, figures base64-embedded, no external
resource) and ``report.md`` (figures linked by relative path).

Sections:

1. **Comparison tables**, one per scenario (experiment × loop mode), columns
   :data:`REPORT_COLUMNS`; in each column the best value (all lower-is-better) is marked
   (``**bold**`` in Markdown, ``<td class="best">`` in HTML) when no other row shares it.
   Runs that stopped early, blew up or left the arm's limits are not eligible for "best"
   (the row says which limit, on how many steps); skipped runs (a missing peer) are listed
   with their install hint.
2. **Ranking** across scenarios by the *mean rank score*:

   .. math::
       \text{score}(c) = \frac{1}{|S_c|\,|M|}\sum_{s \in S_c}\sum_{m \in M}
       \text{rank}_{s,m}(c)

   where :math:`S_c` are the scenarios controller ``c`` ran in, :math:`M` the
   :data:`RANKED_METRICS`, and :math:`\text{rank}_{s,m}` its 1-based rank among the
   controllers of scenario ``s`` on metric ``m`` (ties share the lower rank; a run that blew
   up or stopped early ranks last). Lower is better. Controllers are identified by name.
   Controllers that broke the arm's joint speed or position limits (``velocity_violations``,
   ``position_violations``) rank after those that kept them, and are never "best".

Before them, first on the page: the **claims verdict** (``claims.md``, verbatim; its
evidence column wraps, so it reads without horizontal scrolling). Last: the **figures**.
"""

from __future__ import annotations

import base64
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from otmm_qp.exceptions import ConfigError, OutputPathError
from otmm_qp.metrics.table import columns
from otmm_qp.output.escape import escape
from otmm_qp.output.markdown import REPORT_CSS, Table, markdown_to_html, table_markdown
from otmm_qp.output.png import compact_png
from otmm_qp.output.replays import find_replays
from otmm_qp.output.results import ResultsDir
from otmm_qp.output.summary import RunOutcome
from otmm_qp.paths import atomic_write_text, ensure_inside
from otmm_qp.status import Status

#: ``(column, heading, format)`` shown per scenario, from the metric table; every column is
#: lower-is-better (``tests/metrics/test_table.py``).
REPORT_COLUMNS: tuple[tuple[str, str, str], ...] = columns(
    "rms_error",
    "max_error",
    "max_error_window",
    "max_joint_speed",
    "chattering",
    "max_jump",
    "position_violations",
    "velocity_violations",
    "step_time_median_us",
)
#: Metrics entering the ranking score.
RANKED_METRICS = ("rms_error", "max_error_window", "max_joint_speed", "chattering")


@dataclass
class Row:
    """One ``summary.csv`` row: identity, numeric metrics and status."""

    experiment: str
    loop_mode: str
    controller: str
    values: dict[str, float]
    error_message: str
    blow_up: bool
    stuck_steps: int = 0
    steps: int = 0
    relaxed_steps: int = 0
    outcome: str = RunOutcome.COMPLETED

    @property
    def skipped(self) -> bool:
        """The controller was skipped (a missing peer): the ``outcome`` column says so."""
        return self.outcome == RunOutcome.SKIPPED

    @property
    def stuck(self) -> bool:
        """The backend reported ``stuck`` on more than half of the steps."""
        return self.steps > 0 and 2 * self.stuck_steps > self.steps

    @property
    def limit_steps(self) -> tuple[int, int]:
        """Steps above a joint's own speed limit, and outside its position limits."""
        speed, position = (
            self.values.get(k, math.nan) for k in ("velocity_violations", "position_violations")
        )
        return (
            int(speed) if math.isfinite(speed) else 0,
            int(position) if math.isfinite(position) else 0,
        )

    @property
    def breaks_limits(self) -> bool:
        """A joint left its speed or position limits on some step (the arm's own limits)."""
        return any(self.limit_steps)

    @property
    def eligible(self) -> bool:
        """Completed, no blow-up, not mostly stuck, within the arm's limits: may be "best"."""
        return (
            not self.error_message
            and not self.blow_up
            and not self.stuck
            and (not self.breaks_limits)
        )


def _number(text: str | None) -> float:
    try:
        return float(text or "")
    except ValueError:
        return math.nan


def _count(text: str | None) -> int:
    """A non-negative step count from a CSV cell; 0 when missing, NaN or garbage."""
    value = _number(text)
    return int(value) if math.isfinite(value) and value > 0 else 0


#: Backend statuses that mean a bound was relaxed or could not be met on that step.
RELAXED_STATUSES = tuple(str(status) for status in Status if status.relaxes_bound)


def _read_text(results_dir: Path, path: Path) -> str:
    """A text file of the results folder (see :meth:`ResultsDir.read_text`)."""
    return ResultsDir(results_dir).read_text(path)


def read_summary(path: Path) -> list[Row]:
    """Rows of ``summary.csv`` (read by :meth:`ResultsDir.summary_records`).

    Raises:
        ConfigError: The file is missing, unreadable or lacks the identity columns.
    """
    return [_row(record) for record in ResultsDir(path.parent).summary_records()]


def _row(record: dict[str, str]) -> Row:
    """One summary row; cells missing from a truncated file read as empty."""

    def cell(key: str) -> str:
        return record.get(key, "")

    return Row(
        cell("experiment"),
        cell("loop_mode"),
        cell("controller"),
        {key: _number(cell(key)) for key, _, _ in REPORT_COLUMNS},
        cell("error_message"),
        cell("blow_up") == "True",
        _count(cell("status_stuck")),
        _count(cell("steps")),
        sum(_count(cell(f"status_{status}")) for status in RELAXED_STATUSES),
        cell("outcome") or (RunOutcome.STOPPED if cell("error_message") else RunOutcome.COMPLETED),
    )


def group_scenarios(rows: Sequence[Row]) -> dict[tuple[str, str], list[Row]]:
    """Rows by ``(experiment, loop_mode)``, in file order."""
    groups: dict[tuple[str, str], list[Row]] = {}
    for row in rows:
        groups.setdefault((row.experiment, row.loop_mode), []).append(row)
    return groups


def best_values(rows: Sequence[Row]) -> dict[str, float]:
    """Smallest finite value of each column among eligible rows.

    NaN (nothing marked) when no row is eligible or the smallest value is shared: a tie is a
    tie, not a "best".
    """
    best: dict[str, float] = {}
    for key, _, _ in REPORT_COLUMNS:
        values = [r.values[key] for r in rows if r.eligible and math.isfinite(r.values[key])]
        tie = values.count(min(values)) > 1 if values else False
        best[key] = min(values) if values and not tie else math.nan
    return best


def ranking(rows: Sequence[Row]) -> list[tuple[str, float, int]]:
    """``(controller, score, scenarios)`` sorted by the mean rank score (see module doc).

    Controllers that kept the arm's limits in every scenario come first; those that broke a
    speed or position limit follow (:func:`limit_note` says where), each part by score.
    """
    totals: dict[str, list[float]] = {}
    scenario_count: dict[str, int] = {}
    for group in group_scenarios(rows).values():
        ran = [r for r in group if not r.skipped]
        for row in ran:
            scenario_count[row.controller] = scenario_count.get(row.controller, 0) + 1
        for metric in RANKED_METRICS:

            def key(row: Row, metric: str = metric) -> float:
                value = row.values[metric]
                return value if row.eligible and math.isfinite(value) else math.inf

            ordered = sorted(key(r) for r in ran)
            for row in ran:
                rank = ordered.index(key(row)) + 1
                totals.setdefault(row.controller, []).append(float(rank))
    table = [(c, sum(v) / len(v), scenario_count[c]) for c, v in totals.items()]
    broke = {r.controller for r in rows if not r.skipped and r.breaks_limits}
    return sorted(table, key=lambda item: (item[0] in broke, item[1], item[0]))


def limit_note(rows: Sequence[Row], controller: str) -> str:
    """Where ``controller`` broke the arm's limits, or ``kept`` when it never did.

    E.g. ``broken: speed on 246 of 500 steps in 1 of 2 scenarios``.
    """
    own = [r for r in rows if r.controller == controller and not r.skipped]
    broken = [r for r in own if r.breaks_limits]
    if not broken:
        return "kept"
    speed = sum(r.limit_steps[0] for r in broken)
    position = sum(r.limit_steps[1] for r in broken)
    steps = sum(r.steps for r in broken)
    what = [f"speed on {speed}" if speed else "", f"position on {position}" if position else ""]
    return (
        f"broken: {' and '.join(w for w in what if w)} of {steps} steps "
        f"in {len(broken)} of {len(own)} scenarios"
    )


def _format(value: float, spec: str) -> str:
    if not math.isfinite(value):
        return "–"
    return format(value, spec)


def _figures(results_dir: Path) -> list[Path]:
    """PNG files of the results folder; symlinks and anything resolving outside are ignored."""
    root = results_dir.resolve()
    found = []
    for path in results_dir.rglob("*.png"):
        if path.is_symlink() or any(p.is_symlink() for p in path.parents if p != results_dir):
            continue
        if path.is_file() and root in path.resolve().parents:
            found.append(path)
    return sorted(found)


# ---------------------------------------------------------------- Markdown
def render_markdown(results_dir: Path, rows: Sequence[Row], claims: str | None) -> str:
    """The Markdown report (figures linked relative to ``results_dir``)."""
    lines = [f"# Comparison report: {results_dir.name}", ""]
    lines.append(
        "Best value per column in **bold** (all columns: lower is better; a shared smallest "
        "value is a tie, not marked; runs that blew up, stopped early or broke the arm's joint "
        "limits are not eligible). Metric definitions: `otmm_qp/metrics/metrics.py`."
    )
    lines += ["", "## Claims verdict", ""]
    lines.append(_demote_headings(claims) if claims else "_No claims.md in this results folder._")
    lines += ["", "## Comparison per scenario"]
    for (experiment, mode), group in group_scenarios(rows).items():
        best = best_values(group)
        lines += ["", f"### {experiment} — {mode}", ""]
        header = ["controller", *(label for _, label, _ in REPORT_COLUMNS)]
        body: list[list[str]] = []
        for row in group:
            if row.skipped:
                cells = [row.controller, f"skipped: {row.error_message}"]
                cells += [""] * (len(REPORT_COLUMNS) - 1)
                body.append(cells)
                continue
            cells = [row.controller + _status_note(row)]
            for key, _, spec in REPORT_COLUMNS:
                text = _format(row.values[key], spec)
                if row.eligible and row.values[key] == best[key]:
                    text = f"**{text}**"
                cells.append(text)
            body.append(cells)
        lines += table_markdown(Table(header, body, "l" + "r" * len(REPORT_COLUMNS)))
    lines += ["", "## Ranking across scenarios", ""]
    lines.append(
        "Score = mean rank over scenarios and the metrics "
        + ", ".join(f"`{m}`" for m in RANKED_METRICS)
        + " (1 = best; blown-up or stopped runs rank last). Lower is better. Controllers that "
        "broke the arm's joint speed or position limits rank after those that kept them."
    )
    places = [
        [str(place), controller, f"{score:.2f}", str(count), limit_note(rows, controller)]
        for place, (controller, score, count) in enumerate(ranking(rows), start=1)
    ]
    headers = ["rank", "controller", "score", "scenarios", "arm's limits"]
    lines += ["", *table_markdown(Table(headers, places, "rlrrl"))]
    lines += ["", "## Figures", ""]
    figures = _figures(results_dir)
    if not figures:
        lines.append("_No figures in this results folder._")
    for figure in figures:
        relative = figure.relative_to(results_dir).as_posix()
        lines += [f"![{relative}]({relative})", ""]
    return "\n".join(lines).rstrip() + "\n"


def _status_note(row: Row) -> str:
    return _stop_note(row) + (
        f" (bound relaxed/infeasible on {row.relaxed_steps} steps)" if row.relaxed_steps else ""
    )


def _stop_note(row: Row) -> str:
    speed, position = row.limit_steps
    broke = [
        f"speed limit on {speed}" if speed else "",
        f"position limit on {position}" if position else "",
    ]
    limits = (
        f" (breaks the {' and the '.join(b for b in broke if b)} of {row.steps} steps)"
        if row.breaks_limits and not (row.blow_up or row.stuck or row.error_message)
        else ""
    )
    return _run_note(row) + limits


def _run_note(row: Row) -> str:
    if row.blow_up:
        return " (blow-up)"
    if row.stuck:
        return f" (stuck {row.stuck_steps}/{row.steps} steps)"
    if row.error_message:
        return f" (stopped: {row.error_message})"
    return ""


def _demote_headings(markdown: str) -> str:
    """Shift claims.md headings below the report's own ``##`` level."""
    return re.sub(r"^(#{1,4}) ", lambda m: "#" * (len(m.group(1)) + 2) + " ", markdown, flags=re.M)


# -------------------------------------------------------------------- HTML
def _html_row(row: Row, best: dict[str, float]) -> str:
    """One ``<tr>`` of a scenario table (a skipped controller spans the metric columns)."""
    controller = escape(row.controller)
    if row.skipped:
        return (
            f'<tr data-controller="{controller}"><td>{controller}</td>'
            f'<td class="skip" colspan="{len(REPORT_COLUMNS)}">'
            f"skipped: {escape(row.error_message)}</td></tr>"
        )
    note = escape(_status_note(row))
    cells = [f'<td class="name">{controller}{note}</td>']
    for key, _, spec in REPORT_COLUMNS:
        value = row.values[key]
        classes = []
        if row.eligible and value == best[key]:
            classes.append("best")
        if not row.eligible:
            classes.append("bad")
        attr = f' class="{" ".join(classes)}"' if classes else ""
        cells.append(f'<td data-key="{key}"{attr}>{_format(value, spec)}</td>')
    return f'<tr data-controller="{controller}">' + "".join(cells)


def _html_tables(rows: Sequence[Row]) -> list[str]:
    """One comparison table per (experiment, loop mode)."""
    parts = []
    header = "".join(f"<th>{escape(label)}</th>" for _, label, _ in REPORT_COLUMNS)
    for (experiment, mode), group in group_scenarios(rows).items():
        best = best_values(group)
        parts.append(f"<h3>{escape(experiment)} — {escape(mode)}</h3>")
        table = [f'<table data-scenario="{escape(f"{experiment}/{mode}", "attr")}">']
        table.append(f"<tr><th>controller</th>{header}</tr>")
        table += [_html_row(row, best) for row in group]
        parts.append('<div class="scroll">' + "".join(table) + "</table></div>")
    return parts


def _html_ranking(rows: Sequence[Row]) -> list[str]:
    """The ranking section."""
    parts = ['<h2 id="ranking">Ranking across scenarios</h2>']
    parts.append(
        '<p class="note">Score = mean rank over scenarios and the metrics '
        + ", ".join(f"<code>{m}</code>" for m in RANKED_METRICS)
        + " (1 = best; blown-up or stopped runs rank last). Lower is better. Controllers that "
        "broke the arm's joint speed or position limits rank after those that kept them.</p>"
    )
    table = [
        '<table id="ranking-table"><tr><th>rank</th><th>controller</th><th>score</th>'
        "<th>scenarios</th><th>arm's limits</th></tr>"
    ]
    for place, (controller, score, count) in enumerate(ranking(rows), start=1):
        note = limit_note(rows, controller)
        table.append(
            f"<tr><td>{place}</td><td>{escape(controller)}</td><td>{score:.2f}</td>"
            f"<td>{count}</td><td>{escape(note)}</td></tr>"
        )
    parts.append("".join(table) + "</table>")
    return parts


def _html_figures(results_dir: Path) -> list[str]:
    """The figures section: each PNG of the folder embedded as base64 (palette-compressed)."""
    parts = ['<h2 id="figures">Figures</h2>']
    figures = _figures(results_dir)
    if not figures:
        parts.append('<p class="note">No figures in this results folder.</p>')
    for figure in figures:
        data = base64.b64encode(compact_png(figure.read_bytes())).decode("ascii")
        caption = escape(figure.relative_to(results_dir).as_posix())
        parts.append(
            f'<figure><img alt="{caption}" src="data:image/png;base64,{data}">'
            f"<figcaption>{caption}</figcaption></figure>"
        )
    return parts


def _html_replays(results_dir: Path) -> list[str]:
    """Links to the replays already written (``otmm-qp replay`` / ``--replay``); GIFs shown inline.

    Replays are linked by relative path rather than embedded: an arm replay holds its meshes
    (megabytes) and would swamp the report.
    """
    replays = find_replays(results_dir)
    if not replays:
        return []
    parts = ['<h2 id="replays">Replays</h2>', "<ul>"]
    for title, relative in replays:
        href = escape(relative.as_posix(), "attr")
        label = escape(title)
        if relative.suffix == ".gif":
            parts.append(
                f'<li><a href="{href}">{label}</a><br><img alt="{label}" src="{href}"></li>'
            )
        else:
            parts.append(f'<li><a href="{href}">{label}</a> (3-D replay, opens offline)</li>')
    parts.append("</ul>")
    return parts


def _html_claims(claims: str | None) -> list[str]:
    """The claims verdict, first on the page (what the reproduction found)."""
    if not claims:
        return ['<h2 id="claims">Claims verdict</h2>', '<p class="note">No claims.md.</p>']
    return [
        '<h2 id="claims">Claims verdict</h2>',
        f'<div class="claims">{markdown_to_html(claims)}</div>',
    ]


def render_html(results_dir: Path, rows: Sequence[Row], claims: str | None) -> str:
    """The self-contained HTML report."""
    title = f"Comparison report: {results_dir.name}"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{escape(title)}</title><style>{REPORT_CSS}</style></head><body>",
        f"<h1>{escape(title)}</h1>",
        *_html_claims(claims),
        '<p class="note">Best value per column highlighted (all columns: lower is better; a '
        "shared smallest value is a tie, not marked; runs that blew up, stopped early or broke "
        "the arm's joint limits are not eligible). Metric definitions: "
        "<code>otmm_qp/metrics/metrics.py</code>.</p>",
        '<h2 id="tables">Comparison per scenario</h2>',
    ]
    parts += _html_tables(rows)
    parts += _html_ranking(rows)
    parts += _html_replays(results_dir)
    parts += _html_figures(results_dir)
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def write_report(results_dir: Path) -> tuple[Path, Path]:
    """Write ``report.html`` and ``report.md`` into ``results_dir``.

    Args:
        results_dir: A results folder holding ``summary.csv`` (and optionally ``claims.md``
            and PNG figures, searched recursively).

    Returns:
        ``(html_path, markdown_path)``.

    Raises:
        ConfigError: No readable ``summary.csv``.
    """
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise ConfigError(str(results_dir), "not a results folder (no such directory)")
    rows = read_summary(results_dir / "summary.csv")
    claims_path = results_dir / "claims.md"
    claims = _read_text(results_dir, claims_path) if claims_path.is_file() else None
    html_path = results_dir / "report.html"
    markdown_path = results_dir / "report.md"
    html, markdown = (
        render_html(results_dir, rows, claims),
        render_markdown(results_dir, rows, claims),
    )
    try:
        atomic_write_text(ensure_inside(results_dir, html_path), html)
        atomic_write_text(ensure_inside(results_dir, markdown_path), markdown)
    except OSError as error:
        raise OutputPathError(
            str(results_dir), f"cannot write the report: {error.strerror}"
        ) from None
    return html_path, markdown_path

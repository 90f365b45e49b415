"""Study report: success rates, medians with intervals, paired tests, σ_min curves, figures.

``write_study_report(DIR)`` reads ``DIR/study.json`` and the Parquet dataset and writes
``DIR/study_report.md``, ``DIR/study_report.html`` and ``DIR/figures/*.png`` (contracts §3).
Every number in them is computed here from the stored rows.
"""

from __future__ import annotations

import io
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.exceptions import OtmmError
from otmm_qp.output.escape import escape
from otmm_qp.output.paths import atomic_write_bytes, atomic_write_text, ensure_inside, safe_name
from otmm_qp.studies.episodes import is_success
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.statistics import (
    PairedResult,
    binned_medians,
    bootstrap_median,
    paired_comparisons,
    rank_with_ties,
    wilson_interval,
)
from otmm_qp.studies.storage import read_study_folder

#: Metrics summarised by median + bootstrap interval: (column, label, unit).
MEDIAN_METRICS: tuple[tuple[str, str, str], ...] = (
    ("rms_error", "RMS error", "m"),
    ("max_error", "max error", "m"),
    ("max_joint_speed", "peak joint speed", "rad/s"),
    ("max_jump", "max one-step jump", "rad/s"),
)
#: Metrics compared pairwise.
PAIRED_METRICS = ("max_error", "max_joint_speed")
#: Bins of σ_min at closest approach (log-spaced edges).
SIGMA_BINS = 6


@dataclass
class Rows:
    """Episode rows as Python dicts, with the success flag recomputed from the criteria."""

    rows: list[dict[str, Any]]

    def controllers(self) -> list[str]:
        """Controllers in first-seen order."""
        return list(dict.fromkeys(r["controller"] for r in self.rows))

    def robots(self) -> list[str]:
        """Robots in first-seen order."""
        return list(dict.fromkeys(r["robot"] for r in self.rows))

    def select(self, **equal: Any) -> list[dict[str, Any]]:
        """Rows whose columns equal the given values."""
        return [r for r in self.rows if all(r.get(k) == v for k, v in equal.items())]


def _value(row: dict[str, Any], name: str) -> float:
    value = row.get(name)
    if value is None or isinstance(value, str):
        return math.nan
    return float(value)


def _task_key(row: dict[str, Any]) -> tuple[object, ...]:
    return (row["robot"], row["generator"], row["task_index"], row["loop_mode"])


def _fmt(value: float, digits: int = 3) -> str:
    if not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


def _interval(value: float, low: float, high: float) -> str:
    return f"{_fmt(value)} [{_fmt(low)}, {_fmt(high)}]"


def load_rows(out: Path) -> tuple[StudyConfig, Rows]:
    """The study config (from ``study.json``) and the rows of this study and plan.

    What the reader left out (other studies' parts, symlinks, duplicates...) is printed on
    stderr, one line per reason.

    Raises:
        OtmmError: No study marker, an invalid one, or no episodes in ``out``.
    """
    config, data = read_study_folder(out)
    for line in data.ignored:
        print(f"otmm-qp: report ignored {line}", file=sys.stderr)
    if data.table is None or data.table.num_rows == 0:
        raise OtmmError(f"{out}: the study has no stored episodes yet")
    rows = data.table.to_pylist()
    for row in rows:
        row["success"] = row.get("status") != "error" and is_success(row, config.success)
    return config, Rows(rows)


def success_table(
    rows: Rows, robot: str | None
) -> tuple[list[str], dict[str, tuple[float, float, float]]]:
    """Markdown lines of success rates and medians, and ``controller → (rate, low, high)``."""
    header = (
        "| controller | episodes | errors | success [95 % CI] | "
        + " | ".join(f"median {label} [{unit}] (95 % CI)" for _, label, unit in MEDIAN_METRICS)
        + " |"
    )
    lines = [header, "|" + "---|" * (4 + len(MEDIAN_METRICS))]
    rates: dict[str, tuple[float, float, float]] = {}
    for name in rows.controllers():
        selected = rows.select(controller=name, **({"robot": robot} if robot else {}))
        if not selected:
            continue
        n = len(selected)
        wins = sum(1 for r in selected if r["success"])
        low, high = wilson_interval(wins, n)
        rates[name] = (wins / n, low, high)
        errors = sum(1 for r in selected if r.get("status") == "error")
        cells = [
            name,
            str(n),
            str(errors),
            f"{100 * wins / n:.1f} % [{100 * low:.1f}, {100 * high:.1f}]",
        ]
        for metric, _, _ in MEDIAN_METRICS:
            values = np.array([_value(r, metric) for r in selected])
            cells.append(_interval(*bootstrap_median(values, seed=0, resamples=1000)))
        lines.append("| " + " | ".join(cells) + " |")
    return lines, rates


def generator_table(rows: Rows) -> list[str]:
    """Markdown table: success rate [CI] per controller (rows) and robot/generator (columns)."""
    groups = list(dict.fromkeys((r["robot"], r["generator"]) for r in rows.rows))
    lines = [
        "| controller | " + " | ".join(f"{robot} {gen}" for robot, gen in groups) + " |",
        "|---|" + "---|" * len(groups),
    ]
    for name in rows.controllers():
        cells = []
        for robot, gen in groups:
            selected = rows.select(controller=name, robot=robot, generator=gen)
            wins = sum(1 for r in selected if r["success"])
            low, high = wilson_interval(wins, len(selected))
            rate = 100 * wins / len(selected) if selected else math.nan
            cells.append(f"{rate:.0f} % [{100 * low:.0f}, {100 * high:.0f}]")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def median_intervals(rows: Rows, robot: str, metric: str) -> dict[str, tuple[float, float, float]]:
    """``controller → (median, low, high)`` of ``metric`` on ``robot``."""
    return {
        name: bootstrap_median(
            np.array([_value(r, metric) for r in rows.select(controller=name, robot=robot)]),
            seed=0,
            resamples=1000,
        )
        for name in rows.controllers()
        if rows.select(controller=name, robot=robot)
    }


def paired_for(rows: Rows, robot: str, metric: str) -> list[PairedResult]:
    """Paired comparisons of every controller pair on ``robot``'s tasks."""
    values: dict[str, dict[tuple[object, ...], float]] = {}
    for row in rows.select(robot=robot):
        value = _value(row, metric)
        if math.isfinite(value):
            values.setdefault(row["controller"], {})[_task_key(row)] = value
    return paired_comparisons(values)


def sigma_curves(
    rows: Rows, robot: str, metric: str
) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Binned medians of ``metric`` vs ``task.sigma_min_closest`` per controller on ``robot``."""
    selected = [r for r in rows.select(robot=robot) if _value(r, "task.sigma_min_closest") > 0]
    if not selected:
        return np.zeros(0), {}
    sigma = np.array([_value(r, "task.sigma_min_closest") for r in selected])
    edges = np.quantile(sigma, np.linspace(0.0, 1.0, SIGMA_BINS + 1))
    edges = np.unique(edges)
    if edges.size < 2:
        return np.zeros(0), {}
    curves = {}
    centres = np.zeros(0)
    for name in rows.controllers():
        own = [r for r in selected if r["controller"] == name]
        if not own:
            continue
        centres, medians, counts = binned_medians(
            np.array([_value(r, "task.sigma_min_closest") for r in own]),
            np.array([_value(r, metric) for r in own]),
            edges,
        )
        curves[name] = (medians, counts)
    return centres, curves


def _verdicts(rows: Rows, robot: str) -> list[str]:
    """Plain-language verdicts from the rankings (ties where intervals overlap)."""
    lines = []
    _, rates = success_table(rows, robot)
    ranking = rank_with_ties(rates, higher_is_better=True)
    best = [n for n, rank, _ in ranking if rank == 1]
    lines.append(
        f"- **{robot}, success rate:** best {', '.join(best)} "
        f"({'tied: intervals overlap' if len(best) > 1 else 'interval clear of all others'})."
    )
    for metric, label, unit in MEDIAN_METRICS[1:3]:
        intervals = median_intervals(rows, robot, metric)
        ranking = rank_with_ties(intervals)
        best = [n for n, rank, _ in ranking if rank == 1]
        shown = ", ".join(f"{n} {_interval(*intervals[n])} {unit}" for n in best[:4])
        more = f" (+{len(best) - 4} more)" if len(best) > 4 else ""
        lines.append(f"- **{robot}, median {label}:** lowest {shown}{more}.")
    return lines


def render_markdown(config: StudyConfig, rows: Rows, figures: Sequence[str]) -> str:
    """The Markdown report."""
    out = _overview(config, rows)
    for robot in rows.robots():
        out += _verdicts(rows, robot)
    out.append("")
    lines, _ = success_table(rows, None)
    out += ["## All robots", "", *lines, ""]
    out += [
        "## Success rate by robot and generator (95 % Wilson CI)",
        "",
        *generator_table(rows),
        "",
    ]
    for robot in rows.robots():
        out += _robot_section(rows, robot)
    if figures:
        out += ["## Figures", ""] + [f"![{f}]({f})" for f in figures] + [""]
    return "\n".join(out)


def _overview(config: StudyConfig, rows: Rows) -> list[str]:
    """Report title, description, what was run, the success criteria, the verdicts heading."""
    total = len(rows.rows)
    errors = sum(1 for r in rows.rows if r.get("status") == "error")
    tasks = len({(r["robot"], r["generator"], r["task_index"]) for r in rows.rows})
    criteria = config.success.model_dump()
    return [
        f"# Study {config.name}",
        "",
        config.description,
        "",
        f"{total} episodes ({errors} errors) on {tasks} tasks; robots: "
        f"{', '.join(rows.robots())}; controllers: {len(rows.controllers())}; "
        f"loop modes: {', '.join(config.loop_modes)}; dt = {config.dt:g} s.",
        "",
        "Success: completed and "
        + ", ".join(f"{k} = {v}" for k, v in criteria.items() if v not in (None, False))
        + ". Intervals: Wilson 95 % for rates, percentile bootstrap 95 % (1000 resamples, "
        "seed 0) for medians.",
        "",
        "## Verdicts",
        "",
    ]


def _robot_section(rows: Rows, robot: str) -> list[str]:
    """One robot's section: success table, ranking, paired comparisons, σ_min tables."""
    out = [f"## {robot}", ""]
    lines, rates = success_table(rows, robot)
    out += lines + [""]
    ranking = rank_with_ties(rates, higher_is_better=True)
    out.append(
        "Ranking by success rate (= marks a tie: overlapping intervals): "
        + ", ".join(f"{rank}{'=' if tied else ''} {name}" for name, rank, tied in ranking)
    )
    out.append("")
    for metric in PAIRED_METRICS:
        out += _paired_table(rows, robot, metric)
    for metric in ("max_error", "max_joint_speed"):
        out += _sigma_table(rows, robot, metric)
    return out


def _paired_table(rows: Rows, robot: str, metric: str) -> list[str]:
    """Markdown table of the paired comparisons of ``metric`` on ``robot`` (Holm p < 0.05: *)."""
    out = [
        f"### Paired comparisons on {robot}: {metric} (lower wins)",
        "",
        "| A | B | tasks | A wins | median A−B | Wilcoxon p | Holm p |",
        "|---|---|---|---|---|---|---|",
    ]
    for result in paired_for(rows, robot, metric):
        out.append(
            f"| {result.a} | {result.b} | {result.pairs} | {_fmt(result.win_rate)} | "
            f"{_fmt(result.median_difference)} | {_fmt(result.p_value)} | "
            f"{_fmt(result.p_holm)}{' *' if result.p_holm < 0.05 else ''} |"
        )
    out.append("")
    return out


def _sigma_table(rows: Rows, robot: str, metric: str) -> list[str]:
    """Markdown table of ``metric``'s binned medians vs σ_min at closest approach (or none)."""
    centres, curves = sigma_curves(rows, robot, metric)
    if not curves:
        return []
    out = [
        f"### {robot}: median {metric} vs σ_min at closest approach",
        "",
        "| controller | " + " | ".join(f"σ≈{_fmt(c, 2)}" for c in centres) + " |",
        "|---|" + "---|" * len(centres),
    ]
    for name, (medians, counts) in curves.items():
        cells = [f"{_fmt(m)} (n={c})" for m, c in zip(medians, counts, strict=True)]
        out.append(f"| {name} | " + " | ".join(cells) + " |")
    out.append("")
    return out


def _save(figure: Any, out: Path, name: str) -> str:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=90)
    plt.close(figure)
    relative = f"figures/{safe_name(name)}"
    atomic_write_bytes(ensure_inside(out, out / relative), buffer.getvalue())
    return relative


def write_figures(out: Path, rows: Rows) -> list[str]:
    """ECDFs per metric, σ_min curves and a Pareto plot per robot; relative paths."""
    import matplotlib

    matplotlib.use("Agg")

    (out / "figures").mkdir(exist_ok=True)
    written = []
    for robot in rows.robots():
        written.append(_ecdf_figure(out, rows, robot))
        sigma = _sigma_figure(out, rows, robot)
        if sigma is not None:
            written.append(sigma)
        written.append(_pareto_figure(out, rows, robot))
    return written


def _positive_sorted(rows: Rows, robot: str, controller: str, metric: str) -> np.ndarray:
    """Finite values > 0 of ``metric`` of one controller on ``robot``, sorted."""
    return np.sort(
        [
            v
            for v in (_value(r, metric) for r in rows.select(robot=robot, controller=controller))
            if math.isfinite(v) and v > 0
        ]
    )


def _ecdf_figure(out: Path, rows: Rows, robot: str) -> str:
    """Write ``robot``'s ECDFs of the median metrics, one panel each; its relative path."""
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(MEDIAN_METRICS), figsize=(4 * len(MEDIAN_METRICS), 3.4))
    for ax, (metric, label, unit) in zip(axes, MEDIAN_METRICS, strict=True):
        for name in rows.controllers():
            values = _positive_sorted(rows, robot, name, metric)
            if values.size:
                ax.step(
                    values,
                    np.arange(1, values.size + 1) / values.size,
                    where="post",
                    label=name,
                )
        ax.set_xscale("log")
        ax.set_xlabel(f"{label} [{unit}]")
        ax.set_ylabel("fraction of episodes")
    axes[0].legend(fontsize=6)
    figure.suptitle(f"{robot}: ECDFs")
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.88, wspace=0.3)
    return _save(figure, out, f"ecdf-{robot}.png")


def _sigma_figure(out: Path, rows: Rows, robot: str) -> str | None:
    """Write ``robot``'s medians vs σ_min at closest approach; its relative path, or None."""
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    drawn = False
    for ax, metric in zip(axes, ("max_error", "max_joint_speed"), strict=True):
        centres, curves = sigma_curves(rows, robot, metric)
        for name, (medians, _) in curves.items():
            ax.plot(centres, medians, marker="o", label=name)
            drawn = True
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("σ_min at closest approach")
        ax.set_ylabel(f"median {metric}")
    if not drawn:
        plt.close(figure)
        return None
    axes[0].legend(fontsize=6)
    figure.suptitle(f"{robot}: metrics vs σ_min at closest approach")
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.88, wspace=0.3)
    return _save(figure, out, f"sigma-{robot}.png")


def _pareto_figure(out: Path, rows: Rows, robot: str) -> str:
    """Write ``robot``'s median max error vs median peak joint speed, with CIs; its path."""
    import matplotlib.pyplot as plt

    errors = median_intervals(rows, robot, "max_error")
    speeds = median_intervals(rows, robot, "max_joint_speed")
    figure, ax = plt.subplots(figsize=(5.5, 4.2))
    for name in errors:
        e, s = errors[name], speeds[name]
        if not (math.isfinite(e[0]) and math.isfinite(s[0])):
            continue
        ax.errorbar(
            s[0],
            e[0],
            xerr=[[s[0] - s[1]], [s[2] - s[0]]],
            yerr=[[e[0] - e[1]], [e[2] - e[0]]],
            fmt="o",
            capsize=2,
            label=name,
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median peak joint speed [rad/s]")
    ax.set_ylabel("median max error [m]")
    ax.legend(fontsize=6)
    ax.set_title(f"{robot}: Pareto (lower-left is better)")
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.88, wspace=0.3)
    return _save(figure, out, f"pareto-{robot}.png")


def write_study_report(out: Path) -> tuple[Path, Path]:
    """Write ``study_report.html`` and ``study_report.md`` (and figures) for a study dataset.

    Raises:
        OtmmError: ``out`` is not a study directory or holds no episodes.
    """
    from otmm_qp.output.markdown import markdown_to_html

    out = Path(out)
    config, rows = load_rows(out)
    figures = write_figures(out, rows)
    markdown = render_markdown(config, rows, figures)
    md_path = out / "study_report.md"
    html_path = out / "study_report.html"
    atomic_write_text(md_path, markdown)
    body = markdown_to_html(
        "\n".join(line for line in markdown.splitlines() if not line.startswith("!["))
    )
    images = "".join(
        f'<p><img src="{escape(f, "attr")}" alt="{escape(f, "attr")}"></p>' for f in figures
    )
    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'>"
        f"<title>Study {escape(config.name)}</title>"
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto}"
        "table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ccc;padding:2px 5px}"
        "img{max-width:100%}</style></head><body>"
        f"{body}{images}</body></html>"
    )
    atomic_write_text(html_path, page)
    return html_path, md_path

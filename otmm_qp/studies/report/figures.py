"""The report's matplotlib figures: ECDFs, medians against σ_min and the Pareto plot per robot.

The medians and curves are :mod:`otmm_qp.studies.verdicts`' (``median_intervals``,
``sigma_curves``); each figure is written to ``DIR/figures/`` through the safe-name function.
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.paths import atomic_write_bytes, ensure_inside, safe_name
from otmm_qp.studies.columns import number
from otmm_qp.studies.limit_keeping import limits_clause
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.report.tables import MEDIAN_METRICS
from otmm_qp.studies.rows import RELATIVE_ERROR, Rows
from otmm_qp.studies.verdicts import median_intervals, sigma_curves


def pareto_path(robot: str) -> str:
    """The Pareto figure's path of ``robot``, relative to the study folder."""
    return f"figures/{safe_name(f'pareto-{robot}.png')}"


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
            for v in (number(r, metric) for r in rows.select(robot=robot, controller=controller))
            if math.isfinite(v) and v > 0
        ]
    )


def _ecdf_figure(out: Path, rows: Rows, robot: str) -> str:
    """Write ``robot``'s ECDFs of the median metrics, one panel each; its relative path."""
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(MEDIAN_METRICS), figsize=(4 * len(MEDIAN_METRICS), 3.4))
    for ax, row in zip(axes, MEDIAN_METRICS, strict=True):
        for name in rows.controllers():
            values = _positive_sorted(rows, robot, name, row.name)
            if values.size:
                ax.step(
                    values,
                    np.arange(1, values.size + 1) / values.size,
                    where="post",
                    label=name,
                )
        ax.set_xscale("log")
        ax.set_xlabel(row.heading)
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
    """Write ``robot``'s median accuracy vs median peak joint speed, with CIs; its path.

    Accuracy is the oracle-relative max error (the reference is the point at 0; symmetric-log
    axis, as medians can be 0; defined only on rows that kept every limit, so ``≥ 0``: the
    note below the reference can only come from older stored rows), or the max error (log
    axis) when no reference is stored.
    """
    import matplotlib.pyplot as plt

    metric = rows.accuracy_metric()
    errors = median_intervals(rows, robot, metric)
    speeds = median_intervals(rows, robot, "max_joint_speed")
    figure, ax = plt.subplots(figsize=(6.4, 4.6))
    for name in errors:
        e, s = errors[name], speeds[name]
        if not (math.isfinite(e.value) and math.isfinite(s.value)):
            continue
        if name == REFERENCE_NAME:
            ax.plot(
                s.value,
                0.0,
                marker="*",
                markersize=14,
                color="k",
                linestyle="none",
                label="oracle (reference)",
            )
            continue
        ax.errorbar(
            s.value,
            e.value,
            xerr=[[s.value - s.low], [s.high - s.value]],
            yerr=[[e.value - e.low], [e.high - e.value]],
            fmt="o",
            capsize=2,
            label=name,
        )
    ax.set_xscale("log")
    if metric == RELATIVE_ERROR:
        finite = [abs(v.value) for v in errors.values() if math.isfinite(v.value) and v.value]
        ax.set_yscale("symlog", linthresh=max(1e-6, min(finite) / 2.0) if finite else 1e-4)
    else:
        ax.set_yscale("log")
    below = [
        name
        for name, e in errors.items()
        if name != REFERENCE_NAME and metric == RELATIVE_ERROR and e.value < 0.0
    ]
    if below:  # more accurate than the reference: say why, on the figure
        ax.axhline(0.0, color="k", linewidth=0.6, linestyle=":")
        own = rows.select(robot=robot)
        reasons = [f"{n}{limits_clause(own, n) or ' (limits kept)'}" for n in below]
        ax.text(
            0.01,
            0.01,
            "below the reference (0): "
            + "; ".join(reasons)
            + ".\nThe reference keeps every joint limit and is solved to 1 % of the position "
            "tolerance by a local solver:\na row below it broke a limit, or beat it within "
            "that resolution or where the local solver stopped short.",
            transform=ax.transAxes,
            fontsize=5.5,
            va="bottom",
            wrap=True,
        )
    ax.set_xlabel("median peak joint speed [rad/s]")
    label = "oracle-relative max error" if metric == RELATIVE_ERROR else "max error"
    ax.set_ylabel(f"median {label} [m]")
    ax.legend(fontsize=6)
    ax.set_title(f"{robot}: accuracy vs peak speed (lower-left is better; 95 % CIs)")
    figure.subplots_adjust(left=0.13, right=0.98, bottom=0.12, top=0.9)
    return _save(figure, out, f"pareto-{robot}.png")

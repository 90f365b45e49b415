r"""Figures in the style of the OTMM paper (Figs. 2-8): one per run, one comparison per mode.

Every figure is a fresh :class:`matplotlib.figure.Figure` drawn on an Agg canvas, never
registered with :mod:`matplotlib.pyplot`: no global state, no ``plt.show``, nothing left
open after the PNG is written.

Scale rules, chosen so magnitudes read honestly:

* joint speeds switch to a ``symlog`` axis when the largest peak ``|q̇|`` exceeds
  :data:`SYMLOG_RATIO` times the reference level (per run: the 90th percentile of the
  per-step peak; across controllers: the smallest controller peak); the linear band is
  that reference level and the axis label says so;
* tracking error and σ_min switch to a log axis when their positive values span more than
  :data:`LOG_DECADES` decades; zeros (e.g. a run starting exactly on the path) are left
  out of a log axis instead of being clipped to an invented floor.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullLocator
from matplotlib.transforms import blended_transform_factory

from otmm_qp import interrupt
from otmm_qp.paths import atomic_open, safe_name, unique_names
from otmm_qp.robots.robot import FloatArray
from otmm_qp.runner.prepare import PreparedExperiment
from otmm_qp.runner.run import ExperimentHook, RunRecord
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.status import Status

#: Resolution of the written PNGs [dots per inch].
DPI = 110
#: Peak ratio above which joint speeds are drawn on a symlog axis.
SYMLOG_RATIO = 20.0
#: Decades spanned by positive values above which an axis turns logarithmic.
LOG_DECADES = 2.0
#: Lowest decade shown on a log axis, counted down from the largest value.
LOG_FLOOR_DECADES = 7.0
#: Marker style per backend status other than ``ok``: (marker, colour), from ``Status.marker``.
STATUS_STYLE: dict[str, tuple[str, str]] = {
    str(status): status.marker for status in Status if status.marker is not None
}
_OTHER_STATUS = ("o", "tab:brown")
_STOP_COLOUR = "tab:red"
_THRESHOLD_COLOUR = "0.35"
_P_COLOUR = "tab:green"
_AXIS_NAMES = "xyz"
#: Tick labels of log axes as plain numbers: mathtext labels cost more to lay out.
_PLAIN = FuncFormatter(lambda value, _: f"{value:g}")

# --------------------------------------------------------------------------- helpers


def _new_figure(width: float, height: float) -> Figure:
    """A figure on its own Agg canvas [in]."""
    figure = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(figure)
    return figure


def _save(figure: Figure, path: Path) -> None:
    """Write ``figure`` as PNG."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as handle:
        figure.savefig(handle, dpi=DPI, format="png", pil_kwargs={"compress_level": 1})


def _title(ax: Axes, text: str, **style: object) -> None:
    """Left panel title at a fixed height (skips matplotlib's costly title re-placement)."""
    style.setdefault("fontsize", 9)
    style.setdefault("loc", "left")
    ax.set_title(text, y=1.0, pad=4.0, **style)  # type: ignore[arg-type]


def _time_end(result: RunResult) -> float:
    """End of the last recorded step [s] (0 for an empty run)."""
    return float(result.t[-1] + result.dt) if result.steps else 0.0


def _finite_positive(values: FloatArray) -> FloatArray:
    """Finite values > 0, flattened."""
    flat = np.asarray(values, dtype=float).ravel()
    return flat[np.isfinite(flat) & (flat > 0.0)]


def _wants_log(values: Sequence[FloatArray]) -> bool:
    """True when the positive values span more than :data:`LOG_DECADES` decades."""
    positive = [_finite_positive(v) for v in values]
    positive = [v for v in positive if v.size]
    if not positive:
        return False
    high = max(float(v.max()) for v in positive)
    low = min(float(v.min()) for v in positive)
    return high > low * 10.0**LOG_DECADES


def _log_limits(values: Sequence[FloatArray]) -> tuple[float, float] | None:
    """Y-limits for a log axis: the data range, at most :data:`LOG_FLOOR_DECADES` deep."""
    positive = [p for p in (_finite_positive(v) for v in values) if p.size]
    if not positive:
        return None
    high = max(float(p.max()) for p in positive)
    low = max(min(float(p.min()) for p in positive), high * 10.0**-LOG_FLOOR_DECADES)
    return low / 1.5, high * 1.5


def _for_log(values: FloatArray) -> FloatArray:
    """Copy with values ≤ 0 replaced by NaN (they have no place on a log axis)."""
    out = np.array(values, dtype=float)
    out[~(out > 0.0)] = np.nan
    return out


def _symlog_band(peaks: Sequence[float]) -> float | None:
    """Linear band of a symlog speed axis [rad/s], or None for a linear axis."""
    finite = [p for p in peaks if np.isfinite(p) and p > 0.0]
    if len(finite) < 2:
        return None
    low, high = min(finite), max(finite)
    if high <= SYMLOG_RATIO * low:
        return None
    return float(10.0 ** np.floor(np.log10(low) + 0.3))  # a round number near the low peak


def _plain_log_ticks(ax: Axes) -> None:
    """Log/symlog y-axis without minor ticks and with plain labels (``1e-05``, not mathtext)."""
    ax.yaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_formatter(_PLAIN)


def _set_value_scale(ax: Axes, log: bool, limits: tuple[float, float] | None) -> None:
    """Log y-axis with plain ticks (and ``limits`` if given), or a linear one from 0."""
    if log:
        ax.set_yscale("log")
        _plain_log_ticks(ax)
        if limits is not None:
            ax.set_ylim(*limits)
    else:
        ax.set_ylim(bottom=0.0)


def _apply_speed_scale(ax: Axes, band: float | None) -> str:
    """Set a symlog scale when ``band`` is given; return the label suffix."""
    if band is None:
        return ""
    ax.set_yscale("symlog", linthresh=band, linscale=1.0)
    _plain_log_ticks(ax)
    return f"\n(symlog, linear within ±{band:g})"


def _mark_statuses(ax: Axes, result: RunResult) -> list[str]:
    """Small markers at the bottom of a time axis where the backend status was not ``ok``.

    Returns:
        The distinct statuses marked, in first-seen order.
    """
    status = np.asarray(result.status, dtype=object)
    if status.size == 0:
        return []
    not_ok = status != "ok"
    if not np.any(not_ok):
        return []
    transform = blended_transform_factory(ax.transData, ax.transAxes)
    seen: list[str] = []
    for name in dict.fromkeys(status[not_ok].tolist()):
        mask = status == name
        marker, colour = STATUS_STYLE.get(str(name), _OTHER_STATUS)
        ax.plot(
            result.t[mask],
            np.full(int(mask.sum()), 0.03),
            linestyle="none",
            marker=marker,
            markersize=3.5,
            color=colour,
            transform=transform,
            clip_on=False,
            label=f"{name} ({int(mask.sum())})",
            zorder=5,
        )
        seen.append(str(name))
    return seen


def _mark_stop(ax: Axes, result: RunResult) -> None:
    """A vertical line where a run that stopped early ended."""
    if result.error_message:
        ax.axvline(_time_end(result), color=_STOP_COLOUR, linewidth=1.0, linestyle="--")


def _path_axes(result: RunResult) -> tuple[int, int]:
    """Indices of the two position axes to draw: x–y in 2-D, the two widest spreads in 3-D."""
    d = result.position.shape[1]
    if d <= 2:
        return 0, min(1, d - 1)
    both = np.vstack([result.position, result.position_desired])
    spread = np.nanmax(both, axis=0) - np.nanmin(both, axis=0) if both.size else np.zeros(d)
    first, second = sorted(int(i) for i in np.argsort(-np.nan_to_num(spread))[:2])
    return first, second


def _short(message: str, limit: int = 90) -> str:
    """``message`` on one line, cut to ``limit`` characters."""
    line = " ".join(message.split())
    return line if len(line) <= limit else line[: limit - 1] + "…"


def _stop_note(result: RunResult) -> str:
    """Subtitle fragment for a run that stopped early."""
    if not result.error_message:
        return ""
    return f"  —  stopped at t = {_time_end(result):.3g} s: {_short(result.error_message)}"


# --------------------------------------------------------------------------- panels


def _plot_path(ax: Axes, result: RunResult) -> None:
    """(a) End-effector path against the desired path [m]."""
    i, j = _path_axes(result)
    desired, actual = result.position_desired, result.position
    if result.steps:
        ax.plot(desired[:, i], desired[:, j], "--", color="0.5", linewidth=1.2, label="desired")
        ax.plot(actual[:, i], actual[:, j], color="tab:blue", linewidth=1.0, label="actual")
        ax.plot(actual[0, i], actual[0, j], "o", color="tab:blue", markersize=4, label="start")
        ax.plot(actual[-1, i], actual[-1, j], "x", color="tab:red", markersize=6, label="end")
    ax.set_xlabel(f"{_AXIS_NAMES[i]} [m]")
    ax.set_ylabel(f"{_AXIS_NAMES[j]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize=7, frameon=False)
    _title(ax, "(a) end-effector path")


def _plot_angles(ax: Axes, result: RunResult) -> None:
    """(b) Joint angles [rad], with finite limits when they lie near the data."""
    lower, upper = result.position_limits
    span_low = float(np.nanmin(result.q)) if result.steps else 0.0
    span_high = float(np.nanmax(result.q)) if result.steps else 1.0
    margin = 0.5 * max(span_high - span_low, 1e-3)
    for k, name in enumerate(result.joint_names):
        colour = f"C{k % 10}"
        ax.plot(result.t, result.q[:, k], color=colour, linewidth=1.0, label=name)
        for bound in (lower[k], upper[k]):
            if np.isfinite(bound) and span_low - margin <= bound <= span_high + margin:
                ax.axhline(bound, color=colour, linestyle=":", linewidth=0.8)
    ax.set_ylabel("q [rad]")
    ax.legend(loc="best", fontsize=7, frameon=False, ncols=2 if result.q.shape[1] > 3 else 1)
    _title(ax, "(b) joint angles")


def _plot_speeds(ax: Axes, result: RunResult, band: float | None, legend: bool = True) -> None:
    """(c) Joint velocities q̇_i(t) [rad/s] on the given scale."""
    for k, name in enumerate(result.joint_names):
        ax.plot(result.t, result.qdot[:, k], color=f"C{k % 10}", linewidth=0.9, label=name)
    limits = np.asarray(result.velocity_limits, dtype=float)
    peak = float(np.nanmax(np.abs(result.qdot))) if result.steps else 0.0
    for k, limit in enumerate(limits):
        if np.isfinite(limit) and limit <= 2.0 * max(peak, 1e-9):
            for sign in (-1.0, 1.0):
                ax.axhline(sign * limit, color=f"C{k % 10}", linestyle=":", linewidth=0.8)
    suffix = _apply_speed_scale(ax, band)
    ax.set_ylabel("q̇ [rad/s]" + suffix, fontsize=9 if suffix else None)
    ax.axhline(0.0, color="0.8", linewidth=0.6, zorder=0)
    if legend:
        ax.legend(loc="upper right", fontsize=7, frameon=False, ncols=min(result.qdot.shape[1], 4))


def _plot_error(
    ax: Axes, result: RunResult, log: bool, limits: tuple[float, float] | None
) -> Axes | None:
    """(d) Tracking error ‖e‖ [m]; for pose tasks the orientation error [rad] on a twin axis.

    Returns:
        The twin axis of a pose task, else None.
    """
    position = result.position_error if result.steps else np.zeros(0)
    ax.plot(result.t, _for_log(position) if log else position, color="tab:blue", linewidth=1.0)
    ax.set_ylabel("‖e‖ [m]" + (" (log)" if log else ""), color="tab:blue")
    _set_value_scale(ax, log, limits)
    angular = result.orientation_error
    if angular is None:
        return None
    twin = ax.twinx()
    angle_log = _wants_log([angular])
    twin.plot(
        result.t,
        _for_log(angular) if angle_log else angular,
        color="tab:orange",
        linewidth=1.0,
    )
    twin.set_ylabel("orientation error [rad]" + (" (log)" if angle_log else ""), color="tab:orange")
    _set_value_scale(twin, angle_log, _log_limits([angular]) if angle_log else None)
    return twin


def _plot_sigma(
    ax: Axes,
    result: RunResult,
    sigma_s: float | None,
    log: bool,
    limits: tuple[float, float] | None,
) -> None:
    """(e) σ_min(t) of ``J_w`` with the σ_S threshold line."""
    sigma = result.sigma_min
    ax.plot(result.t, _for_log(sigma) if log else sigma, color="tab:blue", linewidth=1.0)
    if sigma_s is not None:
        ax.axhline(sigma_s, color=_THRESHOLD_COLOUR, linestyle="--", linewidth=0.9)
        ax.text(
            0.99,
            sigma_s,
            f"σ_S = {sigma_s:g} ",
            transform=blended_transform_factory(ax.transAxes, ax.transData),
            fontsize=7,
            color=_THRESHOLD_COLOUR,
            ha="right",
            va="bottom",
        )
    ax.set_ylabel("σ_min" + (" (log)" if log else ""), color="tab:blue")
    _set_value_scale(ax, log, limits)


def _plot_p(ax: Axes, result: RunResult, label: bool = True) -> None:
    """Filter suppression level p(t) ∈ [0, 1] on ``ax``."""
    ax.plot(result.t, result.p, color=_P_COLOUR, linewidth=0.9)
    ax.set_ylim(-0.04, 1.06)
    if label:
        ax.set_ylabel("p (filter level)", color=_P_COLOUR)
    ax.tick_params(axis="y", colors=_P_COLOUR)


def _filter_acted(result: RunResult) -> bool:
    """Whether any filter changed the command during the run."""
    return bool(result.steps and np.any(result.filter_active))


def _no_filter_note(result: RunResult) -> str:
    """Why a run has no p(t) curve."""
    return "no filter" if result.filters in ("", "none") else "filter never acted"


def _plot_backend(ax: Axes, result: RunResult) -> None:
    """(f) Joint speed along the weakest direction [rad/s], and the backend damping λ."""
    weak = np.asarray(result.weak_speed, dtype=float)
    ax.plot(result.t, weak, color="tab:purple", linewidth=1.0)
    band = None
    if weak.size:
        band = _symlog_band([float(np.percentile(weak, 90)), float(np.nanmax(weak))])
    suffix = _apply_speed_scale(ax, band)
    ax.set_ylabel("|v_minᵀ q̇| [rad/s]" + suffix, color="tab:purple")
    ax.set_ylim(bottom=0.0)
    damping = np.asarray(result.damping, dtype=float)
    if damping.size and np.any(np.isfinite(damping)):
        twin = ax.twinx()
        twin.plot(result.t, damping, color="tab:olive", linewidth=0.9)
        twin.set_ylabel("damping λ", color="tab:olive")
        twin.set_ylim(bottom=0.0)
        title = "(f) weak-direction speed, damping λ"
    else:
        title = "(f) joint speed along weakest direction"
    _title(ax, title)


# --------------------------------------------------------------------------- public API


def _plot_run_measures(
    ax_qd: Axes, ax_err: Axes, ax_sigma: Axes, result: RunResult, sigma_s: float | None
) -> None:
    """Panels (c) joint velocities, (d) tracking error and (e) σ_min / p of one run."""
    per_step = np.nanmax(np.abs(result.qdot), axis=1) if result.steps else np.zeros(0)
    band = None
    if per_step.size:
        band = _symlog_band([float(np.percentile(per_step, 90)), float(per_step.max())])
    _plot_speeds(ax_qd, result, band)
    _title(ax_qd, "(c) joint velocities")

    error_log = _wants_log([result.position_error]) if result.steps else False
    error_limits = _log_limits([result.position_error]) if error_log else None
    _plot_error(ax_err, result, error_log, error_limits)
    _title(ax_err, "(d) tracking error")

    sigma_values = [result.sigma_min] + ([np.array([sigma_s])] if sigma_s else [])
    sigma_log = _wants_log(sigma_values) if result.steps else False
    _plot_sigma(
        ax_sigma, result, sigma_s, sigma_log, _log_limits(sigma_values) if sigma_log else None
    )
    if _filter_acted(result):
        _plot_p(ax_sigma.twinx(), result)
        _title(ax_sigma, "(e) σ_min and filter level p")
    else:
        _title(ax_sigma, f"(e) σ_min ({_no_filter_note(result)})")


def _finish_run_axes(ax_path: Axes, time_axes: Sequence[Axes], result: RunResult) -> None:
    """Status marks, the stop line, grids, shared time range and labels of a run figure."""
    ax_q, ax_qd, ax_err, ax_sigma, ax_weak = time_axes
    statuses: list[str] = []
    for ax in (ax_qd, ax_err, ax_sigma):
        statuses = _mark_statuses(ax, result) or statuses
    if statuses:
        ax_qd.legend(loc="upper right", fontsize=7, frameon=False, ncols=2)
    for ax in time_axes:
        _mark_stop(ax, result)
        ax.grid(True, linewidth=0.3, alpha=0.5)
        ax.set_xlim(0.0, max(_time_end(result), result.dt))
    for ax in (ax_err, ax_sigma, ax_weak):
        ax.set_xlabel("t [s]")
    ax_path.grid(True, linewidth=0.3, alpha=0.5)


def _run_titles(figure: Figure, result: RunResult) -> None:
    """Title (experiment · loop mode · controller) and the settings line of a run figure."""
    figure.suptitle(
        f"{result.experiment} · {result.loop_mode} · {result.controller}", fontsize=12, y=0.985
    )
    figure.text(
        0.5,
        0.925,
        f"filters: {result.filters or 'none'}   backend: {result.backend or '?'}   "
        f"dt = {result.dt:g} s   steps: {result.steps}{_stop_note(result)}",
        ha="center",
        fontsize=8,
        color=_STOP_COLOUR if result.error_message else "0.3",
    )


def plot_run(result: RunResult, path: Path, sigma_s: float | None = None) -> None:
    """Write one PNG of a run in the paper's layout (2×3 panels).

    Panels: (a) end-effector path against the desired path, (b) joint angles, (c) joint
    velocities, (d) tracking error, (e) σ_min with the σ_S line and the filter level p,
    (f) joint speed along the weakest right singular vector and the backend damping.
    Backend statuses other than ``ok`` are marked at the bottom of (c)-(e); a run that
    stopped early gets a dashed red line at its last step and the reason in the title.

    Args:
        result: The run.
        path: Output PNG path (parent folders are created).
        sigma_s: Singular-value threshold σ_S drawn in (e), or None for no line.
    """
    figure = _new_figure(13.0, 6.8)
    axes = figure.subplots(2, 3)
    figure.subplots_adjust(left=0.075, right=0.94, bottom=0.08, top=0.86, wspace=0.45, hspace=0.32)
    ax_path, ax_q, ax_qd = axes[0]
    ax_err, ax_sigma, ax_weak = axes[1]
    time_axes = (ax_q, ax_qd, ax_err, ax_sigma, ax_weak)
    for ax in time_axes[1:]:
        ax.sharex(ax_q)

    _plot_path(ax_path, result)
    _plot_angles(ax_q, result)
    _plot_run_measures(ax_qd, ax_err, ax_sigma, result, sigma_s)
    _plot_backend(ax_weak, result)
    _finish_run_axes(ax_path, (ax_q, ax_qd, ax_err, ax_sigma, ax_weak), result)
    _run_titles(figure, result)
    _save(figure, path)


def plot_comparison(
    results: Sequence[RunResult], path: Path, title: str, sigma_s: float | None
) -> None:
    """Write one PNG comparing controllers of one experiment and loop mode, side by side.

    One column per controller (in the given order); rows: joint velocities, tracking error,
    σ_min with the σ_S line, and the filter level p. Time and y-limits are shared per row
    so magnitudes compare honestly; joint speeds go to a symlog axis when the largest
    controller peak exceeds :data:`SYMLOG_RATIO` times the smallest, so one blow-up does
    not flatten the others. Column titles give each controller's peak ``|q̇|`` and peak
    ``‖e‖``; backend statuses other than ``ok`` are marked on the time axes.

    Args:
        results: The runs to compare (same experiment and loop mode).
        path: Output PNG path (parent folders are created).
        title: Figure title, e.g. ``"E1 · clik"``.
        sigma_s: Singular-value threshold σ_S drawn on the σ_min row, or None for no line.
    """
    runs = list(results)
    figure, axes = _comparison_grid(len(runs), title)
    if not runs:
        axes[0, 0].text(0.5, 0.5, "no runs", ha="center", va="center")
        _save(figure, path)
        return

    scales = _comparison_scales(runs, sigma_s)
    statuses_seen: dict[str, None] = {}
    for col, result in enumerate(runs):
        for name in _plot_comparison_column(list(axes[:, col]), col, result, scales, sigma_s):
            statuses_seen[name] = None
    axes[0, 0].set_xlim(0.0, scales.t_end)
    axes[3, 0].set_ylabel("p", color=_P_COLOUR)
    _comparison_legend(figure, runs[0].joint_names, list(statuses_seen))
    _comparison_notes(figure, runs, scales, sigma_s)
    _save(figure, path)


@dataclass(frozen=True)
class _ComparisonScales:
    """Axis scales shared by the columns of a comparison figure.

    Attributes:
        peaks: Peak ``|q̇|`` of each run [rad/s] (0 for an empty run).
        band: Linear band of the symlog speed axis [rad/s], or None for a linear axis.
        error_log: Tracking error on a log axis.
        error_limits: Y-limits of the tracking error row, or None.
        sigma_log: σ_min on a log axis.
        sigma_limits: Y-limits of the σ_min row, or None.
        t_end: End of the shared time axis [s].
    """

    peaks: list[float]
    band: float | None
    error_log: bool
    error_limits: tuple[float, float] | None
    sigma_log: bool
    sigma_limits: tuple[float, float] | None
    t_end: float


def _comparison_grid(count: int, title: str) -> tuple[Figure, np.ndarray]:
    """A titled figure with 4 rows × one column per run (at least one), rows sharing y."""
    n = max(count, 1)
    width = max(2.6 * n + 1.1, 6.5)
    figure = _new_figure(width, 8.0)
    axes = np.asarray(
        figure.subplots(
            4,
            n,
            sharex=True,
            sharey="row",
            squeeze=False,
            gridspec_kw={"height_ratios": [1.0, 1.0, 1.0, 0.55]},
        )
    )
    figure.subplots_adjust(
        left=0.95 / width,
        right=1.0 - 0.25 / width,
        bottom=0.07,
        top=0.85,
        wspace=0.12,
        hspace=0.14,
    )
    figure.suptitle(title, fontsize=12, y=0.985)
    return figure, axes


def _comparison_scales(runs: Sequence[RunResult], sigma_s: float | None) -> _ComparisonScales:
    """Speed, error and σ_min scales and the time range common to all ``runs`` (non-empty)."""
    peaks = [float(np.nanmax(np.abs(r.qdot))) if r.steps else 0.0 for r in runs]
    errors = [r.position_error for r in runs if r.steps]
    error_log = _wants_log(errors)
    error_limits = _log_limits(errors) if error_log else None
    if not error_log and errors:
        top = max(float(np.nanmax(e)) for e in errors)
        error_limits = (0.0, 1.05 * top if top > 0 else 1.0)
    sigmas = [r.sigma_min for r in runs if r.steps] + ([np.array([sigma_s])] if sigma_s else [])
    sigma_log = _wants_log(sigmas)
    return _ComparisonScales(
        peaks=peaks,
        band=_symlog_band(peaks),
        error_log=error_log,
        error_limits=error_limits,
        sigma_log=sigma_log,
        sigma_limits=_log_limits(sigmas) if sigma_log else None,
        t_end=max(max(_time_end(r) for r in runs), runs[0].dt),
    )


def _plot_comparison_column(
    column: Sequence[Axes],
    col: int,
    result: RunResult,
    scales: _ComparisonScales,
    sigma_s: float | None,
) -> list[str]:
    """Draw one run's column (speeds, error, σ_min, p); return the statuses it marked."""
    ax_qd, ax_err, ax_sigma, ax_p = column
    _plot_speeds(ax_qd, result, scales.band, legend=False)
    _plot_error(ax_err, result, scales.error_log, scales.error_limits)
    if scales.error_limits is not None:
        ax_err.set_ylim(*scales.error_limits)
    _plot_sigma(ax_sigma, result, sigma_s, scales.sigma_log, scales.sigma_limits)
    _plot_p_cell(ax_p, result, label=col == 0)
    statuses: list[str] = []
    for ax in (ax_qd, ax_err, ax_sigma, ax_p):
        statuses += _mark_statuses(ax, result)
        _mark_stop(ax, result)
        ax.grid(True, linewidth=0.3, alpha=0.5)
    _column_title(ax_qd, result, scales.peaks[col])
    ax_p.set_xlabel("t [s]")
    if col > 0:
        for ax in (ax_qd, ax_err, ax_sigma, ax_p):
            ax.set_ylabel("")
    return statuses


def _plot_p_cell(ax: Axes, result: RunResult, label: bool) -> None:
    """The filter level p(t) of a comparison column, or why there is none."""
    if _filter_acted(result):
        _plot_p(ax, result, label=label)
        return
    ax.set_ylim(-0.04, 1.06)
    ax.text(
        0.5,
        0.5,
        _no_filter_note(result),
        transform=ax.transAxes,
        ha="center",
        va="center",
        fontsize=8,
        color="0.45",
    )


def _column_title(ax: Axes, result: RunResult, peak: float) -> None:
    """Controller name, peak ``|q̇|`` and peak ``‖e‖`` (and where it stopped) over a column."""
    top_error = float(np.nanmax(result.position_error)) if result.steps else float("nan")
    head = f"{result.controller}\npeak |q̇| {peak:.3g} rad/s · peak ‖e‖ {top_error:.2g} m"
    if result.error_message:
        head += f"\nstopped at t = {_time_end(result):.3g} s"
    _title(
        ax,
        head,
        fontsize=8.5,
        loc="center",
        color=_STOP_COLOUR if result.error_message else "black",
    )


def _comparison_legend(figure: Figure, joint_names: Sequence[str], statuses: list[str]) -> None:
    """Figure legend: one line per joint, one marker per backend status seen."""
    joints = [
        Line2D([], [], color=f"C{k % 10}", linewidth=1.2, label=name)
        for k, name in enumerate(joint_names)
    ]
    for name in statuses:
        marker, colour = STATUS_STYLE.get(name, _OTHER_STATUS)
        joints.append(
            Line2D([], [], linestyle="none", marker=marker, color=colour, label=f"status {name}")
        )
    figure.legend(
        handles=joints,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.948),
        ncols=min(len(joints), 8),
        fontsize=8,
        frameon=False,
    )


def _comparison_notes(
    figure: Figure, runs: Sequence[RunResult], scales: _ComparisonScales, sigma_s: float | None
) -> None:
    """The line under the legend: which axes are logarithmic, what the dashed lines mean."""
    notes = []
    if scales.band is not None:
        moving = [p for p in scales.peaks if np.isfinite(p) and p > 0.0]  # as _symlog_band
        ratio = max(moving) / min(moving)
        notes.append(f"q̇ on symlog axis: controller peaks differ by {ratio:.0f}×")
    if scales.error_log:
        notes.append("‖e‖ on log axis")
    if sigma_s is not None:
        notes.append(f"dashed: σ_S = {sigma_s:g}")
    if any(r.error_message for r in runs):
        notes.append("red dashed: run stopped early")
    figure.text(
        0.5, 0.948, "   ·   ".join(notes), ha="center", va="bottom", fontsize=8, color="0.3"
    )


#: One drawing job: ``("run", (result, path, sigma_s))`` or
#: ``("comparison", (results, path, title, sigma_s))``.
_Job = tuple[str, tuple[Any, ...]]


def _draw_job(job: _Job) -> None:
    """Run one drawing job (module level so worker processes can unpickle it)."""
    kind, args = job
    if kind == "run":
        plot_run(*args)
    else:
        plot_comparison(*args)


def _draw_on_pool(jobs: list[_Job], workers: int) -> None:
    """Draw ``jobs`` on ``workers`` forked processes; a stop signal never leaves one behind.

    The pool is made and every job submitted (which forks all workers: the ``fork`` context
    starts them at the first submit) with stop signals deferred
    (:func:`~otmm_qp.interrupt.deferred_stop_signals`): SIGTERM/SIGINT arriving while
    the pool starts once raised KeyboardInterrupt inside ``ProcessPoolExecutor`` start-up,
    leaving it half made (a traceback instead of exit 130). A deferred signal is raised as
    soon as the start-up is complete, inside the ``try`` that shuts the pool down; shutting
    down defers them too, so the pool is always shut down completely.
    """
    context = multiprocessing.get_context("fork")
    pool: ProcessPoolExecutor | None = None
    try:
        with interrupt.deferred_stop_signals():
            pool = ProcessPoolExecutor(
                max_workers=workers, mp_context=context, initializer=interrupt.worker_initialiser
            )
            results = pool.map(_draw_job, jobs)
        for _ in results:
            interrupt.check()  # re-raises the first failure of a worker, or a stop
    except BaseException:
        # Interrupted (SIGINT/SIGTERM) or failed: drop the queued drawings, then wait for
        # the workers to finish their current one and exit; none is left behind.
        if pool is not None:
            with contextlib.suppress(KeyboardInterrupt), interrupt.deferred_stop_signals():
                pool.shutdown(wait=True, cancel_futures=True)
        raise
    with interrupt.deferred_stop_signals():  # a stop now is raised once every worker exited
        pool.shutdown(wait=True)


def _draw_all(jobs: list[_Job], workers: int) -> None:
    """Draw ``jobs`` serially, or on ``workers`` forked processes where fork exists."""
    if workers > 1 and len(jobs) > 1 and "fork" in multiprocessing.get_all_start_methods():
        _draw_on_pool(jobs, min(workers, len(jobs)))
        return
    for job in jobs:
        _draw_job(job)
        interrupt.check()


def figure_hook(
    sigma_s: float,
    per_run: bool = True,
    workers: int | None = None,
    progress: TextIO | None = None,
) -> ExperimentHook:
    """An ``after_experiment`` hook for :func:`otmm_qp.runner.run_suite` that draws figures.

    Writes ``out_dir/<experiment>/<loop_mode>/<controller-slug>.png`` per run (when
    ``per_run``) and ``out_dir/<experiment>/<loop_mode>/comparison.png`` per loop mode.
    Does nothing when ``out_dir`` is None. The figures of one experiment are drawn on up
    to ``workers`` forked processes (each call opens and closes its own pool; nothing is
    kept between calls).

    Args:
        sigma_s: Threshold σ_S drawn on the σ_min panels.
        per_run: Also write one figure per run.
        workers: Drawing processes; None: up to 2, bounded by the CPU count. 1: serial.
        progress: Where to write one line per experiment's figures (count, seconds), or None.

    Returns:
        The hook.
    """
    if workers is None:
        workers = max(1, min(2, os.cpu_count() or 1))

    def after_experiment(
        prepared: PreparedExperiment, records: list[RunRecord], out_dir: Path | None
    ) -> None:
        if out_dir is None:
            return
        name = prepared.config.name
        # Same order as the runner's (config order), so a PNG is named like its CSV.
        stems = unique_names(dict.fromkeys(r.result.controller for r in records))
        modes: dict[str, list[RunResult]] = {str(m): [] for m in prepared.loop_modes}
        for record in records:
            modes.setdefault(record.result.loop_mode, []).append(record.result)
        comparisons: list[_Job] = []
        runs: list[_Job] = []
        for label, results in modes.items():
            if not results:
                continue
            folder = out_dir / safe_name(name) / safe_name(label)
            folder.mkdir(parents=True, exist_ok=True)
            title = f"{name} · {label}"
            comparisons.append(("comparison", (results, folder / "comparison.png", title, sigma_s)))
            if per_run:
                for result in results:
                    path = folder / f"{stems[result.controller]}.png"
                    runs.append(("run", (result, path, sigma_s)))
        tic = time.perf_counter()
        _draw_all(comparisons + runs, workers)  # the larger comparisons first
        if progress is not None:
            seconds = time.perf_counter() - tic
            print(
                f"  figures: {name}: {len(comparisons)} comparisons + {len(runs)} runs "
                f"in {seconds:.1f} s",
                file=progress,
                flush=True,
            )

    return after_experiment


__all__ = ["ExperimentHook", "figure_hook", "plot_comparison", "plot_run"]

"""The one table of metrics: name, label, unit, number format and direction.

Every reader indexes it — the ``summary.csv``/``summary.md`` columns, the run report's table
and ranking, the Pareto index, the study rows and the study report — so a new metric is one
:class:`Metric` row here plus its value in :func:`~otmm_qp.metrics.metrics.compute_metrics`
(and its test). A study metric (a column a study row adds beyond ``compute_metrics``, computed
in ``otmm_qp/studies/``) is one row of :data:`STUDY_METRICS` plus its value where the study
computes it; the study report's lists (:data:`STUDY_MEDIANS`, :data:`STUDY_PAIRED`,
:data:`STUDY_OBJECTIVES`) name rows of either table.
"""

from __future__ import annotations

from dataclasses import dataclass

from otmm_qp.exceptions import ConfigError
from otmm_qp.status import Status


@dataclass(frozen=True)
class Metric:
    """One metric of a run.

    Attributes:
        name: Column name in ``summary.csv`` and the study's episode rows.
        label: Short human label (tables, figures).
        unit: Unit without brackets (``m``, ``rad/s``, ``µs/step``), or ``""``.
        fmt: ``format`` spec of a value in tables (``""``: ``str``).
        lower_is_better: True for costs (errors, speeds, counts of bad steps), False for
            qualities, None for descriptive values (times, step counts).
    """

    name: str
    label: str
    unit: str = ""
    fmt: str = ".3g"
    lower_is_better: bool | None = True

    @property
    def heading(self) -> str:
        """``label [unit]``, or the label alone when there is no unit."""
        return f"{self.label} [{self.unit}]" if self.unit else self.label


#: Every metric :func:`~otmm_qp.metrics.metrics.compute_metrics` returns, in column order.
METRICS: tuple[Metric, ...] = (
    Metric("max_error", "max err", "m", ".2e"),
    Metric("rms_error", "rms err", "m", ".2e"),
    Metric("max_error_window", "max err window", "m", ".2e"),
    Metric("rms_error_window", "rms err window", "m", ".2e"),
    Metric("final_error", "final err", "m", ".2e"),
    Metric("max_orientation_error", "max orientation err", "rad", ".2e"),
    Metric("rms_orientation_error", "rms orientation err", "rad", ".2e"),
    Metric("max_joint_speed", "max ‖q̇‖∞", "rad/s"),
    Metric("initial_jump", "initial jump", "rad/s"),
    Metric("chattering", "chattering Σ‖Δq̇‖₁", "rad/s"),
    Metric("max_jump", "max ‖Δq̇‖∞", "rad/s"),
    Metric("accel_sign_changes", "accel. sign changes", "", "d"),
    Metric("min_sigma", "min σ", "", ".2e", lower_is_better=False),
    Metric("t_min_sigma", "t at min σ", "s", lower_is_better=None),
    Metric("steps_below_sigma_s", "steps σ<σS", "", "d", lower_is_better=None),
    Metric("max_weak_speed", "max |v_minᵀq̇|", "rad/s"),
    Metric("blow_up", "blow-up", "", ""),
    Metric("position_violations", "limit viol.", "steps", ".0f"),
    Metric("max_position_excess", "max position excess", "rad"),
    Metric("velocity_violations", "speed-limit viol.", "steps", ".0f"),
    Metric("max_velocity_excess", "max speed excess", "rad/s"),
    *(
        Metric(f"status_{s.value}", f"steps {s.value}", "", "d", lower_is_better=None)
        for s in Status
    ),
    Metric("step_time_median_us", "median", "µs/step", ".1f"),
    Metric("step_time_p99_us", "p99", "µs/step", ".1f"),
    Metric("steps", "steps", "", "d", lower_is_better=None),
    Metric("completed", "completed", "", "", lower_is_better=False),
    # What the plant (otmm_qp.plants) and the conditioning stages make meaningful; descriptive
    # (None) so the run report's ranking stays on the controller's own metrics.
    Metric("max_actual_joint_speed", "max ‖q̇_act‖∞", "rad/s", lower_is_better=None),
    Metric("speed_gap_max", "max ‖q̇_cmd − q̇_act‖∞", "rad/s", lower_is_better=None),
    Metric("speed_gap_rms", "rms ‖q̇_cmd − q̇_act‖∞", "rad/s", lower_is_better=None),
    Metric("peak_torque_ratio", "peak |τ|/τ_max", "", ".2f", lower_is_better=None),
    Metric("saturated_steps", "torque-saturated", "steps", "d", lower_is_better=None),
    Metric("conditioned_steps", "conditioned", "steps", "d", lower_is_better=None),
    Metric("filter_switches", "filter on/off switches", "", "d", lower_is_better=None),
    Metric("status_switches", "status switches", "", "d", lower_is_better=None),
    # The command stream as the arm's interface sees it (otmm_qp.plants.interface).
    Metric("max_command_acceleration", "max |q̈_cmd|", "rad/s²"),
    Metric("max_command_jerk", "max |q⃛_cmd|", "rad/s³"),
    Metric("command_acceleration_violations", "accel. over interface", "steps", "d"),
    Metric("command_jerk_violations", "jerk over interface", "steps", "d"),
)

#: Columns a study row adds to :data:`METRICS`, computed in ``otmm_qp/studies/``:
#: ``oracle_relative_error`` = max_error − reference.max_error (``studies/rows.py``),
#: the speed and jump ratios to each joint's own velocity limit (``studies/criteria.py``).
STUDY_METRICS: tuple[Metric, ...] = (
    Metric("oracle_relative_error", "oracle-relative max error", "m"),
    Metric("max_speed_ratio", "peak |q̇_j|/q̇_max,j", ""),
    Metric("max_jump_ratio", "max |Δq̇_j|/q̇_max,j", ""),
)
#: Metrics the study report summarises by median + bootstrap interval (after the headline
#: accuracy), in column order.
STUDY_MEDIANS: tuple[str, ...] = ("rms_error", "max_error", "max_joint_speed", "max_jump")
#: Metrics the study report compares pairwise (the headline accuracy is prepended).
STUDY_PAIRED: tuple[str, ...] = ("max_joint_speed",)
#: The Pareto objectives of a study group (the headline accuracy is prepended): all minimised.
STUDY_OBJECTIVES: tuple[str, ...] = ("max_joint_speed", "max_jump")

_BY_NAME = {m.name: m for m in (*METRICS, *STUDY_METRICS)}


def metric(name: str) -> Metric:
    """The row of ``name``.

    Raises:
        ConfigError: Not a metric (the message lists them).
    """
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ConfigError(
            "metric", f"unknown metric {name!r:.60}; known: {', '.join(_BY_NAME)}"
        ) from None


def columns(*names: str) -> tuple[tuple[str, str, str], ...]:
    """``(name, heading, fmt)`` of each named metric, for table writers."""
    return tuple((m.name, m.heading, m.fmt) for m in map(metric, names))

r"""Run metrics, defined in one place.

All speeds in [rad/s], errors in [m] (position) or [rad] (orientation), times in [s].

* ``max_error`` / ``rms_error``: max and RMS of ‖e_pos‖ over the run; ``*_window``:
  the same within ``±window/2`` [s] of the time of minimum σ_min (the "singular window").
* ``max_joint_speed``: :math:`\max_{k\ge1} \|\dot q_k\|_\infty`, excluding step 0, whose jump
  from rest is reported as ``initial_jump`` = :math:`\|\dot q_0\|_\infty`.
* ``chattering``: :math:`\sum_{k\ge 1}\|\dot q_k - \dot q_{k-1}\|_1` (steps from 0; the jump
  from rest at k = 0 is the initial jump); ``max_jump``: the largest
  :math:`\|\dot q_k-\dot q_{k-1}\|_\infty`, k ≥ 1.
* ``accel_sign_changes``: number of sign changes of each joint's acceleration
  :math:`(\dot q_k - \dot q_{k-1})/dt`, summed over joints, ignoring |accel| below 1e-6 rad/s².
* ``min_sigma`` and ``t_min_sigma``; ``steps_below_sigma_s``: steps with σ_min < σ_S.
* ``max_weak_speed``: :math:`\max_k |v_{min}^\top \dot q_k|`.
* ``blow_up``: any non-finite step, or :math:`\|\dot q\|_\infty` above ``blow_up_speed``.
* ``position_violations`` / ``max_position_excess``: steps with a joint outside its position
  limits and the largest excess [rad]; the same for velocity limits.
* ``status_<name>``: count of backend statuses; ``step_time_median_us`` / ``_p99_us``.

What the plant (:mod:`otmm_qp.plants`) and the conditioning stages make meaningful (for the
ideal plant the gap is 0, the torque ratio NaN and the counts 0):

* ``max_actual_joint_speed``: :math:`\max_{k\ge1}\|\dot q^{act}_k\|_\infty`, the speed the
  plant realised; ``speed_gap_max`` / ``speed_gap_rms``: max and RMS over the steps of
  :math:`\|\dot q^{cmd}_k - \dot q^{act}_k\|_\infty` [rad/s].
* ``peak_torque_ratio``: :math:`\max_{k,i} |\tau_{k,i}|/\tau_{max,i}` (MuJoCo plant; NaN
  otherwise); ``saturated_steps``: steps in which a joint torque was clipped at its limit.
* ``conditioned_steps``: steps on which a conditioning stage changed the command.
* ``filter_switches``: how often the filters' activity flips,
  :math:`\#\{k \ge 1: a_k \ne a_{k-1}\}` with ``a = filter_active`` (e.g. OTMM switching
  on and off under sensor noise); ``status_switches``: the same for the backend status.

The command stream as a streaming interface checks it (:mod:`otmm_qp.plants.interface`), from
rest (:math:`\dot q_{-1} = \dot q_{-2} = 0`):

* ``max_command_acceleration``: :math:`\max_{k \ge 0, i} |\dot q_{k,i} - \dot q_{k-1,i}|/dt`
  [rad/s²]; ``max_command_jerk``:
  :math:`\max_{k \ge 0, i} |\dot q_{k,i} - 2\dot q_{k-1,i} + \dot q_{k-2,i}|/(dt\,p)`
  [rad/s³], :math:`p = \min(dt, \text{period})` with the interface's period the plant declares
  (else :math:`p = dt`): the jerk the interface sees of a linearly interpolated command;
* ``command_acceleration_violations`` / ``command_jerk_violations``: steps on which some joint
  passes the interface's threshold the plant declares (``RunResult.command_limits``, relative
  tolerance 10⁻⁹); 0 when it declares none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from otmm_qp.metrics.table import METRICS
from otmm_qp.paper import SIGMA_S
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.status import DIVERGENCE_SPEED, Status

Metrics = dict[str, float | int | bool | str]


@dataclass(frozen=True)
class MetricSettings:
    """Parameters of the metrics.

    Attributes:
        sigma_s: Threshold for ``steps_below_sigma_s`` [task units].
        window: Width of the singular window around the σ_min minimum [s].
        blow_up_speed: Joint speed above which a run counts as blown up [rad/s].
    """

    sigma_s: float = SIGMA_S
    window: float = 1.0
    blow_up_speed: float = DIVERGENCE_SPEED


#: Column names of every metric, in order (the rows of :data:`~otmm_qp.metrics.table.METRICS`).
METRIC_NAMES: tuple[str, ...] = tuple(m.name for m in METRICS)


def _safe_max(values: np.ndarray) -> float:
    return float(np.max(values)) if values.size else 0.0


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else 0.0


def _accel_sign_changes(jumps: np.ndarray, dt: float) -> int:
    """Sign changes of each joint's acceleration ``jumps / dt``, summed (|a| < 1e-6 ignored)."""
    accel = jumps / dt
    signs = np.sign(np.where(np.abs(accel) < 1e-6, 0.0, accel))
    changes = 0
    for joint in signs.T:
        nonzero = joint[joint != 0.0]
        changes += int(np.count_nonzero(nonzero[1:] != nonzero[:-1]))
    return changes


def _limit_metrics(run: RunResult) -> Metrics:
    """Steps outside the position and velocity limits, and the largest excess of each."""
    out: Metrics = {}
    lower, upper = run.position_limits
    excess = np.maximum(np.maximum(lower - run.q, run.q - upper), 0.0)  # (N, nv) [rad]
    out["position_violations"] = int(np.count_nonzero(np.any(excess > 1e-9, axis=1)))
    out["max_position_excess"] = _safe_max(excess)
    speed_excess = np.maximum(np.abs(run.qdot) - run.velocity_limits, 0.0)
    out["velocity_violations"] = int(np.count_nonzero(np.any(speed_excess > 1e-9, axis=1)))
    out["max_velocity_excess"] = _safe_max(speed_excess)
    return out


def compute_metrics(run: RunResult, settings: MetricSettings | None = None) -> Metrics:
    """All metrics of ``run`` (see the module docstring for definitions)."""
    settings = settings or MetricSettings()
    out: Metrics = {}
    error = run.position_error
    out["max_error"] = _safe_max(error)
    out["rms_error"] = _rms(error)
    if run.steps:
        k_min = int(np.argmin(run.sigma_min))
        t_min = float(run.t[k_min])
        window = np.abs(run.t - t_min) <= settings.window / 2.0
        out["min_sigma"] = float(run.sigma_min[k_min])
        out["t_min_sigma"] = t_min
    else:
        window = np.zeros(0, dtype=bool)
        out["min_sigma"] = float("nan")
        out["t_min_sigma"] = float("nan")
    out["max_error_window"] = _safe_max(error[window])
    out["rms_error_window"] = _rms(error[window])
    out["final_error"] = float(error[-1]) if error.size else float("nan")
    orientation = run.orientation_error
    out["max_orientation_error"] = (
        _safe_max(orientation) if orientation is not None else float("nan")
    )
    out["rms_orientation_error"] = _rms(orientation) if orientation is not None else float("nan")

    speed = np.max(np.abs(run.qdot), axis=1) if run.steps else np.zeros(0)  # ‖q̇_k‖∞
    out["initial_jump"] = float(speed[0]) if speed.size else 0.0
    out["max_joint_speed"] = _safe_max(speed[1:])
    jumps = np.diff(run.qdot, axis=0)  # (N−1, nv): q̇_k − q̇_{k−1}, k ≥ 1
    out["chattering"] = float(np.abs(jumps).sum())
    out["max_jump"] = _safe_max(np.max(np.abs(jumps), axis=1)) if jumps.size else 0.0
    out["accel_sign_changes"] = _accel_sign_changes(jumps, run.dt)
    out["steps_below_sigma_s"] = int(np.count_nonzero(run.sigma_min < settings.sigma_s))
    out["max_weak_speed"] = _safe_max(run.weak_speed)
    nonfinite = bool(np.count_nonzero(run.status == Status.NONFINITE))
    out["blow_up"] = nonfinite or bool(np.any(speed > settings.blow_up_speed))

    out.update(_limit_metrics(run))
    for status in Status:  # every status, so relaxed and saturated steps show in summaries
        out[f"status_{status.value}"] = int(np.count_nonzero(run.status == status.value))
    micro = run.step_time * 1e6
    out["step_time_median_us"] = float(np.median(micro)) if micro.size else float("nan")
    out["step_time_p99_us"] = float(np.percentile(micro, 99)) if micro.size else float("nan")
    out["steps"] = run.steps
    out["completed"] = run.error_message is None
    out.update(plant_metrics(run))
    out.update(command_metrics(run))
    return out


def command_metrics(run: RunResult) -> Metrics:
    """Commanded acceleration and jerk, and the steps over the interface's thresholds."""
    out: Metrics = {}
    qdot = np.asarray(run.qdot, dtype=float)
    padded = np.vstack([np.zeros((2, qdot.shape[1])), qdot]) if run.steps else np.zeros((2, 0))
    acceleration = np.abs(np.diff(padded, axis=0)[1:]) / run.dt  # (N, nv), from rest
    period = min(run.dt, run.command_limits[2] or run.dt)
    jerk = np.abs(np.diff(padded, n=2, axis=0)) / (run.dt * period)  # (N, nv)
    out["max_command_acceleration"] = _safe_max(acceleration)
    out["max_command_jerk"] = _safe_max(jerk)
    for name, values, limit in (
        ("command_acceleration_violations", acceleration, run.command_limits[0]),
        ("command_jerk_violations", jerk, run.command_limits[1]),
    ):
        over = values > np.asarray(limit, dtype=float) * (1.0 + 1e-9) if limit else None
        out[name] = 0 if over is None else int(np.count_nonzero(np.any(over, axis=1)))
    return out


def _switches(values: np.ndarray) -> int:
    """Number of ``k ≥ 1`` with ``values[k] != values[k-1]``."""
    return int(np.count_nonzero(values[1:] != values[:-1])) if values.size > 1 else 0


def plant_metrics(run: RunResult) -> Metrics:
    """Speed gap, torques, conditioning and switching counts (see the module docstring)."""
    out: Metrics = {}
    actual = run.actual_qdot
    speed = np.max(np.abs(actual), axis=1) if run.steps else np.zeros(0)
    out["max_actual_joint_speed"] = _safe_max(speed[1:])
    gap = np.max(np.abs(run.qdot - actual), axis=1) if run.steps else np.zeros(0)
    out["speed_gap_max"] = _safe_max(gap)
    out["speed_gap_rms"] = _rms(gap)
    ratio = run.torque_ratio
    finite = ratio[np.isfinite(ratio)] if ratio is not None else np.zeros(0)
    out["peak_torque_ratio"] = float(np.max(finite)) if finite.size else float("nan")
    out["saturated_steps"] = (
        int(np.count_nonzero(run.saturated)) if run.saturated is not None else 0
    )
    out["conditioned_steps"] = (
        int(np.count_nonzero(run.conditioned)) if run.conditioned is not None else 0
    )
    out["filter_switches"] = _switches(np.asarray(run.filter_active, dtype=bool))
    out["status_switches"] = _switches(np.asarray(run.status, dtype=object))
    return out

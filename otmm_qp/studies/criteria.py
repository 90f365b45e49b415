r"""Success of a study episode and the causes of its failure, judged against the robot.

An episode row is judged by one of two readings, chosen per task by the reference's
``reference.achievable`` column (the offline-optimal ``oracle`` rows, see ``docs/studies.md``):

* **achievable** (or no reference stored): the tolerances hold —
  ``max_error ≤ max_position_error`` [m] and ``max_orientation_error ≤ max_orientation_error``
  [rad];
* **not achievable** (``reference.achievable`` is false and ``reference.status`` is not
  ``failed``: the reference's label is ``unachievable`` or ``undecided``): *graceful* —
  within ``f_e`` of one known path's pair of errors, the reference's best path (so that path
  itself always passes): ``max_error ≤ f_e · reference.position_error`` and
  ``max_orientation_error ≤ f_e · reference.max_orientation_error`` (falling back to
  ``reference.max_error``, the position optimum, for a study stored without
  ``reference.position_error``), back on the path at the end
  (``final_error ≤ max(max_position_error, f_e · reference.final_error)`` when the
  reference's final error is known) and no chatter
  (:math:`\max_{k \ge 1, j} |\dot q_{k,j} - \dot q_{k-1,j}| / \dot q_{max,j} \le f_c`).

In both readings the speed bound holds, the position limits are kept and nothing blows up.
The speed bound is per joint, from the robot's own velocity limits:
:math:`\max_{k \ge 1, j} |\dot q_{k,j}| / \dot q_{max,j} \le f_v` (``joint_speed_factor``),
unless an absolute ``max_joint_speed`` [rad/s] on :math:`\|\dot q_k\|_\infty` is given, which
then replaces it. A robot without velocity limits has no default speed bound.

Failure causes (:data:`FAILURE_CAUSES`): ``error`` (tolerance or graceful error bound),
``speed``, ``position_limit``, ``blow_up``, ``stuck`` (the episode stopped before its end),
``chatter`` (unachievable tasks only), ``interface_abort`` (the commanded acceleration or jerk
passed the thresholds the plant's interface declares, :mod:`otmm_qp.plants.interface`: the arm
would have aborted the motion) and ``run_error`` (no episode: task generation or controller
build failed).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from otmm_qp.metrics.table import metric
from otmm_qp.studies.columns import number

if TYPE_CHECKING:
    from otmm_qp.simulation.run_result import RunResult
    from otmm_qp.studies.schema import SuccessCriteria

#: Every cause :func:`failure_causes` can name, in report order.
FAILURE_CAUSES: tuple[str, ...] = (
    "error",
    "speed",
    "position_limit",
    "blow_up",
    "stuck",
    "chatter",
    "interface_abort",
    "run_error",
)
#: Steps over the interface's thresholds (``interface_abort``, :mod:`otmm_qp.plants.interface`).
INTERFACE_COLUMNS: tuple[str, ...] = (
    "command_acceleration_violations",
    "command_jerk_violations",
)
#: Row columns added by :func:`speed_ratios` (rows of :data:`~otmm_qp.metrics.table.STUDY_METRICS`).
RATIO_COLUMNS: tuple[str, ...] = tuple(
    metric(name).name for name in ("max_speed_ratio", "max_jump_ratio")
)


def speed_ratios(run: RunResult) -> dict[str, float]:
    r"""Peak joint speed and one-step jump relative to each joint's velocity limit [-].

    ``max_speed_ratio`` = :math:`\max_{k \ge 1, j} |\dot q_{k,j}| / \dot q_{max,j}` (step 0,
    the jump from rest, excluded as in ``max_joint_speed``); ``max_jump_ratio`` =
    :math:`\max_{k \ge 1, j} |\dot q_{k,j} - \dot q_{k-1,j}| / \dot q_{max,j}`. An infinite
    limit gives ratio 0 for that joint; a non-finite ``q̇`` gives ``inf``.

    Args:
        run: A finished run; ``qdot`` has shape ``(N, nv)``, ``velocity_limits`` ``(nv,)``.
    """
    qdot = np.asarray(run.qdot, dtype=float)
    limits = np.asarray(run.velocity_limits, dtype=float)
    if qdot.shape[0] < 2:
        return dict.fromkeys(RATIO_COLUMNS, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.abs(qdot[1:]) / limits
        jump = np.abs(np.diff(qdot, axis=0)) / limits
    out = {}
    for name, values in zip(RATIO_COLUMNS, (speed, jump), strict=True):
        out[name] = float(np.max(np.nan_to_num(values, nan=math.inf)))
    return out


def _above(value: float, bound: float | None) -> bool:
    """Whether a known value exceeds a given bound (unknown values and bounds never fail)."""
    return bound is not None and math.isfinite(bound) and not math.isnan(value) and value > bound


def is_achievable(row: dict[str, Any]) -> bool:
    """Whether the row is judged by the tolerances (not by the graceful criteria).

    True when the reference found the task achievable, or no reference says otherwise (none
    stored, or it ``failed``: its best error is unknown).
    """
    achievable = row.get("reference.achievable")
    if row.get("reference.status") == "failed":
        return True
    return achievable is None or bool(achievable) or _is_nan(achievable)


def _is_nan(value: Any) -> bool:
    return isinstance(value, float) and math.isnan(value)


def _error_causes(row: dict[str, Any], criteria: SuccessCriteria) -> bool:
    """Whether the error criterion of the row's reading fails."""
    if is_achievable(row):
        return _above(number(row, "max_error"), criteria.max_position_error) or _above(
            number(row, "max_orientation_error"), criteria.max_orientation_error
        )
    factor = criteria.graceful.error_factor
    reference = number(row, "reference.position_error")
    if math.isnan(reference):
        reference = number(row, "reference.max_error")
    orientation = number(row, "reference.max_orientation_error")
    final = number(row, "reference.final_error")
    final_bound = max(criteria.max_position_error or 0.0, factor * final)
    return (
        _above(number(row, "max_error"), factor * reference)
        or _above(number(row, "max_orientation_error"), factor * orientation)
        or (criteria.graceful.return_to_path and _above(number(row, "final_error"), final_bound))
    )


def failure_causes(row: dict[str, Any], criteria: SuccessCriteria) -> tuple[str, ...]:
    """The criteria an episode row fails, in :data:`FAILURE_CAUSES` order (empty: success).

    Args:
        row: An episode row: the metrics of ``compute_metrics``, ``status``, the
            :data:`RATIO_COLUMNS` and, when the task has a reference, its ``reference.*``
            columns. Missing metrics are not judged.
        criteria: The study's criteria.
    """
    if row.get("status") == "error":
        return ("run_error",)
    causes = []
    if _error_causes(row, criteria):
        causes.append("error")
    if criteria.max_joint_speed is not None:
        fast = _above(number(row, "max_joint_speed"), criteria.max_joint_speed)
    else:
        fast = _above(number(row, "max_speed_ratio"), criteria.joint_speed_factor)
    if fast:
        causes.append("speed")
    if criteria.no_limit_violation and int(row.get("position_violations") or 0) > 0:
        causes.append("position_limit")
    if criteria.no_blow_up and bool(row.get("blow_up")):
        causes.append("blow_up")
    if not row.get("completed"):
        causes.append("stuck")
    if not is_achievable(row) and _above(
        number(row, "max_jump_ratio"), criteria.graceful.max_jump_factor
    ):
        causes.append("chatter")
    if any(int(row.get(name) or 0) > 0 for name in INTERFACE_COLUMNS):
        causes.append("interface_abort")  # the arm's interface would have aborted the motion
    return tuple(causes)

r"""Information made explicit: what a controller may know of the desired path ahead.

A :class:`~otmm_qp.trajectories.trajectory.Trajectory` declares its
:attr:`~otmm_qp.trajectories.trajectory.Trajectory.lookahead` ``L`` [s]: at time ``t`` the
values :math:`x_d(t + \tau)`, :math:`0 \le \tau \le L`, are known. A backend declares the
preview it reads, :attr:`~otmm_qp.backends.backend.Backend.preview_horizon` ``H`` [s] (None:
causal, it sees only the present command). A run needs :math:`H \le L`;
:func:`check_preview` refuses any other pairing in one line before any compute, and
:func:`information_class` is the label a study stores per row (``causal`` or ``preview H s``).
"""

from __future__ import annotations

import math

from otmm_qp.exceptions import PreviewUnavailable
from otmm_qp.robots.robot import FloatArray
from otmm_qp.trajectories.trajectory import Trajectory

__all__ = ["CAUSAL", "check_preview", "information_class", "window"]

#: The information class of a backend that reads only the present command.
CAUSAL = "causal"


def information_class(horizon: float | None) -> str:
    """``causal`` (``horizon`` None) or ``preview H s`` (e.g. ``preview 0.5 s``)."""
    return CAUSAL if horizon is None else f"preview {horizon:g} s"


def check_preview(trajectory: Trajectory, horizon: float | None, field: str = "horizon") -> None:
    """Refuse a preview the trajectory cannot give (nothing to check for a causal backend).

    Args:
        trajectory: The run's desired motion.
        horizon: The preview ``H`` [s] the backend reads, or None (causal).
        field: Config field blamed in the message.

    Raises:
        PreviewUnavailable: ``H`` exceeds the trajectory's ``lookahead`` (or it has none).
    """
    if horizon is None:
        return
    lookahead = float(getattr(trajectory, "lookahead", 0.0))
    if not (math.isfinite(horizon) and horizon <= lookahead):
        raise PreviewUnavailable(field, trajectory.name, horizon, lookahead)


def window(trajectory: Trajectory, t: float, taus: FloatArray) -> list[FloatArray]:
    r"""The desired task values :math:`x_d(t + \tau_i)` of a preview window.

    Args:
        trajectory: A motion whose ``lookahead`` covers ``max τ`` (:func:`check_preview`).
        t: Present time [s].
        taus: Offsets :math:`\tau_i \ge 0` [s], shape ``(K,)``.

    Returns:
        ``K`` task values (points ``(n,)`` or poses ``(4, 4)``).
    """
    return [trajectory.position(t + float(tau)) for tau in taus]

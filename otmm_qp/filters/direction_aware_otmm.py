r"""Direction-aware OTMM: suppress the singular component only while it drives σ_min down."""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any, ClassVar

from otmm_qp.exceptions import ParameterError
from otmm_qp.filters.otmm import DEFAULT_SIGMA_S, OtmmFilter, _full_left_basis
from otmm_qp.filters.p_functions import DEFAULT_GAIN_FACTOR, check_gain_cap
from otmm_qp.filters.task_filter import FilterOutput, FilterReport, TaskFilter
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.singularity import sigma_min_rate
from otmm_qp.state import KinematicState
from otmm_qp.validation import Constraints, Interval, check_params

_FINITE = Interval(Real, None, None)


class DirectionAwareOtmmFilter(TaskFilter):
    r"""OTMM (paper eq. 8) applied only to the part of ``ẋ`` that drives σ_min toward 0.

    With :math:`c = u_s^\top\dot x` the command along the weakest left singular vector and
    :math:`r = \partial\sigma_{min}/\partial q \cdot v_s = u_s^\top W \dot J(q, v_s)\, v_s`
    [task units/rad] the sensitivity of σ_min to joint motion along :math:`v_s`
    (:func:`otmm_qp.singularity.sigma_min_rate`, analytic for planar and Pinocchio arms), the
    singular component moves the joints by :math:`\omega = g\,c\,v_s` with the gain
    :math:`g = (1-p)/\sigma`, so it changes σ_min at the rate :math:`\dot\sigma_s = r\,g\,c`.
    Its unsuppressed relative rate, with the gain capped at ``G``, is

    .. math:: \lambda = \frac{r\,c\,\min(1/\sigma, G)}{\sigma}\quad[1/s].

    A two-state switch with hysteresis decides (``approach_rate < leave_rate``):
    *approaching* once :math:`\lambda <` ``approach_rate``, *leaving* once
    :math:`\lambda >` ``leave_rate``; in between the state is kept, so the switch cannot
    chatter on noise around λ = 0. The filter is

    .. math::
        \dot x_m = \dot x - p\,c\,u_s,\qquad
        p = \begin{cases}
        \max\big(p_{base}(\sigma),\ 1 - G\sigma,\ 1 - \dfrac{G\sigma^2}{\sigma_0},\
            1 - \dfrac{\beta\sigma^2}{dt\,\max(0, -r\,c)}\big) & \text{approaching}\\[4pt]
        \max(0,\ 1 - G\sigma) & \text{leaving}\end{cases}
        \qquad (\sigma \le \sigma_S;\ p = 0 \text{ above}).

    * Leaving (e.g. the paper's Fig. 7 start at σ = 0) is unhindered except for the gain
      cap, which bounds the joint speed along :math:`v_s` by :math:`G|c|` (see
      :func:`otmm_qp.filters.p_functions.bounded`); a switch of state changes q̇ by at most
      :math:`G|c|`.
    * Approaching uses the base p with the same cap, a taper below σ_0 (``taper_sigma``)
      that makes the gain :math:`G\sigma/\sigma_0` vanish at σ = 0 — so crossing a
      singularity (where :math:`v_s` reverses, e.g. the UR5 wrist flip) does not flip the
      joint speed by :math:`2G|c|` in one step — and a discrete barrier on the
      singular channel: :math:`|\dot\sigma_s|\,dt \le \beta\sigma`, i.e. σ_min shrinks by at
      most a fraction β per step through this channel. Its gain vanishes like σ as σ → 0,
      so a CLIK error that cannot be removed (a target beyond the reach) makes the arm
      settle at the boundary instead of overshooting through the singularity and chattering.

    Unbound (no robot), ``r`` is unknown: every step counts as approaching without the
    barrier, i.e. OTMM with the bounded-gain p and the taper. At σ = 0 exactly, p = 1 in
    both states.
    Structurally singular arms (fewer joints than task rows) fall back to plain OTMM.

    Args:
        sigma_s: Threshold σ_S > 0 [task units].
        p: Base p-function used while approaching (any registered name).
        p_params: Parameters of the base p.
        max_gain: Gain cap G ≥ 1/σ_S [rad/(task unit)]; ``None``: ``2/σ_S``.
        approach_rate: λ below which the state becomes approaching [1/s] (< leave_rate).
        leave_rate: λ above which the state becomes leaving [1/s].
        sigma_decay: Barrier fraction β ∈ (0, 1] per step.
        taper_sigma: Taper start σ_0 ∈ [0, σ_S] [task units]; ``None``: σ_S; 0: no taper.
    """

    name = "otmm_directional"
    parameter_constraints: ClassVar[Constraints] = {
        **{key: OtmmFilter.parameter_constraints[key] for key in ("sigma_s", "p", "p_params")},
        "max_gain": [Interval(Real, 0, None, closed="neither"), None],
        "approach_rate": Interval(Real, None, None, unit="1/s"),
        "leave_rate": Interval(Real, None, None, unit="1/s"),
        "sigma_decay": Interval(Real, 0, 1, closed="right"),
        "taper_sigma": [Interval(Real, 0, None, closed="left"), None],
    }

    def __init__(
        self,
        sigma_s: float = DEFAULT_SIGMA_S,
        p: str = "cbrt",
        p_params: Mapping[str, Any] | None = None,
        max_gain: float | None = None,
        approach_rate: float = -1.0,
        leave_rate: float = 1.0,
        sigma_decay: float = 0.5,
        taper_sigma: float | None = None,
    ) -> None:
        check_params(self, locals())
        self._base = OtmmFilter(sigma_s=sigma_s, p=p, p_params=p_params, corank=1)
        self.sigma_s = self._base.sigma_s
        if max_gain is None:
            max_gain = DEFAULT_GAIN_FACTOR / self.sigma_s
        check_gain_cap(max_gain, self.sigma_s)
        if not leave_rate > approach_rate:
            raise ParameterError(
                "leave_rate",
                f"must be a finite number > approach_rate ({approach_rate!r}), got {leave_rate!r}",
            )
        if taper_sigma is None:
            taper_sigma = self.sigma_s
        if not taper_sigma <= self.sigma_s:
            raise ParameterError(
                "taper_sigma", f"must be in [0, sigma_s = {self.sigma_s:g}], got {taper_sigma!r}"
            )
        self.taper_sigma = float(taper_sigma)
        self.max_gain = float(max_gain)
        self.approach_rate = float(approach_rate)
        self.leave_rate = float(leave_rate)
        self.sigma_decay = float(sigma_decay)
        self.robot: Robot | None = None
        self.dt = 0.0
        #: Current state of the switch (True: approaching).
        self.approaching = True
        #: λ of the last active step [1/s] (NaN when not evaluated).
        self.last_rate = float("nan")

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot (for ∂σ_min/∂q) and the period ``dt`` [s] of the barrier."""
        self.robot = robot
        self.dt = float(dt)

    def reset(self) -> None:
        """Start each run in the conservative (approaching) state."""
        self.approaching = True
        self.last_rate = float("nan")

    def apply(self, state: KinematicState, xdot: FloatArray) -> FilterOutput:
        """Filter the weighted command ``xdot``, shape ``(n,)``."""
        n = state.task_dim
        if state.sigma.size < n:  # structurally singular: σ_min ≡ 0, nothing to decide
            U = _full_left_basis(state)[0]
            u_s = U[:, n - 1]
            removed_along = float(u_s @ xdot)
            return FilterOutput(
                xdot - removed_along * u_s, FilterReport(True, 0.0, 1.0, abs(removed_along))
            )
        sigma = float(state.sigma[-1])
        if sigma > self.sigma_s:
            self.approaching = True  # re-enter the window conservatively
            return FilterOutput(xdot, FilterReport(False, sigma, 0.0, 0.0))
        u_s = state.U[:, -1]
        c = float(u_s @ xdot)
        cap = 1.0 - self.max_gain * sigma  # p ≥ cap ⇔ (1 − p)/σ ≤ G
        sensitivity = 0.0
        if sigma > 0.0 and self.robot is not None and c != 0.0:
            sensitivity = sigma_min_rate(self.robot, state, state.Vt[-1])  # r
            rate = sensitivity * c * min(1.0 / sigma, self.max_gain) / sigma  # λ [1/s]
            self.last_rate = rate
            if rate < self.approach_rate:
                self.approaching = True
            elif rate > self.leave_rate:
                self.approaching = False
        if self.approaching:
            p = max(self._base.p(sigma), cap)
            if sigma < self.taper_sigma:  # gain G·σ/σ_0 → 0: no flip when crossing σ = 0
                p = max(p, 1.0 - self.max_gain * sigma * sigma / self.taper_sigma)
            drive = -sensitivity * c  # > 0 when the channel shrinks σ_min
            if drive > 0.0 and self.dt > 0.0:
                p = max(p, 1.0 - self.sigma_decay * sigma * sigma / (self.dt * drive))
        else:
            p = max(0.0, cap)
        p = min(p, 1.0)
        removed_along = p * c
        return FilterOutput(
            xdot - removed_along * u_s, FilterReport(p > 0.0, sigma, p, abs(removed_along))
        )

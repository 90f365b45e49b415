r"""The position limit around the predicted rest state, with a margin, a braking bound, a ramp.

:class:`~otmm_qp.limits.position_limit.PositionLimit` bounds the step from the measured
:math:`\tilde\theta`; on a plant that delays, lags or measures with noise the joint then moves
past the limit by the travel still in flight, or by the measurement error. This limit bounds
the step around the predicted rest state :math:`\hat R = \tilde\theta + r`
(:mod:`otmm_qp.limits.command_prediction`: the commands still in flight and a lag's residual
travel after a zero command) and shrinks the limits by a margin:

.. math::
    m = m_0 + k\,\sigma + r_q/2,\qquad
    \frac{g}{dt}(\theta_{min} + m - \hat R) \le \dot q \le \frac{g}{dt}(\theta_{max} - m - \hat R)

(``margin`` :math:`m_0`, ``noise_bound`` k times the noise σ, half the encoder quantum
:math:`r_q`: the measurement error is below :math:`k\sigma + r_q/2` but with probability
:math:`P(|\mathcal N(0,1)| > k)`). Optionally, with :math:`d^+ = \theta_{max} - m - \hat R` and
:math:`d^- = \hat R - \theta_{min} - m` [rad]:

* braking distance (``deceleration`` :math:`a_{dec}` [rad/s²]): a joint can stop before the
  limit decelerating at :math:`a_{dec}`,
  :math:`-\sqrt{2a_{dec}\max(d^-,0)} \le \dot q \le \sqrt{2a_{dec}\max(d^+,0)}`;
* the command path's rate limit (``rate_limit`` :math:`a` [rad/s²], by default what the
  plant declares, :mod:`otmm_qp.plants.rate_limit`): the limiter
  :math:`v_k = v_{k-1} + \mathrm{clip}(\dot q_k - v_{k-1}, \pm a\,dt)` is run on the commands
  sent, so :math:`\hat R` integrates what the arm is actually sent, and the command is bounded
  so that the limiter can still stop in time — after :math:`v_k` it travels at most
  :math:`v_k\,dt + v_k^2/(2a)` (the limiter decelerates at :math:`a`; the sum of its steps is
  below the integral), hence
  :math:`\dot q \le -a\,dt + \sqrt{(a\,dt)^2 + 2a\max(d^+,0)}` (and likewise below). The bound
  is monotone in :math:`v_k` and :math:`v_k` in :math:`\dot q`, and braking at :math:`a` from
  a feasible :math:`v_{k-1}` stays feasible, so it never asks the limiter for more than
  :math:`a`: :math:`\hat R` — and the servo reference it is — never passes the shrunk limit;
* Drake's ramp (``ramp_start`` :math:`d_1` > ``ramp_stop`` :math:`d_0` [rad]): the speed
  towards a limit falls linearly from :math:`\dot q_{max}` at :math:`d_1` to 0 at :math:`d_0`,
  :math:`\dot q \le \dot q_{max}\,\mathrm{clip}((d^+ - d_0)/(d_1 - d_0), 0, 1)` (and likewise
  below; :math:`\dot q_{max} = g\,d_1/dt` for a joint without a speed limit).

Every plant-dependent parameter defaults to ``plant``: what the run's plant declares
(:mod:`otmm_qp.plants.declaration`), nothing for the ideal plant; then, without margin, braking
or ramp, the box equals ``position``'s bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ParameterError
from otmm_qp.limits.command_prediction import CommandPrediction
from otmm_qp.limits.limit import Box, per_joint
from otmm_qp.limits.position_limit import PositionLimit, StoppingBound
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.rate_limit import rate_limit_step
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, OneOf, check_params, positive_per_joint

__all__ = ["FROM_PLANT", "PredictedPositionLimit"]

#: The value of a plant-dependent parameter that means "what the plant declares".
FROM_PLANT = "plant"
_PLANT = OneOf(FROM_PLANT)


def _non_negative(unit: str) -> Interval:
    return Interval(Real, 0, None, closed="left", unit=unit)


class PredictedPositionLimit(PositionLimit):
    r"""Position box around the predicted rest state, shrunk by a margin (see the module).

    Args:
        gain: ``g ∈ (0, 1]`` [-]: the fraction of the distance to the (shrunk) limit one step
            may close.
        margin: :math:`m_0 \ge 0` [rad]: a fixed distance kept from each limit.
        delay: Command latency N [periods], an integer ≥ 0, or ``plant``.
        tau: Servo lag τ ≥ 0 [s] (0: none), or ``plant`` (the plant's lags, a cascade).
        noise: Measurement noise σ ≥ 0 [rad], or ``plant``.
        quantum: Encoder quantum ≥ 0 [rad], or ``plant``.
        servo_frequency: Bandwidth f > 0 [Hz] of a servo following the integrated command (inf:
            none; adds the margin :math:`\dot q_{max,i}/(e\,2\pi f)`), or ``plant``.
        reference: ``measured`` (:math:`\hat R = \tilde\theta + r`), ``command``
            (:math:`\hat R` the integrated commands from the first measurement) or ``plant``
            (``command`` when the plant's body is a servo that follows the integrated
            command, else ``measured``).
        noise_bound: k ≥ 0 [-]: the margin counts k σ of noise.
        deceleration: :math:`a_{dec}` > 0 [rad/s²] (inf: that joint unbounded), a scalar or one
            per joint, or None: no braking bound.
        rate_limit: The command path's rate limit :math:`a` > 0 [rad/s²] (inf: that joint
            unlimited), a scalar or one per joint; ``plant`` (default): what the plant declares
            (none for a plant without a rate limiter); None: not modelled.
        ramp_start: :math:`d_1` > 0 [rad] where the ramp starts, or None: no ramp.
        ramp_stop: :math:`d_0 \ge 0` [rad] where the ramp reaches 0, below ``ramp_start``.

    Raises:
        ParameterError: A value out of range, NaN, or ``ramp_stop ≥ ramp_start``.
    """

    name: ClassVar[str] = "predicted_position"
    priority: ClassVar[int] = 1
    parameter_constraints: ClassVar[Constraints] = {
        "gain": Interval(Real, 0, 1, closed="right"),
        "margin": _non_negative("rad"),
        "delay": [Interval(Integral, 0, None, closed="left", unit="periods"), _PLANT],
        "tau": [_non_negative("s"), _PLANT],
        "noise": [_non_negative("rad"), _PLANT],
        "quantum": [_non_negative("rad"), _PLANT],
        "servo_frequency": [
            Interval(Real, 0, None, closed="neither", unit="Hz", inf_ok=True),
            _PLANT,
        ],
        "reference": [OneOf("measured", "command"), _PLANT],
        "noise_bound": _non_negative("-"),
        "deceleration": [positive_per_joint("rad/s²"), None],
        "ramp_start": [Interval(Real, 0, None, closed="neither", unit="rad"), None],
        "rate_limit": [positive_per_joint("rad/s²"), _PLANT, None],
        "ramp_stop": _non_negative("rad"),
    }

    def __init__(
        self,
        gain: float = 0.5,
        margin: float = 0.0,
        delay: int | str = FROM_PLANT,
        tau: float | str = FROM_PLANT,
        noise: float | str = FROM_PLANT,
        quantum: float | str = FROM_PLANT,
        servo_frequency: float | str = FROM_PLANT,
        reference: str = FROM_PLANT,
        noise_bound: float = 4.0,
        deceleration: float | Sequence[float] | None = None,
        ramp_start: float | None = None,
        ramp_stop: float = 0.0025,
        rate_limit: float | Sequence[float] | str | None = FROM_PLANT,
    ) -> None:
        check_params(self, locals())
        if ramp_start is not None and not ramp_stop < ramp_start:
            raise ParameterError(
                "ramp_stop",
                f"must be < ramp_start = {ramp_start:g} rad, got {ramp_stop!r}",
            )
        super().__init__(gain)
        self.margin = float(margin)
        self.delay, self.tau, self.noise, self.quantum = delay, tau, noise, quantum
        self.servo_frequency = servo_frequency
        self.reference = reference
        self.noise_bound = float(noise_bound)
        self.deceleration = deceleration
        self.ramp_start = None if ramp_start is None else float(ramp_start)
        self.ramp_stop = float(ramp_stop)
        self.rate_limit = rate_limit
        self.declared = PlantDeclaration()

    def declare_plant(self, declaration: PlantDeclaration) -> None:
        """Take the plant's declaration for every parameter left at ``plant``."""
        self.declared = declaration

    def servo(self) -> float:
        """The servo bandwidth f [Hz] in force (inf: no servo)."""
        if self.servo_frequency == FROM_PLANT:
            return self.declared.servo_frequency
        return float(self.servo_frequency)

    def integrates(self) -> bool:
        r"""Whether :math:`\hat R` is the integrated command (``reference`` in force)."""
        if self.reference == FROM_PLANT:
            return bool(np.isfinite(self.servo()))
        return self.reference == "command"

    def rate(self) -> float | Sequence[float] | None:
        """The rate limit :math:`a` [rad/s²] in force (None: none)."""
        if isinstance(self.rate_limit, str):  # FROM_PLANT
            declared = self.declared.acceleration
            if not declared:
                return None
            return declared[0] if len(declared) == 1 else declared
        return self.rate_limit

    def model(self) -> tuple[CommandPrediction, float]:
        """The prediction model and the total margin :math:`m` [rad] in force."""
        declared = self.declared
        delay = declared.delay if self.delay == FROM_PLANT else int(self.delay)
        lags = declared.lags if self.tau == FROM_PLANT else (float(self.tau),)
        noise = declared.noise if self.noise == FROM_PLANT else float(self.noise)
        quantum = declared.quantum if self.quantum == FROM_PLANT else float(self.quantum)
        margin = self.margin + self.noise_bound * noise + 0.5 * quantum
        return CommandPrediction(delay, lags), margin

    def bind(self, robot: Robot, dt: float) -> None:
        """Build the prediction, the shrunk limits ``(2, nv)`` and the optional bounds.

        Raises:
            ParameterError: The margin leaves a joint no range (``2m`` ≥ its range).
            DimensionError: ``deceleration`` is neither a scalar nor of shape ``(nv,)``.
        """
        super().bind(robot, dt)
        nv = robot.nv
        self.prediction, margin = self.model()
        self.prediction.bind(nv, dt)
        margins = np.full(nv, margin)
        frequency = self.servo()
        if np.isfinite(frequency):
            speed = np.array(robot.velocity_limits, dtype=float)
            margins += np.where(np.isfinite(speed), speed, 0.0) / (
                math.e * 2.0 * math.pi * frequency
            )
        #: The total margin per joint [rad], shape ``(nv,)``.
        self.margins: FloatArray = margins
        self.total_margin = float(np.max(margins, initial=0.0))
        if self.total_margin > 0.0:
            narrow = self._theta[1] - self._theta[0] <= 2.0 * margins
            if np.any(narrow):
                i = int(np.argmax(narrow))
                raise ParameterError(
                    "margin",
                    f"the total margin {margins[i]:g} rad (margin + noise_bound·noise + "
                    f"quantum/2 + servo) leaves joint {robot.joint_names[i]!r} no range",
                )
            self._theta[0] += margins
            self._theta[1] -= margins
        self._rest: FloatArray = np.empty(nv)
        self._integrate = self.integrates()
        self._started = False
        self._extra: FloatArray = np.empty(nv)
        #: Distances to the shrunk limits ``[θ_min + m − R̂; θ_max − m − R̂]`` [rad], ``(2, nv)``.
        self._distance: FloatArray = np.empty((2, nv))
        decel = per_joint(self.deceleration, "deceleration", nv)
        self._twice_decel = None if decel is None else 2.0 * decel
        rate = per_joint(self.rate(), "rate_limit", nv)
        #: The rate limiter's :math:`a\,dt` [rad/s] per joint (None: no rate limit).
        self._rate_step: FloatArray | None = None
        if rate is not None:
            self._stoppable = StoppingBound(rate, dt)
            self._rate_step = self._stoppable.step
            self._limited: FloatArray = np.zeros(nv)
        self._ramp_speed: FloatArray | None = None
        if self.ramp_start is not None:
            speed = np.array(robot.velocity_limits, dtype=float)
            fallback = self.gain * self.ramp_start / dt
            self._ramp_speed = np.where(np.isfinite(speed), speed, fallback) / (
                self.ramp_start - self.ramp_stop
            )

    def reset(self) -> None:
        """Nothing in flight (a new run)."""
        super().reset()
        if hasattr(self, "prediction"):
            self.prediction.reset()
            if self._rate_step is not None:
                self._limited.fill(0.0)
        self._started = False

    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """The box of the module docstring [rad/s] into ``out``.

        ``qdot_prev`` is the last command sent: it enters the prediction (through the rate
        limiter's model when there is one).
        """
        rest = theta
        if self._rate_step is not None and (self._started or not self._integrate):
            qdot_prev = rate_limit_step(qdot_prev, self._limited, self._rate_step, self._limited)
        if self._integrate:
            rest = self._rest
            if self._started:
                np.multiply(qdot_prev, self.dt, out=self._extra)
                rest += self._extra
            else:
                np.copyto(rest, theta)
                self._started = True
        elif self.prediction.active:
            rest = np.add(theta, self.prediction.advance(qdot_prev), out=self._rest)
        super().compute_box(rest, qdot_prev, out)
        if self._twice_decel is None and self._ramp_speed is None and self._rate_step is None:
            return out  # the position box alone (the distances below feed only these two)
        distance = self._distance  # [θ_min + m − R̂; θ_max − m − R̂]
        np.subtract(self._theta_min, rest, out=distance[0])
        np.subtract(self._theta_max, rest, out=distance[1])
        extra = self._extra
        if self._twice_decel is not None:
            np.maximum(distance[1], 0.0, out=extra)
            extra *= self._twice_decel
            np.sqrt(extra, out=extra)
            np.minimum(out.upper, extra, out=out.upper)
            np.minimum(distance[0], 0.0, out=extra)
            extra *= -self._twice_decel
            np.sqrt(extra, out=extra)
            np.negative(extra, out=extra)
            np.maximum(out.lower, extra, out=out.lower)
        if self._rate_step is not None:
            np.minimum(out.upper, self._stoppable(distance[1]), out=out.upper)
            np.negative(distance[0], out=extra)
            bound = self._stoppable(extra)
            np.negative(bound, out=bound)
            np.maximum(out.lower, bound, out=out.lower)
        if self._ramp_speed is not None:
            self._ramp(distance[1], out.upper, np.minimum, 1.0)
            self._ramp(distance[0], out.lower, np.maximum, -1.0)
        return out

    def _ramp(self, distance: FloatArray, bound: FloatArray, keep: np.ufunc, sign: float) -> None:
        """``bound ← keep(bound, sign·q̇_max·clip((sign·distance − d0)/(d1 − d0), 0, 1))``."""
        extra, speed = self._extra, self._ramp_speed
        assert speed is not None and self.ramp_start is not None
        np.multiply(distance, sign, out=extra)
        extra -= self.ramp_stop
        np.clip(extra, 0.0, self.ramp_start - self.ramp_stop, out=extra)
        extra *= speed
        extra *= sign
        keep(bound, extra, out=bound)

r"""What a plant declares about itself, so a controller's limits need not be told twice.

A stage states the parts of its model a controller can compensate (:meth:`Plant.declares`);
the chain combines them (:meth:`~otmm_qp.plants.chain.PlantChain.declares`) and the loop hands
the result to the controller before a run (``Controller.declare_plant``). The
``predicted_position`` limit (:mod:`otmm_qp.limits.predicted_position_limit`) reads it for
every parameter it was not given explicitly.

Combination over the stages of a chain:

.. math::
    N = \sum_s N_s,\qquad \tau = (\tau_1, \dots, \tau_L)\ \text{(a cascade)},\qquad
    \sigma = \sqrt{\textstyle\sum_s \sigma_s^2},\qquad r = \sum_s r_s,\qquad
    a = \min_s a_s,\qquad a^{if} = \min_s a^{if}_s,\qquad j^{if} = \min_s j^{if}_s

(latencies add; first-order lags commute with each other and with a latency, so a cascade in
any order is the same filter; independent Gaussian noises add in variance; the rounding errors
of several quantisers add at worst; of several rate limiters the strictest per joint is
declared — exact for one, which is what the presets have). A rate limiter commutes with a
latency (both are time-invariant and start at rest) but not with a lag: the prediction models
it ahead of the lags, so :class:`~otmm_qp.plants.chain.PlantChain` refuses a rate limiter
listed after a lag. The interface's own thresholds on the command stream (:math:`a^{if}`,
:math:`j^{if}`, :mod:`otmm_qp.plants.interface`: what a streaming interface checks and aborts
on, without changing the command) combine like rate limits, the strictest per joint.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

__all__ = ["PlantDeclaration", "combine"]


class PlantDeclaration(NamedTuple):
    r"""A plant's declared command path and measurement.

    Attributes:
        delay: Command latency N [control periods], an integer ≥ 0.
        lags: Time constants τ [s] of the first-order lags on the command path (zero-order
            hold exact: α = 1 − e^{−dt/τ}), each ≥ 0 (0: no lag).
        noise: Standard deviation σ of the measured joint position [rad], ≥ 0.
        quantum: Encoder quantum r [rad] (rounding error ≤ r/2), ≥ 0 (0: none).
        servo_frequency: Bandwidth f [Hz] of a position servo that follows the integrated
            command (a MuJoCo body), or inf when the body integrates the command exactly.
        acceleration: Rate limit a [rad/s²] of the command path
            (:mod:`otmm_qp.plants.rate_limit`): empty (none), one value for every joint, or one
            per joint (inf: that joint unlimited).
        interface_acceleration: The interface's threshold on the commanded acceleration
            :math:`|\dot q_k - \dot q_{k-1}|/dt` [rad/s²] (:mod:`otmm_qp.plants.interface`):
            empty (none), one value, or one per joint.
        interface_jerk: Its threshold on the commanded jerk [rad/s³], likewise.
        interface_period: The interface's own period p [s] (0: the control period), which
            sets the jerk it sees of a command interpolated linearly between control periods.
    """

    delay: int = 0
    lags: tuple[float, ...] = ()
    noise: float = 0.0
    quantum: float = 0.0
    servo_frequency: float = math.inf
    acceleration: tuple[float, ...] = ()
    interface_acceleration: tuple[float, ...] = ()
    interface_jerk: tuple[float, ...] = ()
    interface_period: float = 0.0


def combine(parts: Iterable[PlantDeclaration]) -> PlantDeclaration:
    """The declaration of a chain of stages (see the module docstring).

    Raises:
        ValueError: Two rate limits of different lengths (neither one value nor the same
            number of joints).
    """
    delay, noise, quantum, frequency = 0, 0.0, 0.0, math.inf
    lags: list[float] = []
    acceleration: tuple[float, ...] = ()
    interface: list[tuple[float, ...]] = [(), ()]
    period = 0.0
    for part in parts:
        delay += part.delay
        lags.extend(part.lags)
        noise = math.hypot(noise, part.noise)  # √(Σσ²) without squaring: no overflow
        quantum += part.quantum
        frequency = min(frequency, part.servo_frequency)
        if part.acceleration:
            acceleration = _stricter(acceleration, part.acceleration)
        for i, value in enumerate((part.interface_acceleration, part.interface_jerk)):
            if value:
                interface[i] = _stricter(interface[i], value)
        if part.interface_period > 0.0:
            period = part.interface_period if period == 0.0 else min(period, part.interface_period)
    return PlantDeclaration(
        delay,
        tuple(lags),
        noise,
        quantum,
        frequency,
        acceleration,
        interface_acceleration=interface[0],
        interface_jerk=interface[1],
        interface_period=period,
    )


def _stricter(first: tuple[float, ...], second: tuple[float, ...]) -> tuple[float, ...]:
    """The per-joint minimum of two rate limits (a one-value limit applies to every joint)."""
    if not first:
        return second
    if len(first) != len(second) and 1 not in (len(first), len(second)):
        raise ValueError(f"rate limits of {len(first)} and {len(second)} joints cannot be combined")
    return tuple(float(x) for x in np.minimum(np.array(first), np.array(second)))

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
    a = \min_s a_s

(latencies add; first-order lags commute with each other and with a latency, so a cascade in
any order is the same filter; independent Gaussian noises add in variance; the rounding errors
of several quantisers add at worst; of several rate limiters the strictest per joint is
declared — exact for one, which is what the presets have). A rate limiter commutes with a
latency (both are time-invariant and start at rest) but not with a lag: the prediction models
it ahead of the lags, so :class:`~otmm_qp.plants.chain.PlantChain` refuses a rate limiter
listed after a lag.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

__all__ = ["PlantDeclaration", "combine"]


class PlantDeclaration(NamedTuple):
    """A plant's declared command path and measurement.

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
    """

    delay: int = 0
    lags: tuple[float, ...] = ()
    noise: float = 0.0
    quantum: float = 0.0
    servo_frequency: float = math.inf
    acceleration: tuple[float, ...] = ()


def combine(parts: Iterable[PlantDeclaration]) -> PlantDeclaration:
    """The declaration of a chain of stages (see the module docstring).

    Raises:
        ValueError: Two rate limits of different lengths (neither one value nor the same
            number of joints).
    """
    delay, noise, quantum, frequency = 0, 0.0, 0.0, math.inf
    lags: list[float] = []
    acceleration: tuple[float, ...] = ()
    for part in parts:
        delay += part.delay
        lags.extend(part.lags)
        noise = math.hypot(noise, part.noise)  # √(Σσ²) without squaring: no overflow
        quantum += part.quantum
        frequency = min(frequency, part.servo_frequency)
        if part.acceleration:
            acceleration = _stricter(acceleration, part.acceleration)
    return PlantDeclaration(delay, tuple(lags), noise, quantum, frequency, acceleration)


def _stricter(first: tuple[float, ...], second: tuple[float, ...]) -> tuple[float, ...]:
    """The per-joint minimum of two rate limits (a one-value limit applies to every joint)."""
    if not first:
        return second
    if len(first) != len(second) and 1 not in (len(first), len(second)):
        raise ValueError(f"rate limits of {len(first)} and {len(second)} joints cannot be combined")
    return tuple(float(x) for x in np.minimum(np.array(first), np.array(second)))

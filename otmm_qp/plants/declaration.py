r"""What a plant declares about itself, so a controller's limits need not be told twice.

A stage states the parts of its model a controller can compensate (:meth:`Plant.declares`);
the chain combines them (:meth:`~otmm_qp.plants.chain.PlantChain.declares`) and the loop hands
the result to the controller before a run (``Controller.declare_plant``). The
``predicted_position`` limit (:mod:`otmm_qp.limits.predicted_position_limit`) reads it for
every parameter it was not given explicitly.

Combination over the stages of a chain:

.. math::
    N = \sum_s N_s,\qquad \tau = (\tau_1, \dots, \tau_L)\ \text{(a cascade)},\qquad
    \sigma = \sqrt{\textstyle\sum_s \sigma_s^2},\qquad r = \sum_s r_s

(latencies add; first-order lags commute with each other and with a latency, so a cascade in
any order is the same filter; independent Gaussian noises add in variance; the rounding errors
of several quantisers add at worst).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

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
    """

    delay: int = 0
    lags: tuple[float, ...] = ()
    noise: float = 0.0
    quantum: float = 0.0
    servo_frequency: float = math.inf


def combine(parts: Iterable[PlantDeclaration]) -> PlantDeclaration:
    """The declaration of a chain of stages (see the module docstring)."""
    delay, variance, quantum, frequency = 0, 0.0, 0.0, math.inf
    lags: list[float] = []
    for part in parts:
        delay += part.delay
        lags.extend(part.lags)
        variance += part.noise**2
        quantum += part.quantum
        frequency = min(frequency, part.servo_frequency)
    return PlantDeclaration(delay, tuple(lags), math.sqrt(variance), quantum, frequency)

r"""Joint encoders: seeded Gaussian noise and quantisation on what the controller sees.

.. math::
    \tilde\theta_k = r\,\operatorname{round}\!\big((\theta_k + \varepsilon_k)/r\big),\qquad
    \varepsilon_k \sim \mathcal N(0, \sigma^2 I),\quad r = 2\pi / \text{counts}

on the joint coordinates θ (nv,) of the true configuration; without ``counts`` there is no
rounding. The noise is drawn from ``numpy.random.default_rng(seed)``, restarted at every
:meth:`reset`, so a run is reproducible. Metrics use the true state, never this one.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import ClassVar

import numpy as np

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import Constraints, Interval, check_params

__all__ = ["SensorPlant"]


#: Finest encoder resolution accepted [counts/rev] (2³²: beyond any encoder).
MAX_COUNTS = 2**32


class SensorPlant(Plant):
    """Noisy, quantised joint-position measurement.

    Args:
        noise: Standard deviation σ of the joint-position noise [rad], finite and >= 0.
        counts: Encoder counts per revolution (quantum 2π/counts [rad]), an integer > 0, or
            None for no quantisation.
        seed: Seed of the noise generator, an integer >= 0.
    """

    name: ClassVar[str] = "sensor"
    exact_measurement: ClassVar[bool] = False

    parameter_constraints: ClassVar[Constraints] = {
        "noise": Interval(Real, 0, None, closed="left", unit="rad"),
        "counts": [Interval(Integral, 0, MAX_COUNTS, closed="right", unit="counts/rev"), None],
        "seed": Interval(Integral, 0, None, closed="left"),
    }

    def __init__(self, noise: float = 0.0, counts: int | None = None, seed: int = 0) -> None:
        check_params(self, locals())
        self.noise = float(noise)
        self.counts = None if counts is None else int(counts)
        self.seed = int(seed)
        self.quantum = 2.0 * math.pi / self.counts if self.counts is not None else 0.0
        self._rng = np.random.default_rng(self.seed)
        self._robot: Robot | None = None

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Restart the noise generator from ``seed``."""
        self._robot = robot
        self._rng = np.random.default_rng(self.seed)

    def measure(self, q: FloatArray) -> FloatArray:
        """The measured configuration (nq,) of the true ``q`` (nq,)."""
        if self._robot is None:
            raise RuntimeError("SensorPlant.measure called before reset")
        theta = self._robot.joint_coordinates(q)
        if self.noise > 0.0:
            theta = theta + self._rng.normal(0.0, self.noise, theta.shape)
        if self.quantum > 0.0:
            theta = self.quantum * np.round(theta / self.quantum)
        return self._robot.configuration(theta)

    def declares(self, dt: float) -> PlantDeclaration:
        """The noise σ [rad] and the quantum 2π/counts [rad] (0 without counts)."""
        return PlantDeclaration(noise=self.noise, quantum=self.quantum)

    def label(self) -> str:
        """``sensor(noise=…,counts=…)``."""
        parts = [f"noise={self.noise:g}"]
        if self.counts is not None:
            parts.append(f"counts={self.counts}")
        return f"sensor({','.join(parts)})"

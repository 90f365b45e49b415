r"""The travel still in flight: where each joint comes to rest if every later command is zero.

A plant whose command path is a latency of N periods and a cascade of first-order lags
(:mod:`otmm_qp.plants.delay`, :mod:`otmm_qp.plants.lag`) turns the commands :math:`u_j`
[rad/s] into actual velocities :math:`v_j = (h * u)_j` with a non-negative impulse response
:math:`h` of unit sum (each lag :math:`x \leftarrow x + \alpha(\text{in} - x)`,
:math:`\alpha = 1 - e^{-dt/\tau}`). The arm, at :math:`\theta_k` after
:math:`\theta_{k+1} = \theta_k + v_k\,dt`, therefore comes to rest under zero commands at

.. math::
    R_k = \theta_k + r_k,\qquad r_k = dt\sum_{j<k}(u_j - \hat v_j)

(the unit sum: every command's travel :math:`u_j\,dt` is eventually realised in full), with
:math:`\hat v` the declared model run on the commands sent. Two facts make :math:`R` the state
to bound:

* :math:`R_{k+1} = R_k + u_k\,dt` exactly: the new command moves the rest point by its own
  travel, so a box on :math:`u_k` keeps :math:`R` inside the limits;
* :math:`\theta_k = \sum_{m \le k} w_m R_m` with :math:`w_m \ge 0`, :math:`\sum w_m = 1`
  (summation by parts with the filter's non-decreasing step response), so :math:`\theta`
  never leaves an interval that every :math:`R_m` stays in.

:class:`CommandPrediction` keeps :math:`r_k` in preallocated arrays: one update per step,
O(nv (N + L)) and no allocation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from otmm_qp.robots.robot import FloatArray

__all__ = ["CommandPrediction"]


class CommandPrediction:
    r"""The residual travel :math:`r_k` [rad], shape ``(nv,)``, of a latency and lags.

    Args:
        delay: Latency N [control periods], ≥ 0.
        lags: Lag time constants τ [s], each ≥ 0 (0: none).

    Attributes:
        residual: :math:`r_k` [rad], shape ``(nv,)`` (after :meth:`bind`).
        active: Whether the model moves anything (N > 0 or some τ > 0); when False
            :attr:`residual` stays zero and :meth:`advance` is not needed.
    """

    def __init__(self, delay: int, lags: Sequence[float]) -> None:
        self.delay = int(delay)
        self.lags = tuple(float(tau) for tau in lags if tau > 0.0)
        self.active = self.delay > 0 or bool(self.lags)

    def bind(self, nv: int, dt: float) -> None:
        """Allocate for ``nv`` joints and the period ``dt`` [s]; start at rest."""
        self.dt = dt
        self.alphas = tuple(-math.expm1(-dt / tau) for tau in self.lags)
        self._queue: FloatArray = np.zeros((self.delay, nv))
        self._states: FloatArray = np.zeros((len(self.lags), nv))
        self._entering: FloatArray = np.zeros(nv)
        self._scratch: FloatArray = np.zeros(nv)
        self.residual: FloatArray = np.zeros(nv)
        self._head = 0

    def reset(self) -> None:
        """The arm at rest: nothing in flight."""
        self._queue.fill(0.0)
        self._states.fill(0.0)
        self.residual.fill(0.0)
        self._head = 0

    def advance(self, command: FloatArray) -> FloatArray:
        r"""Account for the command :math:`u_{k-1}` [rad/s] sent last period; return :math:`r_k`.

        :math:`r_k = r_{k-1} + dt\,(u_{k-1} - \hat v_{k-1})`, :math:`\hat v` the command
        ``N`` periods older passed through the lags.
        """
        entering = command
        if self.delay:
            slot = self._queue[self._head]
            np.copyto(self._entering, slot)
            np.copyto(slot, command)
            self._head = (self._head + 1) % self.delay
            entering = self._entering
        scratch = self._scratch
        for alpha, state in zip(self.alphas, self._states, strict=True):
            np.subtract(entering, state, out=scratch)
            scratch *= alpha
            state += scratch
            entering = state
        np.subtract(command, entering, out=scratch)
        scratch *= self.dt
        self.residual += scratch
        return self.residual

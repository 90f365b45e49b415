"""Circle traversed at constant speed."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots.robot import FloatArray
from otmm_qp.trajectories.trajectory import Trajectory
from otmm_qp.validation import ArrayOf, Constraints, Interval, OneOf, check_params


class CircleTrajectory(Trajectory):
    r"""Circle of radius ``r`` about ``centre``, one turn per ``period``.

    .. math::
        x_d(t) = c + r\,(\cos\phi(t)\,e_1 + \sin\phi(t)\,e_2),\qquad
        \phi(t) = \phi_0 \mp 2\pi t/T \quad(\texttt{constant}),\qquad
        \phi(t) = \phi_0 \mp 2\pi\,\text{turns}\;s(t/T_d) \quad(\texttt{quintic})

    (``−`` clockwise), ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` clipped to ``[0, 1]`` and ``T_d =
    turns·T``: the quintic profile starts and ends at rest and holds the end point after
    ``T_d``; the constant one keeps circling (the paper's law). ``e_1, e_2`` span the plane:
    the x–y plane in 2-D, or ``normal``'s
    orthogonal complement in 3-D. ``φ₀`` defaults to the angle of the circle point nearest
    to the start position.

    Args:
        start: Task value at the start configuration, shape ``(2,)`` or ``(3,)``.
        centre: Circle centre [m], shape ``(2,)`` or ``(3,)``.
        radius: Radius [m], > 0.
        period: Time for one turn [s], > 0.
        direction: ``clockwise`` or ``counterclockwise`` (seen from +normal).
        start_angle: φ₀ [rad]; nearest point to ``start`` when omitted.
        normal: Plane normal for 3-D circles (default +z).
        turns: Number of turns making up the natural duration.
        profile: ``constant`` (the paper's law, default) or ``quintic`` (smooth start and stop).
    """

    #: A planned motion: known in full at any time (:attr:`Trajectory.lookahead`).
    lookahead = math.inf

    name = "circle"

    parameter_constraints: ClassVar[Constraints] = {
        "centre": ArrayOf(Interval(Real, None, None, unit="m"), per="task coordinate"),
        "radius": Interval(Real, 0, None, closed="neither", unit="m"),
        "period": Interval(Real, 0, None, closed="neither", unit="s"),
        "direction": OneOf("clockwise", "counterclockwise"),
        "start_angle": [Interval(Real, None, None, unit="rad"), None],
        "normal": [ArrayOf(Interval(Real, None, None), length=3, per="coordinate"), None],
        "turns": Interval(Real, 0, None, closed="neither"),
        "profile": OneOf("constant", "quintic"),
    }

    def __init__(
        self,
        start: FloatArray,
        centre: Sequence[float],
        radius: float,
        period: float,
        direction: Literal["clockwise", "counterclockwise"] = "clockwise",
        start_angle: float | None = None,
        normal: Sequence[float] | None = None,
        turns: float = 1.0,
        profile: Literal["constant", "quintic"] = "constant",
    ) -> None:
        check_params(self, locals())
        if profile not in ("constant", "quintic"):
            raise ParameterError("profile", f"must be constant or quintic, got {profile!r}")
        self.profile = profile
        self.turns = float(turns)
        self.centre = np.asarray(centre, dtype=float)
        dim = self.centre.size
        if dim not in (2, 3):
            raise DimensionError("centre", (2,), self.centre.shape)
        if not radius > 0.0:
            raise ParameterError("radius", f"must be > 0 [m], got {radius}")
        if not period > 0.0:
            raise ParameterError("period", f"must be > 0 [s], got {period}")
        if direction not in ("clockwise", "counterclockwise"):
            raise ParameterError(
                "direction", f"must be clockwise or counterclockwise, got {direction!r}"
            )
        if not turns > 0.0:
            raise ParameterError("turns", f"must be > 0, got {turns}")
        self.radius = float(radius)
        self.period = float(period)
        self.duration = float(turns) * self.period
        self.sign = -1.0 if direction == "clockwise" else 1.0
        if dim == 2:
            self.e1, self.e2 = np.array([1.0, 0.0]), np.array([0.0, 1.0])
        else:
            n = np.asarray(normal if normal is not None else [0.0, 0.0, 1.0], dtype=float)
            if n.shape != (3,) or not np.linalg.norm(n) > 0:
                raise ConfigError("normal", "must be a nonzero 3-vector")
            n = n / np.linalg.norm(n)
            helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            self.e1 = np.cross(n, helper)
            self.e1 /= np.linalg.norm(self.e1)
            self.e2 = np.cross(n, self.e1)
        start_position = np.asarray(start, dtype=float)
        if start_position.ndim == 2:  # homogeneous pose: use its translation
            start_position = start_position[:dim, 3]
        if start_position.size < dim:  # a 3-D circle on a planar arm
            raise ParameterError(
                "centre",
                f"has {dim} coordinates but the robot's task position has "
                f"{start_position.size}: give a centre of {start_position.size} coordinates",
            )
        start_position = start_position[:dim]
        if start_angle is None:
            offset = start_position - self.centre
            start_angle = float(np.arctan2(offset @ self.e2, offset @ self.e1))
        self.start_angle = float(start_angle)

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Position [m] and velocity [m/s] on the circle at ``t`` [s]."""
        if self.profile == "quintic":
            tau = min(max(t / self.duration, 0.0), 1.0)
            sweep = self.sign * 2.0 * math.pi * self.turns  # [rad]
            phi = self.start_angle + sweep * tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
            moving = 0.0 <= t <= self.duration
            rate = sweep * 30.0 * tau**2 * (1.0 - tau) ** 2 / self.duration if moving else 0.0
        else:
            rate = self.sign * 2.0 * math.pi / self.period  # [rad/s]
            phi = self.start_angle + rate * t
        c, s = math.cos(phi), math.sin(phi)
        r, v = self.radius, self.radius * rate
        return self.centre + (r * c) * self.e1 + (r * s) * self.e2, (v * c) * self.e2 - (
            v * s
        ) * self.e1

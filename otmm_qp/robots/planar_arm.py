"""Planar serial arm with revolute joints and a 2-D position task (and its URDF / MJCF)."""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real
from typing import ClassVar

import numpy as np

from otmm_qp.exceptions import ConfigError, DimensionError, ParameterError
from otmm_qp.robots.peer_description import PeerDescription
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import ArrayOf, Constraints, InstanceOf, Interval

#: Name of the end-effector frame (URDF link) / site (MJCF) of generated planar models.
PLANAR_FRAME = "ee"


class PlanarArm(Robot):
    r"""Planar arm with ``m`` revolute joints; task = end-effector position (n = 2).

    .. math::
        x = \sum_{i=1}^{m} l_i \cos\theta_i,\quad y = \sum_{i=1}^{m} l_i \sin\theta_i,
        \quad \theta_i = \sum_{j \le i} q_j

    and :math:`J_{:,j} = \sum_{i \ge j} l_i(-\sin\theta_i, \cos\theta_i)`.

    Args:
        link_lengths: Link lengths [m], shape ``(m,)``, all > 0.
        limits: Optional joint position limits ``[[lower, upper], ...]`` [rad], shape ``(m, 2)``;
            unbounded when omitted.
        velocity_limits: Optional joint speed limits [rad/s], shape ``(m,)``; inf when omitted.
    """

    parameter_constraints: ClassVar[Constraints] = {
        "link_lengths": ArrayOf(Interval(Real, 0, None, closed="neither", unit="m"), per="link"),
        "limits": [
            InstanceOf(
                (list, tuple, np.ndarray),
                "a list of [lower, upper] [rad] per joint",
                exclude=(str,),
            ),
            None,
        ],
        "velocity_limits": [
            ArrayOf(
                Interval(Real, 0, None, closed="neither", unit="rad/s", inf_ok=True), per="joint"
            ),
            None,
        ],
    }

    task_kind = "position"

    def __init__(
        self,
        link_lengths: Sequence[float] | FloatArray,
        limits: Sequence[Sequence[float]] | None = None,
        velocity_limits: Sequence[float] | None = None,
    ) -> None:
        lengths = np.asarray(link_lengths, dtype=float)
        if lengths.ndim != 1 or lengths.size < 1:
            raise ParameterError("link_lengths", "must be a non-empty list of lengths [m]")
        if not np.all(np.isfinite(lengths)) or np.any(lengths <= 0.0):
            raise ParameterError(
                "link_lengths", f"every length must be > 0 [m], got {lengths.tolist()}"
            )
        self.link_lengths = lengths
        m = lengths.size
        self.name = f"planar{m}"
        if limits is None:
            self._lower = np.full(m, -np.inf)
            self._upper = np.full(m, np.inf)
        else:
            bounds = np.asarray(limits, dtype=float)
            if bounds.shape != (m, 2):
                raise DimensionError("limits", (m, 2), bounds.shape)
            if np.any(np.isnan(bounds)):
                raise ParameterError(
                    "limits", "must not be NaN; each row is [lower, upper] [rad] (±inf: none)"
                )
            if np.any(bounds[:, 0] >= bounds[:, 1]):
                raise ConfigError("limits", "each row must be [lower, upper] with lower < upper")
            self._lower, self._upper = bounds[:, 0].copy(), bounds[:, 1].copy()
        if velocity_limits is None:
            self._velocity = np.full(m, np.inf)
        else:
            speeds = np.asarray(velocity_limits, dtype=float)
            if speeds.shape != (m,):
                raise DimensionError("velocity_limits", (m,), speeds.shape)
            if np.any(np.isnan(speeds)) or np.any(speeds <= 0.0):
                raise ParameterError("velocity_limits", "every limit must be > 0 [rad/s]")
            self._velocity = speeds
        self._names = tuple(f"joint{i + 1}" for i in range(m))
        self._m = int(m)
        # Matrix forms of the cumulative sums keep kinematics() to a few numpy calls.
        self._prefix_sum = np.tril(np.ones((m, m)))  # θ = L q
        self._suffix_sum = np.triu(np.ones((m, m))).T  # column j of (links @ S): Σ_{i≥j}
        # Reach annulus: r_max = Σl, r_min = max(0, 2·max(l) − Σl).
        self.reach_max = float(lengths.sum())
        self.reach_min = float(max(0.0, 2.0 * lengths.max() - lengths.sum()))

    @property
    def joint_names(self) -> tuple[str, ...]:
        """``joint1 … jointm``."""
        return self._names

    @property
    def nv(self) -> int:
        """Number of joints ``m``."""
        return self._m

    @property
    def nq(self) -> int:
        """Number of joints ``m`` (revolute: one coordinate each)."""
        return self._m

    @property
    def task_dim(self) -> int:
        """Planar position: 2."""
        return 2

    @property
    def position_limits(self) -> tuple[FloatArray, FloatArray]:
        """Joint position limits [rad]."""
        return self._lower, self._upper

    @property
    def velocity_limits(self) -> FloatArray:
        """Joint speed limits [rad/s]."""
        return self._velocity

    def kinematics(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """End-effector position [m], shape ``(2,)``, and Jacobian, shape ``(2, m)``."""
        theta = self._prefix_sum @ q  # θ_i = Σ_{j≤i} q_j, (m,)
        links = self.link_lengths * np.array([np.cos(theta), np.sin(theta)])  # (2, m) [m]
        # Column j sums the links from j outward, rotated by +90°: (−Σy, Σx).
        outward = links @ self._suffix_sum  # (2, m)
        jacobian = np.array([-outward[1], outward[0]])
        return outward[:, 0].copy(), jacobian

    def jacobian_derivative(self, q: FloatArray, direction: FloatArray) -> FloatArray:
        r"""Analytic :math:`\dot J(q, d)`, shape ``(2, m)``.

        With :math:`\dot\theta = L d` (prefix sums), link ``i`` rotates at :math:`\dot\theta_i`:

        .. math:: \dot J_{:,j} = -\sum_{i \ge j} l_i \dot\theta_i (\cos\theta_i, \sin\theta_i)
        """
        theta = self._prefix_sum @ q
        theta_rate = self._prefix_sum @ np.asarray(direction, dtype=float)
        weighted = self.link_lengths * theta_rate
        rates = weighted * np.array([np.cos(theta), np.sin(theta)])  # (2, m)
        return np.asarray(-(rates @ self._suffix_sum), dtype=float)

    def can_reach(self, x: FloatArray) -> bool:
        """Whether ``x`` [m] lies in the reach annulus ``r_min ≤ ‖x‖ ≤ r_max``."""
        radius = float(np.hypot(x[0], x[1]))
        return self.reach_min - 1e-9 <= radius <= self.reach_max + 1e-9

    def peer_description(self) -> PeerDescription:
        """Generated URDF (:func:`planar_urdf`) and MJCF (:func:`planar_mjcf`); planar task.

        The end-effector frame/site is :data:`PLANAR_FRAME`; the limits written into the
        files are the arm's, so each call reflects the current limits.
        """
        return PeerDescription(
            urdf=planar_urdf(self),
            frame=PLANAR_FRAME,
            joint_names=self.joint_names,
            planar=True,
            mjcf=planar_mjcf(self),
        )


def _fmt(value: float) -> str:
    """``value`` with full double precision (17 significant digits)."""
    return f"{value:.17g}"


def planar_urdf(arm: PlanarArm) -> str:
    r"""URDF text of a planar arm, base fixed at the world origin.

    Joint ``i`` sits at the tip of link ``i−1`` (``origin xyz = (l_{i-1}, 0, 0)``) and turns
    about ``z``; finite limits give ``revolute`` joints, unbounded ones ``continuous``.
    Links get a unit point mass (Drake rejects massless bodies in some checks).

    Args:
        arm: The planar arm; lengths [m], limits [rad], speed limits [rad/s].

    Returns:
        URDF XML; the end-effector link is ``ee`` (:data:`PLANAR_FRAME`).
    """
    lower, upper = arm.position_limits
    speeds = arm.velocity_limits
    inertial = (
        '<inertial><mass value="1"/><origin xyz="0 0 0"/>'
        '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>'
    )
    lines = [f'<robot name="{arm.name}">', f'  <link name="base">{inertial}</link>']
    parent, offset = "base", 0.0
    for i, name in enumerate(arm.joint_names):
        bounded = bool(np.isfinite(lower[i]) and np.isfinite(upper[i]))
        speed = _fmt(float(speeds[i])) if np.isfinite(speeds[i]) else "0"
        limit = (
            f'<limit lower="{_fmt(lower[i])}" upper="{_fmt(upper[i])}" effort="0" '
            f'velocity="{speed}"/>'
            if bounded
            else f'<limit effort="0" velocity="{speed}"/>'
        )
        child = f"link{i + 1}"
        lines += [
            f'  <link name="{child}">{inertial}</link>',
            f'  <joint name="{name}" type="{"revolute" if bounded else "continuous"}">',
            f'    <parent link="{parent}"/><child link="{child}"/>',
            f'    <origin xyz="{_fmt(offset)} 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>',
            f"    {limit}",
            "  </joint>",
        ]
        parent, offset = child, float(arm.link_lengths[i])
    lines += [
        f'  <link name="{PLANAR_FRAME}">{inertial}</link>',
        f'  <joint name="{PLANAR_FRAME}_joint" type="fixed">',
        f'    <parent link="{parent}"/><child link="{PLANAR_FRAME}"/>',
        f'    <origin xyz="{_fmt(offset)} 0 0" rpy="0 0 0"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def planar_mjcf(arm: PlanarArm) -> str:
    r"""MJCF text of a planar arm, in radians.

    MJCF reads angles in *degrees* unless ``<compiler angle="radian"/>``; the joint ranges
    here are radians, so the compiler flag is set. Hinges turn about ``z``; unbounded joints
    are ``limited="false"``. The end-effector site is ``ee`` (:data:`PLANAR_FRAME`).

    Args:
        arm: The planar arm; lengths [m], limits [rad].

    Returns:
        MJCF XML.
    """
    lower, upper = arm.position_limits
    lines = [
        f'<mujoco model="{arm.name}">',
        '  <compiler angle="radian" autolimits="true"/>',
        '  <option integrator="Euler" gravity="0 0 0"/>',
        "  <worldbody>",
    ]
    offset, depth = 0.0, 2
    for i, name in enumerate(arm.joint_names):
        pad = "  " * depth
        bounded = bool(np.isfinite(lower[i]) and np.isfinite(upper[i]))
        limit = (
            f'limited="true" range="{_fmt(lower[i])} {_fmt(upper[i])}"'
            if bounded
            else 'limited="false"'
        )
        length = float(arm.link_lengths[i])
        lines += [
            f'{pad}<body name="link{i + 1}" pos="{_fmt(offset)} 0 0">',
            f'{pad}  <joint name="{name}" type="hinge" axis="0 0 1" {limit}/>',
            f'{pad}  <geom type="capsule" fromto="0 0 0 {_fmt(length)} 0 0" size="0.02" mass="1"/>',
        ]
        offset, depth = length, depth + 1
    lines.append(f'{"  " * depth}<site name="{PLANAR_FRAME}" pos="{_fmt(offset)} 0 0"/>')
    for level in range(depth - 1, 1, -1):
        lines.append(f"{'  ' * level}</body>")
    lines += ["  </worldbody>", "</mujoco>"]
    return "\n".join(lines) + "\n"

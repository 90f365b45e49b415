r"""The arm simulated by MuJoCo: rigid-body dynamics, gravity, joint servos with torque limits.

The MuJoCo model is the one the peers use (:func:`otmm_qp.robots.peer_models.mujoco_spec`: the
robot's URDF, inertias from its ``<inertial>`` elements; planar arms their generated MJCF).
Each joint gets a position servo fed by the integrated command plus a velocity servo on the
command (two MuJoCo joint actuators) and, by default, gravity compensation routed through
the same actuators:

.. math::
    q^{ref} \leftarrow q^{ref} + \dot q^{cmd}\,h,\qquad
    \tau = \operatorname{clip}\big(g(q) + K_p(q^{ref} - q) + K_d(\dot q^{cmd} - \dot q),\
    -\tau_{max},\ \tau_{max}\big)

with :math:`K_{p,i} = \omega^2 M_{ii}(q_0)`, :math:`K_{d,i} = 2\zeta\omega M_{ii}(q_0)`,
:math:`\omega = 2\pi f` (``frequency`` f [Hz], ``damping_ratio`` ζ) and :math:`M_{ii}(q_0)`
the joint's diagonal of the mass matrix at the start — a decoupled servo of bandwidth f on
the inertia the joint sees there. With ``command_cutoff`` :math:`f_c` [Hz] the command in both
terms is first low-passed every MuJoCo step (libfranka's command filter, see the argument): the
reference integrates the filtered command, whose unit DC gain leaves where it comes to rest
unchanged, and a command's step no longer reaches the velocity servo whole. The mass matrix
is the URDF links' plus ``armature``
:math:`I_a` [kg·m²] on its diagonal (each drive's reflected rotor inertia; without it a URDF
arm's ill-conditioned :math:`M` gives decentralised servos closed-loop modes several times
faster than f, which chatter at the torque limits). Contacts between the links (the peer
model's collision geometry) are simulated unless ``contacts`` is false (the kinematic model and
the task generators ignore self-collision; the presets and the plants study set it false).
τ_max [N·m] is the URDF ``effort`` of each joint, applied
as MuJoCo's joint ``actuatorfrcrange`` (the clip acts on the sum). The command is held over
the control period ``dt``; MuJoCo steps ``ceil(dt / timestep)`` times at
``h = dt / substeps`` in between, with its ``implicitfast`` integrator (the servo damping is
integrated implicitly, so stiff servos stay stable). The controller sees MuJoCo's ``qpos``
after the last substep; the period's actual velocity is its ``qvel`` there.

Reported per period: the largest :math:`|\tau_i|/\tau_{max,i}` of the applied (clipped)
torques, never above 1, and whether any joint asked for more than its limit. A state that
becomes non-finite or faster than ``unstable_speed`` makes the period unstable: the loop
stores why and stops the run (its other runs keep their results).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real
from typing import Any, ClassVar, Literal

import numpy as np

from otmm_qp.exceptions import ConfigError, ParameterError, RobotLoadError
from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.plants.plant import Plant, PlantStep
from otmm_qp.plants.urdf_dynamics import effort_limits
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.validation import (
    ArrayOf,
    Boolean,
    Constraints,
    Interval,
    OneOf,
    check_params,
    per_joint,
)

__all__ = ["MujocoPlant"]

MUJOCO_HINT = "pip install mujoco (or otmm-qp[peers])"


def _one_line(error: BaseException) -> str:
    """MuJoCo's (multi-line) message on one line."""
    return " ".join(str(error).split())


#: Smallest MuJoCo timestep accepted [s].
MIN_TIMESTEP = 1e-6
#: Most MuJoCo steps per control period (``ceil(dt / timestep)``).
MAX_SUBSTEPS = 1_000


class MujocoPlant(Plant):
    r"""MuJoCo body with per-joint PD servos on the integrated command.

    Args:
        frequency: Servo bandwidth f [Hz], finite and > 0.
        damping_ratio: Servo damping ratio ζ, finite and > 0.
        timestep: Largest MuJoCo time step [s], finite and > 0 (the period is split evenly).
        gravity: Whether gravity (−9.81 m/s² along world z) acts.
        compensation: ``gravity`` adds the gravity torque (MuJoCo's gravity compensation,
            routed through the joint's actuators so it counts against the torque limit);
            ``none`` leaves gravity to the servo's PD.
        effort_limit: Torque limit [N·m] for joints whose URDF has no positive ``effort``;
            None (default) refuses such a URDF.
        unstable_speed: Joint speed above which the simulation counts as unstable [rad/s].
        armature: Reflected rotor inertia :math:`I_a` [kg·m²] added to each joint's inertia
            (MuJoCo's joint ``armature``: :math:`M(q) + \operatorname{diag}(I_a)`), ≥ 0, a scalar
            or one per joint; 0 (default): the URDF's link inertias alone.
        contacts: Whether the links collide with each other (the peer model's collision
            geometry), True (default, as before the parameter existed); False: no contact is
            simulated, as in the kinematic model.
        command_cutoff: Cutoff :math:`f_c` [Hz] of a first-order low-pass on the command,
            applied every MuJoCo step before both servos (libfranka's ``lowpassFilter``:
            :math:`u \leftarrow u + \beta(\dot q^{cmd} - u)`,
            :math:`\beta = 2\pi f_c h/(2\pi f_c h + 1)`, at rest at the start), or None
            (default): the held command itself.

    Raises:
        ParameterError: A parameter out of range (naming it).
        ConfigError: MuJoCo is not installed (with the install hint).
    """

    name: ClassVar[str] = "mujoco"
    body: ClassVar[bool] = True
    parameter_constraints: ClassVar[Constraints] = {
        "frequency": Interval(Real, 0, None, closed="neither", unit="Hz"),
        "damping_ratio": Interval(Real, 0, None, closed="neither"),
        "timestep": Interval(Real, MIN_TIMESTEP, None, closed="left", unit="s"),
        "gravity": Boolean(),
        "compensation": OneOf("gravity", "none"),
        "effort_limit": [Interval(Real, 0, None, closed="neither", unit="N·m or N"), None],
        "unstable_speed": Interval(Real, 0, None, closed="neither", unit="rad/s"),
        "armature": ArrayOf(
            Interval(Real, 0, None, closed="left", unit="kg·m²"), scalar=True, per="joint"
        ),
        "contacts": Boolean(),
        "command_cutoff": [Interval(Real, 0, None, closed="neither", unit="Hz"), None],
    }

    def __init__(
        self,
        frequency: float = 10.0,
        damping_ratio: float = 1.0,
        timestep: float = 0.002,
        gravity: bool = True,
        compensation: Literal["gravity", "none"] = "gravity",
        effort_limit: float | None = None,
        unstable_speed: float = 100.0,
        armature: float | Sequence[float] = 0.0,
        contacts: bool = True,
        command_cutoff: float | None = None,
    ) -> None:
        check_params(self, locals())
        self.frequency = float(frequency)
        self.damping_ratio = float(damping_ratio)
        self.timestep = float(timestep)
        self.gravity = bool(gravity)
        self.compensation = compensation
        self.effort_limit = None if effort_limit is None else float(effort_limit)
        self.unstable_speed = float(unstable_speed)
        self.armature = armature
        self.contacts = bool(contacts)
        self.command_cutoff = None if command_cutoff is None else float(command_cutoff)
        try:
            import mujoco
        except ImportError:
            raise ConfigError("type", f"MuJoCo is not installed; {MUJOCO_HINT}") from None
        self._mujoco = mujoco
        self._robot: Robot | None = None
        self._model: Any = None
        self._data: Any = None
        self.tau_max = np.zeros(0)
        self.kp = np.zeros(0)
        self.kd = np.zeros(0)

    def _build(self, robot: Robot) -> None:
        """Compile the robot's MuJoCo model with its servos and torque limits (once per robot)."""
        from otmm_qp.robots import peer_models as models

        mujoco = self._mujoco
        try:
            description = models.describe(robot)
            self.tau_max = effort_limits(description.urdf, robot.joint_names, self.effort_limit, "")
            spec, _ = models.mujoco_spec(description)
        except RobotLoadError as error:
            raise ConfigError("", f"MuJoCo model: {_one_line(error)}") from None
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.option.gravity = [0.0, 0.0, -9.81] if self.gravity else [0.0, 0.0, 0.0]
        if not self.contacts:
            spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        armature = per_joint(self.armature, "armature", robot.nv)
        assert armature is not None
        joints = {j.name: j for j in spec.joints}
        for name, limit, rotor in zip(robot.joint_names, self.tau_max, armature, strict=True):
            joint = joints.get(name)
            if joint is None:
                raise ConfigError("", f"MuJoCo model: joint {name!r} is not in the model")
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.actfrcrange = [-float(limit), float(limit)]
            joint.actgravcomp = self.compensation == "gravity"
            joint.armature = float(rotor)
            for kind in ("position", "velocity"):
                actuator = spec.add_actuator()
                actuator.name = f"otmm_{kind}_{name}"
                actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
                actuator.target = name
                if kind == "position":
                    actuator.set_to_position(kp=1.0)
                else:
                    actuator.set_to_velocity(kv=1.0)
        if self.compensation == "gravity":
            for body in spec.bodies:
                body.gravcomp = 1.0
        try:
            model = spec.compile()
            joint_map = models.mujoco_joint_map(robot, model)
        except (ValueError, RobotLoadError) as error:
            raise ConfigError("", f"MuJoCo cannot compile the model: {_one_line(error)}") from None
        self._robot = robot
        self._model = model
        self._data = mujoco.MjData(model)
        self._qpos_index = joint_map.position_index
        self._qvel_index = joint_map.velocity_index
        ids = {
            kind: np.array(
                [
                    mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"otmm_{kind}_{n}")
                    for n in robot.joint_names
                ]
            )
            for kind in ("position", "velocity")
        }
        self._position_ids, self._velocity_ids = ids["position"], ids["velocity"]

    def reset(self, robot: Robot, q0: FloatArray, dt: float) -> None:
        """Arm at rest at ``q0`` (nq,); gains from the mass matrix there; substeps for ``dt``.

        Raises:
            ConfigError: The robot has no peer description, MuJoCo cannot compile its model,
                a joint has no effort limit or a moved link no inertia (naming it).
            ParameterError: ``dt / timestep`` above :data:`MAX_SUBSTEPS` MuJoCo steps.
        """
        self.substeps = max(1, math.ceil(dt / self.timestep - 1e-9))
        if self.substeps > MAX_SUBSTEPS:
            raise ParameterError(
                "timestep",
                f"dt / timestep = {self.substeps} MuJoCo steps per control period exceeds "
                f"{MAX_SUBSTEPS}; raise timestep to at least {dt / MAX_SUBSTEPS:.3g} s",
            )
        mujoco = self._mujoco
        if self._robot is not robot:
            self._build(robot)
        model, data = self._model, self._data
        mujoco.mj_resetData(model, data)
        theta0 = robot.joint_coordinates(q0)
        data.qpos[self._qpos_index] = theta0
        mujoco.mj_forward(model, data)
        mass = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, mass)
        inertia = np.diag(mass)[self._qvel_index]  # M_ii(q0), the armature included
        omega = 2.0 * math.pi * self.frequency
        self.kp = omega**2 * inertia
        self.kd = 2.0 * self.damping_ratio * omega * inertia
        pos, vel = self._position_ids, self._velocity_ids
        model.actuator_gainprm[pos, 0] = self.kp
        model.actuator_biasprm[pos, 1] = -self.kp
        model.actuator_biasprm[pos, 2] = 0.0
        model.actuator_gainprm[vel, 0] = self.kd
        model.actuator_biasprm[vel, 2] = -self.kd
        model.opt.timestep = dt / self.substeps
        self._reference = np.array(theta0, dtype=float)
        self._filtered = np.zeros(robot.nv)
        self._beta = 1.0
        if self.command_cutoff is not None:
            x = 2.0 * math.pi * self.command_cutoff * model.opt.timestep
            self._beta = x / (x + 1.0)
        data.ctrl[pos] = theta0
        mujoco.mj_forward(model, data)

    def advance(self, q: FloatArray, qdot: FloatArray) -> PlantStep:
        """Simulate one control period under the held command ``qdot`` (nv,) [rad/s]."""
        mujoco, model, data, robot = self._mujoco, self._model, self._data, self._robot
        if robot is None:
            raise RuntimeError("MujocoPlant.advance called before reset")
        h = model.opt.timestep
        dofs, tau_max = self._qvel_index, self.tau_max
        pos, vel = self._position_ids, self._velocity_ids
        command = np.asarray(qdot, dtype=float)
        filtering = self.command_cutoff is not None
        if not filtering:
            data.ctrl[vel] = command
        gravcomp = self.compensation == "gravity"
        peak, saturated = 0.0, False
        for _ in range(self.substeps):
            if filtering:
                self._filtered = self._filtered + self._beta * (command - self._filtered)
                data.ctrl[vel] = self._filtered
                self._reference = self._reference + self._filtered * h
            else:
                self._reference = self._reference + command * h
            data.ctrl[pos] = self._reference
            mujoco.mj_step(model, data)
            applied = data.qfrc_actuator[dofs]
            wanted = data.actuator_force[pos] + data.actuator_force[vel]
            if gravcomp:
                wanted = wanted + data.qfrc_gravcomp[dofs]
            saturated = saturated or bool(np.any(np.abs(wanted) > tau_max * (1.0 + 1e-9)))
            peak = max(peak, float(np.max(np.abs(applied) / tau_max)))
        theta = np.array(data.qpos[self._qpos_index])
        actual = np.array(data.qvel[dofs])
        stable = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(actual)))
        detail = "" if stable else "MuJoCo state became non-finite"
        if stable and float(np.max(np.abs(actual), initial=0.0)) > self.unstable_speed:
            stable = False
            detail = (
                f"MuJoCo joint speed {float(np.max(np.abs(actual))):.3g} rad/s exceeds "
                f"unstable_speed = {self.unstable_speed:g}"
            )
        if not stable:
            return PlantStep(q, np.zeros(robot.nv), peak, saturated, False, detail)
        return PlantStep(robot.configuration(theta), actual, peak, saturated)

    def declares(self, dt: float) -> PlantDeclaration:
        """The servo bandwidth f [Hz] and the command low-pass as a lag τ [s].

        The servo follows the integrated command; τ = 1/(2π f_c) when there is a cutoff.
        """
        cutoff = self.command_cutoff
        lags = () if cutoff is None else (1.0 / (2.0 * math.pi * cutoff),)
        return PlantDeclaration(lags=lags, servo_frequency=self.frequency)

    def label(self) -> str:
        """``mujoco(f=…,zeta=…)`` plus the non-default options."""
        parts = [f"f={self.frequency:g}", f"zeta={self.damping_ratio:g}"]
        if not self.gravity:
            parts.append("no-gravity")
        if self.compensation == "none":
            parts.append("no-compensation")
        if np.any(np.asarray(self.armature, dtype=float) != 0.0):
            parts.append(f"armature={self.armature!r}".replace(" ", ""))
        if not self.contacts:
            parts.append("no-contacts")
        if self.command_cutoff is not None:
            parts.append(f"cutoff={self.command_cutoff:g}")
        return f"mujoco({','.join(parts)})"

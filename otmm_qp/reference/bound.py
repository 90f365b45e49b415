r"""A certified lower bound on the best achievable error of every sample.

No path within the limits does better than these bounds, so ``max_k`` of them bounds the
min-max from below (the *lower* end of the reference's bracket; the best path found is the
upper end). Per sample ``k`` with target position ``p*_k``, three position bounds [m]:

* **Outside the reach ball**: every configuration's frame is within ``R`` of the base ``b``
  (planar arms: the annulus ``r_min ≤ ‖p − b‖ ≤ r_max``; Pinocchio arms: ``R`` the
  certified reach over the joint box, :func:`~otmm_qp.reference.reach.certified_reach`,
  or the sum of link offsets, :meth:`PinocchioArm._reach_bound`, where none can be
  certified; none for an unbounded prismatic joint), so ``‖e_pos‖ ≥ ‖p*_k − b‖ − R`` (and
  ``≥ r_min − ‖p*_k − b‖``).
* **Too far to travel from q₀ in time**: joint ``i`` moves at most
  ``θ_{k,i} = min(k·s_i, max(u_i − q_{0,i}, q_{0,i} − l_i))`` by sample ``k`` (``s_i =
  v_max,i dt``), and moving it by ``θ`` moves the frame by at most ``λ_i min(θ, 2)``
  (revolute: a chord of a circle of radius ``≤ λ_i``, the sum of the offsets from joint
  ``i`` to the frame) or ``θ`` (prismatic). Moving the joints one after another,
  ``‖p(q_k) − p(q_0)‖ ≤ ρ_k = Σ_i λ_i min(θ_{k,i}, 2)``, so ``‖e_pos‖ ≥ ‖p*_k − p(q_0)‖ − ρ_k``.
* Sample 0 is ``q_0`` itself: its error is exact.

Orientation (pose tasks) [rad]: the geodesic distance is bi-invariant, each revolute joint
turns the frame by at most ``min(θ_{k,i}, π)``, so
``‖e_rot‖ ≥ ‖log₃(R*_k R(q_0)ᵀ)‖ − Σ_{revolute} min(θ_{k,i}, π)``.

Pose tasks with both tolerances (Pinocchio arms): the **wrist** bound of :mod:`.wrist` (the
last joint's origin, carried by the tool, past its own certified reach), a bound of ``m_k``
itself rather than of one of its parts.

A robot of another kind gets the travel bound only when it is not given, i.e. the exact
sample-0 error (still a valid bound).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from otmm_qp.reference.problem import TrackingProblem
from otmm_qp.reference.reach import DegenerateReach, certified_reach
from otmm_qp.reference.wrist import carried_points, wrist_merits
from otmm_qp.robots.robot import FloatArray, Robot

#: Relative and absolute room [m or rad] taken off every bound against rounding.
ROUNDING = 1e-9
ROUNDING_FLOOR = 1e-12


@dataclass(frozen=True)
class Reach:
    """What bounds where a robot's frame can be.

    Attributes:
        base: Centre of the reach ball [m], shape ``(d,)``.
        outer: Largest ``‖p − base‖`` over every configuration [m] (inf: unknown).
        inner: Smallest ``‖p − base‖`` [m] (0: none).
        levers: Per joint, bound on how far moving it by 1 moves the frame ``λ_i``
            [m/rad or m/m], shape ``(nv,)``.
        revolute: Per joint, whether it turns the frame (chord and angle bounds apply),
            shape ``(nv,)``.
    """

    base: FloatArray
    outer: float
    inner: float
    levers: FloatArray
    revolute: np.ndarray


def reach_of(robot: Robot) -> Reach | None:
    """The :class:`Reach` of a planar or Pinocchio arm; None for any other robot."""
    from otmm_qp.robots.pinocchio_arm import PinocchioArm
    from otmm_qp.robots.planar_arm import PlanarArm

    if isinstance(robot, PlanarArm):
        lengths = np.asarray(robot.link_lengths, dtype=float)
        levers = np.cumsum(lengths[::-1])[::-1]  # Σ_{j ≥ i} l_j
        return Reach(
            np.zeros(2), robot.reach_max, robot.reach_min, levers, np.ones(robot.nv, dtype=bool)
        )
    if isinstance(robot, PinocchioArm):
        return _pinocchio_reach(robot)
    return None


def _pinocchio_reach(robot: Robot) -> Reach:
    """Levers from the joint chain supporting the frame (offsets at the neutral pose)."""
    import pinocchio as pin

    model = robot.model  # type: ignore[attr-defined]
    frame_id = robot.frame_id  # type: ignore[attr-defined]
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacement(model, data, frame_id)
    chain = [j for j in model.supports[model.frames[frame_id].parentJoint] if j > 0]
    points = [np.asarray(data.oMi[j].translation) for j in chain]
    points.append(np.asarray(data.oMf[frame_id].translation))
    offsets = [float(np.linalg.norm(b - a)) for a, b in zip(points, points[1:], strict=False)]
    levers = np.zeros(robot.nv)
    revolute = np.zeros(robot.nv, dtype=bool)
    travel_after = 0.0
    offset_after = 0.0
    for position in range(len(chain) - 1, -1, -1):
        joint = model.joints[chain[position]]
        offset_after += offsets[position]
        prismatic = joint.shortname().startswith("JointModelP")
        index = joint.idx_v
        if prismatic:
            levers[index] = 1.0
            lo = model.lowerPositionLimit[joint.idx_q]
            hi = model.upperPositionLimit[joint.idx_q]
            travel_after += float(max(abs(lo), abs(hi)))
        else:
            levers[index] = offset_after + travel_after
            revolute[index] = True
    base = np.array(robot._base, dtype=np.float64)  # type: ignore[attr-defined]
    outer = float(robot.reach)  # type: ignore[attr-defined]
    try:
        certificate = certified_reach(robot)
    except DegenerateReach:
        certificate = None  # the offset sum stays the bound (documented fallback)
        if _unbounded_prismatic(robot):
            outer = math.inf  # no reach at all (the offset sum reads the URDF's limits)
    if certificate is not None and certificate.outer < outer:
        # the certificate's own centre (the first joint's origin, as the offset sum's)
        base, outer = np.array(certificate.base, dtype=np.float64), certificate.outer
    return Reach(base, outer, 0.0, levers, revolute)


def _unbounded_prismatic(robot: Robot) -> bool:
    """Whether a prismatic joint of the frame's chain has an infinite position limit."""
    from otmm_qp.reference.chain import UnsupportedChain, chain_of

    try:
        chain = chain_of(robot)
    except UnsupportedChain:
        return False
    lower, upper = (np.asarray(v, dtype=float)[chain.columns] for v in robot.position_limits)
    return bool(np.any(chain.prismatic & ~(np.isfinite(lower) & np.isfinite(upper))))


@dataclass(frozen=True)
class LowerBound:
    """Per-sample lower bounds of one task.

    Attributes:
        position: ``‖e_pos,k‖ ≥ position[k]`` on every path within the limits [m], ``(N,)``.
        orientation: ``‖e_rot,k‖ ≥ orientation[k]`` [rad], ``(N,)`` (zeros: position task).
        merit: ``m_k ≥ merit[k]`` [tolerances], ``(N,)``.
        kinds: Per sample, which bound gives ``merit[k]``: ``start`` (sample 0), ``reach``,
            ``travel``, ``turn`` (orientation travel), ``wrist`` (:mod:`.wrist`), ``search``
            (:mod:`~otmm_qp.reference.sample_bound`) or ``none`` (0).
    """

    position: FloatArray
    orientation: FloatArray
    merit: FloatArray
    kinds: tuple[str, ...] = ()

    @property
    def certificate(self) -> str:
        """``kind@k`` of the sample that sets :attr:`value` (``none`` when it is 0)."""
        sample = int(np.argmax(self.merit))
        if not self.merit[sample] > 0.0 or not self.kinds:
            return "none"
        return f"{self.kinds[sample]}@{sample}"

    def raised(self, sample: int, merit: float, kind: str) -> LowerBound:
        """This bound with ``merit[sample]`` raised to ``merit`` (if higher) by ``kind``."""
        if not merit > self.merit[sample]:
            return self
        merits = self.merit.copy()
        merits[sample] = merit
        kinds = list(self.kinds) if self.kinds else ["none"] * merits.size
        kinds[sample] = kind
        return LowerBound(self.position, self.orientation, merits, tuple(kinds))

    @property
    def value(self) -> float:
        """Lower bound of ``max_k m_k`` [tolerances]."""
        return float(np.max(self.merit))

    @property
    def position_value(self) -> float:
        """Lower bound of ``max_k ‖e_pos,k‖`` [m]."""
        return float(np.max(self.position))


def lower_bound(problem: TrackingProblem) -> LowerBound:
    """The bounds of the module docstring for every sample of ``problem``."""
    robot = problem.robot
    count = problem.samples
    x0 = robot.forward(robot.configuration(problem.q0))
    start = np.array([robot.task_error(target, x0) for target in problem.targets])
    away = np.linalg.norm(start[:, : problem.linear], axis=1)  # ‖p*_k − p(q_0)‖
    turn = np.linalg.norm(start[:, 3:], axis=1) if problem.pose else np.zeros(count)
    position = np.zeros(count)
    orientation = np.zeros(count)
    reach_term = travel_term = np.zeros(count)
    reach = reach_of(robot)
    if reach is not None:
        finite = np.isfinite(problem.step)
        per_step = np.where(finite, problem.step, 0.0)
        steps = np.arange(count, dtype=float)[:, None] * per_step[None, :]
        steps = np.where(finite[None, :], steps, math.inf)  # no speed limit: any distance
        room = np.maximum(problem.upper - problem.q0, problem.q0 - problem.lower)
        theta = np.minimum(steps, room[None, :])
        chord = np.where(reach.revolute[None, :], np.minimum(theta, 2.0), theta)
        moved = np.where(reach.levers[None, :] > 0.0, reach.levers * chord, 0.0)
        travel = np.sum(moved, axis=1)  # inf for an unbounded prismatic joint: no bound
        points = _target_positions(problem)
        radius = np.linalg.norm(points - reach.base[None, : points.shape[1]], axis=1)
        reach_term = np.nan_to_num(np.maximum(radius - reach.outer, reach.inner - radius))
        travel_term = np.nan_to_num(away - travel, nan=0.0)
        position = np.maximum.reduce([np.zeros(count), reach_term, travel_term])
        if problem.pose:
            angle = np.sum(
                np.where(reach.revolute[None, :], np.minimum(theta, math.pi), 0.0), axis=1
            )
            orientation = np.maximum(turn - angle, 0.0)
    position = np.nan_to_num(position, nan=0.0)
    position[0], orientation[0] = away[0], turn[0]
    # Rounding: the bound is computed in floating point, so give it a few ulps of room.
    position = np.maximum(position * (1.0 - ROUNDING) - ROUNDING_FLOOR, 0.0)
    orientation = np.maximum(orientation * (1.0 - ROUNDING) - ROUNDING_FLOOR, 0.0)
    merit = np.zeros(count)
    kinds = np.where(reach_term >= travel_term, "reach", "travel").astype(object)
    settings = problem.settings
    if settings.position_tolerance is not None:
        merit = np.maximum(merit, position / settings.position_tolerance)
    if problem.pose and settings.orientation_tolerance is not None:
        turning = orientation / settings.orientation_tolerance
        kinds = np.where(turning > merit, "turn", kinds)
        merit = np.maximum(merit, turning)
    wrist = _wrist_term(problem)
    kinds = np.where(wrist > merit, "wrist", kinds)
    merit = np.maximum(merit, wrist)
    kinds[0] = "start"
    kinds[merit <= 0.0] = "none"
    return LowerBound(position, orientation, merit, tuple(str(k) for k in kinds))


def _wrist_term(problem: TrackingProblem) -> FloatArray:
    """The wrist bound of every sample (:mod:`.wrist`) [tolerances], shape ``(N,)``.

    0 at sample 0 (its error is exact) and where it does not apply (position tasks, a
    tolerance missing, no carried point).
    """
    settings = problem.settings
    count = problem.samples
    position, orientation = settings.position_tolerance, settings.orientation_tolerance
    if not problem.pose or position is None or orientation is None:
        return np.zeros(count)
    wrist = carried_points(problem.robot)
    if not wrist:
        return np.zeros(count)
    targets = np.array([np.asarray(target, dtype=float) for target in problem.targets])
    merit = wrist_merits(wrist, targets[:, :3, 3], targets[:, :3, :3], position, orientation)
    merit[0] = 0.0
    return merit


def _target_positions(problem: TrackingProblem) -> FloatArray:
    """Target positions ``p*_k`` [m], shape ``(N, d)``."""
    values = [np.asarray(target, dtype=float) for target in problem.targets]
    return np.array([v[:3, 3] if v.ndim == 2 else v[: problem.linear] for v in values])

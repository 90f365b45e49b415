r"""The limit interfaces: a box on ``q̇`` per step (``Limit``) or a constraint row (``RowLimit``).

Every limit of the velocity-level problem is bound once per run (:meth:`BaseLimit.bind`, with
the robot and the control period ``dt`` [s]) and then evaluated each step:

* a :class:`Limit` writes a joint-velocity box ``lower ≤ q̇ ≤ upper`` [rad/s], shapes
  ``(nv,)``, into arrays it is handed (``out=``: the per-step path allocates nothing). Boxes are
  intersected, relaxed by :attr:`Limit.priority` and described in one place,
  :mod:`otmm_qp.limits.box`;
* a :class:`RowLimit` adds one general row ``c·q̇ ≥ l`` (mink's ``Constraint``), e.g. the
  singularity barrier on σ_min; it is enforced lazily (only when the optimum under the box
  violates it).
"""

from __future__ import annotations

import abc
from typing import ClassVar, NamedTuple

from otmm_qp.plants.declaration import PlantDeclaration
from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState
from otmm_qp.validation import per_joint

__all__ = ["BaseLimit", "Box", "Limit", "Row", "RowLimit", "per_joint"]


class Box(NamedTuple):
    """A joint-velocity box ``lower ≤ q̇ ≤ upper`` [rad/s] (±inf allowed).

    Attributes:
        lower: Lower bounds, shape ``(nv,)``.
        upper: Upper bounds, shape ``(nv,)``.
    """

    lower: FloatArray
    upper: FloatArray


class Row(NamedTuple):
    """One constraint row of a step, ``row·q̇ ≥ lower`` (``lower`` after relaxation).

    Attributes:
        row: The row ``c`` [task units·s/rad], shape ``(nv,)``.
        lower: The bound the QP enforces [task units].
        slack: ``required − lower ≥ 0`` [task units]; > 0 when the row had to be relaxed (no
            ``q̇`` in the box satisfies the required bound).
    """

    row: FloatArray
    lower: float
    slack: float


class BaseLimit(abc.ABC):
    """What every limit has: a registered name and a per-run :meth:`bind`.

    Subclass :class:`Limit` (a box) or :class:`RowLimit` (a row), not this class.
    """

    #: Registered name (the ``type`` of its YAML entry), e.g. ``position``.
    name: ClassVar[str] = "limit"
    robot: Robot
    dt: float

    def bind(self, robot: Robot, dt: float) -> None:
        """Attach the robot and the control period ``dt`` [s]; called once per run.

        Raises:
            DimensionError: A per-joint parameter does not match ``robot.nv``.
        """
        self.robot = robot
        self.dt = dt

    def declare_plant(self, declaration: PlantDeclaration) -> None:  # noqa: B027 - optional hook
        """Take what the run's plant declares about itself (before :meth:`bind`; ignored here)."""

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget the last run's per-step state (none here)."""


class Limit(BaseLimit):
    r"""One joint-velocity box per step, ``lower ≤ q̇ ≤ upper`` [rad/s], shapes ``(nv,)``.

    Boxes of several limits are intersected (:func:`otmm_qp.limits.box.intersect`). When they
    do not intersect, a non-raising infeasibility policy keeps them by :attr:`priority`
    (:func:`otmm_qp.limits.box.relaxed`): the lowest value is honoured first.
    """

    #: Relaxation priority: 0 velocity (never given up), 1 position, 2 acceleration.
    priority: ClassVar[int] = 1
    #: Whether the box depends on neither θ nor q̇_prev (computed once, at bind).
    static: ClassVar[bool] = False
    #: Whether a clash with the other boxes relaxes this box within the step (braking first,
    #: :class:`~otmm_qp.limits.box.LimitBox`) instead of making the step's box empty.
    soft: ClassVar[bool] = False
    #: The braking acceleration [rad/s²], shape ``(nv,)``, a soft limit asks the position
    #: limits to keep a stopping distance for (set at :meth:`bind`; None: none).
    braking: FloatArray | None = None

    def secondary(self) -> tuple[Box, ...]:
        """Further boxes of the last :meth:`compute_box`, relaxed after this one (none here)."""
        return ()

    #: The jerk step :math:`J` [rad/s] (nv,) the stopping distance must respect (None: none).
    jerk_braking: FloatArray | None = None

    #: The soft box a position limit writes its jerk-limited stopping distance into.
    stop_box: Box | None = None

    def brake_with(  # noqa: B027 - optional hook
        self, acceleration: FloatArray, jerk_step: FloatArray | None = None, soft: Box | None = None
    ) -> None:
        """Keep a stopping distance at ``acceleration`` [rad/s²] (nv,) (after :meth:`bind`).

        With ``jerk_step`` [rad/s] (nv,) and ``soft``, also the jerk-limited one, written into
        ``soft`` each step (a soft box).
        """

    @abc.abstractmethod
    def compute_box(self, theta: FloatArray, qdot_prev: FloatArray, out: Box) -> Box:
        """Write this step's box into ``out`` and return it.

        Args:
            theta: Joint coordinates [rad or m], shape ``(nv,)``.
            qdot_prev: Previous joint velocity [rad/s], shape ``(nv,)``.
            out: Arrays of shape ``(nv,)`` to overwrite (never read before written).

        Returns:
            ``out`` [rad/s]; NaN never (±inf for an unlimited joint).
        """


class RowLimit(BaseLimit):
    r"""One general row ``c·q̇ ≥ l`` per step (e.g. a control-barrier function).

    The QP backend first solves under the box alone and keeps that optimum when
    :meth:`satisfied` says it meets the row (adding a constraint the optimum satisfies leaves
    a convex problem's optimum unchanged); only otherwise does it call :meth:`compute_row` and
    re-solve with the row.
    """

    @abc.abstractmethod
    def applies(self, state: KinematicState) -> bool:
        """Whether the row exists at ``state`` (e.g. False when σ_min ≡ 0 structurally)."""

    @abc.abstractmethod
    def satisfied(self, state: KinematicState, qdot: FloatArray) -> bool:
        """Whether ``qdot`` [rad/s], shape ``(nv,)``, meets the row's required bound."""

    @abc.abstractmethod
    def compute_row(self, state: KinematicState, box: Box) -> Row:
        """The step's row, relaxed (``slack > 0``) when no ``q̇`` in ``box`` satisfies it.

        Args:
            state: The step's kinematic state.
            box: The step's joint-velocity box [rad/s], finite (±BIG for unlimited joints).
        """

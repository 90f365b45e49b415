"""The task-filter interface: modify the commanded task velocity before inversion."""

from __future__ import annotations

import abc
from typing import ClassVar, NamedTuple

from otmm_qp.robots.robot import FloatArray, Robot
from otmm_qp.state import KinematicState


class FilterReport(NamedTuple):
    """What a filter did in one step.

    Attributes:
        active: Whether the filter changed the command.
        sigma_min: Smallest singular value of the (weighted) task Jacobian it saw.
        p: Suppression level in [0, 1] along the filtered direction(s) (largest one), 0 if inactive.
        removed: ‖ẋ − ẋ_m‖ in weighted task units.
    """

    active: bool
    sigma_min: float
    p: float
    removed: float


class FilterOutput(NamedTuple):
    """Filtered task velocity and the report."""

    xdot: FloatArray
    report: FilterReport


class TaskFilter(abc.ABC):
    """Maps a commanded (weighted) task velocity ``ẋ`` to a modified one ``ẋ_m``.

    Filters see the :class:`~otmm_qp.state.KinematicState` of the step (its SVD is
    shared, never recomputed) and the weighted command ``ẋ_w``, shape ``(n,)``.
    """

    #: The class's own name (e.g. ``"otmm"``), a class constant never assigned on an instance;
    #: the name a filter was registered under is kept beside it (``Controller.filter_names``).
    name: ClassVar[str] = "filter"

    @abc.abstractmethod
    def apply(self, state: KinematicState, xdot: FloatArray) -> FilterOutput:
        """Return the modified weighted task velocity, shape ``(n,)``, and a report."""

    def bind(self, robot: Robot, dt: float) -> None:  # noqa: B027 - optional hook
        """Attach the robot and the control period ``dt`` [s]; called once per run."""

    def reset(self) -> None:  # noqa: B027 - optional hook, stateless filters need nothing
        """Forget any state kept between steps (called at the start of each run)."""

"""What the offline-optimal reference solves for: tolerances, limits and its budget."""

from __future__ import annotations

import math
from dataclasses import dataclass

from otmm_qp.exceptions import ParameterError
from otmm_qp.paper import SIGMA_S

#: Distance [rad or m] from a finite position limit at which a path counts as touching it.
LIMIT_TOUCH = 1e-6


def _positive(name: str, value: float | None, allow_none: bool = True) -> None:
    if value is None and allow_none:
        return
    if value is None or not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ParameterError(name, f"must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class ReferenceSettings:
    """Tolerances and budget of one reference solve (validated on construction).

    Attributes:
        position_tolerance: Error bound a certificate must meet on ‖e_pos‖ [m]; None: none.
        orientation_tolerance: Bound on ‖e_rot‖ [rad] (pose tasks); None: none.
        speed_limit: Cap on every joint speed [rad/s] on top of the robot's own limits
            (the study's ``max_joint_speed`` criterion); None: the robot's limits only.
        sigma_s: σ_min threshold of ``near_singular`` [task units].
        time_budget: Wall-clock budget of one solve [s]; past it the solve stops with the
            best path so far.
        iterations: Newton iterations of the least-squares phase.
        minimax_rounds: Lawson re-weighting rounds toward the min-max error (only when the
            least-squares path misses a tolerance).
        polish_iterations: Cap on the epigraph min-max QPs per start
            (:class:`~otmm_qp.reference.conic.ConicEpigraph`; it stops earlier on its
            convergence test).
        starts: Best distinct starts (damped IK, the task's joint path, controller paths)
            the epigraph solve is run from, when no start meets the tolerances.
        perturbations: Extra starts: the best path plus seeded joint noise.
        seed: Seed of the perturbations.
    """

    position_tolerance: float | None = 0.01
    orientation_tolerance: float | None = None
    speed_limit: float | None = None
    sigma_s: float = SIGMA_S
    time_budget: float = 60.0
    iterations: int = 6
    minimax_rounds: int = 1
    polish_iterations: int = 20
    starts: int = 1
    perturbations: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        """Check every field.

        Raises:
            ParameterError: Naming the field and what is allowed.
        """
        _positive("reference.position_tolerance", self.position_tolerance)
        _positive("reference.orientation_tolerance", self.orientation_tolerance)
        _positive("reference.speed_limit", self.speed_limit)
        _positive("reference.sigma_s", self.sigma_s, allow_none=False)
        _positive("reference.time_budget", self.time_budget, allow_none=False)
        for name in (
            "iterations",
            "minimax_rounds",
            "polish_iterations",
            "starts",
            "perturbations",
            "seed",
        ):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise ParameterError(f"reference.{name}", f"must be an integer >= 0, got {value!r}")

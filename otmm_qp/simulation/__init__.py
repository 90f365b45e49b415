"""Simulation loop, loop modes, episodes and run results."""

from otmm_qp.simulation.episode import DEFAULT_MAX_STEPS, Episode, Loop
from otmm_qp.simulation.loop_modes import LOOP_MODES, LoopMode, commanded_velocity
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.simulation.simulate import simulate, task_position

__all__ = [
    "DEFAULT_MAX_STEPS",
    "LOOP_MODES",
    "Episode",
    "Loop",
    "LoopMode",
    "RunResult",
    "commanded_velocity",
    "simulate",
    "task_position",
]

"""Simulation loop, loop modes and run results."""

from otmm_qp.simulation.loop_modes import LOOP_MODES, LoopMode, commanded_velocity
from otmm_qp.simulation.run_result import RunResult
from otmm_qp.simulation.simulate import simulate, task_position

__all__ = ["LOOP_MODES", "LoopMode", "RunResult", "commanded_velocity", "simulate", "task_position"]

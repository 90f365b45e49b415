"""Loop settings shared by run files and study files: ``dt``, loop modes, CLIK gain, step cap."""

from __future__ import annotations

from pydantic import Field, field_validator

from otmm_qp.config.base import Strict
from otmm_qp.simulation.episode import DEFAULT_MAX_STEPS
from otmm_qp.simulation.loop_modes import LoopMode

#: Loop modes run when a file names none.
DEFAULT_LOOP_MODES: tuple[LoopMode, ...] = ("clik",)


def default_loop_modes() -> list[LoopMode]:
    """A fresh list of :data:`DEFAULT_LOOP_MODES`."""
    return list(DEFAULT_LOOP_MODES)


class LoopSettings(Strict):
    """How every run of a file is stepped.

    Attributes:
        dt: Control period [s], finite and > 0 (the run and study files state their default).
        loop_modes: Loop modes to run, unique (see :mod:`otmm_qp.simulation.loop_modes`).
        clik_gain: CLIK gain K [1/s], finite and >= 0.
        max_steps: Cap on control steps per run or episode (``duration/dt``).
    """

    dt: float = Field(0.02, gt=0.0)
    loop_modes: list[LoopMode] = Field(default_factory=default_loop_modes, min_length=1)
    clik_gain: float = Field(10.0, ge=0.0)
    max_steps: int = Field(DEFAULT_MAX_STEPS, gt=0)

    @field_validator("loop_modes")
    @classmethod
    def _unique_modes(cls, value: list[LoopMode]) -> list[LoopMode]:
        if len(set(value)) != len(value):
            raise ValueError("loop modes must be unique")
        return value

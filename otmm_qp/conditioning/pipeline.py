r"""The conditioning stages of a run, in order: :math:`\dot q \leftarrow s_m(\dots s_1(\dot q))`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from otmm_qp import registry
from otmm_qp.conditioning.stage import CommandStage
from otmm_qp.exceptions import ConfigError
from otmm_qp.robots.robot import FloatArray, Robot

__all__ = ["Conditioning", "build_conditioning"]


class Conditioning:
    """Stages applied in list order; with none, the command passes unchanged (the same array).

    Args:
        stages: The stages, in order.
    """

    def __init__(self, stages: Sequence[CommandStage] = ()) -> None:
        self.stages = tuple(stages)
        #: Whether the last :meth:`apply` changed the command.
        self.active = False

    def reset(self, robot: Robot, dt: float) -> None:
        """Reset every stage for a run on ``robot`` at period ``dt`` [s]."""
        for stage in self.stages:
            stage.reset(robot, dt)
        self.active = False

    def apply(self, q: FloatArray, qdot: FloatArray) -> FloatArray:
        """The conditioned command (nv,) [rad/s]; sets :attr:`active`."""
        if not self.stages:
            return qdot
        out = qdot
        for stage in self.stages:
            out = stage.apply(q, out)
        self.active = not np.array_equal(out, qdot)
        return out

    def label(self) -> str:
        """``none`` or the stage labels joined by ``+``."""
        return "+".join(s.label() for s in self.stages) or "none"


def build_conditioning(
    spec: Sequence[Mapping[str, Any]] | None, field: str = "conditioning"
) -> Conditioning:
    """Build the stages ``[{type: speed_scale}, {type: jerk_limit, ...}, ...]`` (None: none).

    Raises:
        ConfigError: Unknown stage or parameter, or one out of range (naming its path).
    """
    stages: list[CommandStage] = []
    for i, block in enumerate(spec or []):
        where = f"{field}.{i}"
        if not isinstance(block, Mapping) or not isinstance(block.get("type"), str):
            raise ConfigError(where, "must be a mapping with a 'type' (a conditioning stage)")
        params = {k: v for k, v in block.items() if k != "type"}
        stages.append(registry.create(registry.CONDITIONING, block["type"], params, where))
    return Conditioning(stages)

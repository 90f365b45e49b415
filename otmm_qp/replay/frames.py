"""Which stored steps become replay frames: every step, or every k-th to bound the file size."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FramePlan:
    """Stored step indices shown as frames.

    Attributes:
        indices: Step index of each frame, shape ``(F,)``, increasing, first and last step
            always included.
        steps: Number of stored steps ``N``.
    """

    indices: np.ndarray

    steps: int

    @property
    def frames(self) -> int:
        """Number of frames ``F``."""
        return int(self.indices.size)

    @property
    def decimated(self) -> bool:
        """Whether some stored steps are not shown."""
        return self.frames < self.steps

    def describe(self) -> str:
        """``"501 frames"`` or ``"126 of 501 steps (decimated to bound the file size)"``."""
        if not self.decimated:
            return f"{self.frames} frames"
        return f"{self.frames} of {self.steps} steps as frames (decimated to bound the file size)"


def plan_frames(steps: int, max_frames: int) -> FramePlan:
    """Evenly spaced frames, at most ``max_frames`` (≥ 2), including the first and last step."""
    if steps <= 0:
        return FramePlan(np.zeros(0, dtype=int), 0)
    limit = max(2, int(max_frames))
    if steps <= limit:
        return FramePlan(np.arange(steps), steps)
    indices = np.unique(np.linspace(0, steps - 1, limit).round().astype(int))
    return FramePlan(indices, steps)

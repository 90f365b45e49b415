"""An example p-function for the OTMM filter."""

from __future__ import annotations

import numpy as np


def smoothstep(s: float, sigma_s: float) -> float:
    r"""Suppression level rising smoothly from 0 at ``s = σ_S`` to 1 at ``s = 0``.

    .. math:: u = \mathrm{clip}(1 - s/\sigma_S,\ 0,\ 1),\qquad p(s) = 3u^2 - 2u^3

    Args:
        s: Singular value [task units], ≥ 0.
        sigma_s: Threshold σ_S > 0 [task units].

    Returns:
        p ∈ [0, 1].
    """
    u = float(np.clip(1.0 - s / sigma_s, 0.0, 1.0))
    return 3.0 * u**2 - 2.0 * u**3

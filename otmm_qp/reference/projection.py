r"""Make a joint path satisfy the position and step limits exactly."""

from __future__ import annotations

import numpy as np

from otmm_qp.robots.robot import FloatArray


def project_path(
    path: FloatArray, lower: FloatArray, upper: FloatArray, step: FloatArray
) -> FloatArray:
    r"""Forward pass that keeps ``q_0`` and limits every later sample.

    .. math:: q'_{k} = \Pi_{[l,u]}\big(q'_{k-1}
              + \operatorname{clip}(q_k - q'_{k-1}, -s, s)\big)

    Because ``q'_{k-1}`` lies in ``[l, u]``, clipping into the box never lengthens the step, so
    the result satisfies ``l ≤ q'_k ≤ u`` and ``|q'_k − q'_{k−1}| ≤ s`` for every ``k ≥ 1``
    (``q_0`` is assumed inside the limits). A path that already satisfies them is unchanged.

    Args:
        path: Joint path, shape ``(N, nv)`` [rad or m].
        lower: Position limits, shape ``(nv,)`` (−inf: none).
        upper: Position limits, shape ``(nv,)`` (inf: none).
        step: Largest step per sample ``v_max dt``, shape ``(nv,)`` (inf: none).

    Returns:
        The projected path, shape ``(N, nv)`` (a new array).
    """
    out = np.array(path, dtype=float, copy=True)
    minimum, maximum = np.minimum, np.maximum  # cheaper than np.clip on short rows
    back = -step
    previous = out[0]
    for k in range(1, out.shape[0]):
        row = out[k]
        move = minimum(maximum(row - previous, back), step)
        row[:] = minimum(maximum(previous + move, lower), upper)
        previous = row
    return out

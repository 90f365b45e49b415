"""Replays of stored runs: offline MeshCat pages for URDF arms, animated GIFs for planar arms.

A replay reads the time series a run stored (never re-simulates). Entry points:
:func:`write_replays` (``otmm-qp replay``, ``run --replay``, ``report --replay``) and
:func:`find_replays` (the report's "Replays" section).
"""

from __future__ import annotations

from otmm_qp.output.replays import find_replays
from otmm_qp.replay.write import write_replays

__all__ = ["find_replays", "write_replays"]

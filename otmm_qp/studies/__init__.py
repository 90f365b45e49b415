"""Studies: random tasks × controllers on Dask, stored as Parquet, reported with intervals.

``otmm_qp.studies.load(DIR)`` reads a study folder into one typed table (see
:mod:`otmm_qp.studies.rows`; the columns are declared in :mod:`otmm_qp.studies.columns`).
It is imported on first use, so ``python -m otmm_qp.studies.<module>`` runs each module once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from otmm_qp.studies.rows import load

__all__ = ["load"]


def __getattr__(name: str) -> Any:
    """``load`` on first use (PEP 562)."""
    if name == "load":
        from otmm_qp.studies.rows import load

        return load
    raise AttributeError(f"module 'otmm_qp.studies' has no attribute {name!r}")

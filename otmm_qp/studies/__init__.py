"""Studies: random tasks × controllers on Dask, stored as Parquet, reported with intervals.

``otmm_qp.studies.load(DIR)`` reads a study folder into one typed table (see
:mod:`otmm_qp.studies.rows`; the columns are declared in :mod:`otmm_qp.studies.columns`).
"""

from otmm_qp.studies.rows import load

__all__ = ["load"]

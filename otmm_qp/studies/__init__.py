"""Studies: random tasks × controllers on Dask, stored as Parquet, reported with intervals."""

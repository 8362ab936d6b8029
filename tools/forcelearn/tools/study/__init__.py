"""The engine of ``forcelearn study``: grid, runner (local or Dask), tasks, report."""

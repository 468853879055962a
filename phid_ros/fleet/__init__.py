"""A fleet of units: recordings identified as tasks on a Dask cluster, a parameter history per unit."""

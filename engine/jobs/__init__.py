"""Running many splices: the batch (Dask) and the child-process sandbox that reads untrusted files."""

"""Running the pipeline over many files: the feature cache, the per-object tasks, the executors
that run them in this process, on local processes or on a Dask cluster, a whole ``match`` run,
and the paper's user study that ``pinchmatch demo`` rebuilds."""

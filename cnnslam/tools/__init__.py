"""Edge tools of the agent: speed benchmark, ``cnnslam map`` and its replay core, the numba warm-up."""

"""Camera trajectories at 30 Hz: the trajectory record, path building steps, and the generators."""

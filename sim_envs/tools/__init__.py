"""Edge tools of the world: render benchmark, contact sheets, camera calibration command."""

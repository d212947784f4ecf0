"""The simulated camera sensor: composable stages of image formation, their physics, presets, calibration statistics."""

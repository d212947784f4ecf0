"""What one frame of the world is: image, ground truth, and the semantic classes of the paper.

``NO_DEPTH`` (0.0) marks pixels with no surface in ground-truth depth (as in TUM's 16-bit PNGs, where 0 means no
measurement). Label maps use ``NO_LABEL`` (255) there. Both, and the classes, are defined in
:mod:`slamcommon.labels` (shared with the agent and the judge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamcommon.labels import NO_DEPTH, NO_LABEL, NUM_CLASSES, SemanticClass

__all__ = ["NO_DEPTH", "NO_INSTANCE", "NO_LABEL", "NUM_CLASSES", "Frame", "SemanticClass"]

NO_INSTANCE: int = -1


@dataclass(frozen=True)
class Frame:
    """One frame with its ground truth.

    rgb: (H, W, 3) uint8; depth: (H, W) float32 planar z in metres, ``NO_DEPTH`` where no surface;
    T_world_cam: (4, 4) float64 camera-to-world, OpenCV camera axes; labels: (H, W) uint8 ``SemanticClass`` values,
    ``NO_LABEL`` where no surface; instances: (H, W) int32 instance ids, ``NO_INSTANCE`` where no surface.
    labels / instances are None when the source has none (a real TUM folder). sensor_depth: (H, W) float32 metres,
    0 = no measurement, a noisy depth as a depth sensor would give it (a simulated camera with Kinect-like depth noise,
    :func:`sim_envs.sensor.camera_effects.kinect_depth`), None otherwise; ``depth`` stays the exact ground truth.
    """

    index: int
    timestamp: float
    rgb: np.ndarray
    depth: np.ndarray
    T_world_cam: np.ndarray
    labels: np.ndarray | None = None
    instances: np.ndarray | None = None
    sensor_depth: np.ndarray | None = None

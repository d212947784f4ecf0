"""What one frame of the world is: image, ground truth, and the semantic classes of the paper.

``NO_DEPTH`` (0.0) marks pixels with no surface in ground-truth depth (as in TUM's 16-bit PNGs, where 0 means no
measurement). Label maps use ``NO_LABEL`` (255) there.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

NO_DEPTH: float = 0.0
NO_LABEL: int = 255
NO_INSTANCE: int = -1


class SemanticClass(IntEnum):
    """The paper's 4 NYU super-classes (CNN-SLAM Sec. 4): what every surface of a scene is labelled with."""

    FLOOR = 0
    VERTICAL_STRUCTURE = 1  # walls, ceiling, doors, windows
    LARGE_STRUCTURE = 2  # furniture: desks, tables, chairs, sofas, shelves, cabinets, beds
    SMALL_STRUCTURE = 3  # small objects: books, boxes, cups, monitors, plants


NUM_CLASSES: int = len(SemanticClass)


@dataclass(frozen=True)
class Frame:
    """One frame with its ground truth.

    rgb: (H, W, 3) uint8; depth: (H, W) float32 planar z in metres, ``NO_DEPTH`` where no surface;
    T_world_cam: (4, 4) float64 camera-to-world, OpenCV camera axes; labels: (H, W) uint8 ``SemanticClass`` values,
    ``NO_LABEL`` where no surface; instances: (H, W) int32 instance ids, ``NO_INSTANCE`` where no surface.
    labels / instances are None when the source has none (a real TUM folder). sensor_depth: (H, W) float32 metres,
    0 = no measurement, a noisy depth as a depth sensor would give it (a simulated camera with Kinect-like depth noise,
    :func:`sim_envs.camera_effects.kinect_depth`), None otherwise; ``depth`` stays the exact ground truth.
    """

    index: int
    timestamp: float
    rgb: np.ndarray
    depth: np.ndarray
    T_world_cam: np.ndarray
    labels: np.ndarray | None = None
    instances: np.ndarray | None = None
    sensor_depth: np.ndarray | None = None

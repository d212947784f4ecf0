"""The paper's semantic classes and the ground-truth markers of pixels without a surface.

``NO_DEPTH`` (0.0) marks pixels with no surface in ground-truth depth (as in TUM's 16-bit PNGs, where 0 means no
measurement); label maps use ``NO_LABEL`` (255) there.
"""

from __future__ import annotations

from enum import IntEnum

NO_DEPTH: float = 0.0
NO_LABEL: int = 255


class SemanticClass(IntEnum):
    """The paper's 4 NYU super-classes (CNN-SLAM Sec. 4): what every surface of a scene is labelled with."""

    FLOOR = 0
    VERTICAL_STRUCTURE = 1  # walls, ceiling, doors, windows
    LARGE_STRUCTURE = 2  # furniture: desks, tables, chairs, sofas, shelves, cabinets, beds
    SMALL_STRUCTURE = 3  # small objects: books, boxes, cups, monitors, plants


NUM_CLASSES: int = len(SemanticClass)

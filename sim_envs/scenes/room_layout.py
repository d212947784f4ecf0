"""The floor plan of a generated room (:mod:`sim_envs.scenes.scenegen`): oriented footprints and their overlap, the
layout
of what is placed, the frames of the four walls, doors and windows, and the small objects about to be dropped.
Metres and radians; world z up, the room's interior spans ``[0, Lx] x [0, Ly]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sim_envs.scenes import furniture as fur

CLEARANCE = 0.04  # metres kept free between pieces of furniture (ours)


@dataclass(frozen=True)
class Rect:
    """An oriented footprint: centre (cx, cy), yaw (rad), half sizes (hx, hy) in metres; occupies z in [z0, z1]."""

    cx: float
    cy: float
    yaw: float
    hx: float
    hy: float
    z0: float = 0.0
    z1: float = np.inf

    def cv(self, grow: float = 0.0) -> tuple[tuple[float, float], tuple[float, float], float]:
        """The rectangle in OpenCV's RotatedRect form, grown by ``grow`` metres on each side."""
        return ((self.cx, self.cy), (2 * (self.hx + grow), 2 * (self.hy + grow)), float(np.degrees(self.yaw)))

    def corners(self) -> np.ndarray:
        """(4, 2) corner points (m)."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [self.hx, self.hy]
        return local @ np.array([[c, s], [-s, c]]) + [self.cx, self.cy]

    def overlaps(self, other: Rect, grow: float = 0.0) -> bool:
        """Whether the two footprints intersect (after growing this one by ``grow``) and their heights overlap."""
        if self.z1 <= other.z0 or other.z1 <= self.z0:
            return False
        if (
            np.hypot(self.cx - other.cx, self.cy - other.cy)
            > np.hypot(self.hx, self.hy) + np.hypot(other.hx, other.hy) + 2 * grow
        ):
            return False
        return cv2.rotatedRectangleIntersection(self.cv(grow), other.cv())[0] != cv2.INTERSECT_NONE


@dataclass(frozen=True)
class Drop:
    """A small object about to be dropped.

    assembly: the object; T_world: (4, 4) upright pose ``lift`` metres above its resting place; tilt: (roll, pitch)
    in radians it is tumbled by before falling (0 for objects set down upright), used only with physics.
    """

    assembly: fur.Assembly
    T_world: np.ndarray
    lift: float
    tilt: tuple[float, float] = (0.0, 0.0)

    def start_pose(self) -> np.ndarray:
        """(4, 4) initial pose for physics: tilted about the object's origin, raised so no corner starts lower."""
        if not any(self.tilt):
            return self.T_world
        R = fur.pose((0.0, 0.0, 0.0), (self.tilt[0], self.tilt[1], 0.0))
        corners = np.concatenate([fur.part_corners(p) for p in self.assembly.parts])
        low = (corners @ R[:3, :3].T)[:, 2].min()  # <= 0: how far the tilted object reaches below its origin
        return self.T_world @ yaw_pose(0.0, 0.0, -low, 0.0) @ R


@dataclass
class Placed:
    """An assembly placed in the room: its pose (yaw about z, translation) and footprint."""

    assembly: fur.Assembly
    T_world: np.ndarray
    rect: Rect


class Layout:
    """The room's floor plan: what occupies which footprint (furniture, door clearances, window zones)."""

    def __init__(self, size: np.ndarray) -> None:
        self.size = size
        self.rects: list[Rect] = []

    def inside(self, rect: Rect, margin: float = 0.0) -> bool:
        """Whether a footprint lies inside the room, ``margin`` metres from the walls."""
        c = rect.corners()
        return bool((c >= margin - 1e-9).all() and (c[:, 0] <= self.size[0] - margin + 1e-9).all()
                    and (c[:, 1] <= self.size[1] - margin + 1e-9).all())  # fmt: skip

    def fits(self, rects: list[Rect]) -> bool:
        """Whether all ``rects`` lie inside the room, clear of everything placed and of each other."""
        for k, r in enumerate(rects):
            if not self.inside(r) or any(r.overlaps(o, CLEARANCE) for o in self.rects + rects[:k]):
                return False
        return True


def wall_frame(wall: int, size: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Wall ``wall`` (0: y = 0, 1: x = Lx, 2: y = Ly, 3: x = 0): (origin (2,), tangent (2,), length).

    The tangent runs so that the inward normal is its left-hand perpendicular: n = (-t_y, t_x).
    """
    Lx, Ly = size[0], size[1]
    return {
        0: (np.array([0.0, 0.0]), np.array([1.0, 0.0]), Lx),
        1: (np.array([Lx, 0.0]), np.array([0.0, 1.0]), Ly),
        2: (np.array([Lx, Ly]), np.array([-1.0, 0.0]), Lx),
        3: (np.array([0.0, Ly]), np.array([0.0, -1.0]), Ly),
    }[wall]


def inward(tangent: np.ndarray) -> np.ndarray:
    """The inward normal (2,) of a wall with unit ``tangent`` (its left-hand perpendicular)."""
    return np.array([-tangent[1], tangent[0]])


def yaw_facing(direction: np.ndarray) -> float:
    """The yaw that turns an assembly's front (+y) towards ``direction`` (2,)."""
    return float(np.arctan2(-direction[0], direction[1]))


def yaw_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """(4, 4) pose: yaw about z (radians), then translation (x, y, z) metres."""
    return fur.pose((x, y, z), (0.0, 0.0, yaw))


@dataclass(frozen=True)
class Opening:
    """A door or window on a wall: wall index, centre along the wall s (m), width, bottom and top heights (m)."""

    kind: str
    wall: int
    s: float
    width: float
    z0: float
    z1: float

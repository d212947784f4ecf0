"""Camera views of the depth network's training data, drawn in a room like a hand-held Kinect (NYU Depth v2,
ICL-NUIM, TUM): the view's configuration, its rotation from a viewing direction and roll, the draw of a pose (a room
view, or a close-range view of a surface 0.4-1.5 m away), and the check that a rendered view is usable. Used by
:mod:`cnnslam.depthnet.data` (which re-exports these names) when it renders the training split.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError


@dataclass(frozen=True)
class ViewConfig:
    """How camera views are drawn in a room (ours, after a hand-held Kinect as in NYU Depth v2 / ICL-NUIM / TUM).

    Modes, drawn with probabilities ``p_interest`` / ``p_look_down`` / rest: look at an interest point (furniture
    tops, objects); look down at the floor or a table from close by; free look (random heading, pitch in
    ``free_pitch_deg``) at whatever is there, mostly walls.
    """

    height_m: tuple[float, float] = (0.8, 1.8)  # optical centre above the floor, hand-held
    low_height_m: tuple[float, float] = (0.5, 1.0)  # for the look-down mode (like TUM fr3 "near" sequences)
    margin_m: float = 0.3  # free-space margin around the optical centre
    p_interest: float = 0.55
    p_look_down: float = 0.12
    free_pitch_deg: tuple[float, float] = (-40.0, 10.0)  # negative = looking down
    look_down_pitch_deg: tuple[float, float] = (-85.0, -45.0)
    max_pitch_down_deg: float = 70.0  # interest-point views steeper than this are redrawn
    roll_std_deg: float = 4.0
    max_roll_deg: float = 12.0
    min_valid_fraction: float = 0.97  # share of pixels with a surface (a view out of a gap is redrawn)
    min_median_depth_m: float = 0.5
    max_attempts: int = 200
    # Close-range views (:func:`sample_close_view_pose`; ours, after what hand-held cameras see in TUM fr1/desk, fr3
    # "near" and 7-Scenes): the camera ``close_distance_m`` from the surface it aims at, along its optical axis.
    # Kinds drawn with ``close_kind_p``: look down at the floor or a furniture top, face a desk / table / object
    # from above, face a wall or the furniture along it (cupboards, shelves).
    close_distance_m: tuple[float, float] = (0.4, 1.5)
    close_kind_p: tuple[float, float, float] = (0.35, 0.35, 0.3)  # close_down, close_desk, close_wall
    close_down_pitch_deg: tuple[float, float] = (-88.0, -45.0)
    close_desk_pitch_deg: tuple[float, float] = (-65.0, -15.0)
    close_wall_pitch_deg: tuple[float, float] = (-30.0, 10.0)
    close_wall_yaw_deg: float = 35.0  # heading off the wall's normal, at most
    close_height_m: tuple[float, float] = (0.3, 2.0)  # optical centre above the floor, hand-held
    close_margin_m: float = 0.15  # free-space margin of a close view's optical centre
    close_median_depth_m: tuple[float, float] = (0.3, 1.6)  # a rendered close view's median depth, else redrawn


def camera_rotation(forward: np.ndarray, roll_rad: float) -> np.ndarray:
    """(3, 3) camera-to-world rotation (OpenCV axes, world z up) looking along ``forward`` with a roll.

    forward: (3,) world direction of the optical axis (not vertical). Image x is horizontal before the roll; the roll
    turns the camera about its optical axis.
    """
    z = np.asarray(forward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    n = np.linalg.norm(x)
    if n < 1e-6:
        raise CnnSlamError("camera_rotation: the viewing direction is vertical")
    x /= n
    y = np.cross(z, x)
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    x_r, y_r = c * x + s * y, -s * x + c * y
    return np.stack([x_r, y_r, z], axis=1)


def _direction(yaw: float, pitch: float) -> np.ndarray:
    return np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])


def sample_view_pose(scene: Any, rng: np.random.Generator, cfg: ViewConfig) -> tuple[np.ndarray, str]:
    """One candidate ``T_world_cam`` (4, 4) float64 in ``scene``'s free space and the mode that drew it.

    The caller checks the rendered view (:func:`view_is_usable`) and draws again if it is unusable.
    """
    room = np.asarray(scene.room_size, dtype=np.float64)
    points = scene.interest_points()
    for _ in range(cfg.max_attempts):
        u = rng.random()
        mode = "interest" if u < cfg.p_interest else ("look_down" if u < cfg.p_interest + cfg.p_look_down else "free")
        heights = cfg.low_height_m if mode == "look_down" else cfg.height_m
        eye = np.array([rng.uniform(0, room[0]), rng.uniform(0, room[1]), rng.uniform(*heights)])
        if not scene.free_space(eye[None], margin=cfg.margin_m)[0]:
            continue
        if mode == "interest" and len(points):
            target = points[rng.integers(len(points))] + rng.normal(0.0, 0.15, 3)
            d = target - eye
            dist = np.linalg.norm(d)
            if dist < 0.6:
                continue
            pitch = np.arcsin(np.clip(d[2] / dist, -1.0, 1.0))
            if np.degrees(-pitch) > cfg.max_pitch_down_deg:
                continue
            yaw = np.arctan2(d[1], d[0])
        else:
            yaw = rng.uniform(-np.pi, np.pi)
            pitch_range = cfg.look_down_pitch_deg if mode == "look_down" else cfg.free_pitch_deg
            pitch = np.radians(rng.uniform(*pitch_range))
            mode = "free" if mode == "interest" else mode
        roll = np.radians(np.clip(rng.normal(0.0, cfg.roll_std_deg), -cfg.max_roll_deg, cfg.max_roll_deg))
        T = np.eye(4)
        T[:3, :3] = camera_rotation(_direction(yaw, pitch), roll)
        T[:3, 3] = eye
        return T, mode
    raise CnnSlamError(f"no free camera position found in {cfg.max_attempts} draws in room {scene.style}/{scene.seed}")


CLOSE_KINDS = ("close_down", "close_desk", "close_wall")  # the modes of :func:`sample_close_view_pose`


def sample_close_view_pose(scene: Any, rng: np.random.Generator, cfg: ViewConfig) -> tuple[np.ndarray, str]:
    """One candidate close-range ``T_world_cam`` (4, 4) float64 in ``scene``'s free space and its mode (one of
    :data:`CLOSE_KINDS`): the optical axis meets a surface point ``d`` ~ U(``close_distance_m``) metres ahead.

    close_down: the point on the floor or on a furniture top, pitch in ``close_down_pitch_deg``; close_desk: the
    point near a furniture top or object (interest points), pitch in ``close_desk_pitch_deg``; close_wall: the point
    on a wall (the furniture along it may be nearer), heading within ``close_wall_yaw_deg`` of the wall's normal,
    pitch in ``close_wall_pitch_deg``. The caller checks the rendered view (:func:`view_is_usable` with its mode).
    """
    room = np.asarray(scene.room_size, dtype=np.float64)
    points = scene.interest_points()
    for _ in range(cfg.max_attempts):
        mode = CLOSE_KINDS[int(rng.choice(3, p=np.asarray(cfg.close_kind_p) / np.sum(cfg.close_kind_p)))]
        d = rng.uniform(*cfg.close_distance_m)
        roll = np.radians(np.clip(rng.normal(0.0, cfg.roll_std_deg), -cfg.max_roll_deg, cfg.max_roll_deg))
        if mode == "close_wall":
            wall = int(rng.integers(4))  # -x, +x, -y, +y walls; the camera faces it
            axis, far = wall // 2, wall % 2
            normal_yaw = (np.pi if not far else 0.0) if axis == 0 else (-np.pi / 2 if not far else np.pi / 2)
            yaw = normal_yaw + np.radians(rng.uniform(-cfg.close_wall_yaw_deg, cfg.close_wall_yaw_deg))
            pitch = np.radians(rng.uniform(*cfg.close_wall_pitch_deg))
            target = np.array([rng.uniform(0, room[0]), rng.uniform(0, room[1]), rng.uniform(0.2, room[2] - 0.2)])
            target[axis] = room[axis] if far else 0.0
        else:
            use_floor = mode == "close_down" and (not len(points) or rng.random() < 0.5)
            if use_floor:
                target = np.array([rng.uniform(0, room[0]), rng.uniform(0, room[1]), 0.0])
            elif len(points):
                target = points[rng.integers(len(points))] + rng.normal(0.0, 0.1, 3)
            else:
                continue
            yaw = rng.uniform(-np.pi, np.pi)
            pitch = np.radians(rng.uniform(*(cfg.close_down_pitch_deg if mode == "close_down"
                                             else cfg.close_desk_pitch_deg)))
        forward = _direction(yaw, pitch)
        eye = target - d * forward
        if not (cfg.close_height_m[0] <= eye[2] <= cfg.close_height_m[1]):
            continue
        if not scene.free_space(eye[None], margin=cfg.close_margin_m)[0]:
            continue
        T = np.eye(4)
        T[:3, :3] = camera_rotation(forward, roll)
        T[:3, 3] = eye
        return T, mode
    raise CnnSlamError(f"no free close-range camera position found in {cfg.max_attempts} draws in room "
                       f"{scene.style}/{scene.seed}")


def view_is_usable(depth: np.ndarray, cfg: ViewConfig, mode: str = "") -> bool:
    """A rendered view is kept when almost every pixel sees a surface and it is not pressed against one: its median
    depth at least ``min_median_depth_m``, or, for a close-range ``mode`` (:data:`CLOSE_KINDS`), within
    ``close_median_depth_m`` (so that a close view really is close).

    depth: (H, W) float32 metres, 0 = no surface.
    """
    valid = depth > 0
    if valid.mean() < cfg.min_valid_fraction:
        return False
    median = float(np.median(depth[valid]))
    if mode in CLOSE_KINDS:
        return cfg.close_median_depth_m[0] <= median <= cfg.close_median_depth_m[1]
    return median >= cfg.min_median_depth_m

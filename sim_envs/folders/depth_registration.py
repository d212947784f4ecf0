"""Depth registration: move depth maps from one camera to another, and check depth maps against poses.

:func:`register_depth` re-projects a depth camera's map into a colour camera beside it (:class:`DepthRig`: the depth
camera's intrinsics and the depth-to-colour transform), the nearest surface winning where several land on one pixel.
:func:`move_pixels` (back-project, move, project to the nearest pixel) is shared with :func:`depth_consistency`,
which scores how well two frames' depth maps agree under their poses (the loader decides an ICL-NUIM folder's pose
convention with it).

7-Scenes' depth maps and KinectFusion poses are the depth camera's; its colour camera is another, unregistered one.
:data:`SEVEN_SCENES_T_COLOUR_DEPTH` is the Kinect's depth-to-colour baseline with which
:class:`sim_envs.folders.datasets.RgbdFolder` registers them (when and how: :mod:`sim_envs.folders.datasets`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError

# 7-Scenes' depth camera -> colour camera (X_colour = T X_depth, metres): the Kinect's 2.6 cm baseline between
# them, the translation of the LIRIS Kinect calibration (projet.liris.cnrs.fr/voir/activities-dataset/
# kinect-calibration.html) with which the relocalisation setups ACE and DSAC* register 7-Scenes. Its 0.65 deg
# rotation is another Kinect's and is left out: on redkitchen's frames the depth edges fall on the colour edges far
# better without it (sim_envs.sensor.camera_calibration.depth_edge_alignment over 20 frames: 2.57 without, 1.41 with,
# 1.30 unregistered; with the translation, 525 px beats 510 and 540: 2.57 vs 1.81 and 2.07).
SEVEN_SCENES_T_COLOUR_DEPTH = np.array([
    [1.0, 0.0, 0.0, -2.5558943178152542e-02],
    [0.0, 1.0, 0.0, 1.0109636268061706e-04],
    [0.0, 0.0, 1.0, 2.0318321729487039e-03],
    [0.0, 0.0, 0.0, 1.0],
])  # fmt: skip
SEVEN_SCENES_T_COLOUR_DEPTH.setflags(write=False)


@dataclass(frozen=True)
class DepthRig:
    """A depth camera beside the colour camera, whose depth maps and poses the loader moves to the colour camera.

    depth_intrinsics: the depth camera's pinhole K at the depth images' size; T_colour_depth: (4, 4) maps depth-camera
    coordinates to colour-camera coordinates (OpenCV axes, metres); source: where both came from (for the record).
    """

    depth_intrinsics: Intrinsics
    T_colour_depth: np.ndarray
    source: str


def register_depth(depth: np.ndarray, depth_intrinsics: Intrinsics, colour_intrinsics: Intrinsics,
                   T_colour_depth: np.ndarray) -> np.ndarray:  # fmt: skip
    """A depth camera's (H, W) planar z map (metres, 0 = none) seen from the colour camera: each measured pixel is
    back-projected with ``depth_intrinsics``, moved by ``T_colour_depth`` and projected with ``colour_intrinsics``
    to its nearest pixel, the nearest surface winning where several land on one pixel (a z-buffer). Returns
    (colour height, colour width) float32 planar z in the colour camera, 0 where no measurement lands."""
    d = np.asarray(depth, dtype=np.float64)
    Kd, Kc = depth_intrinsics, colour_intrinsics
    if d.shape != (Kd.height, Kd.width):
        raise SimEnvError(f"depth of shape {d.shape} for a depth camera of {Kd.width}x{Kd.height}")
    v, u = np.nonzero(d > 0)
    uc, vc, zc = move_pixels(u, v, d[v, u], Kd, T_colour_depth, Kc, (Kc.height, Kc.width))
    out = np.full(Kc.height * Kc.width, np.inf)
    np.minimum.at(out, vc * Kc.width + uc, zc)
    out[~np.isfinite(out)] = 0.0
    return out.reshape(Kc.height, Kc.width).astype(np.float32)


def depth_consistency(
    depth_a: np.ndarray,
    T_world_a: np.ndarray,
    depth_b: np.ndarray,
    T_world_b: np.ndarray,
    intrinsics: Intrinsics,
    rel_tol: float = 0.05,
    stride: int = 2,
) -> float:
    """Share (0..1) of frame a's depth pixels that, moved into frame b by the poses, land on a depth of b agreeing
    within ``rel_tol`` (relative). Only pixels landing inside b on a valid depth count; NaN if none does.

    depth_*: (H, W) planar z metres (0 = none); T_world_*: (4, 4) camera-to-world; every ``stride``-th pixel is used.
    """
    v, u = np.mgrid[0 : depth_a.shape[0] : stride, 0 : depth_a.shape[1] : stride]
    z = np.asarray(depth_a, dtype=np.float64)[v, u]
    ok = np.isfinite(z) & (z > 0)
    ub, vb, zb = move_pixels(u[ok], v[ok], z[ok], intrinsics, np.linalg.inv(T_world_b) @ T_world_a, intrinsics,
                             depth_b.shape)  # fmt: skip
    measured = np.asarray(depth_b, dtype=np.float64)[vb, ub]
    valid = np.isfinite(measured) & (measured > 0)
    if not valid.any():
        return math.nan
    agree = np.abs(zb[valid] - measured[valid]) < rel_tol * measured[valid]
    return float(agree.mean())


def move_pixels(u: np.ndarray, v: np.ndarray, z: np.ndarray, K_from: Intrinsics, T_to_from: np.ndarray,
                K_to: Intrinsics, shape_to: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Pixels (u, v) with planar depth z (1-D arrays, metres) of a camera ``K_from``, back-projected, moved by
    ``T_to_from`` (4, 4; OpenCV axes) and projected with ``K_to`` to their nearest pixel: (u', v', z') int64, int64,
    float64 of those that land in front of the camera and inside an image of ``shape_to`` (height, width, ...)."""
    points = np.stack([(u - K_from.cx) / K_from.fx * z, (v - K_from.cy) / K_from.fy * z, z, np.ones_like(z)])
    moved = (np.asarray(T_to_from, dtype=np.float64) @ points)[:3]
    zt = moved[2]
    front = zt > 1e-6
    ut = np.rint(K_to.fx * moved[0, front] / zt[front] + K_to.cx).astype(np.int64)
    vt = np.rint(K_to.fy * moved[1, front] / zt[front] + K_to.cy).astype(np.int64)
    zt = zt[front]
    inside = (ut >= 0) & (ut < shape_to[1]) & (vt >= 0) & (vt < shape_to[0])
    return ut[inside], vt[inside], zt[inside]

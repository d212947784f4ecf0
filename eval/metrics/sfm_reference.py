"""A second reference for real sequences: the camera self-calibrated from the images, and camera poses from
structure from motion (COLMAP, through pycolmap), beside the folder's own ground truth.

Why: a real sequence's "ground truth" is another algorithm's output. 7-Scenes' poses come from KinectFusion on the
depth camera, and Brachmann et al. ("On the Limits of Pseudo Ground Truth in Visual Camera Re-localisation", ICCV
2021) showed that rankings on 7-Scenes change when its KinectFusion poses are replaced by an SfM reconstruction of
the colour images. A verdict should hold against both. This module makes the SfM one from the images alone, and says
how far the two references disagree; that disagreement is the floor below which no method's error against either
can be read.

What it computes:

- :func:`reconstruct` (:mod:`slamcommon.sfm`, shared with COLMAP the method): COLMAP's incremental SfM on the
  given images (SIFT, sequential matching, one shared camera whose focal length and radial distortion are refined
  in the bundle adjustment; the initial focal length is COLMAP's own guess, 1.2 x the image width, so nothing from
  the folder's stated camera goes in). Returns the largest model.
- :func:`colmap_to_opencv_camera`: that camera in OpenCV's convention (pixel centres at integers: COLMAP puts them at
  +0.5, so ``cx = cx_colmap - 0.5``), radial ``k1 k2`` in OpenCV's order ``k1 k2 p1 p2 k3``.
- :func:`metric_scale`: SfM has no scale; the median over all observations of sensor depth / SfM depth of the
  observed 3D point (planar z in the camera), when the folder has depth. This uses the depth images only, not the
  folder's poses, so the scaled reference is independent of them.
- :func:`reference_trajectory`: camera poses ``T_world_cam`` (OpenCV camera frame, metres once scaled), one per
  registered image, with the images' timestamps.

Numeric cores (:func:`metric_scale`, :func:`colmap_to_opencv_camera`) do no I/O; :func:`reconstruct` writes
COLMAP's database and model under a work folder.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim_envs.camera import CameraModel, Intrinsics
from slamcommon.sfm import CAMERA_MODELS as SFM_CAMERA_MODELS
from slamcommon.sfm import (  # noqa: F401  (the reference's pipeline, re-exported for its users)
    COLMAP_PIXEL_OFFSET,
    DEFAULT_CAMERA_MODEL,
    DEFAULT_OVERLAP,
    SfmError,
    model_poses,
    reconstruct,
)

# COLMAP camera models the reference self-calibrates: those with a single radial polynomial OpenCV can use
CAMERA_MODELS: tuple[str, ...] = tuple(m for m in SFM_CAMERA_MODELS if m != "PINHOLE")


@dataclass
class SfmReference:
    """Camera poses from structure from motion.

    ``frame_indices`` (n,) int: which of the given images were registered (sorted); ``timestamps`` (n,) seconds;
    ``T_world_cam`` (n, 4, 4): OpenCV camera frame, in metres when ``scale_source`` says so (else SfM units);
    ``camera``: the self-calibrated camera, fitted as COLMAP's ``camera_model``; ``images``: how many were given;
    ``points``: 3D points of the model; ``reprojection_px``: COLMAP's mean reprojection error; ``scale``: the factor
    applied to the SfM units.
    """

    frame_indices: np.ndarray
    timestamps: np.ndarray
    T_world_cam: np.ndarray
    camera: CameraModel
    camera_model: str
    images: int
    points: int
    reprojection_px: float
    scale: float = 1.0
    scale_source: str = "none (SfM units)"
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def registered_share(self) -> float:
        """Share of the given images that the model registered."""
        return len(self.frame_indices) / self.images if self.images else 0.0


def colmap_to_opencv_camera(model: str, params: Sequence[float], width: int, height: int) -> CameraModel:
    """A COLMAP camera (``model``, its ``params``) as a :class:`~sim_envs.camera.CameraModel` in OpenCV's pixel
    convention.

    SIMPLE_RADIAL ``f cx cy k``, RADIAL ``f cx cy k1 k2``, OPENCV ``fx fy cx cy k1 k2 p1 p2``; COLMAP's radial and
    tangential terms are OpenCV's (same normalised-coordinate polynomial), its pixel centres are 0.5 further.
    """
    p = [float(x) for x in params]
    if model == "SIMPLE_RADIAL" and len(p) == 4:
        fx = fy = p[0]
        cx, cy, dist = p[1], p[2], (p[3], 0.0, 0.0, 0.0, 0.0)
    elif model == "RADIAL" and len(p) == 5:
        fx = fy = p[0]
        cx, cy, dist = p[1], p[2], (p[3], p[4], 0.0, 0.0, 0.0)
    elif model == "OPENCV" and len(p) == 8:
        fx, fy, cx, cy = p[:4]
        dist = (p[4], p[5], p[6], p[7], 0.0)
    else:
        raise SfmError(f"COLMAP camera {model} with {len(p)} parameters: valid models {', '.join(CAMERA_MODELS)}")
    K = Intrinsics(fx, fy, cx - COLMAP_PIXEL_OFFSET, cy - COLMAP_PIXEL_OFFSET, int(width), int(height))
    return CameraModel(K, dist)  # type: ignore[arg-type]


def metric_scale(sfm_depth: np.ndarray, sensor_depth: np.ndarray, min_observations: int = 50) -> tuple[float, int]:
    """Metres per SfM unit: the median of ``sensor_depth / sfm_depth`` over the observations where both are
    positive and finite (planar z of the same 3D point in the same camera). Returns (scale, observations used).

    The median makes it robust to the depth-to-colour misregistration at depth edges and to SfM outliers.
    """
    a = np.asarray(sfm_depth, dtype=np.float64).reshape(-1)
    b = np.asarray(sensor_depth, dtype=np.float64).reshape(-1)
    if a.shape != b.shape:
        raise SfmError(f"sfm_depth and sensor_depth differ in length: {a.size} and {b.size}")
    ok = np.isfinite(a) & np.isfinite(b) & (a > 0) & (b > 0)
    n = int(ok.sum())
    if n < min_observations:
        raise SfmError(f"only {n} observations have both an SfM depth and a sensor depth (need {min_observations})")
    return float(np.median(b[ok] / a[ok])), n


def reference_trajectory(
    model: Any,
    timestamps: Sequence[float],
    depth_at: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> SfmReference:
    """The poses of a COLMAP model made by :func:`reconstruct` as an :class:`SfmReference`.

    ``timestamps``: of the images in the order given to :func:`reconstruct`. ``depth_at(i, uv)``: the sensor's
    planar depth in metres (0 = none) of image ``i`` at the (m, 2) OpenCV pixel coordinates ``uv`` of that image's
    resolution; when given, the poses are scaled to metres by :func:`metric_scale`.
    """
    stamps = np.asarray(timestamps, dtype=np.float64)
    images = {int(Path(image.name).stem): image for image in model.images.values()}
    rows = [(index, images[index], T) for index, T in model_poses(model)]
    if len(rows) < 3:
        raise SfmError(f"COLMAP registered {len(rows)} of {len(stamps)} images; a reference needs at least 3")
    camera = next(iter(model.cameras.values()))
    calibration = colmap_to_opencv_camera(camera.model.name, camera.params, camera.width, camera.height)
    T = np.stack([r[2] for r in rows])
    reference = SfmReference(
        frame_indices=np.array([r[0] for r in rows]),
        timestamps=stamps[[r[0] for r in rows]],
        T_world_cam=T,
        camera=calibration,
        camera_model=camera.model.name,
        images=len(stamps),
        points=int(model.num_points3D()),
        reprojection_px=float(model.compute_mean_reprojection_error()),
    )
    if depth_at is not None:
        sfm_z, sensor_z = [], []
        for index, image, T_world_cam in rows:
            observed = [p for p in image.points2D if p.has_point3D()]
            if not observed:
                continue
            xyz = np.array([model.points3D[p.point3D_id].xyz for p in observed])
            uv = np.array([p.xy for p in observed]) - COLMAP_PIXEL_OFFSET
            z = (xyz - T_world_cam[:3, 3]) @ T_world_cam[:3, 2]  # planar depth: along the camera's z axis
            sfm_z.append(z)
            sensor_z.append(np.asarray(depth_at(index, uv), dtype=np.float64))
        scale, used = metric_scale(np.concatenate(sfm_z), np.concatenate(sensor_z))
        reference.T_world_cam = T.copy()
        reference.T_world_cam[:, :3, 3] *= scale
        reference.scale = scale
        reference.scale_source = f"sensor depth (median ratio over {used} observations)"
        reference.details["depth_observations"] = used
    return reference


def nearest_depth(depth: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Depth (H, W) at the nearest pixel of each OpenCV pixel coordinate in ``uv`` (m, 2); 0 outside the image."""
    h, w = depth.shape
    u = np.rint(uv[:, 0]).astype(np.int64)
    v = np.rint(uv[:, 1]).astype(np.int64)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    out = np.zeros(len(uv), dtype=np.float64)
    out[inside] = depth[v[inside], u[inside]]
    return out

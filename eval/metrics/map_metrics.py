"""The agent's global 3D model scored against the scene (CNN-SLAM Sec. 3.5 / Fig. 1c, made quantitative), as run
metrics of every suite: what ``cnnslam map`` measures in depth, here in the run record and the gate.

Input: the agent's :class:`sim_envs.agent.MapModel` (points in its own world frame, fused labels), its key-frame
poses and the ground-truth frames at those key-frames (the driver's matching), and the scene's labelled surface
samples (:func:`sim_envs.scenes.surface_sampling.sample_scene_surface`, 2 cm apart). The model is moved onto the ground
truth with the alignment of the run's trajectory, the one its ATE uses (:func:`slamcommon.alignment.align`, the
run's alignment method: SE(3) by default, so absolute scale counts). Only surfaces at least one key-frame saw count
for completeness (:func:`slamcommon.reconstruction_metrics.visible_in_views`); accuracy is measured against every
surface. Both come from :func:`slamcommon.reconstruction_metrics.reconstruction_metrics`, as in `cnnslam map`.

Metrics (metres, shares 0..1): ``map_accuracy_median`` and ``map_accuracy_within`` (model point to the nearest
surface, any surface of the scene, point-to-plane within a sample's cell; share within 5 cm),
``map_completeness_median`` and ``map_completeness_within`` (each surface sample a key-frame saw to the nearest
model point),
``map_label_accuracy`` (share of labelled model points whose fused label is the label of the nearest surface
sample within 10 cm; the model's own elements, one vote each) and ``map_points``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sim_envs.scenes.surface_sampling import sample_scene_surface
from slamcommon.alignment import align
from slamcommon.labels import NO_LABEL
from slamcommon.reconstruction_metrics import (
    DEFAULT_LABEL_DISTANCE,
    DEFAULT_THRESHOLD,
    nearest_tree,
    reconstruction_metrics,
    visible_in_views,
)

GT_SPACING: float = 0.02  # m, the surface samples' spacing (as `cnnslam map`)
MAP_METRICS: tuple[str, ...] = ("map_accuracy_median", "map_accuracy_within", "map_completeness_median",
                                "map_completeness_within", "map_label_accuracy", "map_points")


def map_metrics(model: Any, T_world_cam_gt: np.ndarray, T_world_cam_est: np.ndarray, keyframe_gt: list[Any],
                intrinsics: np.ndarray, scene: Any, alignment: str = "se3",
                threshold: float = DEFAULT_THRESHOLD) -> dict[str, float]:
    """The ``map_*`` metrics of the module docstring. model: a ``MapModel``; T_world_cam_gt, T_world_cam_est: (N, 4,
    4) the episode's poses, paired by index (they fit the alignment); keyframe_gt: the ground-truth frames
    (``T_world_cam``, ``depth``) of the agent's key-frames; intrinsics: [fx, fy, cx, cy]; scene: the simulated
    scene (its surfaces are sampled here). Empty dict without key-frames."""
    if len(keyframe_gt) == 0:
        return {}
    T_gt = np.stack([np.asarray(f.T_world_cam, dtype=np.float64) for f in keyframe_gt])
    S = align(np.asarray(T_world_cam_gt, dtype=np.float64), np.asarray(T_world_cam_est, dtype=np.float64),
              alignment).matrix
    points = np.asarray(model.points, dtype=np.float64) @ S[:3, :3].T + S[:3, 3]
    surface = sample_scene_surface(scene, GT_SPACING)
    seen = visible_in_views(surface.points, T_gt, [f.depth for f in keyframe_gt], np.asarray(intrinsics))
    if not seen.any():
        return {}
    # each model point's nearest surface sample, found once: the accuracy's distances and the labels' samples
    distances, nearest = nearest_tree(surface.points).query(points, k=1)
    recon = reconstruction_metrics(points, surface.points, surface.normals, surface.spacing, threshold, seen=seen,
                                   nearest=(distances, nearest))
    out = {
        "map_accuracy_median": recon.accuracy_median,
        "map_accuracy_within": recon.accuracy_within,
        "map_completeness_median": recon.completeness_median,
        "map_completeness_within": recon.completeness_within,
        "map_points": float(points.shape[0]),
    }
    labels = None if model.labels is None else np.asarray(model.labels).reshape(-1)
    if labels is not None and (labels != NO_LABEL).any():
        labelled = labels != NO_LABEL
        # slamcommon.reconstruction_metrics.nearest_labels of the labelled points, from the search above
        gt_labels = np.where(distances[labelled] <= DEFAULT_LABEL_DISTANCE, surface.labels[nearest[labelled]],
                             NO_LABEL).astype(np.uint8)
        scored = gt_labels != NO_LABEL
        out["map_label_accuracy"] = (float(np.mean(labels[labelled][scored] == gt_labels[scored])) if scored.any()
                                     else math.nan)
    return out

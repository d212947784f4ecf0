"""Replaying and scoring a global model against a simulated scene: the numeric core of ``cnnslam map``
(:mod:`cnnslam.tools.cli_map` is its edge: arguments, files, the summary). No I/O here.

:func:`fuse_keyframes` fuses key-frames (``sim_envs.agent.KeyframeDepth``) into a new
:class:`~cnnslam.model.global_model.GlobalModel` as the paper's key-frame thread does (Sec. 3.5): at the poses answered
online, then re-placed at the final ones; for agents whose model is not live, and for the label replays below.
:func:`map_scores` scores a model with the shared metrics of :mod:`slamcommon.reconstruction_metrics` against the
scene's ground-truth surfaces (:mod:`sim_envs.scenes.surface_sampling`), after aligning the key-frame poses onto the
ground
truth (SE(3) by default: absolute scale is part of what is measured).

Semantic accuracy is reported four ways, fused model vs the frame-wise CNN labels each time:

- ``semantic``: in 3D, on back-projected key-frame pixels, each scored against the nearest ground-truth surface
  sample (:func:`slamcommon.reconstruction_metrics.label_fusion_metrics`); a pixel whose estimated depth is off by more
  than the surface spacing is scored against whatever surface lies there, for both labels alike;
- ``semantic_image``: the model rendered into each key-frame (front-most surfel per pixel) against the rendered
  ground-truth labels of that key-frame (the paper's Fig. 6 view);
- ``semantic_measurements``: on the fused measurements themselves (the issue's "same surfaces", exactly): the fusion
  is replayed with each key-frame pixel's ground-truth label and whether its CNN label was right in place of the
  class probabilities (same depth, poses and association, so the same surfels; for the agent's live model, both
  fusions are replays of its key-frames, as its thread re-places surfels between them), and every fused measurement is
  scored against its own ground-truth label with its frame-wise label and with its surfel's fused label
  (:func:`slamcommon.reconstruction_metrics.measurement_label_metrics`; weights: Keller's radial confidence alpha). It
  separates what the label averaging does (``pure_*``: surfels whose measurements share one ground-truth label) from
  what the data association costs (``mixed_*``; ``purity`` is the ceiling of any one label per surfel);
- ``semantic_measurements_exact_geometry``: the same, fusing the same CNN labels with the ground-truth depth and
  poses of the key-frames (no depth variance): what the label fusion gains when geometry is not in the way.

Ground truth enters only through the arguments (the episode's ``keyframe_gt`` and the scene), at the edge's call.
"""

from __future__ import annotations

import dataclasses
import math
import time
import tracemalloc
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError

FRAMEWISE_STRIDE = 4  # pixels; key-frame pixels back-projected for the semantic comparison (every 4th per axis)


def corrected_trajectory(T_online: np.ndarray, kf_steps: np.ndarray, T_kf_online: np.ndarray,
                         T_kf_final: np.ndarray) -> np.ndarray:
    """Every frame's online pose (N, 4, 4) moved with its key-frame: T_final_k T_online_k^-1 T_online_f, with k the
    last key-frame at or before frame f (the first one for earlier frames)."""
    from cnnslam.geometry import se3_inverse

    out = np.array(T_online, dtype=np.float64)
    if len(kf_steps) == 0:
        return out
    corrections = T_kf_final @ se3_inverse(T_kf_online)
    order = np.argsort(kf_steps, kind="stable")
    which = np.searchsorted(kf_steps[order], np.arange(out.shape[0]), side="right") - 1
    which = order[np.clip(which, 0, None)]
    return corrections[which] @ out


def fuse_keyframes(keyframes: list[Any], images: list[np.ndarray], intrinsics: np.ndarray,
                   online_poses: np.ndarray | None, config: Any,
                   label_maps: list[np.ndarray] | None = None) -> tuple[Any, dict[str, Any]]:
    """Fuse key-frames (``sim_envs.agent.KeyframeDepth``) with their images into a new global model.

    online_poses: (K, 4, 4) poses to fuse at, then re-place at each key-frame's final ``T_world_cam``; None to fuse
    at the final poses. label_maps: per key-frame (H, W, C) maps fused in place of the key-frames' labels (None: their
    own). Returns (model, report with sizes per key-frame, re-placement, seconds, tracemalloc peak).
    """
    from cnnslam.model.global_model import GlobalModel

    model = GlobalModel(config)
    sizes = []
    t0 = time.perf_counter()
    tracing = not tracemalloc.is_tracing()
    if tracing:
        tracemalloc.start()
    try:
        for i, (kf, rgb) in enumerate(zip(keyframes, images, strict=True)):
            T = np.asarray(kf.T_world_cam if online_poses is None else online_poses[i], dtype=np.float64)
            labels = kf.labels if label_maps is None else label_maps[i]
            stats = model.integrate(kf.depth, T, intrinsics, rgb, labels, kf.uncertainty, anchor=i)
            sizes.append(stats.surfels)
        replacement = None
        if online_poses is not None:
            r = model.update_poses({i: np.asarray(kf.T_world_cam) for i, kf in enumerate(keyframes)})
            replacement = {"keyframes_moved": r.keyframes_moved, "surfels_moved": r.surfels_moved,
                           "surfels_merged": r.surfels_merged, "max_displacement_m": r.max_displacement,
                           "mean_displacement_m": r.mean_displacement}
        _, peak = tracemalloc.get_traced_memory()
    finally:
        if tracing:
            tracemalloc.stop()
    report = {"surfels_per_keyframe": sizes, "replacement": replacement, "seconds": time.perf_counter() - t0,
              "tracemalloc_peak_mb": peak / 2**20, "model_mb": model.nbytes / 2**20, "surfels": len(model)}
    return model, report


def framewise_labels(keyframe: Any) -> np.ndarray:
    """(H, W) uint8 frame-wise CNN labels of a key-frame: the argmax of its class probabilities, or its label map."""
    labels = np.asarray(keyframe.labels)
    return (np.argmax(labels, axis=2) if labels.ndim == 3 else labels).astype(np.uint8)


def evidence_maps(keyframes: list[Any], gt_frames: list[Any], num_classes: int) -> list[np.ndarray]:
    """Per key-frame (H, W, C + 2) float32 maps to replay the fusion with: the pixel's ground-truth label one-hot
    (channels 0..C-1), then 1 in channel C where the key-frame's CNN label equals it, 1 in channel C + 1 where it does
    not (all 0 without a ground-truth label)."""
    from sim_envs.frames import NO_LABEL

    maps = []
    for kf, gt_frame in zip(keyframes, gt_frames, strict=True):
        framewise = framewise_labels(kf)
        gt = np.asarray(gt_frame.labels)
        known = gt != NO_LABEL
        out = np.zeros((*gt.shape, num_classes + 2), np.float32)
        out[known, gt[known].astype(np.int64)] = 1.0
        right = known & (framewise == gt)
        out[right, num_classes] = 1.0
        out[known & ~right, num_classes + 1] = 1.0
        maps.append(out)
    return maps


def measurement_scores(keyframes: list[Any], images: list[np.ndarray], intrinsics: np.ndarray,
                       online_poses: np.ndarray | None, config: Any, evidence: list[np.ndarray],
                       model: Any = None) -> dict[str, Any]:
    """``semantic_measurements`` (see the module docstring) of the key-frames' fusion with ``config`` at
    ``online_poses`` (:func:`fuse_keyframes`): the fusion is replayed with ``evidence`` maps in place of the labels
    and each fused measurement scored with its frame-wise and its surfel's fused label. ``model``: that fusion when
    already made (the same inputs), else it is made here. A live model (the agent's key-frame thread) is not it: the
    thread re-places surfels whenever the pose graph moves a key-frame, between integrations, so its surfels need
    not be the replay's."""
    from slamcommon.reconstruction_metrics import measurement_label_metrics

    if model is None:
        model, _ = fuse_keyframes(keyframes, images, intrinsics, online_poses, config)
    C = config.num_classes
    replay_config = dataclasses.replace(config, num_classes=C + 2, label_weighting="confidence")
    replay, _ = fuse_keyframes(keyframes, images, intrinsics, online_poses, replay_config, label_maps=evidence)
    if len(replay) != len(model) or not np.array_equal(replay.snapshot().positions, model.snapshot().positions):
        raise CnnSlamError("the replayed fusion built a different model; labels must not change the geometry")
    E = replay.label_evidence()
    return measurement_label_metrics(model.labels(), E[:, :C], E[:, C]).to_dict()


def map_scores(cloud: Any, model: Any, result: Any, scene: Any, *, alignment: str = "se3", gt_spacing: float = 0.02,
               threshold: float = 0.05, label_distance: float = 0.10, online_poses: np.ndarray | None = None,
               config: Any = None, live: bool = False) -> dict[str, Any]:
    """The shared reconstruction and semantic metrics of a fused model against the scene's surfaces (see the module
    docstring): key-frame poses aligned onto the ground truth (``alignment``), surface samples every ``gt_spacing``
    m, accuracy/completeness within ``threshold`` m, 3D labels within ``label_distance`` m. ``online_poses`` and
    ``config`` are those the model was fused with (:func:`fuse_keyframes`); ``live``: the model is the agent's own
    (its key-frame thread's), so the measurement scores replay the fusion from the key-frames instead."""
    from cnnslam.geometry import transform_points, vertex_map
    from cnnslam.model.global_model import GlobalModelConfig
    from sim_envs.frames import NO_LABEL
    from sim_envs.scenes.surface_sampling import sample_scene_surface
    from slamcommon.alignment import align
    from slamcommon.reconstruction_metrics import (
        image_label_accuracy,
        label_fusion_metrics,
        reconstruction_metrics,
        visible_in_views,
    )

    intr = result.intrinsics.as_array()
    size = (result.intrinsics.height, result.intrinsics.width)
    kf_est = np.stack([np.asarray(k.T_world_cam, dtype=np.float64) for k in result.keyframes])
    kf_gt = np.stack([f.T_world_cam for f in result.keyframe_gt])
    fit = align(kf_gt, kf_est, alignment)
    S = fit.matrix

    def to_gt(points: np.ndarray) -> np.ndarray:
        return transform_points(S, points)

    gt = sample_scene_surface(scene, gt_spacing)
    seen = visible_in_views(gt.points, kf_gt, [f.depth for f in result.keyframe_gt], intr)
    model_points = to_gt(cloud.positions.astype(np.float64))
    recon = reconstruction_metrics(model_points, gt.points, gt.normals, gt.spacing, threshold, seen=seen)
    out: dict[str, Any] = {"alignment": fit.describe(), "gt_samples": len(gt), "gt_visible": int(seen.sum()),
                           "gt_spacing_m": gt.spacing, "reconstruction": recon.to_dict()}
    if all(k.labels is not None for k in result.keyframes) and (cloud.labels != NO_LABEL).any():
        frame_points, frame_labels = [], []
        fused_maps, frame_maps, gt_maps = [], [], []
        s = FRAMEWISE_STRIDE
        surfel_labels = model.labels()
        for kf, gt_frame in zip(result.keyframes, result.keyframe_gt, strict=True):
            label_map = framewise_labels(kf)
            depth = np.asarray(kf.depth, dtype=np.float32)
            has = np.isfinite(depth) & (depth > 0)
            V = vertex_map(np.where(has, depth, 0.0), intr)
            sub = has[::s, ::s]
            frame_points.append(to_gt(transform_points(kf.T_world_cam, V[::s, ::s][sub])))
            frame_labels.append(label_map[::s, ::s][sub])
            if gt_frame.labels is not None:
                view = model.render(kf.T_world_cam, intr, size)
                fused = np.full(size, NO_LABEL, np.uint8)
                hit = view.index >= 0
                fused[hit] = surfel_labels[view.index[hit]]
                fused_maps.append(np.where(has, fused, NO_LABEL).astype(np.uint8))
                frame_maps.append(label_map)
                gt_maps.append(gt_frame.labels)
        sem = label_fusion_metrics(model_points, cloud.labels, np.concatenate(frame_points),
                                   np.concatenate(frame_labels), gt.points, gt.labels, label_distance)
        out["semantic"] = sem.to_dict()
        if gt_maps:
            fused_acc, frame_acc, n = image_label_accuracy(fused_maps, frame_maps, gt_maps)
            out["semantic_image"] = {"fused_accuracy": fused_acc, "framewise_accuracy": frame_acc,
                                     "gain_points": (fused_acc - frame_acc) * 100.0 if n else math.nan,
                                     "n_pixels": n}
        if len(gt_maps) == len(result.keyframes):
            config = config or GlobalModelConfig()
            images = [f.rgb for f in result.keyframe_gt]
            evidence = evidence_maps(result.keyframes, result.keyframe_gt, config.num_classes)
            out["semantic_measurements"] = measurement_scores(result.keyframes, images, intr, online_poses, config,
                                                              evidence, None if live else model)
            exact = [dataclasses.replace(kf, depth=np.asarray(f.depth, np.float32), T_world_cam=f.T_world_cam,
                                         uncertainty=None) for kf, f in zip(result.keyframes, result.keyframe_gt,
                                                                            strict=True)]
            exact_model, _ = fuse_keyframes(exact, images, intr, None, config)
            out["semantic_measurements_exact_geometry"] = measurement_scores(exact, images, intr, None, config,
                                                                             evidence, exact_model)
    return out

"""``cnnslam map SEQUENCE``: run an agent on a registered sequence, fuse its key-frames into the global model
(:mod:`cnnslam.global_model`), and write the model as PLY, the paper's Fig. 6-style pictures and a JSON of metrics.

What it does, in order:

1. runs the agent (``--agent module:Class``, default the paper's CNN-SLAM with the trained network) over the
   sequence's Gymnasium environment (``sim_envs/<SEQUENCE>-v0``; ``--length N`` regenerates the sequence's trajectory
   with N frames, ``--frames N`` stops after N);
2. fuses the key-frames the agent hands back (depth, uncertainty, class probabilities) with the image the agent saw
   at each key-frame (the source's RGB of that frame, the same bytes as the observation). ``--fuse online`` (default)
   replays the key-frame thread of the paper: each key-frame is fused at the pose the agent answered for its frame,
   then the key-frames are re-placed at their final pose-graph poses (:meth:`GlobalModel.update_poses`); ``--fuse
   final`` fuses directly at the final poses. The paper's agent (:class:`cnnslam.agent.CnnSlamAgent`) fuses its
   key-frames live in its key-frame thread and re-places them at the end (``global_model.enabled``): with ``--fuse
   online`` and its voxel size, that model is used as it is, and nothing is fused here;
3. writes ``model.ply``, ``map.png`` (and a copy at ``--figure``), and ``metrics.json`` with the model's size, the
   re-placement, the fusion's memory (tracemalloc peak during fusion) and the process's peak RSS (scoring included),
   and (unless ``--no-metrics``) the shared reconstruction and semantic metrics
   (:mod:`slamcommon.reconstruction_metrics`, the judge's) against the scene's ground-truth surfaces
   (:mod:`sim_envs.surface_sampling`), after aligning the key-frame poses onto the ground truth (``--alignment``,
   SE(3) by default: absolute scale is part of what is measured).

Semantic accuracy is reported four ways, fused model vs the frame-wise CNN labels each time:

- ``semantic``: in 3D, on back-projected key-frame pixels, each scored against the nearest ground-truth surface
  sample (:func:`slamcommon.reconstruction_metrics.label_fusion_metrics`); a pixel whose estimated depth is off by more
  than the surface spacing is scored against whatever surface lies there, for both labels alike;
- ``semantic_image``: the model rendered into each key-frame (front-most surfel per pixel) against the rendered
  ground-truth labels of that key-frame (the paper's Fig. 6 view);
- ``semantic_measurements``: on the fused measurements themselves (the issue's "same surfaces", exactly): the fusion
  is replayed with each key-frame pixel's ground-truth label and whether its CNN label was right in place of the
  class probabilities (same depth, poses and association, so the same surfels), and every fused measurement is
  scored against its own ground-truth label with its frame-wise label and with its surfel's fused label
  (:func:`slamcommon.reconstruction_metrics.measurement_label_metrics`; weights: Keller's radial confidence alpha). It
  separates what the label averaging does (``pure_*``: surfels whose measurements share one ground-truth label) from
  what the data association costs (``mixed_*``; ``purity`` is the ceiling of any one label per surfel);
- ``semantic_measurements_exact_geometry``: the same, fusing the same CNN labels with the ground-truth depth and
  poses of the key-frames (no depth variance): what the label fusion gains when geometry is not in the way.

Ground truth is read only here, at the edge, for scoring and for the image of each key-frame; the agent never sees
it unless its class declares ``uses_ground_truth``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import resource
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError

DEFAULT_AGENT = "cnnslam.agent:CnnSlamAgent"
FRAMEWISE_STRIDE = 4  # pixels; key-frame pixels back-projected for the semantic comparison (every 4th per axis)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("sequence", help="a registered sequence name (sim_envs.sequences), e.g. office0")
    parser.add_argument("--agent", default=DEFAULT_AGENT,
                        help=f"agent entry point 'module:Class' (default {DEFAULT_AGENT}; without trained weights use "
                             "cnnslam.agent:GroundTruthAidedAgent, the development predictor)")
    parser.add_argument("--agent-options", default="{}", help="JSON object of keyword arguments for the agent")
    parser.add_argument("--frames", type=int, default=None, help="process only the first N frames")
    parser.add_argument("--length", type=int, default=None,
                        help="regenerate the sequence's trajectory with N frames (e.g. 3000 for a memory test)")
    parser.add_argument("--out", default=None, help="output folder (default runs/map/<sequence>)")
    parser.add_argument("--figure", default=None, help="also write the picture here (e.g. results/map_office0.png)")
    parser.add_argument("--renderer", default="mujoco", help="renderer backend of the sequence (default mujoco)")
    parser.add_argument("--fuse", choices=("online", "final"), default="online",
                        help="fuse at the online poses and re-place at the final ones (default), or at the final ones")
    parser.add_argument("--voxel", type=float, default=0.02, help="voxel size of the model's hash, metres")
    parser.add_argument("--alignment", default="se3", help="alignment onto ground truth: se3 (default), sim3, origin")
    parser.add_argument("--gt-spacing", type=float, default=0.02, help="ground-truth surface sample spacing, metres")
    parser.add_argument("--threshold", type=float, default=0.05, help="accuracy/completeness threshold, metres")
    parser.add_argument("--label-distance", type=float, default=0.10,
                        help="a point farther than this from the ground truth gets no ground-truth label, metres")
    parser.add_argument("--no-metrics", action="store_true", help="skip the ground-truth metrics")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def peak_rss_mb() -> float:
    """The process's peak resident set size in MiB (``getrusage``: KiB on Linux, bytes on macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def keyframe_frame_indices(keyframes: list[Any], timestamps: np.ndarray) -> np.ndarray:
    """The episode step (index into ``timestamps``) of each key-frame, by nearest timestamp."""
    stamps = np.asarray(timestamps, dtype=np.float64)
    return np.array([int(np.argmin(np.abs(stamps - float(k.timestamp)))) for k in keyframes], dtype=np.int64)


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
    from cnnslam.global_model import GlobalModel

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
                       online_poses: np.ndarray | None, config: Any, model: Any,
                       evidence: list[np.ndarray]) -> dict[str, Any]:
    """``semantic_measurements`` of ``model`` (see the module docstring): replays its fusion with ``evidence`` maps
    and scores each fused measurement with its frame-wise and its surfel's fused label."""
    from slamcommon.reconstruction_metrics import measurement_label_metrics

    C = config.num_classes
    replay_config = dataclasses.replace(config, num_classes=C + 2, label_weighting="confidence")
    replay, _ = fuse_keyframes(keyframes, images, intrinsics, online_poses, replay_config, label_maps=evidence)
    if len(replay) != len(model) or not np.array_equal(replay.snapshot().positions, model.snapshot().positions):
        raise CnnSlamError("the replayed fusion built a different model; labels must not change the geometry")
    E = replay.label_evidence()
    return measurement_label_metrics(model.labels(), E[:, :C], E[:, C]).to_dict()


def _finite(value: Any) -> Any:
    """JSON-safe: NaN / inf become None, numpy scalars plain numbers."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def score_model(cloud: Any, model: Any, result: Any, scene: Any, args: argparse.Namespace,
                online_poses: np.ndarray | None = None, config: Any = None) -> dict[str, Any]:
    """The judge's reconstruction and semantic metrics of a fused model (see the module docstring); ``online_poses``
    and ``config`` are those the model was fused with (:func:`fuse_keyframes`)."""
    from cnnslam.geometry import transform_points, vertex_map
    from cnnslam.global_model import GlobalModelConfig
    from sim_envs.frames import NO_LABEL
    from sim_envs.surface_sampling import sample_scene_surface
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
    alignment = align(kf_gt, kf_est, args.alignment)
    S = alignment.matrix

    def to_gt(points: np.ndarray) -> np.ndarray:
        return transform_points(S, points)

    gt = sample_scene_surface(scene, args.gt_spacing)
    seen = visible_in_views(gt.points, kf_gt, [f.depth for f in result.keyframe_gt], intr)
    model_points = to_gt(cloud.positions.astype(np.float64))
    recon = reconstruction_metrics(model_points, gt.points, gt.normals, gt.spacing, args.threshold, seen=seen)
    out: dict[str, Any] = {"alignment": alignment.describe(), "gt_samples": len(gt), "gt_visible": int(seen.sum()),
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
                                   np.concatenate(frame_labels), gt.points, gt.labels, args.label_distance)
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
                                                              model, evidence)
            exact = [dataclasses.replace(kf, depth=np.asarray(f.depth, np.float32), T_world_cam=f.T_world_cam,
                                         uncertainty=None) for kf, f in zip(result.keyframes, result.keyframe_gt,
                                                                            strict=True)]
            exact_model, _ = fuse_keyframes(exact, images, intr, None, config)
            out["semantic_measurements_exact_geometry"] = measurement_scores(exact, images, intr, None, config,
                                                                             exact_model, evidence)
    return out


def _open_env(args: argparse.Namespace) -> Any:
    import gymnasium as gym

    import sim_envs  # noqa: F401  (registers the environments)
    from sim_envs.env import SlamEnv
    from sim_envs.sequences import get_sequence

    if args.length is not None:
        spec = get_sequence(args.sequence).with_frames(args.length)
        return SlamEnv(spec=spec, renderer=args.renderer, max_frames=args.frames)
    return gym.make(get_sequence(args.sequence).gym_id, renderer=args.renderer, max_frames=args.frames)


def run(args: argparse.Namespace) -> int:
    from cnnslam.config import CnnSlamConfig
    from cnnslam.global_model import GlobalModelConfig
    from cnnslam.model_io import write_ply
    from cnnslam.model_render import render_map_views, save_map_figure
    from sim_envs.agent import load_agent
    from sim_envs.driver import run_episode
    from sim_envs.errors import SimEnvError

    out = Path(args.out or os.path.join("runs", "map", args.sequence))
    try:
        options = json.loads(args.agent_options)
        if not isinstance(options, dict):
            raise CnnSlamError(f"--agent-options must be a JSON object, got {args.agent_options!r}")
        config = GlobalModelConfig(voxel_size=args.voxel)
        agent = load_agent(args.agent, **options)
        if isinstance(getattr(agent, "config", None), CnnSlamConfig):  # the paper's agent (any entry point to it):
            # its key-frames keep their class probabilities, which the replays below fuse again
            agent.config = agent.config.with_overrides({"system.keep_label_probabilities": True})
        env = _open_env(args)
        try:
            t0 = time.perf_counter()
            result = run_episode(env, agent, progress=not args.no_progress)
            run_seconds = time.perf_counter() - t0
            source = env.unwrapped.source
            scene = getattr(source, "scene", None)
        finally:
            env.close()
        if not result.keyframes:
            raise CnnSlamError(f"the agent {result.agent!r} returned no key-frames: nothing to fuse")
        steps = keyframe_frame_indices(result.keyframes, result.timestamps)
        online = result.T_world_cam_est[steps] if args.fuse == "online" else None
        images = [f.rgb for f in result.keyframe_gt]
        live = getattr(getattr(agent, "result", None), "model", None)  # CnnSlamAgent: fused by its key-frame thread
        if (live is not None and args.fuse == "online" and live.config.voxel_size == args.voxel
                and len(live.keyframe_poses) == len(result.keyframes)):
            model, config = live, live.config
            fusion = {"source": "live: the agent's key-frame thread (Sec. 3.5)", "surfels": len(live),
                      "seconds": result.extras.get("seconds", {}).get("fusion"), "model_mb": live.nbytes / 2**20,
                      "tracemalloc_peak_mb": math.nan}
        else:  # another agent's key-frames, --fuse final or another voxel size: fuse them here
            model, fusion = fuse_keyframes(result.keyframes, images, result.intrinsics.as_array(), online, config)
            fusion["source"] = "replayed from the agent's key-frames"
        cloud = model.snapshot()
        final = np.stack([np.asarray(k.T_world_cam, dtype=np.float64) for k in result.keyframes])
        trajectory = corrected_trajectory(result.T_world_cam_est, steps, result.T_world_cam_est[steps], final)
        comments = [f"sequence {result.sequence}", f"agent {args.agent} ({result.agent})",
                    f"keyframes {len(result.keyframes)}", f"frames {result.n_frames}"]
        ply = write_ply(out / "model.ply", cloud, comments)
        views = render_map_views(cloud, trajectory, keyframes=final)
        title = f"{result.sequence}, {result.agent} ({len(result.keyframes)} key-frames)"
        figure = save_map_figure(out / "map.png", views, title)
        if args.figure:
            save_map_figure(args.figure, views, title)
        record: dict[str, Any] = {
            "schema": "cnnslam-map/1", "sequence": result.sequence, "agent": args.agent, "agent_name": result.agent,
            "agent_options": options, "uses_ground_truth": result.uses_ground_truth, "frames": result.n_frames,
            "keyframes": len(result.keyframes), "fuse": args.fuse, "voxel_size_m": args.voxel,
            "run_seconds": run_seconds, "fusion": fusion,
            "model": {"surfels": len(cloud), "labelled": int((cloud.labels != 255).sum())},
            "agent_extras": {k: v for k, v in result.extras.items() if isinstance(v, int | float | str | bool)},
            "files": {"ply": str(ply), "figure": str(figure)},
        }
        if "model_size_history" in result.extras:
            record["agent_model_size_history"] = result.extras["model_size_history"]
        if not args.no_metrics:
            if scene is None:
                raise CnnSlamError(f"the source of {args.sequence!r} has no scene geometry; use --no-metrics")
            record["metrics"] = score_model(cloud, model, result, scene, args, online, config)
        record["peak_rss_mb"] = peak_rss_mb()
        out.mkdir(parents=True, exist_ok=True)
        tmp = out / "metrics.json.part"
        tmp.write_text(json.dumps(_finite(record), indent=2) + "\n")
        os.replace(tmp, out / "metrics.json")
    except (CnnSlamError, SimEnvError, json.JSONDecodeError) as exc:
        print(f"cnnslam map: error: {exc}", file=sys.stderr)
        return 1
    summary = [f"{result.sequence}: {len(result.keyframes)} key-frames -> {len(cloud)} surfels ({ply})",
               f"peak RSS {record['peak_rss_mb']:.0f} MiB, model {fusion['source']}"]
    m = record.get("metrics", {})
    if "reconstruction" in m:
        r = m["reconstruction"]
        summary.append(f"accuracy {r['accuracy_mean']:.3f} m ({100 * r['accuracy_within']:.1f} % < "
                       f"{args.threshold:g} m), completeness {r['completeness_mean']:.3f} m "
                       f"({100 * r['completeness_within']:.1f} %)")
    if "semantic" in m:
        s = m["semantic"]
        summary.append(f"semantic accuracy fused {100 * s['fused_accuracy']:.1f} % vs frame-wise "
                       f"{100 * s['framewise_accuracy']:.1f} % ({s['gain_points']:+.1f} points)")
    for key, what in (("semantic_measurements", "fused measurements"),
                      ("semantic_measurements_exact_geometry", "same, exact depth and poses")):
        if key in m:
            s = m[key]
            summary.append(f"{what}: fused {100 * s['fused_accuracy']:.1f} % vs frame-wise "
                           f"{100 * s['framewise_accuracy']:.1f} % ({s['gain_points']:+.1f} points; purity "
                           f"{100 * s['purity']:.1f} %)")
    print("\n".join(summary))
    return 0

"""``cnnslam map SEQUENCE``: run an agent on a registered sequence, fuse its key-frames into the global model
(:mod:`cnnslam.model.global_model`), and write the model as PLY, the paper's Fig. 6-style pictures and a JSON of
metrics.

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
   (:mod:`sim_envs.scenes.surface_sampling`), after aligning the key-frame poses onto the ground truth (``--alignment``,
   SE(3) by default: absolute scale is part of what is measured).

The replays and metrics are :mod:`cnnslam.tools.map_replay` (its docstring says what each semantic figure measures).

Ground truth is read only here, at the edge, for scoring and for the image of each key-frame; the agent never sees
it unless its class declares ``uses_ground_truth``.

Exit status: 0 written; 2 a bad argument, refused in one line naming the value and what is valid before the episode
runs (an unknown sequence, renderer or alignment; ``--frames`` outside 1..the sequence's length, ``--length`` < 2, a
size or distance that is not positive; an agent that cannot be loaded or refuses its options; an ``--out`` or
``--figure`` that cannot be written); 1 when the run gives nothing to fuse or score (the message says why).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError
from slamcommon.alignment import parse_method
from slamcommon.errors import ProjectError
from slamcommon.output_paths import check_output_file, check_output_folder

DEFAULT_AGENT = "cnnslam.agent:CnnSlamAgent"


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


def _open_env(args: argparse.Namespace) -> Any:
    import gymnasium as gym

    import sim_envs  # noqa: F401  (registers the environments)
    from sim_envs.env import SlamEnv
    from sim_envs.sequences import get_sequence

    if args.length is not None:
        spec = get_sequence(args.sequence).with_frames(args.length)
        return SlamEnv(spec=spec, renderer=args.renderer, max_frames=args.frames)
    return gym.make(get_sequence(args.sequence).gym_id, renderer=args.renderer, max_frames=args.frames)


def check_arguments(args: argparse.Namespace) -> tuple[Path, dict[str, Any]]:
    """Refuse, before anything is loaded or run, an argument ``cnnslam map`` cannot use: an unknown alignment or
    sequence, ``--frames`` outside 1..the sequence's length (``--length``'s when given), ``--length`` < 2, a voxel,
    spacing, threshold or label distance that is not a positive number of metres, ``--agent-options`` that is not a
    JSON object, an ``--out`` folder or ``--figure`` file that cannot be written. Returns the output folder and the
    agent's options; :class:`CnnSlamError` (or the error of the check that refused) with one line otherwise."""
    from sim_envs.sequences import get_sequence

    try:
        parse_method(args.alignment)
    except ProjectError as exc:
        raise CnnSlamError(f"--alignment: {exc}") from None
    spec = get_sequence(args.sequence)  # UnknownNameError listing the valid names
    if args.length is not None and args.length < 2:
        raise CnnSlamError(f"--length {args.length}: a sequence needs at least 2 frames")
    n_frames = spec.n_frames if args.length is None else args.length
    if args.frames is not None and not 1 <= args.frames <= n_frames:
        raise CnnSlamError(f"--frames {args.frames}: {args.sequence} has {n_frames} frames; give 1..{n_frames} "
                               "(or leave it out for all of them)")  # fmt: skip
    for flag, value in (("--voxel", args.voxel), ("--gt-spacing", args.gt_spacing), ("--threshold", args.threshold),
                        ("--label-distance", args.label_distance)):  # fmt: skip
        if not (math.isfinite(value) and value > 0):
            raise CnnSlamError(f"{flag} {value:g}: must be a positive number of metres")
    try:
        options = json.loads(args.agent_options)
    except json.JSONDecodeError as exc:
        raise CnnSlamError(f"--agent-options {args.agent_options!r}: not JSON ({exc}); give a JSON object, e.g. "
                               "'{}'") from None  # fmt: skip
    if not isinstance(options, dict):
        raise CnnSlamError(f"--agent-options must be a JSON object, got {args.agent_options!r}")
    out = check_output_folder(args.out or os.path.join("runs", "map", args.sequence), "--out")
    if args.figure:
        from matplotlib.figure import Figure

        formats = Figure().canvas.get_supported_filetypes()
        if Path(args.figure).suffix.lstrip(".").lower() not in formats:
            raise CnnSlamError(f"--figure {args.figure}: matplotlib cannot write this suffix; valid suffixes: "
                                   f"{', '.join('.' + f for f in sorted(formats))}")  # fmt: skip
        check_output_file(args.figure, "--figure")
    return out, options


def run(args: argparse.Namespace) -> int:
    from cnnslam.config import CnnSlamConfig
    from cnnslam.model.global_model import GlobalModelConfig
    from cnnslam.model.model_io import write_ply
    from cnnslam.model.model_render import render_map_views, save_map_figure
    from cnnslam.tools.map_replay import corrected_trajectory, fuse_keyframes, map_scores
    from sim_envs.agent import load_agent
    from sim_envs.driver import run_episode
    from slamcommon.resources import peak_resident_mib
    from slamcommon.strict_json import json_ready

    try:  # bad arguments, an agent that cannot be loaded, an environment that cannot be made: before the episode runs
        out, options = check_arguments(args)
        config = GlobalModelConfig(voxel_size=args.voxel)
        try:
            agent = load_agent(args.agent, **options)
        except TypeError as exc:  # a keyword the agent's class does not take
            raise CnnSlamError(f"--agent-options {args.agent_options}: {args.agent} refuses them ({exc})") from None
        if isinstance(getattr(agent, "config", None), CnnSlamConfig):  # the paper's agent (any entry point to it):
            # its key-frames keep their class probabilities, which the replays below fuse again
            agent.config = agent.config.with_overrides({"system.keep_label_probabilities": True})
        env = _open_env(args)
    except ProjectError as exc:
        print(f"cnnslam map: error: {exc}", file=sys.stderr)
        return 2
    try:
        t0 = time.perf_counter()
        result = run_episode(env, agent, progress=not args.no_progress)
        run_seconds = time.perf_counter() - t0
        scene = getattr(env.unwrapped.source, "scene", None)
    except ProjectError as exc:
        print(f"cnnslam map: error: {exc}", file=sys.stderr)
        return 1
    finally:
        env.close()
    try:
        if not result.keyframes:
            raise CnnSlamError(f"the agent {result.agent!r} returned no key-frames: nothing to fuse")
        steps = np.array([f.index for f in result.keyframe_gt], dtype=np.int64)  # matched once, by the driver
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
            record["metrics"] = map_scores(cloud, model, result, scene, alignment=args.alignment,
                                           gt_spacing=args.gt_spacing, threshold=args.threshold, live=model is live,
                                           label_distance=args.label_distance, online_poses=online, config=config)
        record["peak_rss_mb"] = peak_resident_mib()
        out.mkdir(parents=True, exist_ok=True)
        tmp = out / "metrics.json.part"
        tmp.write_text(json.dumps(json_ready(record), indent=2) + "\n")
        os.replace(tmp, out / "metrics.json")
        if args.figure:  # the picture's metrics beside it, and what made both: `cnnslam results status`
            from slamcommon.provenance import record_outputs

            beside = Path(args.figure).with_suffix(".json")
            beside.write_text(json.dumps(json_ready(record), indent=2) + "\n")
            from cnnslam.depthnet.weights_io import DEFAULT_WEIGHTS

            network = isinstance(getattr(agent, "config", None), CnnSlamConfig)  # the paper's agent: its weights
            record_outputs([Path(args.figure), beside], "cnnslam map",
                           ["cnnslam.tools.cli_map", "sim_envs.env", "sim_envs.sources.simsource",
                            args.agent.partition(":")[0]],
                           [DEFAULT_WEIGHTS] if network else [], seconds=run_seconds)
    except ProjectError as exc:
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

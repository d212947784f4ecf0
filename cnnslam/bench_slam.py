"""Speed of CNN-SLAM: frames per second of tracking alone and of the whole system, at the sequence's resolution
(320x240 for the registered sequences), on the cores this process may use.

``python -m cnnslam.bench_slam [--sequence office0] [--frames 300] [--predictor auto|network|degraded_ground_truth]``
(also ``cnnslam bench-slam``). Frames are rendered before timing (rendering is not SLAM's cost); numba kernels are
compiled and the network is warmed up on a short run first. Three runs over the same frames:

- single-thread system (``SystemConfig.threads = False``): its per-stage times give **tracking alone** (eq. 1-4, the
  time spent in frame-to-key-frame tracking per frame) and the cost of every other stage;
- two-thread system (the paper's frame thread + key-frame thread): **whole system** fps = frames / wall time of
  ``process`` over the sequence (key-frame initialisation waits included, pose-graph work overlapping);
- the frame thread's worst step.

Figures print as a table and come back from :func:`benchmark` as a dict. Speed is measured, never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

import numpy as np

from cnnslam.config import CnnSlamConfig
from cnnslam.depth_prediction import GroundTruthHint, make_predictor
from cnnslam.system import CnnSlam


def _available_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _load_frames(sequence: str, n_frames: int) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, float]]]:
    from sim_envs.sequences import get_sequence
    from sim_envs.simsource import SimulatedSequence

    spec = get_sequence(sequence)
    with SimulatedSequence(spec) as source:
        n = min(n_frames, len(source))
        frames = []
        for i in range(n):
            f = source.frame(i)
            frames.append((f.rgb, f.depth, float(f.timestamp)))
        return source.intrinsics.as_array(), frames


def _make_predictor(kind: str) -> tuple[str, Any]:
    if kind == "auto":
        try:
            return "network", make_predictor("network")
        except Exception:  # noqa: BLE001 - no trained weights yet: fall back to the development predictor
            return "degraded_ground_truth", make_predictor("degraded_ground_truth")
    return kind, make_predictor(kind)


def _run(config: CnnSlamConfig, intrinsics: np.ndarray, frames: list, predictor: Any,
         ) -> tuple[float, list[float], dict[str, Any]]:
    slam = CnnSlam(config, intrinsics, frames[0][0].shape[:2], predictor)
    steps = []
    t_start = time.perf_counter()
    for rgb, depth, stamp in frames:
        t0 = time.perf_counter()
        slam.process(rgb, stamp, GroundTruthHint(depth))
        steps.append(time.perf_counter() - t0)
    wall = time.perf_counter() - t_start
    result = slam.finish()
    return wall, steps, result.stats


def benchmark(sequence: str = "office0", n_frames: int = 300, predictor: str = "auto") -> dict[str, Any]:
    """Time the system on the first ``n_frames`` of ``sequence``; returns the figures (see the module docstring).

    The development predictor reads each key-frame's ground-truth depth (it stands in for the network until trained
    weights exist); the network, when used, sees only the image.
    """
    intrinsics, frames = _load_frames(sequence, n_frames)
    name, pred = _make_predictor(predictor)
    base = CnnSlamConfig()
    _run(base.with_overrides({"system.threads": False}), intrinsics, frames[: min(40, len(frames))], pred)  # warm-up
    wall_1, steps_1, stats_1 = _run(base.with_overrides({"system.threads": False}), intrinsics, frames, pred)
    wall_2, steps_2, stats_2 = _run(base.with_overrides({"system.threads": True}), intrinsics, frames, pred)
    n = len(frames)
    sec = stats_1["seconds"]
    h, w = frames[0][0].shape[:2]
    return {
        "sequence": sequence,
        "frames": n,
        "resolution": f"{w}x{h}",
        "cores": _available_cores(),
        "predictor": name,
        "keyframes": stats_1["keyframes"],
        "tracking_fps": n / max(sec["tracking"], 1e-9),
        "tracking_ms_per_frame": 1000 * sec["tracking"] / n,
        "refinement_ms_per_frame": 1000 * sec["refinement"] / n,
        "pyramid_ms_per_frame": 1000 * sec["pyramid"] / n,
        "keyframe_init_ms_per_keyframe": 1000 * sec["keyframe_init"] / max(stats_1["keyframes"], 1),
        "prediction_ms_per_keyframe": 1000 * sec["prediction"] / max(stats_1["keyframes"], 1),
        "pose_graph_ms_per_keyframe": 1000 * sec["pose_graph"] / max(stats_1["keyframes"] - 1, 1),
        "single_thread_fps": n / wall_1,
        "whole_system_fps": n / wall_2,
        "frame_thread_median_ms": 1000 * float(np.median(steps_2)),
        "frame_thread_max_ms": 1000 * float(np.max(steps_2)),
        "tracked_share": stats_2["tracked_share"],
    }


def format_figures(figures: dict[str, Any]) -> str:
    """The figures as an aligned two-column table."""
    width = max(len(k) for k in figures)
    lines = []
    for key, value in figures.items():
        text = f"{value:.1f}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<{width}}  {text}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sequence", default="office0", help="registered sequence name (default office0)")
    parser.add_argument("--frames", type=int, default=300, help="frames to process (default 300)")
    parser.add_argument("--predictor", default="auto", choices=("auto", "network", "degraded_ground_truth"),
                        help="depth predictor; auto = the trained network if its weights exist, else the "
                             "development predictor")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")


def run(args: argparse.Namespace) -> int:
    figures = benchmark(args.sequence, args.frames, args.predictor)
    print(json.dumps(figures, indent=2) if args.json else format_figures(figures))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cnnslam.bench_slam", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark: time of the trajectory metrics over a long trajectory (default 100k poses).

``python -m eval.metrics.bench_metrics [N]`` prints the best of 5 timings of: TUM association, SE(3) alignment + ATE +
RPE (1 s) on associated poses, and the whole :func:`eval.metrics.trajectory_metrics.evaluate_trajectory`. A benchmark
prints figures; it asserts nothing about speed.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from eval.metrics.association import associate
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import (
    evaluate_trajectory,
    relative_pose_errors,
    rpe_pair_indices,
    translation_errors,
)
from slamcommon.alignment import align


def synthetic_pair(n: int, seed: int = 0) -> tuple[PoseTrajectory, PoseTrajectory]:
    """A smooth ground truth at 30 Hz and a noisy, rigidly moved estimate with jittered timestamps."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = np.stack([np.sin(t / 7), np.cos(t / 5), 0.3 * np.sin(t / 3)], axis=1)
    T[:, :3, :3] = Rotation.from_rotvec(np.stack([0.2 * np.sin(t / 4), t / 20, 0.1 * np.cos(t / 6)], 1)).as_matrix()
    move = np.eye(4)
    move[:3, :3] = Rotation.from_rotvec([0.3, -0.2, 1.0]).as_matrix()
    move[:3, 3] = [1.0, 2.0, -0.5]
    T_est = move @ T
    T_est[:, :3, 3] += rng.normal(0.0, 0.01, (n, 3))
    return PoseTrajectory(t, T), PoseTrajectory(t + rng.uniform(-0.004, 0.004, n), T_est)


def best_of(fn: Callable[[], object], repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args else 100_000
    gt, est = synthetic_pair(n)
    assoc = associate(gt, est)
    T_gt, T_est = gt.T_world_cam[assoc.gt_indices], est.T_world_cam[assoc.est_indices]

    def ate_rpe() -> None:
        fit = align(T_gt, T_est, "se3")
        T_al = fit.apply(T_est)
        translation_errors(T_gt, T_al)
        i, j = rpe_pair_indices(gt.timestamps[assoc.gt_indices], 1.0)
        relative_pose_errors(T_gt, T_al, i, j)

    t_assoc = best_of(lambda: associate(gt, est))
    t_metrics = best_of(ate_rpe)
    t_all = best_of(lambda: evaluate_trajectory(gt, est))
    print(f"poses: {n}, associated pairs: {len(assoc)}")
    print(f"TUM association:                 {1000 * t_assoc:8.1f} ms")
    print(f"SE(3) alignment + ATE + RPE(1 s): {1000 * t_metrics:8.1f} ms")
    print(f"evaluate_trajectory (all):       {1000 * t_all:8.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())

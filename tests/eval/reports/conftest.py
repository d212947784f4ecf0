"""A suite run made of run folders written here, without running an agent: for the reports that read the folders
(the per-sequence figures, the HTML report, the speed and relative-error tables). Two sequences, two seeds; CNN-SLAM
close to the truth, LSD 20 % too large with one failed run, REMODE with depth only (no trajectory of its own), the
oracle exact, ORB skipped."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from eval.bench.methods import load_methods
from eval.bench.run import RunSpec, run_trajectory_metrics, write_json
from eval.bench.runner import RunOutcome, SuiteRun, plan_runs
from eval.bench.suites import get_suite
from eval.metrics.results import RunRecord
from sim_envs.folders.formats import write_tum_trajectory

SEQUENCES = ("office0@clean", "living1@clean")
METHODS = ("CNN-SLAM", "LSD", "REMODE", "oracle", "ORB")
FRAMES = 60
FAILED = ("living1", "LSD", 1)  # (sequence, method, seed): the clean camera's sequences carry no @ suffix


def _poses(n: int, seed: int, scale: float, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """Ground truth (a curve at 30 Hz, turning about z) and an estimate of it (``scale`` x, ``noise`` m)."""
    k = np.arange(n)
    gt = np.repeat(np.eye(4)[None], n, axis=0)
    yaw = 0.02 * k
    gt[:, 0, 0], gt[:, 0, 1], gt[:, 1, 0], gt[:, 1, 1] = np.cos(yaw), -np.sin(yaw), np.sin(yaw), np.cos(yaw)
    gt[:, :3, 3] = np.column_stack([0.05 * k, 0.4 * np.sin(k / 15), np.full(n, 1.2)])
    est = gt.copy()
    est[:, :3, 3] = scale * gt[:, :3, 3] + np.random.default_rng(seed).normal(0, noise, (n, 3))
    return gt, est


def make_suite_run(root: Path) -> SuiteRun:
    table = load_methods()
    suite = get_suite("table1").select(list(SEQUENCES), list(METHODS), frames=FRAMES, seeds=[0, 1])
    available = [table[m] for m in METHODS if m != "ORB"]
    specs = plan_runs(suite, available, revision="abc123")
    outcomes, records, timings = {}, [], {}
    depth = np.dstack([np.tile(np.linspace(0, 255, 90, dtype=np.uint8), (60, 1))] * 3)
    for spec in specs:
        folder = root / spec.key
        folder.mkdir(parents=True)
        method, seed = spec.method.name, spec.seed
        if (spec.sequence.name, method, seed) == FAILED:
            write_json(folder / "failed.json", {"error": "RuntimeError: tracking lost for good",
                                                "traceback": "Traceback (most recent call last):\n  File x\n"
                                                             "RuntimeError: tracking lost for good"})  # fmt: skip
            outcomes[spec.key] = RunOutcome(spec.key, "failed", folder, "RuntimeError: tracking lost for good")
            continue
        scale, noise = {"CNN-SLAM": (1.0, 0.01), "LSD": (1.2, 0.02), "REMODE": (1.0, 0.0), "oracle": (1.0, 0.0)}[method]
        gt, est = _poses(FRAMES, seed + 10 * [s.name for s in suite.sequences].index(spec.sequence.name), scale, noise)
        stamps = np.arange(FRAMES) / 30.0
        write_tum_trajectory(folder / "groundtruth.tum", stamps, gt)
        write_tum_trajectory(folder / "trajectory.tum", stamps, est)
        if "depth" in spec.method.metrics and method != "oracle":
            cv2.imwrite(str(folder / "depth.png"), depth)
        metrics = run_trajectory_metrics(stamps, gt, est, spec.alignment).flat_metrics()
        metrics.update({"frames": float(FRAMES), "depth_percent_correct": {"CNN-SLAM": 50.0 + seed, "LSD": 5.0,
                        "REMODE": 20.0, "oracle": 100.0}[method]})  # fmt: skip
        resources = {"wall_s": 2.0 + seed, "fps_end_to_end": FRAMES / (2.0 + seed), "fps": 40.0,
                     "peak_rss_mib": {"CNN-SLAM": 700.0, "LSD": 400.0, "REMODE": 500.0, "oracle": 300.0}[method]}
        record = RunRecord(spec.sequence.name, method, spec.method.entry_point or method,
                           spec.method.select_metrics(metrics), uses_ground_truth=method in ("REMODE", "oracle"),
                           metadata={"git_revision": "abc123", "seed": seed}, run=spec.key,
                           resources=resources)  # fmt: skip
        write_json(folder / "metrics.json", record.to_json())
        timing = {**resources, "environment": {"cpu": "Test CPU", "isa": ["avx2"], "packages": {"numpy": "2"}}}
        (folder / "timing.json").write_text(json.dumps(timing))
        outcomes[spec.key] = RunOutcome(spec.key, "done", folder)
        records.append(record)
        timings[spec.key] = timing
    return SuiteRun(suite, root, tuple(specs), outcomes, {"ORB": "cannot import pyorb here"}, records, timings,
                    tuple(available))  # fmt: skip


@pytest.fixture(scope="module")
def folder_run(tmp_path_factory: pytest.TempPathFactory) -> SuiteRun:
    """The suite run of the module docstring, its folders under a temporary ``runs/``."""
    return make_suite_run(tmp_path_factory.mktemp("runs"))


__all__ = ["FAILED", "FRAMES", "METHODS", "SEQUENCES", "RunSpec", "make_suite_run"]

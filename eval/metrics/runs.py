"""A benchmark run as the judge reads it back: the names of a run folder's record files, the run's trajectory
scored as its record scores it, the metric group a flat metric name belongs to, and a suite's records as one JSON
file. The benchmark (:mod:`eval.bench.run`, :mod:`eval.bench.runner`) writes runs with these; the reports
(:mod:`eval.reports`) read them back with the same, and import nothing of :mod:`eval.bench`.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence

import numpy as np

from eval.metrics import catalogue
from eval.metrics.results import RunRecord, json_ready
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import TrajectoryMetrics, evaluate_trajectory

DONE_FILE = "metrics.json"  # a finished run's record (eval.metrics.results.RunRecord.to_json)
FAILED_FILE = "failed.json"  # a failed run's error, traceback and wall time: the only file of its folder

# the metric groups a method declares (each metric's group: its spec in eval.metrics.catalogue)
METRIC_GROUPS: tuple[str, ...] = catalogue.GROUPS
# what a method without a group does not give, as the reports say it ("n/a: no trajectory of its own")
GROUP_ABSENT: dict[str, str] = {
    "trajectory": "no trajectory of its own",
    "depth": "no key-frame depth",
    "semantic": "no semantic labels",
    "map": "no global model",
}


def metric_group(metric: str) -> str | None:
    """The metric group (:data:`METRIC_GROUPS`) a flat metric name belongs to (its catalogue spec's,
    :func:`eval.metrics.catalogue.group_of`); None for one of no group (the frame count, a resource figure)."""
    return catalogue.group_of(metric)


def run_trajectory_metrics(timestamps: np.ndarray, T_gt: np.ndarray, T_est: np.ndarray,
                           alignment: str) -> TrajectoryMetrics:
    """A run's trajectory scored as its record scores it: poses paired by index (the driver's, or an external
    trajectory already associated), aligned with the run's ``alignment``."""
    stamps = np.asarray(timestamps)
    return evaluate_trajectory(PoseTrajectory(stamps, T_gt), PoseTrajectory(stamps, T_est), alignment=alignment,
                               association="index")  # fmt: skip


def suite_records_json(records: Sequence[RunRecord]) -> str:
    """The run records as one JSON list, in run order, each with its run key (the run file of ``cnnslam regress``)."""
    buffer = io.StringIO()
    json.dump(json_ready([r.to_json(include_run=True) for r in records]), buffer, indent=1, allow_nan=False)
    return buffer.getvalue() + "\n"

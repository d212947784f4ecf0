"""eval.metrics.runs: a run folder's file names, a run's trajectory scored, metric groups, a suite's records file."""

import json
import math

import numpy as np
import pytest

from eval.metrics.results import RunRecord
from eval.metrics.runs import (
    DONE_FILE,
    FAILED_FILE,
    GROUP_ABSENT,
    METRIC_GROUPS,
    metric_group,
    run_trajectory_metrics,
    suite_records_json,
)


@pytest.mark.parametrize("metric, group", [("ate_rmse", "trajectory"), ("rot_deg_orient_rmse", "trajectory"),
                                           ("rpe_trans_rmse_p10", "trajectory"), ("tracked_share", "trajectory"),
                                           ("depth_percent_correct", "depth"), ("semantic_iou", "semantic"),
                                           ("map_accuracy_m", "map"), ("frames", None), ("fps", None)])
def test_metric_group_by_prefix(metric, group):
    assert metric_group(metric) == group


def test_every_group_says_what_a_method_without_it_lacks():
    assert set(GROUP_ABSENT) == set(METRIC_GROUPS)


def test_a_run_scored_against_itself_has_no_error_and_an_offset_one_its_offset():
    n = 20
    stamps = np.arange(n) * 0.1
    T_gt = np.tile(np.eye(4), (n, 1, 1))
    T_gt[:, 0, 3] = np.linspace(0.0, 2.0, n)
    T_gt[:, 2, 3] = np.sin(np.linspace(0.0, 3.0, n))
    same = run_trajectory_metrics(stamps, T_gt, T_gt.copy(), "se3")
    assert same.ate.rmse == pytest.approx(0.0, abs=1e-9)
    shifted = T_gt.copy()
    shifted[:, 1, 3] += 0.5  # a constant offset: SE(3) alignment removes it, no alignment keeps it
    assert run_trajectory_metrics(stamps, T_gt, shifted, "se3").ate.rmse == pytest.approx(0.0, abs=1e-9)
    assert run_trajectory_metrics(stamps, T_gt, shifted, "none").ate.rmse == pytest.approx(0.5, rel=1e-9)


def test_suite_records_json_lists_records_in_order_with_their_run_keys():
    records = [RunRecord("office0", m, "a:B", {"ate_rmse": v, "frames": 10.0}, run=f"office0/{m}/seed0")
               for m, v in (("First", 0.25), ("Second", float("nan")))]
    data = json.loads(suite_records_json(records))
    assert [d["method"] for d in data] == ["First", "Second"] and [d["run"] for d in data] == [r.run for r in records]
    assert data[0]["metrics"]["ate_rmse"] == 0.25 and data[1]["metrics"]["ate_rmse"] is None  # NaN as null
    assert math.isnan(RunRecord.from_json(data[1]).metrics["ate_rmse"])


def test_the_benchmark_keeps_the_old_names():
    """The benchmark writes runs with these very names (eval.bench.run, eval.bench.runner, eval.bench.methods)."""
    from eval.bench import methods, run, runner

    assert (run.DONE_FILE, run.FAILED_FILE) == (DONE_FILE, FAILED_FILE) == ("metrics.json", "failed.json")
    assert run.run_trajectory_metrics is run_trajectory_metrics and runner.suite_records_json is suite_records_json
    assert methods.metric_group is metric_group and methods.GROUP_ABSENT is GROUP_ABSENT

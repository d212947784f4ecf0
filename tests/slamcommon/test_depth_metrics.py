import math

import numpy as np
import pytest

from slamcommon.depth_metrics import (
    aggregate_depth_metrics,
    correct_depth_mask,
    depth_metrics,
    relative_depth_error,
)
from slamcommon.errors import MetricError

GT = np.array([[1.0, 2.0, 4.0, 0.0], [2.0, 2.0, 5.0, 1.0]], dtype=np.float32)
# pixel by pixel: exact, 5 % off (correct), 20 % off, no gt, missing (0), missing (NaN), 10 % off (not < 10 %), 2x
EST = np.array([[1.0, 2.1, 4.8, 3.0], [0.0, np.nan, 5.5, 2.0]], dtype=np.float32)


def test_percent_correct_counts_missing_estimates_as_wrong():
    m = depth_metrics(EST, GT)
    assert m.n_valid_gt == 7 and m.n_estimated == 5
    assert m.n_correct == 2  # exact and 5 %; 10 % exactly is not below the threshold
    assert m.percent_correct == pytest.approx(100 * 2 / 7)
    assert m.density == pytest.approx(100 * 5 / 7)
    rel = np.array([0.0, 0.05, 0.2, 0.1, 1.0])
    assert m.abs_rel == pytest.approx(rel.mean(), rel=1e-6)
    err = np.array([0.0, 0.1, 0.8, 0.5, 1.0])
    assert m.rmse == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-6)
    assert m.delta_1_25 == pytest.approx(100 * 4 / 5)  # only the 2x pixel fails delta < 1.25


def test_masks():
    correct = correct_depth_mask(EST, GT)
    assert correct.tolist() == [[True, True, False, False], [False, False, False, False]]
    rel = relative_depth_error(EST, GT)
    assert np.isnan(rel[0, 3]) and np.isnan(rel[1, 0]) and rel[1, 3] == pytest.approx(1.0)
    assert correct_depth_mask(EST, GT, threshold=0.25)[0, 2]


def test_empty_and_bad_input():
    m = depth_metrics(np.ones((2, 2)), np.zeros((2, 2)))
    assert m.n_valid_gt == 0 and np.isnan(m.percent_correct) and np.isnan(m.abs_rel)
    with pytest.raises(MetricError, match="resize the estimate"):
        depth_metrics(np.ones((2, 3)), np.ones((2, 2)))


def test_pooled_and_mean_aggregation_differ_as_defined():
    a = depth_metrics(EST, GT)  # 2 of 7 correct
    b = depth_metrics(np.ones((1, 3)), np.ones((1, 3)))  # 3 of 3 correct
    pooled = aggregate_depth_metrics([a, b], "pooled")
    mean = aggregate_depth_metrics([a, b], "mean")
    assert pooled.percent_correct == pytest.approx(100 * 5 / 10)
    assert mean.percent_correct == pytest.approx((100 * 2 / 7 + 100) / 2)
    assert pooled.frames == mean.frames == 2 and pooled.n_correct == 5
    assert pooled.abs_rel == pytest.approx(a.abs_rel * 5 / 8)  # weighted by pixels with both
    assert pooled.rmse == pytest.approx(np.sqrt(a.rmse**2 * 5 / 8))
    assert aggregate_depth_metrics([], "pooled").frames == 0
    with pytest.raises(MetricError, match="pooled, mean"):
        aggregate_depth_metrics([a], "median")


def test_known_values_pooled_over_frames_as_the_network_validation_uses_them():
    gt = np.array([[1.0, 2.0], [4.0, 0.0]], np.float32)
    pred = np.array([[1.05, 2.6], [3.0, 9.0]], np.float32)  # rel errors 0.05, 0.3, 0.25; last pixel has no gt
    m = depth_metrics(pred, gt)
    assert m.n_valid_gt == 3 and m.n_estimated == 3
    assert m.abs_rel == pytest.approx((0.05 + 0.3 + 0.25) / 3, rel=1e-6)
    assert m.rmse == pytest.approx(math.sqrt((0.05**2 + 0.6**2 + 1.0**2) / 3), rel=1e-6)
    assert m.delta_1_25 == pytest.approx(100 / 3)  # ratios 1.05, 1.3, 4/3: only the first is < 1.25
    assert m.percent_correct == pytest.approx(100 / 3)
    # delta counts the ratio both ways: 1.2, 1.235, 1.3, 1.43
    assert depth_metrics(np.array([[1.2, 0.81, 1.3, 0.7]]), np.ones((1, 4))).delta_1_25 == pytest.approx(50.0)
    # pooled: every pixel once, whatever frame it came from
    a = depth_metrics(np.array([[1.0, 1.0]]), np.array([[1.0, 2.0]]))
    b = depth_metrics(np.array([[3.0]]), np.array([[3.0]]))
    pooled = aggregate_depth_metrics([a, b], "pooled")
    assert pooled.n_valid_gt == 3 and pooled.abs_rel == pytest.approx(0.5 / 3)
    assert pooled.percent_correct == pytest.approx(200 / 3)

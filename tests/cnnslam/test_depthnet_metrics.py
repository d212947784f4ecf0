"""Known answers for the depth and semantic metrics of the validation report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnnslam.depthnet.metrics import DepthSums, confusion_matrix, depth_sums, semantic_metrics
from cnnslam.errors import CnnSlamError


def test_depth_metrics_known_values() -> None:
    gt = np.array([[1.0, 2.0], [4.0, 0.0]], np.float32)
    pred = np.array([[1.05, 2.6], [3.0, 9.0]], np.float32)  # rel errors 0.05, 0.3, 0.25; last pixel has no gt
    m = depth_sums(pred, gt).metrics()
    assert m.n_pixels == 3
    assert m.abs_rel == pytest.approx((0.05 + 0.3 + 0.25) / 3, rel=1e-6)
    assert m.rmse == pytest.approx(math.sqrt((0.05**2 + 0.6**2 + 1.0**2) / 3), rel=1e-6)
    assert m.delta_1_25 == pytest.approx(1 / 3)  # ratios 1.05, 1.3, 4/3: only the first is < 1.25
    assert m.within_10pct == pytest.approx(1 / 3)


def test_delta_counts_ratio_both_ways() -> None:
    gt = np.array([1.0, 1.0, 1.0, 1.0])
    pred = np.array([1.2, 0.81, 1.3, 0.7])  # ratios 1.2, 1.235, 1.3, 1.43
    assert depth_sums(pred, gt).metrics().delta_1_25 == pytest.approx(0.5)


def test_sums_pool_pixels_over_frames() -> None:
    a = depth_sums(np.array([1.0, 1.0]), np.array([1.0, 2.0]))
    b = depth_sums(np.array([3.0]), np.array([3.0]))
    m = (a + b).metrics()
    assert m.n_pixels == 3 and m.abs_rel == pytest.approx(0.5 / 3)
    assert math.isnan(DepthSums().metrics().abs_rel)


def test_non_positive_prediction_is_wrong_not_nan() -> None:
    m = depth_sums(np.array([0.0, 1.0]), np.array([1.0, 1.0])).metrics()
    assert m.delta_1_25 == 0.5 and m.within_10pct == 0.5 and m.abs_rel == 0.5


def test_confusion_and_iou() -> None:
    gt = np.array([[0, 0, 1], [1, 2, 255]])
    pred = np.array([[0, 1, 1], [1, 2, 3]])
    conf = confusion_matrix(pred, gt, 4)
    assert conf.sum() == 5
    assert conf[0, 0] == 1 and conf[0, 1] == 1 and conf[1, 1] == 2 and conf[2, 2] == 1
    sm = semantic_metrics(conf)
    assert sm.pixel_accuracy == pytest.approx(4 / 5)
    # IoU: class 0 = 1 / 2, class 1 = 2 / 3, class 2 = 1, class 3 absent -> NaN, mean over 3 classes
    assert sm.iou[:3] == pytest.approx((0.5, 2 / 3, 1.0))
    assert math.isnan(sm.iou[3])
    assert sm.mean_iou == pytest.approx((0.5 + 2 / 3 + 1.0) / 3)


def test_confusion_rejects_out_of_range_classes() -> None:
    with pytest.raises(CnnSlamError):
        confusion_matrix(np.array([5]), np.array([0]), 4)

"""Known answers for the depth and semantic metrics of the validation report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnnslam.depthnet.metrics import (
    DepthSums,
    confusion_matrix,
    depth_sums,
    gradient_pixel_scale,
    log_depth_slope,
    semantic_metrics,
)
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


def test_log_depth_slope_known_compression() -> None:
    gt = np.linspace(0.5, 4.0, 48 * 64).reshape(48, 64)
    assert log_depth_slope(1.3 * gt**0.6, gt) == pytest.approx(0.6, abs=1e-9)  # a power law: its exponent
    assert log_depth_slope(0.8 * gt, gt) == pytest.approx(1.0, abs=1e-9)  # a scale error is not a compression
    assert math.isnan(log_depth_slope(np.full((48, 64), 2.0), np.full((48, 64), 2.0)))  # no spread in gt
    assert math.isnan(log_depth_slope(gt, np.zeros_like(gt)))  # no valid pixel


def test_gradient_pixel_scale_looks_at_the_edges() -> None:
    gray = np.zeros((48, 64), np.float32)
    gray[:, 16:48] = 200.0  # a bright band: two vertical edges, gradient only in columns 15-16 and 47-48
    gt = np.full((48, 64), 2.0)
    pred = gt.copy()
    pred[:, 13:19] = pred[:, 45:51] = 2.5  # too far near the edges only
    assert gradient_pixel_scale(gray, pred, gt, share=0.05) == pytest.approx(0.8)
    assert np.median(gt / pred) == pytest.approx(1.0)  # the whole frame's scale does not see it
    assert math.isnan(gradient_pixel_scale(gray, pred, np.zeros_like(gt)))
    assert math.isnan(gradient_pixel_scale(np.zeros_like(gray), pred, gt))  # no gradient anywhere

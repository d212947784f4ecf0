"""Known answers for the network's depth diagnostics (its accuracies are slamcommon's, tested there)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnnslam.depthnet.metrics import gradient_pixel_scale, log_depth_slope


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

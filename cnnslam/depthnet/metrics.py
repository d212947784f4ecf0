"""Diagnostics of the network's depth beyond its accuracy (pure numpy; no I/O).

The accuracies themselves (the paper's correct depth, AbsRel, RMSE, delta < 1.25, pixel accuracy and IoU) are the
shared definitions of :mod:`slamcommon.depth_metrics` and :mod:`slamcommon.semantic_metrics`, the judge's too; the
validation pools them over every valid ground-truth pixel of the frames it scores (``"pooled"`` aggregation).

Two per-frame figures say how a prediction is wrong rather than how much (ours; for frames from another domain):
the log-depth slope, the least-squares slope of log d on log g (1: the depth range is right, below 1: compressed
towards the middle, near surfaces too far and far ones too near); and the scale at high-gradient pixels,
median(g / d) over the pixels of strongest image gradient, those that direct tracking weighs most.
"""

from __future__ import annotations

import numpy as np


def log_depth_slope(pred: np.ndarray, gt: np.ndarray, min_pixels: int = 100) -> float:
    """Least-squares slope of log(pred) on log(gt) over pixels where both are positive (1 = the right depth range,
    < 1 = compressed); nan with fewer than ``min_pixels`` such pixels or no spread in gt. pred, gt: (H, W) metres."""
    d, g = np.asarray(pred, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    ok = (d > 0) & (g > 0)
    if int(ok.sum()) < min_pixels:
        return float("nan")
    x, y = np.log(g[ok]), np.log(d[ok])
    var = float(np.var(x))
    return float(np.mean((x - x.mean()) * (y - y.mean())) / var) if var > 0 else float("nan")


def gradient_pixel_scale(gray: np.ndarray, pred: np.ndarray, gt: np.ndarray, share: float = 0.2,
                         min_pixels: int = 100) -> float:
    """median(gt / pred) over the ``share`` of valid pixels (both depths > 0) with the largest image gradient
    magnitude (3x3 Sobel of ``gray``, (H, W) any intensity scale; pixels without gradient never count); nan with
    fewer than ``min_pixels`` of them.
    1 = the right metric scale where direct tracking looks."""
    import cv2

    g_img = np.asarray(gray, dtype=np.float32)
    mag = np.hypot(cv2.Sobel(g_img, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(g_img, cv2.CV_32F, 0, 1, ksize=3))
    d, g = np.asarray(pred, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    ok = (d > 0) & (g > 0)
    if int(ok.sum()) < min_pixels:
        return float("nan")
    strong = ok & (mag > 0) & (mag >= np.quantile(mag[ok], 1.0 - share))
    if int(strong.sum()) < min_pixels:
        return float("nan")
    return float(np.median(g[strong] / d[strong]))

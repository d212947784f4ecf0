"""Depth and semantic accuracy of the network's predictions (pure numpy; no I/O).

Depth metrics are pooled over every valid ground-truth pixel (gt > 0) of every frame given, so frames count by their
valid pixels:

- AbsRel = mean |d - g| / g;  RMSE = sqrt(mean (d - g)^2) metres;
- delta < 1.25 = share of pixels with max(d / g, g / d) < 1.25;
- within 10 % = share of pixels with |d - g| / g < 0.10 (CNN-SLAM Table 1's "correct depth", here over every valid
  pixel of a dense prediction).

Two per-frame figures say how a prediction is wrong rather than how much (ours; for frames from another domain):
the log-depth slope, the least-squares slope of log d on log g (1: the depth range is right, below 1: compressed
towards the middle, near surfaces too far and far ones too near); and the scale at high-gradient pixels,
median(g / d) over the pixels of strongest image gradient, those that direct tracking weighs most.

Semantic metrics come from a confusion matrix over pixels with a label (255 = none): pixel accuracy = trace / total;
IoU_c = TP_c / (TP_c + FP_c + FN_c); mean IoU over the classes present in the ground truth or the prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnnslam.errors import CnnSlamError

CORRECT_DEPTH_THRESHOLD = 0.10  # CNN-SLAM Sec. 4.1: a depth is correct within 10 % of the ground truth
DELTA_THRESHOLD = 1.25  # the usual delta < 1.25 accuracy (Eigen et al. 2014)


@dataclass(frozen=True)
class DepthSums:
    """Sufficient sums for the pooled depth metrics; add two with ``+``. All zero for no pixels."""

    n: int = 0
    abs_rel: float = 0.0
    sq_err: float = 0.0
    delta: int = 0
    within10: int = 0

    def __add__(self, other: DepthSums) -> DepthSums:
        return DepthSums(
            self.n + other.n,
            self.abs_rel + other.abs_rel,
            self.sq_err + other.sq_err,
            self.delta + other.delta,
            self.within10 + other.within10,
        )

    def metrics(self) -> DepthMetrics:
        """The pooled metrics; NaN everywhere when no pixel was valid."""
        if self.n == 0:
            nan = float("nan")
            return DepthMetrics(nan, nan, nan, nan, 0)
        return DepthMetrics(
            abs_rel=self.abs_rel / self.n,
            rmse=float(np.sqrt(self.sq_err / self.n)),
            delta_1_25=self.delta / self.n,
            within_10pct=self.within10 / self.n,
            n_pixels=self.n,
        )


@dataclass(frozen=True)
class DepthMetrics:
    """abs_rel: mean relative error; rmse: metres; delta_1_25, within_10pct: shares in [0, 1]; n_pixels: count."""

    abs_rel: float
    rmse: float
    delta_1_25: float
    within_10pct: float
    n_pixels: int


def depth_sums(pred: np.ndarray, gt: np.ndarray) -> DepthSums:
    """Sums of one frame. pred, gt: (H, W) float32 metres; pixels with gt <= 0 (no ground truth) are skipped.

    A predicted depth <= 0 where gt is valid counts as an error (relative error |d - g| / g, never within 10 %).
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    if pred.shape != gt.shape:
        raise CnnSlamError(f"prediction {pred.shape} and ground truth {gt.shape} differ in shape")
    valid = gt > 0
    d, g = pred[valid], gt[valid]
    rel = np.abs(d - g) / g
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(d > 0, np.maximum(d / g, g / np.where(d > 0, d, 1.0)), np.inf)
    return DepthSums(
        n=int(valid.sum()),
        abs_rel=float(rel.sum()),
        sq_err=float(((d - g) ** 2).sum()),
        delta=int((ratio < DELTA_THRESHOLD).sum()),
        within10=int((rel < CORRECT_DEPTH_THRESHOLD).sum()),
    )


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


def confusion_matrix(pred: np.ndarray, gt: np.ndarray, num_classes: int, ignore: int = 255) -> np.ndarray:
    """(C, C) int64 counts, rows = ground-truth class, columns = predicted class, over pixels with gt != ignore.

    pred, gt: (H, W) integer class maps.
    """
    pred = np.asarray(pred).reshape(-1).astype(np.int64)
    gt = np.asarray(gt).reshape(-1).astype(np.int64)
    if pred.shape != gt.shape:
        raise CnnSlamError(f"prediction and ground-truth label maps differ in size: {pred.size} vs {gt.size}")
    keep = gt != ignore
    gt, pred = gt[keep], pred[keep]
    if gt.size and (gt.max() >= num_classes or pred.min() < 0 or pred.max() >= num_classes):
        raise CnnSlamError(f"class ids must lie in [0, {num_classes}) (or {ignore} in the ground truth)")
    return np.bincount(gt * num_classes + pred, minlength=num_classes * num_classes).reshape(num_classes, num_classes)


@dataclass(frozen=True)
class SemanticMetrics:
    """pixel_accuracy in [0, 1]; iou: per-class IoU (NaN for a class absent from both maps); mean_iou over present
    classes; n_pixels: labelled pixels."""

    pixel_accuracy: float
    mean_iou: float
    iou: tuple[float, ...]
    n_pixels: int


def semantic_metrics(confusion: np.ndarray) -> SemanticMetrics:
    """Pixel accuracy and IoU from a (C, C) confusion matrix (:func:`confusion_matrix`)."""
    conf = np.asarray(confusion, dtype=np.float64)
    total = conf.sum()
    tp = np.diag(conf)
    union = conf.sum(0) + conf.sum(1) - tp
    with np.errstate(divide="ignore", invalid="ignore"):
        iou = np.where(union > 0, tp / np.where(union > 0, union, 1.0), np.nan)
    present = union > 0
    return SemanticMetrics(
        pixel_accuracy=float(tp.sum() / total) if total else float("nan"),
        mean_iou=float(iou[present].mean()) if present.any() else float("nan"),
        iou=tuple(float(v) for v in iou),
        n_pixels=int(total),
    )

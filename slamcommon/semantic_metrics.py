"""Semantic segmentation metrics for the paper's 4 classes (``slamcommon.labels.SemanticClass``).

Pixels whose ground truth is ``NO_LABEL`` (255) are ignored. A predicted label outside 0..C-1 (255 = the agent has
no label there) counts as wrong. Predictions may be (H, W) integer labels or (H, W, C) class probabilities (argmax).

- pixel accuracy = correctly labelled / labelled ground-truth pixels;
- IoU_c = TP_c / (TP_c + FP_c + FN_c), NaN for a class absent from both ground truth and prediction;
- mean IoU = mean of the IoU_c that are not NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slamcommon.errors import MetricError
from slamcommon.labels import NO_LABEL, NUM_CLASSES, SemanticClass


@dataclass(frozen=True)
class SemanticMetrics:
    """Pixel accuracy (0..1), per-class IoU (C,) (0..1, NaN where undefined), mean IoU, labelled pixel count."""

    pixel_accuracy: float
    iou: tuple[float, ...]
    mean_iou: float
    n_pixels: int

    def to_dict(self, class_names: list[str] | None = None) -> dict[str, float | int]:
        names = class_names or [c.name.lower() for c in SemanticClass][: len(self.iou)]
        out: dict[str, float | int] = {"pixel_accuracy": self.pixel_accuracy, "mean_iou": self.mean_iou}
        out.update({f"iou_{n}": v for n, v in zip(names, self.iou, strict=True)})
        out["n_pixels"] = self.n_pixels
        return out


def as_label_map(prediction: np.ndarray) -> np.ndarray:
    """(H, W) labels from (H, W) labels or (H, W, C) class scores (argmax over C)."""
    p = np.asarray(prediction)
    if p.ndim == 3:
        return np.argmax(p, axis=2)
    if p.ndim != 2:
        raise MetricError(f"a label prediction must be (H, W) labels or (H, W, C) scores, got shape {p.shape}")
    return p


def confusion_matrix(
    prediction: np.ndarray, labels_gt: np.ndarray, num_classes: int = NUM_CLASSES, ignore: int = NO_LABEL
) -> np.ndarray:
    """(C, C+1) int64 counts: row = ground-truth class, column = predicted class, last column = predicted "other"
    (no label or out of range). Ground-truth pixels equal to ``ignore`` or outside 0..C-1 are skipped."""
    pred = as_label_map(prediction).astype(np.int64)
    gt = np.asarray(labels_gt).astype(np.int64)
    if pred.shape != gt.shape:
        raise MetricError(f"prediction {pred.shape} and ground truth {gt.shape} must have the same (H, W)")
    keep = (gt != ignore) & (gt >= 0) & (gt < num_classes)
    g = gt[keep]
    p = pred[keep]
    p = np.where((p >= 0) & (p < num_classes), p, num_classes)
    return np.bincount(g * (num_classes + 1) + p, minlength=num_classes * (num_classes + 1)).reshape(
        num_classes, num_classes + 1
    )


def metrics_from_confusion(conf: np.ndarray) -> SemanticMetrics:
    """Pixel accuracy, IoU per class and mean IoU from a (C, C+1) confusion matrix (sums over frames are fine)."""
    conf = np.asarray(conf, dtype=np.int64)
    c = conf.shape[0]
    tp = np.diag(conf[:, :c]).astype(np.float64)
    n = int(conf.sum())
    fn = conf.sum(axis=1) - tp
    fp = conf[:, :c].sum(axis=0) - tp
    union = tp + fp + fn
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, tp / union, np.nan)
    present = iou[~np.isnan(iou)]
    return SemanticMetrics(
        pixel_accuracy=float(tp.sum() / n) if n else math.nan,
        iou=tuple(float(v) for v in iou),
        mean_iou=float(present.mean()) if present.size else math.nan,
        n_pixels=n,
    )


def semantic_metrics(prediction: np.ndarray, labels_gt: np.ndarray, num_classes: int = NUM_CLASSES) -> SemanticMetrics:
    """Metrics of one predicted label map against ground truth (both (H, W); prediction may be (H, W, C))."""
    return metrics_from_confusion(confusion_matrix(prediction, labels_gt, num_classes))

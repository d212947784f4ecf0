"""Depth metrics of key-frame depth maps against ground-truth depth.

The paper's "percentage of correct depth" (CNN-SLAM Sec. 4.1, Table 1): a pixel is correct when
|d - d_gt| / d_gt < 0.10. The share is taken over ALL pixels with valid ground truth, and a pixel without an
estimate (0 or NaN) counts as wrong, so a semi-dense method is penalised for what it does not estimate: the number
measures accuracy and density at once. The density (share of valid-ground-truth pixels that have an estimate) is
reported beside it, and the usual AbsRel, RMSE and delta < 1.25 (Eigen et al. 2014) over the pixels that have both.

Valid ground truth: finite and > 0 (``slamcommon.labels.NO_DEPTH`` = 0 marks no surface). Valid estimate: finite and
> 0. Depth maps are (H, W) metres; estimate and ground truth must have the same size. Percentages are 0..100.

Aggregation over the key-frames of a sequence (:func:`aggregate_depth_metrics`): ``"pooled"`` counts every pixel
of every key-frame once (the share of all ground-truth pixels of the sequence that are correct); ``"mean"`` averages
the per-key-frame figures. Table 1 here uses ``"pooled"`` (:data:`TABLE_AGGREGATION`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np

from slamcommon.errors import MetricError

CORRECT_THRESHOLD: float = 0.10  # CNN-SLAM Sec. 4.1: relative error below 10 %
DELTA_THRESHOLD: float = 1.25  # Eigen et al. 2014: max(d/d_gt, d_gt/d) < 1.25
Aggregation = Literal["pooled", "mean"]
TABLE_AGGREGATION: Aggregation = "pooled"


@dataclass(frozen=True)
class DepthMetrics:
    """Depth accuracy of one key-frame (or of several, aggregated). Counts are pixels; percentages 0..100; NaN where
    there is nothing to measure (no valid ground truth, or no pixel with both)."""

    percent_correct: float  # correct / valid-ground-truth pixels, x100 (the paper's Table 1 metric)
    density: float  # estimated / valid-ground-truth pixels, x100
    abs_rel: float  # mean |d - d_gt| / d_gt over pixels with both
    rmse: float  # metres, over pixels with both
    delta_1_25: float  # share of pixels with both where max(d/d_gt, d_gt/d) < 1.25, x100
    n_valid_gt: int
    n_estimated: int  # pixels with valid ground truth AND an estimate
    n_correct: int
    frames: int = 1

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def valid_depth(depth: np.ndarray) -> np.ndarray:
    """(H, W) bool: finite and > 0."""
    d = np.asarray(depth)
    return np.isfinite(d) & (d > 0)


def relative_depth_error(depth_est: np.ndarray, depth_gt: np.ndarray) -> np.ndarray:
    """|d - d_gt| / d_gt (H, W) float64, NaN where the ground truth or the estimate is not valid."""
    est, gt = _check_pair(depth_est, depth_gt)
    both = valid_depth(est) & valid_depth(gt)
    out = np.full(gt.shape, np.nan)
    out[both] = np.abs(est[both] - gt[both]) / gt[both]
    return out


def correct_depth_mask(depth_est: np.ndarray, depth_gt: np.ndarray, threshold: float = CORRECT_THRESHOLD) -> np.ndarray:
    """(H, W) bool: valid ground truth, valid estimate, and |d - d_gt| / d_gt < threshold."""
    rel = relative_depth_error(depth_est, depth_gt)
    with np.errstate(invalid="ignore"):
        return rel < threshold


def depth_metrics(depth_est: np.ndarray, depth_gt: np.ndarray, threshold: float = CORRECT_THRESHOLD) -> DepthMetrics:
    """Metrics of one estimated depth map (H, W) against ground truth (H, W), both metres."""
    est, gt = _check_pair(depth_est, depth_gt)
    gt_ok = valid_depth(gt)
    both = gt_ok & valid_depth(est)
    d, g = est[both], gt[both]
    rel = np.abs(d - g) / g
    n_gt, n_both = int(gt_ok.sum()), int(both.sum())
    n_correct = int(np.count_nonzero(rel < threshold))
    ratio = np.maximum(d / g, g / d) if n_both else np.zeros(0)
    return DepthMetrics(
        percent_correct=100.0 * n_correct / n_gt if n_gt else math.nan,
        density=100.0 * n_both / n_gt if n_gt else math.nan,
        abs_rel=float(rel.mean()) if n_both else math.nan,
        rmse=float(np.sqrt(np.mean((d - g) ** 2))) if n_both else math.nan,
        delta_1_25=100.0 * float(np.mean(ratio < DELTA_THRESHOLD)) if n_both else math.nan,
        n_valid_gt=n_gt,
        n_estimated=n_both,
        n_correct=n_correct,
    )


def aggregate_depth_metrics(per_frame: Sequence[DepthMetrics], how: Aggregation = TABLE_AGGREGATION) -> DepthMetrics:
    """Combine per-key-frame metrics: ``"pooled"`` (every pixel once) or ``"mean"`` (every key-frame once).

    Pooled AbsRel/RMSE/delta weight each frame by its pixels with both; pooled RMSE is sqrt of the pooled mean
    square. Frames with nothing to measure are skipped by ``"mean"``.
    """
    if how not in ("pooled", "mean"):
        raise MetricError(f"unknown depth aggregation {how!r}; valid: pooled, mean")
    frames = list(per_frame)
    if not frames:
        nan = math.nan
        return DepthMetrics(nan, nan, nan, nan, nan, 0, 0, 0, frames=0)
    n_gt = sum(f.n_valid_gt for f in frames)
    n_est = sum(f.n_estimated for f in frames)
    n_ok = sum(f.n_correct for f in frames)
    if how == "mean":

        def mean(name: str) -> float:
            values = [getattr(f, name) for f in frames if not math.isnan(getattr(f, name))]
            return float(np.mean(values)) if values else math.nan

        return DepthMetrics(
            mean("percent_correct"),
            mean("density"),
            mean("abs_rel"),
            mean("rmse"),
            mean("delta_1_25"),
            n_gt,
            n_est,
            n_ok,
            frames=len(frames),
        )

    def weighted(name: str, square: bool = False) -> float:
        pairs = [(getattr(f, name), f.n_estimated) for f in frames if f.n_estimated]
        if not pairs:
            return math.nan
        values, weights = np.array(pairs).T
        if square:
            return float(np.sqrt(np.average(values**2, weights=weights)))
        return float(np.average(values, weights=weights))

    return DepthMetrics(
        percent_correct=100.0 * n_ok / n_gt if n_gt else math.nan,
        density=100.0 * n_est / n_gt if n_gt else math.nan,
        abs_rel=weighted("abs_rel"),
        rmse=weighted("rmse", square=True),
        delta_1_25=weighted("delta_1_25"),
        n_valid_gt=n_gt,
        n_estimated=n_est,
        n_correct=n_ok,
        frames=len(frames),
    )


def _check_pair(depth_est: np.ndarray, depth_gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    est = np.asarray(depth_est, dtype=np.float64)
    gt = np.asarray(depth_gt, dtype=np.float64)
    if est.ndim != 2 or est.shape != gt.shape:
        raise MetricError(
            f"depth maps must both be (H, W) of one size, got estimate {est.shape} and ground truth {gt.shape}; "
            "resize the estimate to the ground truth's resolution first"
        )
    return est, gt

"""Semantic label fusion (CNN-SLAM Sec. 3.5): the CNN's per-pixel class probabilities of each key-frame fused into
the global model's elements, as the Global Segmentation Model of Tateno et al. 2015 [27] fuses segment labels.

Every model element keeps label evidence L (C,), the weighted sum of the class distributions P of the measurements
fused into it; its distribution is L / sum(L), the average of the frame-wise distributions of the key-frames that
saw it; its label is the argmax (``NO_LABEL`` without evidence). :func:`fuse_labels` is the update L <- L + w P; the
weights w are Keller's confidence alpha (``label_weighting = "confidence"``) or alpha scaled by the measurement's
precision, alpha sigma_min^2 / sigma_d^2 (``"precision"``, :func:`label_weights`).

Numeric cores only; labels are uint8 ids, evidence float32, as :class:`cnnslam.model.global_model.GlobalModel` stores
them.
"""

from __future__ import annotations

import numpy as np

from cnnslam.config import LABEL_WEIGHTINGS, LabelWeighting
from cnnslam.errors import CnnSlamError
from cnnslam.model.surfel_kernels import probability_kernel
from slamcommon.labels import NO_LABEL


def checked_class_scores(label_probs: np.ndarray | None, size: tuple[int, int], num_classes: int
                         ) -> np.ndarray | None:
    """``label_probs`` checked as label fusion takes it: (H, W, C) non-negative class scores (NaN = 0; returned as
    C-contiguous float32) or (H, W) integer labels (a value outside 0..C-1, e.g. ``NO_LABEL``, = no evidence;
    returned as given); None gives None. ``size`` is (H, W). :class:`CnnSlamError` for another shape or a negative
    score, before anything is computed from it."""
    if label_probs is None:
        return None
    C = int(num_classes)
    p = np.asarray(label_probs)
    if p.ndim == 2:
        if p.shape != tuple(size):
            raise CnnSlamError(f"a label map must be (H, W) = {tuple(size)}, got {p.shape}")
        return p
    if p.shape != (*size, C):
        raise CnnSlamError(f"label probabilities must be (H, W, C) = {(*size, C)}, got {p.shape}")
    p = np.ascontiguousarray(p, dtype=np.float32)
    if (p < 0).any():  # -inf included, NaN not
        raise CnnSlamError("label probabilities must be >= 0")
    return p


def class_probabilities_at(scores: np.ndarray, vs: np.ndarray, us: np.ndarray, num_classes: int) -> np.ndarray:
    """The per-pixel class distributions P that label fusion takes, at the pixels (``vs[k]``, ``us[k]``): (M, C)
    float32 rows summing to 1 (0 where a pixel has no evidence), from :func:`checked_class_scores`' array: scores
    normalised per pixel (+-inf as +-float32 max), labels one-hot."""
    C = int(num_classes)
    vs, us = np.asarray(vs, dtype=np.int64), np.asarray(us, dtype=np.int64)
    if scores.ndim == 2:
        out = np.zeros((vs.size, C), np.float32)
        labels = scores[vs, us]
        ok = (labels >= 0) & (labels < C)
        out[np.flatnonzero(ok), labels[ok].astype(np.intp)] = 1.0
        return out
    return probability_kernel(scores, vs, us)


def class_probability_map(label_probs: np.ndarray | None, size: tuple[int, int],
                          num_classes: int) -> np.ndarray | None:
    """:func:`class_probabilities_at` every pixel: (H, W, C) float32 distributions from ``label_probs`` as
    :func:`checked_class_scores` takes it; None gives None."""
    scores = checked_class_scores(label_probs, size, num_classes)
    if scores is None:
        return None
    h, w = size
    vs, us = np.divmod(np.arange(h * w, dtype=np.int64), w)
    return class_probabilities_at(scores, vs, us, num_classes).reshape(h, w, int(num_classes))


def label_weights(alpha: np.ndarray, sigma2: np.ndarray, weighting: LabelWeighting, min_sigma: float) -> np.ndarray:
    """The weight w of each measurement's class distribution in :func:`fuse_labels`: Keller's confidence ``alpha``
    (``weighting = "confidence"``), or ``alpha * min_sigma^2 / sigma2`` (``"precision"``: depth variance sigma_d^2 in
    m^2, so a measurement as certain as the floor ``min_sigma`` counts alpha)."""
    if weighting == "confidence":
        return alpha
    if weighting == "precision":
        return alpha * (min_sigma**2 / sigma2)
    raise CnnSlamError(f"label weighting must be one of {', '.join(LABEL_WEIGHTINGS)}, got {weighting!r}")


def fuse_labels(evidence: np.ndarray, ids: np.ndarray, probs: np.ndarray, weight: np.ndarray) -> None:
    """CNN-SLAM Sec. 3.5, label fusion: L_i <- L_i + w_k P_k for each element i = ``ids[k]`` (unique) observed by one
    (grouped) measurement k with class distribution ``probs[k]`` (C,) and weight ``weight[k]``; ``evidence`` (N, C)
    float32 in place (each product rounded to float32, then added)."""
    evidence[ids] += (np.asarray(weight)[:, None] * probs).astype(np.float32)


def label_distribution(evidence: np.ndarray) -> np.ndarray:
    """(N, C) float32 fused class distributions L / sum(L) (rows of zeros without evidence)."""
    s = evidence.sum(axis=1, keepdims=True)
    return np.where(s > 0, evidence / np.where(s > 0, s, 1.0), 0.0).astype(np.float32)


def fused_labels(evidence: np.ndarray) -> np.ndarray:
    """(N,) uint8 fused labels: the argmax of the evidence, ``NO_LABEL`` where there is none."""
    return np.where(evidence.sum(axis=1) > 0, np.argmax(evidence, axis=1), NO_LABEL).astype(np.uint8)

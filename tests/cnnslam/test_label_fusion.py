"""Known answers of semantic label fusion (CNN-SLAM Sec. 3.5): the update L <- L + w P, the distributions and
labels read back, the per-pixel probability maps it takes, and the two label weightings."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.errors import CnnSlamError
from cnnslam.model.label_fusion import (
    checked_class_scores,
    class_probabilities_at,
    class_probability_map,
    fuse_labels,
    fused_labels,
    label_distribution,
    label_weights,
)
from slamcommon.labels import NO_LABEL


def test_fuse_labels_adds_weighted_distributions_to_the_elements_named():
    L = np.zeros((3, 4), np.float32)
    fuse_labels(L, np.array([0, 2]), np.array([[1.0, 0, 0, 0], [0, 0.5, 0.5, 0]], np.float32), np.array([2.0, 1.0]))
    fuse_labels(L, np.array([0]), np.array([[0, 1.0, 0, 0]], np.float32), np.array([1.0]))
    assert np.array_equal(L, [[2, 1, 0, 0], [0, 0, 0, 0], [0, 0.5, 0.5, 0]])
    assert np.allclose(label_distribution(L), [[2 / 3, 1 / 3, 0, 0], [0, 0, 0, 0], [0, 0.5, 0.5, 0]])
    assert fused_labels(L).tolist() == [0, NO_LABEL, 1]  # a tie goes to the lower class id (argmax)


def test_class_probability_map_normalises_scores_and_reads_label_maps():
    p = np.zeros((1, 3, 4), np.float32)
    p[0, 0] = [1.0, 1.0, 2.0, 0.0]
    p[0, 1] = [np.nan, 3.0, 0.0, 1.0]
    out = class_probability_map(p, (1, 3), 4)
    assert np.allclose(out[0], [[0.25, 0.25, 0.5, 0.0], [0.0, 0.75, 0.0, 0.25], [0.0, 0.0, 0.0, 0.0]])
    labels = np.array([[3, NO_LABEL, 0]], np.uint8)
    assert np.array_equal(class_probability_map(labels, (1, 3), 4)[0], [[0, 0, 0, 1], [0, 0, 0, 0], [1, 0, 0, 0]])
    assert class_probability_map(None, (1, 3), 4) is None
    with pytest.raises(CnnSlamError, match=">= 0"):
        class_probability_map(-p, (1, 3), 4)
    with pytest.raises(CnnSlamError, match=r"\(H, W, C\)"):
        class_probability_map(p, (1, 3), 5)
    q = p.copy()
    q[0, 2, 1] = -np.inf  # -inf is a negative score; NaN is none
    with pytest.raises(CnnSlamError, match=">= 0"):
        checked_class_scores(q, (1, 3), 4)


def test_class_probabilities_at_sampled_pixels_are_the_maps_rows():
    rng = np.random.default_rng(5)
    p = rng.random((30, 40, 4)).astype(np.float32)
    p[3, 4] = [np.nan, 1.0, np.inf, 2.0]
    p[5, 6] = 0.0
    p[7, 8] = [np.nan, np.nan, np.nan, np.nan]
    scores = checked_class_scores(p, (30, 40), 4)
    vs, us = np.mgrid[0:30:2, 0:40:2].reshape(2, -1)
    vs, us = np.r_[vs, 3, 5, 7], np.r_[us, 4, 6, 8]
    rows = class_probabilities_at(scores, vs, us, 4)
    full = class_probability_map(p, (30, 40), 4)
    assert rows.dtype == np.float32 and rows.tobytes() == full[vs, us].tobytes()
    assert np.allclose(rows.sum(axis=1)[:-3], 1.0, atol=1e-6) and np.array_equal(rows[-2:], np.zeros((2, 4)))
    assert np.allclose(rows[-3], [0.0, 0.0, 1.0, 0.0], atol=1e-30)  # +inf as the float32 maximum dominates
    expected = p[vs[:5], us[:5]] / p[vs[:5], us[:5]].sum(axis=1, keepdims=True)
    assert np.allclose(rows[:5], expected, rtol=1e-6)
    labels = rng.integers(0, 6, (30, 40)).astype(np.uint8)  # 4 and 5: no evidence
    one_hot = class_probabilities_at(checked_class_scores(labels, (30, 40), 4), vs, us, 4)
    assert np.array_equal(one_hot.argmax(axis=1)[one_hot.sum(axis=1) > 0], labels[vs, us][labels[vs, us] < 4])
    assert np.array_equal(one_hot.sum(axis=1), (labels[vs, us] < 4).astype(np.float32))


def test_label_weights_confidence_or_precision():
    alpha, sigma2 = np.array([1.0, 0.5]), np.array([0.01**2, 0.02**2])
    assert np.array_equal(label_weights(alpha, sigma2, "confidence", 0.01), alpha)
    assert np.allclose(label_weights(alpha, sigma2, "precision", 0.01), [1.0, 0.125])
    with pytest.raises(CnnSlamError, match="precision"):
        label_weights(alpha, sigma2, "votes", 0.01)

"""Known answers of semantic label fusion (CNN-SLAM Sec. 3.5): the update L <- L + w P, the distributions and
labels read back, the per-pixel probability maps it takes, and the two label weightings."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.errors import CnnSlamError
from cnnslam.label_fusion import class_probability_map, fuse_labels, fused_labels, label_distribution, label_weights
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


def test_label_weights_confidence_or_precision():
    alpha, sigma2 = np.array([1.0, 0.5]), np.array([0.01**2, 0.02**2])
    assert np.array_equal(label_weights(alpha, sigma2, "confidence", 0.01), alpha)
    assert np.allclose(label_weights(alpha, sigma2, "precision", 0.01), [1.0, 0.125])
    with pytest.raises(CnnSlamError, match="precision"):
        label_weights(alpha, sigma2, "votes", 0.01)

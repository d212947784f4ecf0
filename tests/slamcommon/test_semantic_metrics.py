import math

import numpy as np
import pytest

from slamcommon.errors import MetricError
from slamcommon.semantic_metrics import confusion_matrix, metrics_from_confusion, semantic_metrics

GT = np.array([[0, 0, 1, 1], [2, 2, 255, 1]], dtype=np.uint8)
PRED = np.array([[0, 1, 1, 1], [2, 255, 3, 1]], dtype=np.uint8)


def test_known_confusion_and_metrics():
    conf = confusion_matrix(PRED, GT)
    assert conf.shape == (4, 5)
    assert conf[0].tolist() == [1, 1, 0, 0, 0] and conf[1].tolist() == [0, 3, 0, 0, 0]
    assert conf[2].tolist() == [0, 0, 1, 0, 1]  # a "no label" prediction counts as wrong
    m = semantic_metrics(PRED, GT)
    assert m.n_pixels == 7 and m.pixel_accuracy == pytest.approx(5 / 7)
    assert m.iou[0] == pytest.approx(1 / 2) and m.iou[1] == pytest.approx(3 / 4) and m.iou[2] == pytest.approx(1 / 2)
    assert np.isnan(m.iou[3])  # absent from ground truth and (on labelled pixels) from the prediction
    assert m.mean_iou == pytest.approx((0.5 + 0.75 + 0.5) / 3)
    d = m.to_dict()
    assert d["iou_floor"] == pytest.approx(0.5) and "iou_small_structure" in d


def test_probabilities_are_argmaxed_and_shapes_checked():
    scores = np.zeros((2, 4, 4), dtype=np.float32)
    scores[np.arange(2)[:, None], np.arange(4)[None, :], np.where(GT == 255, 0, GT)] = 1.0
    assert semantic_metrics(scores, GT).pixel_accuracy == 1.0
    with pytest.raises(MetricError, match="same"):
        confusion_matrix(PRED[:, :3], GT)


def test_iou_known_answer_with_a_class_absent():
    gt = np.array([[0, 0, 1], [1, 2, 255]])
    pred = np.array([[0, 1, 1], [1, 2, 3]])
    conf = confusion_matrix(pred, gt, 4)
    assert conf.shape == (4, 5) and conf.sum() == 5  # the NO_LABEL pixel is not scored
    m = metrics_from_confusion(conf)
    assert m.pixel_accuracy == pytest.approx(4 / 5)
    # IoU: class 0 = 1 / 2, class 1 = 2 / 3, class 2 = 1; class 3 is predicted only on the unlabelled pixel, so it
    # is absent from both (NaN) and the mean is over 3 classes
    assert m.iou[:3] == pytest.approx((0.5, 2 / 3, 1.0))
    assert math.isnan(m.iou[3])
    assert m.mean_iou == pytest.approx((0.5 + 2 / 3 + 1.0) / 3)

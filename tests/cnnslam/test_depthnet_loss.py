"""Tests of the berHu and cross-entropy losses: known values."""

from __future__ import annotations

import math

import pytest
import torch

from cnnslam.depthnet.loss import berhu, berhu_loss, berhu_threshold, semantic_loss, total_loss


def test_berhu_threshold_is_a_fifth_of_the_max_error() -> None:
    e = torch.tensor([0.5, -2.0, 1.0])
    assert float(berhu_threshold(e)) == pytest.approx(0.4)


def test_berhu_known_values() -> None:
    c = 0.4
    e = torch.tensor([0.1, -0.3, 0.4, -1.0, 2.0])
    expected = [0.1, 0.3, 0.4, (1.0 + c * c) / (2 * c), (4.0 + c * c) / (2 * c)]
    torch.testing.assert_close(berhu(e, c), torch.tensor(expected))


def test_berhu_loss_uses_batch_threshold_and_valid_pixels() -> None:
    pred = torch.tensor([[1.0, 2.0], [3.0, 5.0]])
    gt = torch.tensor([[1.5, 0.0], [2.0, 2.0]])  # errors -0.5, (invalid), 1.0, 3.0 -> c = 0.6
    c = 0.6
    expected = (0.5 + (1.0 + c * c) / (2 * c) + (9.0 + c * c) / (2 * c)) / 3
    assert float(berhu_loss(pred, gt)) == pytest.approx(expected, rel=1e-6)


def test_berhu_loss_in_log_space() -> None:
    pred = torch.tensor([1.0, 2.0, 8.0])
    gt = torch.tensor([1.0, 1.0, 1.0])  # log errors 0, ln 2, ln 8 = 3 ln 2 -> c = 0.6 ln 2
    ln2, c = math.log(2.0), 0.6 * math.log(2.0)
    expected = (0.0 + (ln2**2 + c * c) / (2 * c) + ((3 * ln2) ** 2 + c * c) / (2 * c)) / 3
    assert float(berhu_loss(pred, gt, space="log")) == pytest.approx(expected, rel=1e-6)
    # scale-free: the same relative errors at 10x the depth give the same loss
    assert float(berhu_loss(10 * pred, 10 * gt, space="log")) == pytest.approx(expected, rel=1e-5)
    with pytest.raises(ValueError):
        berhu_loss(pred, gt, space="sqrt")


def test_berhu_is_continuous_at_c_and_l1_below() -> None:
    c = torch.tensor(0.7)
    below, at = berhu(torch.tensor([0.69999]), c), berhu(torch.tensor([0.70001]), c)
    assert float(at) == pytest.approx(float(below), abs=1e-4)
    assert float(berhu(torch.tensor([0.2]), c)) == pytest.approx(0.2)


def test_berhu_gradient_does_not_flow_through_threshold() -> None:
    pred = torch.tensor([0.0, 10.0], requires_grad=True)
    gt = torch.tensor([1.0, 1.0])
    berhu_loss(pred, gt).backward()
    # errors -1 and 9, c = 1.8: d/dd of |e| = sign(e) = -1 (first, below c); of (e^2+c^2)/2c = e/c = 5 (second); / 2
    torch.testing.assert_close(pred.grad, torch.tensor([-0.5, 9.0 / 1.8 / 2]))


def test_berhu_loss_zero_error_and_no_valid_pixel() -> None:
    x = torch.ones(3, 3, requires_grad=True)
    assert float(berhu_loss(x, torch.ones(3, 3)).detach()) == 0.0
    loss = berhu_loss(x, torch.zeros(3, 3))
    assert float(loss.detach()) == 0.0
    loss.backward()  # a graph exists even with nothing valid


def test_semantic_loss_ignores_unlabelled_and_matches_uniform_logits() -> None:
    logits = torch.zeros(1, 4, 2, 2)
    labels = torch.tensor([[[0, 1], [255, 3]]])
    assert float(semantic_loss(logits, labels)) == pytest.approx(math.log(4))
    assert float(semantic_loss(logits, torch.full((1, 2, 2), 255))) == 0.0


def test_total_loss_weights_semantic_term() -> None:
    pred = torch.full((1, 1, 2, 2), 2.0)
    gt = torch.full((1, 1, 2, 2), 1.0)
    logits = torch.zeros(1, 4, 2, 2)
    labels = torch.zeros(1, 2, 2, dtype=torch.long)
    terms = total_loss(pred, logits, gt, labels, semantic_weight=0.5)
    # all errors 1 -> c = 0.2 -> berHu = (1 + 0.04) / 0.4 = 2.6
    assert float(terms.depth) == pytest.approx(2.6)
    assert float(terms.total) == pytest.approx(2.6 + 0.5 * math.log(4))

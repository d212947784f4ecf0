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


def test_scale_invariant_log_loss_known_values() -> None:
    from cnnslam.depthnet.loss import scale_invariant_log_loss

    g = torch.rand(2, 1, 8, 10) + 0.5
    # a pure scale factor k: mean(R^2) - lam mean(R)^2 = (1 - lam) log(k)^2
    assert float(scale_invariant_log_loss(2.0 * g, g, lam=0.5)) == pytest.approx(0.5 * math.log(2.0) ** 2, rel=1e-5)
    assert float(scale_invariant_log_loss(2.0 * g, g, lam=1.0)) == pytest.approx(0.0, abs=1e-6)
    # shape errors are not scale-invariant: log error +-e on two halves gives e^2 whatever lam
    d = g.clone()
    d[..., :5] *= math.exp(0.1)
    d[..., 5:] *= math.exp(-0.1)
    assert float(scale_invariant_log_loss(d, g, lam=1.0)) == pytest.approx(0.01, rel=1e-4)
    # pixels without ground truth are ignored, an image without any counts nothing
    g2 = g.clone()
    g2[1] = 0.0
    assert float(scale_invariant_log_loss(2.0 * g, g2, lam=0.0)) == pytest.approx(math.log(2.0) ** 2, rel=1e-5)


def test_gradient_matching_loss_known_values() -> None:
    from cnnslam.depthnet.loss import gradient_matching_loss

    g = torch.rand(1, 1, 16, 16) + 0.5
    assert float(gradient_matching_loss(3.0 * g, g)) == pytest.approx(0.0, abs=1e-6)  # blind to the global scale
    # a log-depth step of 0.2 between the two halves (columns 7 | 8): one pair per row on level 0 (16 rows of 15 x
    # pairs + 15 rows of 16 y pairs = 480 pairs) -> 16 * 0.2 / 480
    d = g.clone()
    d[..., 8:] *= math.exp(0.2)
    level0 = 16 * 0.2 / 480
    loss = float(gradient_matching_loss(d, g, scales=1))
    assert loss == pytest.approx(level0, rel=1e-4)
    # pairs touching an invalid pixel are left out
    g_hole = g.clone()
    g_hole[..., 7] = 0.0
    assert float(gradient_matching_loss(d, g_hole, scales=1)) == pytest.approx(0.0, abs=1e-6)
    t = total_loss(d, torch.zeros(1, 4, 16, 16), g, torch.full((1, 16, 16), 255), 0.5, "log", 0.5, 0.5)
    assert t.gradient is not None and t.silog is not None
    assert float(t.depth) == pytest.approx(float(berhu_loss(d, g, space="log") + 0.5 * t.silog + 0.5 * t.gradient))

"""Tests of the FCRN-style network: shapes for odd sizes, the ResNet-50 variant, the fast up-convolution."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F
from torch import nn

from cnnslam.depthnet.model import (
    DepthSemanticNet,
    ModelConfig,
    UpConv,
    count_parameters,
    fold_batch_norms,
    normalize_rgb,
    unpool2x,
    unpool_conv5_as_phases,
)
from cnnslam.errors import CnnSlamError

TINY = ModelConfig(trunk_depth=18, base_width=8, decoder_min_channels=8, dropout=0.0)


@pytest.mark.parametrize("size", [(240, 320), (37, 53), (1, 1), (64, 64), (228, 304)])
def test_output_shapes_for_any_size(size: tuple[int, int]) -> None:
    torch.manual_seed(0)
    net = DepthSemanticNet(TINY).eval()
    h, w = size
    with torch.inference_mode():
        depth, logits = net(torch.randn(2, 3, h, w))
    assert depth.shape == (2, 1, h, w)
    assert logits.shape == (2, 4, h, w)
    assert depth.dtype == torch.float32
    assert bool((depth > 0).all())


def test_padding_does_not_leak_into_valid_region_shape_only_crop() -> None:
    # The padded output is cropped: the top-left region of a 240x320 prediction equals the prediction of the same
    # image padded by the network itself (the network pads 240 -> 256 internally; calling it on the pre-padded image
    # gives the same numbers on the original pixels).
    torch.manual_seed(1)
    net = DepthSemanticNet(TINY).eval()
    x = torch.randn(1, 3, 240, 320)
    with torch.inference_mode():
        d1, l1 = net(x)
        d2, l2 = net(F.pad(x, (0, 0, 0, 16), mode="replicate"))
    torch.testing.assert_close(d1, d2[..., :240, :])
    torch.testing.assert_close(l1, l2[..., :240, :])


def test_resnet50_fcrn_variant_constructs_and_runs(reference_facts: dict) -> None:
    cfg = ModelConfig.fcrn_resnet50()
    net = DepthSemanticNet(cfg).eval()
    assert net.trunk.out_channels == 2048
    assert net.reduce[0].out_channels == 1024  # FCRN: 1x1 conv 2048 -> 1024
    chans = [blk.branch_b[0].conv.out_channels for blk in net.decoder]
    assert chans == [512, 256, 128, 64]
    # FCRN's parameter count (tests/reference_facts.toml, Laina et al. 2016); our second head adds 64 * 4 * 9 + 4
    fcrn = reference_facts["fcrn"]["parameters_millions"]
    assert fcrn - 0.1 < count_parameters(net) / 1e6 < fcrn + 0.2
    with torch.inference_mode():
        depth, logits = net(torch.randn(1, 3, 40, 56))
    assert depth.shape == (1, 1, 40, 56) and logits.shape == (1, 4, 40, 56)


@pytest.mark.parametrize("activation", ["softplus", "exp"])
def test_skips_and_depth_activations(activation: str) -> None:
    torch.manual_seed(3)
    cfg = ModelConfig(trunk_depth=18, base_width=8, decoder_min_channels=8, skips=True, depth_activation=activation)
    net = DepthSemanticNet(cfg).eval()
    assert len(net.skips) == 4
    with torch.inference_mode():
        depth, logits = net(torch.randn(2, 3, 45, 70))
    assert depth.shape == (2, 1, 45, 70) and logits.shape == (2, 4, 45, 70)
    assert bool((depth > 0).all())
    # both heads start at 2.5 m (a room's depth) whatever the activation
    assert float(depth.mean()) == pytest.approx(2.5, rel=0.05)


def test_skip_connections_change_the_output() -> None:
    torch.manual_seed(5)
    net = DepthSemanticNet(ModelConfig(base_width=8, decoder_min_channels=8, skips=True, dropout=0.0)).eval()
    x = torch.randn(1, 3, 64, 64)
    with torch.inference_mode():
        with_skips = net(x)[1]
        for proj in net.skips:
            proj[1].weight.zero_()  # BN gain 0: the skip adds only its bias (0)
        without = net(x)[1]
    assert not torch.allclose(with_skips, without)


def test_resnet34_constructs() -> None:
    net = DepthSemanticNet(ModelConfig(trunk_depth=34, base_width=8, decoder_min_channels=4))
    assert sum(len(s) for s in net.trunk.stages) == 16


def test_fast_upconv_equals_unpool_then_conv5() -> None:
    torch.manual_seed(2)
    c_in, c_out = 3, 5
    literal = UpConv(c_in, c_out, "unpool")
    fast = UpConv(c_in, c_out, "fast")
    with torch.no_grad():
        fast.conv.weight.copy_(unpool_conv5_as_phases(literal.conv.weight))
    x = torch.randn(2, c_in, 7, 9)
    torch.testing.assert_close(fast(x), literal(x), rtol=1e-5, atol=1e-5)


def test_unpool_places_values_top_left() -> None:
    x = torch.arange(4.0).reshape(1, 1, 2, 2)
    u = unpool2x(x)
    expected = torch.tensor([[0.0, 0, 1, 0], [0, 0, 0, 0], [2, 0, 3, 0], [0, 0, 0, 0]])
    torch.testing.assert_close(u[0, 0], expected)


def test_normalize_rgb_uses_imagenet_statistics() -> None:
    x = torch.full((1, 3, 2, 2), 255, dtype=torch.uint8)
    y = normalize_rgb(x)
    expected = torch.tensor([(1 - 0.485) / 0.229, (1 - 0.456) / 0.224, (1 - 0.406) / 0.225])
    torch.testing.assert_close(y[0, :, 0, 0], expected)


@pytest.mark.parametrize(
    "kwargs",
    [{"trunk_depth": 101}, {"base_width": 2}, {"upsample": "bilinear"}, {"dropout": 1.0}, {"num_classes": 1},
     {"depth_activation": "relu"}],
)
def test_bad_configs_are_rejected(kwargs: dict) -> None:
    with pytest.raises(CnnSlamError):
        ModelConfig(**kwargs)


def test_config_round_trip_and_unknown_key() -> None:
    cfg = ModelConfig(trunk_depth=34, base_width=16)
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(CnnSlamError, match="unknown model config keys"):
        ModelConfig.from_dict({**cfg.to_dict(), "width": 3})


def test_bad_input_shape() -> None:
    with pytest.raises(CnnSlamError):
        DepthSemanticNet(TINY)(torch.randn(1, 4, 32, 32))


@pytest.mark.parametrize("upsample", ["fast", "unpool"])
def test_folded_batch_norms_compute_the_same_function(upsample: str) -> None:
    """Every BN (trained statistics, not the identity of a fresh net) folded away: same outputs to float32 rounding,
    no BN left, the original untouched."""
    torch.manual_seed(3)
    net = DepthSemanticNet(ModelConfig(trunk_depth=18, base_width=8, decoder_min_channels=8, dropout=0.0,
                                       upsample=upsample)).eval()  # fmt: skip
    with torch.no_grad():
        for m in net.modules():
            if isinstance(m, nn.BatchNorm2d):
                m.running_mean.uniform_(-0.5, 0.5)
                m.running_var.uniform_(0.2, 3.0)
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.3, 0.3)
    before = {k: v.clone() for k, v in net.state_dict().items()}
    folded = fold_batch_norms(net)
    assert not any(isinstance(m, nn.BatchNorm2d) for m in folded.modules())
    assert sum(isinstance(m, nn.BatchNorm2d) for m in net.modules()) > 20
    x = torch.randn(2, 3, 64, 96)
    with torch.inference_mode():
        (d0, l0), (d1, l1) = net(x), folded(x)
    torch.testing.assert_close(d1, d0, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(l1, l0, rtol=1e-5, atol=1e-5)
    for k, v in net.state_dict().items():
        assert torch.equal(v, before[k]), k

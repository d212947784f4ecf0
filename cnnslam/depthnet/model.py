"""The depth + semantic network: an FCRN (Laina et al. 2016, CNN-SLAM's [16]) with a configurable ResNet trunk.

Architecture (FCRN, reference-facts sec. 5; CNN-SLAM Sec. 3.2):

    ResNet trunk (stride 32) -> 1x1 conv + BN (halves the channels) -> 4 up-projection blocks (each 2x up, halves the
    channels) -> dropout -> final 3x3 conv per head -> bilinear 2x up to the input size.

An up-projection block is ``2x unpool -> {A: 5x5 conv, BN, ReLU, 3x3 conv, BN;  B: 5x5 conv, BN} -> A + B -> ReLU``.
"2x unpool" places each input pixel at the top-left of a 2x2 cell of zeros (Laina et al.). ``upsample="fast"`` (the
default) computes ``unpool -> 5x5 conv`` as FCRN's "fast up-convolution": one 3x3 conv producing the 4 sub-pixel
phases, then a pixel shuffle. It is exactly the same family of functions (every unpool + 5x5 kernel has a 3x3 phase
equivalent, see :func:`unpool_conv5_as_phases`) at a third of the multiply-adds; ``upsample="unpool"`` runs the
literal form.

Deviations from the paper, all deliberate:

- One shared trunk and decoder with TWO heads (1-channel depth, 4-channel semantic logits). The paper trains two
  separate networks of the same architecture; sharing halves the CPU cost and lets one set of shipped weights give
  both outputs.
- Trained from scratch (no ImageNet initialisation exists here) and, by default, a narrow ResNet-18 trunk sized for
  CPU inference (``ModelConfig.fcrn_resnet50()`` builds the paper's ResNet-50 / 1024-channel variant).
- Depth is made positive: by default the depth head regresses log depth (depth = exp(x), ``depth_activation``),
  trained with berHu on log depth (:mod:`cnnslam.depthnet.loss`); ``"softplus"`` is the linear alternative. FCRN
  regresses depth linearly.
- Skip connections (``skips``, default on): the trunk's features at strides 16, 8, 4 and 2 pass through a 1x1 conv +
  BN and are added to the output of the up-projection block of the same stride. FCRN has none. Trained from scratch
  on 2 CPU cores, a 1000-step pilot with skips + log-depth berHu reached AbsRel 0.47 / pixel accuracy 76 % on
  held-out training-split rooms against 0.54 / 70 % for the plain FCRN decoder with linear berHu (same data, steps
  and schedule). ``ModelConfig(skips=False, depth_activation="softplus")`` is the plain FCRN decoder.
- Input sizes that are not multiples of 32 (320x240) are padded on the right/bottom by edge replication up to the
  next multiple of 32 and the outputs are cropped back. Padding keeps the pixel scale (a resize would change the
  focal length seen by the network, which eq. 5 relies on).
- Outputs are at the full input resolution (FCRN's are at about half resolution; here the half-resolution maps are
  upsampled bilinearly inside the network).
- The shipped network works at 160x120, half the SLAM resolution 320x240 (FCRN works at 304x228 and the paper
  resizes to 320x240): the predictor area-averages a 320x240 image to 160x120 and upsamples the outputs bilinearly.
  On 2 CPU cores this buys about 4x the training samples per hour, which matters more for a network trained from
  scratch than the detail lost at depth edges. The training focal length is stored at 160x120, and eq. 5 compares
  f_cur brought to the same resolution (``cnnslam.depthnet.predict``). Nothing else depends on it: the network is
  fully convolutional and ``train --downsample 1`` trains one at 320x240.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass
from typing import Any, Literal

import torch
import torch.nn.functional as F
from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval, fuse_conv_bn_weights

from cnnslam.errors import CnnSlamError
from sim_envs.frames import NUM_CLASSES

UpsampleMode = Literal["fast", "unpool"]
DepthActivation = Literal["softplus", "exp"]
LOG_DEPTH_RANGE: tuple[float, float] = (-5.0, 4.5)  # "exp" head clamps log depth: 7 mm .. 90 m (ours)
TRUNK_DEPTHS: tuple[int, ...] = (18, 34, 50)
_BLOCKS_PER_STAGE: dict[int, tuple[int, int, int, int]] = {18: (2, 2, 2, 2), 34: (3, 4, 6, 3), 50: (3, 4, 6, 3)}
OUTPUT_STRIDE = 32  # ResNet trunk: stem conv /2, max-pool /2, three strided stages /8


@dataclass(frozen=True)
class ModelConfig:
    """Architecture of :class:`DepthSemanticNet`; stored with the weights so that a checkpoint rebuilds its network.

    trunk_depth: ResNet depth, 18 / 34 (basic blocks) or 50 (bottlenecks) (He et al. 2016; FCRN uses 50).
    base_width: channels of the stem and first stage (ResNet: 64; ours default 32 so that inference fits a CPU).
    decoder_min_channels: floor on the up-projection blocks' channel count (ours: keeps a narrow decoder from
        shrinking to a handful of channels; 0 = FCRN's plain halving).
    upsample: "fast" (3x3 phase conv + pixel shuffle, FCRN's fast up-convolution) or "unpool" (literal 2x unpool +
        5x5 conv); see the module docstring.
    dropout: dropout probability before the final convolutions (FCRN: dropout after up-sampling; rate ours).
    num_classes: semantic classes (the paper's 4 NYU super-classes, ``sim_envs.frames.SemanticClass``).
    skips: add the trunk's features at strides 16, 8, 4, 2 (1x1 conv + BN) to the up-projection outputs of the same
        stride (ours, not in FCRN; see the module docstring). False = FCRN's plain decoder.
    depth_activation: "softplus" (depth = softplus(x)) or "exp" (depth = exp(x), so the head regresses log depth);
        FCRN regresses depth linearly.
    """

    trunk_depth: int = 18
    base_width: int = 32
    decoder_min_channels: int = 32
    upsample: UpsampleMode = "fast"
    dropout: float = 0.2
    num_classes: int = NUM_CLASSES
    skips: bool = True
    depth_activation: DepthActivation = "exp"

    def __post_init__(self) -> None:
        if self.trunk_depth not in TRUNK_DEPTHS:
            raise CnnSlamError(f"trunk_depth must be one of {TRUNK_DEPTHS}, got {self.trunk_depth!r}")
        if not (isinstance(self.base_width, int) and self.base_width >= 4):
            raise CnnSlamError(f"base_width must be an integer >= 4, got {self.base_width!r}")
        if not (isinstance(self.decoder_min_channels, int) and self.decoder_min_channels >= 0):
            raise CnnSlamError(f"decoder_min_channels must be an integer >= 0, got {self.decoder_min_channels!r}")
        if self.upsample not in ("fast", "unpool"):
            raise CnnSlamError(f"upsample must be 'fast' or 'unpool', got {self.upsample!r}")
        if not 0.0 <= self.dropout < 1.0:
            raise CnnSlamError(f"dropout must be in [0, 1), got {self.dropout!r}")
        if not (isinstance(self.num_classes, int) and self.num_classes >= 2):
            raise CnnSlamError(f"num_classes must be an integer >= 2, got {self.num_classes!r}")
        if self.depth_activation not in ("softplus", "exp"):
            raise CnnSlamError(f"depth_activation must be 'softplus' or 'exp', got {self.depth_activation!r}")

    @classmethod
    def fcrn_resnet50(cls) -> ModelConfig:
        """The paper's network: ResNet-50 (width 64) -> 1x1 conv to 1024 -> up-projections 512, 256, 128, 64.

        Uses the literal unpool + 5x5 up-convolutions, so the parameter count is FCRN's (63.6 M plus our second head).
        """
        return cls(
            trunk_depth=50,
            base_width=64,
            decoder_min_channels=0,
            upsample="unpool",
            dropout=0.5,
            skips=False,
            depth_activation="softplus",
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (the manifest's ``architecture``)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelConfig:
        """Inverse of :meth:`to_dict`; unknown keys are an error naming the valid ones."""
        valid = set(cls.__dataclass_fields__)
        unknown = set(data) - valid
        if unknown:
            raise CnnSlamError(f"unknown model config keys {sorted(unknown)}; valid keys: {sorted(valid)}")
        return cls(**data)


# ---------------------------------------------------------------------------------------------------------- trunk


def _conv_bn(c_in: int, c_out: int, k: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(c_in, c_out, k, stride, k // 2, bias=False), nn.BatchNorm2d(c_out))


class BasicBlock(nn.Module):
    """ResNet-18/34 block: 3x3 conv, BN, ReLU, 3x3 conv, BN, plus the (projected) shortcut, ReLU."""

    expansion = 1

    def __init__(self, c_in: int, width: int, stride: int) -> None:
        super().__init__()
        c_out = width * self.expansion
        self.body = nn.Sequential(_conv_bn(c_in, width, 3, stride), nn.ReLU(inplace=True), _conv_bn(width, c_out, 3))
        self.shortcut = _conv_bn(c_in, c_out, 1, stride) if (stride != 1 or c_in != c_out) else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.body(x) + self.shortcut(x))


class Bottleneck(nn.Module):
    """ResNet-50 block: 1x1 conv, 3x3 conv (strided), 1x1 conv to 4x width, each with BN, plus shortcut, ReLU."""

    expansion = 4

    def __init__(self, c_in: int, width: int, stride: int) -> None:
        super().__init__()
        c_out = width * self.expansion
        self.body = nn.Sequential(
            _conv_bn(c_in, width, 1),
            nn.ReLU(inplace=True),
            _conv_bn(width, width, 3, stride),
            nn.ReLU(inplace=True),
            _conv_bn(width, c_out, 1),
        )
        self.shortcut = _conv_bn(c_in, c_out, 1, stride) if (stride != 1 or c_in != c_out) else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.body(x) + self.shortcut(x))


class ResNetTrunk(nn.Module):
    """ResNet without its pooling and fully connected layers (He et al. 2016), as in FCRN.

    Input (B, 3, H, W) float32 with H, W multiples of 32; output (B, out_channels, H/32, W/32).
    """

    def __init__(self, depth: int, base_width: int) -> None:
        super().__init__()
        block: type[BasicBlock] | type[Bottleneck] = Bottleneck if depth >= 50 else BasicBlock
        self.stem = nn.Sequential(
            _conv_bn(3, base_width, 7, 2), nn.ReLU(inplace=True), nn.MaxPool2d(3, stride=2, padding=1)
        )
        stages: list[nn.Module] = []
        c_in = base_width
        for i, n_blocks in enumerate(_BLOCKS_PER_STAGE[depth]):
            width = base_width * 2**i
            blocks: list[nn.Module] = []
            for j in range(n_blocks):
                blocks.append(block(c_in, width, 2 if (j == 0 and i > 0) else 1))
                c_in = width * block.expansion
            stages.append(nn.Sequential(*blocks))
        self.stages = nn.Sequential(*stages)
        self.out_channels = c_in
        # channels of the features returned by forward_features, strides 2, 4, 8, 16, 32
        self.feature_channels = [base_width] + [base_width * 2**i * block.expansion for i in range(4)]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.stages(self.stem(x))

    def forward_features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Features at strides 2 (stem conv, before the max-pool), 4, 8, 16 and 32 (the four stages)."""
        x = self.stem[1](self.stem[0](x))
        feats = [x]
        x = self.stem[2](x)
        for stage in self.stages:
            x = stage(x)
            feats.append(x)
        return feats


# -------------------------------------------------------------------------------------------------------- decoder


def unpool2x(x: torch.Tensor) -> torch.Tensor:
    """FCRN's 2x unpooling: (B, C, h, w) -> (B, C, 2h, 2w), input at even rows/cols, zeros elsewhere."""
    b, c, h, w = x.shape
    out = x.new_zeros(b, c, 2 * h, 2 * w)
    out[:, :, 0::2, 0::2] = x
    return out


def unpool_conv5_as_phases(weight5: torch.Tensor) -> torch.Tensor:
    """The 3x3 phase kernels equivalent to ``conv5x5(unpool2x(x))`` (padding 2), for use with a pixel shuffle.

    weight5: (C_out, C_in, 5, 5). Returns (4 * C_out, C_in, 3, 3), channel ``4 * o + 2 * a + b`` giving output
    pixel (2i + a, 2j + b) of channel o. Kernel rows 0, 2, 4 act on input rows i - 1, i, i + 1 for even output rows;
    rows 1, 3 on input rows i, i + 1 for odd output rows (FCRN's fast up-convolution; same for columns).
    """
    c_out, c_in = weight5.shape[:2]
    taps = {0: ((0, 0), (1, 2), (2, 4)), 1: ((1, 1), (2, 3))}  # phase -> (3x3 index, 5x5 index)
    out = weight5.new_zeros(c_out, 2, 2, c_in, 3, 3)
    for a in (0, 1):
        for b in (0, 1):
            for r3, r5 in taps[a]:
                for s3, s5 in taps[b]:
                    out[:, a, b, :, r3, s3] = weight5[:, :, r5, s5]
    return out.reshape(4 * c_out, c_in, 3, 3)


class UpConv(nn.Module):
    """``2x unpool -> 5x5 conv`` (no bias), literal or as FCRN's fast up-convolution. (B, C_in, h, w) -> (B, C_out,
    2h, 2w)."""

    def __init__(self, c_in: int, c_out: int, mode: UpsampleMode) -> None:
        super().__init__()
        self.mode = mode
        if mode == "fast":
            self.conv = nn.Conv2d(c_in, 4 * c_out, 3, padding=1, bias=False)
        else:
            self.conv = nn.Conv2d(c_in, c_out, 5, padding=2, bias=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.mode == "fast":
            return F.pixel_shuffle(self.conv(x), 2)
        return self.conv(unpool2x(x))


class UpProjection(nn.Module):
    """FCRN up-projection: A = upconv5, BN, ReLU, 3x3 conv, BN; B = upconv5, BN; ReLU(A + B). Doubles H and W."""

    def __init__(self, c_in: int, c_out: int, mode: UpsampleMode) -> None:
        super().__init__()
        self.branch_a = nn.Sequential(
            UpConv(c_in, c_out, mode), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True), _conv_bn(c_out, c_out, 3)
        )
        self.branch_b = nn.Sequential(UpConv(c_in, c_out, mode), nn.BatchNorm2d(c_out))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.branch_a(x) + self.branch_b(x))


# ---------------------------------------------------------------------------------------------------------- network


class DepthSemanticNet(nn.Module):
    """FCRN with a depth head and a semantic head (see the module docstring).

    forward(x): x (B, 3, H, W) float32 normalised RGB (:func:`normalize_rgb`), any H, W >= 1. Returns
    ``(depth, logits)``: depth (B, 1, H, W) float32 metres (> 0, the RAW network output at the training camera's
    focal length), logits (B, num_classes, H, W) float32 (softmax not applied).
    """

    def __init__(self, config: ModelConfig | None = None) -> None:
        super().__init__()
        self.config = config or ModelConfig()
        cfg = self.config
        self.trunk = ResNetTrunk(cfg.trunk_depth, cfg.base_width)
        c = self.trunk.out_channels // 2
        self.reduce = _conv_bn(self.trunk.out_channels, c, 1)  # FCRN: 1x1 conv 2048 -> 1024, BN
        blocks: list[nn.Module] = []
        for _ in range(4):
            c_next = max(c // 2, cfg.decoder_min_channels)
            blocks.append(UpProjection(c, c_next, cfg.upsample))
            c = c_next
        self.decoder = nn.Sequential(*blocks)
        # skip projections: trunk features at strides 16, 8, 4, 2 -> the channels of up-projection blocks 1..4
        self.skips = nn.ModuleList()
        if cfg.skips:
            outs = [blk.branch_b[1].num_features for blk in blocks]
            for c_feat, c_out in zip(self.trunk.feature_channels[3::-1], outs, strict=True):
                self.skips.append(_conv_bn(c_feat, c_out, 1))
        self.dropout = nn.Dropout2d(cfg.dropout) if cfg.dropout > 0 else nn.Identity()
        self.depth_head = nn.Conv2d(c, 1, 3, padding=1)
        self.semantic_head = nn.Conv2d(c, cfg.num_classes, 3, padding=1)
        self._init_weights()

    def _init_weights(self) -> None:
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.ones_(m.weight)
                nn.init.zeros_(m.bias)
        # Zero-init the last BN of each residual body (Goyal et al. 2017): blocks start as identities, which helps
        # training from scratch.
        for m in self.trunk.modules():
            if isinstance(m, (BasicBlock, Bottleneck)):
                nn.init.zeros_(m.body[-1][1].weight)
        nn.init.normal_(self.depth_head.weight, std=1e-3)
        # initial depth 2.5 m everywhere, a room's typical depth
        init = math.log(2.5) if self.config.depth_activation == "exp" else math.log(math.expm1(2.5))
        nn.init.constant_(self.depth_head.bias, init)
        nn.init.normal_(self.semantic_head.weight, std=1e-3)
        nn.init.zeros_(self.semantic_head.bias)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if x.ndim != 4 or x.shape[1] != 3:
            raise CnnSlamError(f"input must be (B, 3, H, W), got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        ph, pw = (-h) % OUTPUT_STRIDE, (-w) % OUTPUT_STRIDE
        if ph or pw:
            x = F.pad(x, (0, pw, 0, ph), mode="replicate")
        if self.config.skips:
            feats = self.trunk.forward_features(x)
            feat = self.reduce(feats[-1])
            for block, proj, skip in zip(self.decoder, self.skips, feats[3::-1], strict=True):
                feat = block(feat) + proj(skip)
        else:
            feat = self.decoder(self.reduce(self.trunk(x)))
        feat = self.dropout(feat)
        raw = self.depth_head(feat)
        if self.config.depth_activation == "exp":
            depth = torch.exp(raw.clamp(*LOG_DEPTH_RANGE))
        else:
            depth = F.softplus(raw)
        logits = self.semantic_head(feat)
        size = (x.shape[-2], x.shape[-1])
        depth = F.interpolate(depth, size=size, mode="bilinear", align_corners=False)[..., :h, :w]
        logits = F.interpolate(logits, size=size, mode="bilinear", align_corners=False)[..., :h, :w]
        return depth, logits


# ImageNet statistics, the usual normalisation for a ResNet input (fixed constants, not learnt).
RGB_MEAN: tuple[float, float, float] = (0.485, 0.456, 0.406)
RGB_STD: tuple[float, float, float] = (0.229, 0.224, 0.225)


def normalize_rgb(rgb: torch.Tensor) -> torch.Tensor:
    """uint8 or [0, 255] float images (B, 3, H, W) -> float32 network input ((x / 255 - mean) / std per channel)."""
    x = rgb.float() / 255.0
    mean = torch.tensor(RGB_MEAN, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    std = torch.tensor(RGB_STD, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    return (x - mean) / std


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def _fold_into_upconv(up: UpConv, bn: nn.BatchNorm2d) -> None:
    """Fold the eval-mode ``bn`` that follows ``up`` into ``up``'s convolution (in place). In "fast" mode conv
    channel ``4 * o + k`` becomes output channel ``o`` through the pixel shuffle, so each BN statistic is repeated
    4 times along the conv's output channels."""
    if up.mode != "fast":
        up.conv = fuse_conv_bn_eval(up.conv, bn)
        return
    assert bn.running_mean is not None and bn.running_var is not None
    rep = 4  # pixel_shuffle(2): 2 * 2 conv channels per output channel
    weight, bias = fuse_conv_bn_weights(
        up.conv.weight, None, bn.running_mean.repeat_interleave(rep), bn.running_var.repeat_interleave(rep), bn.eps,
        bn.weight.repeat_interleave(rep), bn.bias.repeat_interleave(rep),
    )
    conv = nn.Conv2d(up.conv.in_channels, up.conv.out_channels, up.conv.kernel_size, padding=up.conv.padding)
    conv.weight, conv.bias = weight, bias
    up.conv = conv


def fold_batch_norms(model: DepthSemanticNet) -> DepthSemanticNet:
    """An inference copy of ``model`` in which every batch norm is folded into the convolution before it.

    An eval-mode BN is the affine map ``y = (x - mean) * g / sqrt(var + eps) + b`` per channel; after a convolution
    it is the same convolution with weights scaled by ``g / sqrt(var + eps)`` per output channel and a bias
    ``b - mean * g / sqrt(var + eps)`` (torch.nn.utils.fusion). The copy computes the same function (to float32
    rounding: a few ulps) with one pass over each feature map fewer; the BN modules become identities. ``model`` is
    left as it is; the copy is in eval mode and holds its own parameters (a snapshot: later training of ``model``
    does not reach it).
    """
    folded = copy.deepcopy(model).eval()
    for seq in list(folded.modules()):
        if not isinstance(seq, nn.Sequential):
            continue
        for i in range(len(seq) - 1):
            first, bn = seq[i], seq[i + 1]
            if not isinstance(bn, nn.BatchNorm2d):
                continue
            if isinstance(first, nn.Conv2d):
                seq[i] = fuse_conv_bn_eval(first, bn)
            elif isinstance(first, UpConv):
                _fold_into_upconv(first, bn)
            else:
                continue
            seq[i + 1] = nn.Identity()
    return folded

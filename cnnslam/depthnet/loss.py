"""Training losses: reverse Huber (berHu) for depth (FCRN, Laina et al. 2016) and cross-entropy for labels.

berHu (Laina et al. 2016, eq. 3; CNN-SLAM Sec. 3.2 "the loss function is based on the reverse Huber"):

    B(e) = |e|                    if |e| <= c
         = (e^2 + c^2) / (2 c)    otherwise,      c = 0.2 * max_i |e_i| over the valid pixels of the batch.

c is a constant of the batch (no gradient flows through the max), as in FCRN. FCRN applies it to the depth error in
metres (``space="linear"``); the shipped network applies it to the error of log depth (``space="log"``,
e = log d - log g, about the relative error), which weighs a 0.3 m error at 1 m as much as a 1.5 m error at 5 m, as
the report's AbsRel and "within 10 %" do (a pilot comparison is in ``cnnslam.depthnet.model``'s docstring).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import torch
import torch.nn.functional as F

from sim_envs.frames import NO_LABEL

BERHU_C_FRACTION = 0.2  # FCRN: c = 1/5 of the largest absolute error in the batch
DepthSpace = Literal["linear", "log"]


def berhu_threshold(error: torch.Tensor) -> torch.Tensor:
    """FCRN's berHu threshold c = 0.2 * max |error| (a detached scalar tensor; 0 for an empty or all-zero error)."""
    if error.numel() == 0:
        return error.new_zeros(())
    return BERHU_C_FRACTION * error.detach().abs().max()


def berhu(error: torch.Tensor, c: torch.Tensor | float) -> torch.Tensor:
    """Element-wise reverse Huber of ``error`` (any shape, metres) with threshold ``c`` >= 0 (metres).

    L1 up to c, ``(e^2 + c^2) / (2c)`` above (continuous at c, where both equal c). c = 0 gives plain L1.
    """
    a = error.abs()
    c_t = torch.as_tensor(c, dtype=a.dtype, device=a.device)
    if float(c_t) <= 0.0:
        return a
    return torch.where(a <= c_t, a, (a * a + c_t * c_t) / (2.0 * c_t))


def berhu_loss(
    pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor | None = None, space: DepthSpace = "linear"
) -> torch.Tensor:
    """Mean berHu over valid pixels, c = 0.2 * max |error| over those pixels (FCRN).

    pred, target: same shape, float32 metres; valid: bool mask of that shape (default ``target > 0``, i.e. pixels
    with ground truth). space: "linear" (error = pred - target, metres, FCRN) or "log" (error = log pred - log
    target, about the relative error; ours). Returns a scalar; 0 (with a gradient path) when no pixel is valid.
    """
    if space not in ("linear", "log"):
        raise ValueError(f"space must be 'linear' or 'log', got {space!r}")
    if valid is None:
        valid = target > 0
    if space == "log":
        valid = valid & (pred > 0)
        error = torch.log(pred[valid]) - torch.log(target[valid])
    else:
        error = (pred - target)[valid]
    if error.numel() == 0:
        return pred.sum() * 0.0
    return berhu(error, berhu_threshold(error)).mean()


def semantic_loss(logits: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """Softmax cross-entropy (CNN-SLAM Sec. 3.2) averaged over labelled pixels.

    logits: (B, C, H, W) float32; labels: (B, H, W) int64 class ids, ``NO_LABEL`` (255) ignored. Returns a scalar; 0
    (with a gradient path) when no pixel is labelled.
    """
    if not bool((labels != NO_LABEL).any()):
        return logits.sum() * 0.0
    return F.cross_entropy(logits, labels, ignore_index=NO_LABEL)


@dataclass(frozen=True)
class LossTerms:
    """The training loss and its parts (scalar tensors): total = depth + semantic_weight * semantic."""

    total: torch.Tensor
    depth: torch.Tensor
    semantic: torch.Tensor


def total_loss(
    depth_pred: torch.Tensor,
    logits: torch.Tensor,
    depth_gt: torch.Tensor,
    labels_gt: torch.Tensor,
    semantic_weight: float,
    depth_space: DepthSpace = "linear",
) -> LossTerms:
    """berHu on depth (in ``depth_space``, see :func:`berhu_loss`) plus ``semantic_weight`` x cross-entropy on labels.

    depth_pred, depth_gt: (B, 1, H, W) or (B, H, W) float32 metres (gt 0 = none); logits (B, C, H, W);
    labels_gt (B, H, W) int64 (255 = none).
    """
    depth_term = berhu_loss(depth_pred.reshape(depth_gt.shape), depth_gt, space=depth_space)
    sem_term = semantic_loss(logits, labels_gt)
    return LossTerms(depth_term + semantic_weight * sem_term, depth_term, sem_term)

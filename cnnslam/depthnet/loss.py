"""Training losses: reverse Huber (berHu) for depth (FCRN, Laina et al. 2016) and cross-entropy for labels.

berHu (Laina et al. 2016, eq. 3; CNN-SLAM Sec. 3.2 "the loss function is based on the reverse Huber"):

    B(e) = |e|                    if |e| <= c
         = (e^2 + c^2) / (2 c)    otherwise,      c = 0.2 * max_i |e_i| over the valid pixels of the batch.

c is a constant of the batch (no gradient flows through the max), as in FCRN. FCRN applies it to the depth error in
metres (``space="linear"``); the shipped network applies it to the error of log depth (``space="log"``,
e = log d - log g, about the relative error), which weighs a 0.3 m error at 1 m as much as a 1.5 m error at 5 m, as
the report's AbsRel and "within 10 %" do (a pilot comparison is in ``cnnslam.depthnet.model``'s docstring).

Two scale-invariant terms can be added to the metric berHu (ours, after MiDaS, Ranftl et al. TPAMI 2020, and
MegaDepth, Li and Snavely CVPR 2018): with R = log d - log g on the valid pixels,

- :func:`scale_invariant_log_loss`, Eigen et al. (NIPS 2014) eq. 4: mean(R^2) - lambda mean(R)^2, the error of the
  depth's shape once its global scale is taken out (lambda = 0.5, Eigen's training value);
- :func:`gradient_matching_loss`: the multi-scale gradient-matching term of MegaDepth / MiDaS on log depth,
  mean over scales k of mean |d_x R_k| + |d_y R_k| over pixels whose neighbour is valid too, R_k being R at
  1 / 2^k of the resolution (nearest subsampling). It penalises wrong depth steps and blurred depth edges, and is
  blind to the global scale (a constant R has no gradient).

Both only see the relative structure, so the metric scale stays the berHu term's (and eq. 5's) to learn.
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


def scale_invariant_log_loss(
    pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor | None = None, lam: float = 0.5
) -> torch.Tensor:
    """Eigen et al. (NIPS 2014) eq. 4 per image, averaged over the batch: mean(R^2) - lam * mean(R)^2 with
    R = log pred - log target on the image's valid pixels (default ``target > 0``).

    pred, target: (B, 1, H, W) or (B, H, W) float32 metres. lam = 0 is the plain log MSE, 1 fully scale-invariant.
    Returns a scalar; 0 (with a gradient path) when no pixel is valid.
    """
    pred, target = pred.reshape(pred.shape[0], -1), target.reshape(target.shape[0], -1)
    valid = (target > 0) if valid is None else valid.reshape(valid.shape[0], -1)
    valid = valid & (pred > 0)
    r = torch.where(valid, torch.log(pred.clamp_min(1e-6)) - torch.log(target.clamp_min(1e-6)), 0.0)
    n = valid.sum(dim=1)
    keep = n > 0
    if not bool(keep.any()):
        return pred.sum() * 0.0
    n = n[keep].to(r.dtype)
    mean_sq = (r[keep] ** 2).sum(dim=1) / n
    mean = r[keep].sum(dim=1) / n
    return (mean_sq - lam * mean * mean).mean()


def gradient_matching_loss(
    pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor | None = None, scales: int = 4
) -> torch.Tensor:
    """The multi-scale gradient-matching term (MegaDepth; MiDaS) on log depth: sum over ``scales`` levels of
    mean(|R(x+1) - R(x)| + |R(y+1) - R(y)|) over pixel pairs valid at both ends, R = log pred - log target, the
    level-k maps subsampled by 2^k (every 2^k-th pixel). Averaged over the levels that have a valid pair.

    pred, target: (B, 1, H, W) float32 metres; valid: (B, 1, H, W) bool (default ``target > 0``). Returns a scalar;
    0 (with a gradient path) when no pair is valid.
    """
    if pred.ndim == 3:
        pred, target = pred[:, None], target[:, None]
        valid = None if valid is None else valid[:, None]
    valid = (target > 0) if valid is None else valid
    valid = valid & (pred > 0)
    r = torch.where(valid, torch.log(pred.clamp_min(1e-6)) - torch.log(target.clamp_min(1e-6)), 0.0)
    terms = []
    for k in range(max(1, int(scales))):
        step = 2**k
        rk, vk = r[..., ::step, ::step], valid[..., ::step, ::step]
        if rk.shape[-1] < 2 or rk.shape[-2] < 2:
            break
        vx = vk[..., :, 1:] & vk[..., :, :-1]
        vy = vk[..., 1:, :] & vk[..., :-1, :]
        n = vx.sum() + vy.sum()
        if int(n) == 0:
            continue
        gx = (rk[..., :, 1:] - rk[..., :, :-1]).abs() * vx
        gy = (rk[..., 1:, :] - rk[..., :-1, :]).abs() * vy
        terms.append((gx.sum() + gy.sum()) / n)
    if not terms:
        return pred.sum() * 0.0
    return torch.stack(terms).mean()


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
    """The training loss and its parts (scalar tensors): total = depth + semantic_weight * semantic, where depth =
    berHu + silog_weight * scale-invariant log + gradient_weight * gradient matching (the last two 0 when off)."""

    total: torch.Tensor
    depth: torch.Tensor
    semantic: torch.Tensor
    silog: torch.Tensor | None = None
    gradient: torch.Tensor | None = None


def total_loss(
    depth_pred: torch.Tensor,
    logits: torch.Tensor,
    depth_gt: torch.Tensor,
    labels_gt: torch.Tensor,
    semantic_weight: float,
    depth_space: DepthSpace = "linear",
    silog_weight: float = 0.0,
    gradient_weight: float = 0.0,
) -> LossTerms:
    """berHu on depth (in ``depth_space``, see :func:`berhu_loss`), plus ``silog_weight`` x
    :func:`scale_invariant_log_loss` and ``gradient_weight`` x :func:`gradient_matching_loss` when positive, plus
    ``semantic_weight`` x cross-entropy on labels.

    depth_pred, depth_gt: (B, 1, H, W) or (B, H, W) float32 metres (gt 0 = none); logits (B, C, H, W);
    labels_gt (B, H, W) int64 (255 = none).
    """
    pred = depth_pred.reshape(depth_gt.shape)
    depth_term = berhu_loss(pred, depth_gt, space=depth_space)
    silog = scale_invariant_log_loss(pred, depth_gt) if silog_weight > 0 else None
    grad = gradient_matching_loss(pred, depth_gt) if gradient_weight > 0 else None
    if silog is not None:
        depth_term = depth_term + silog_weight * silog
    if grad is not None:
        depth_term = depth_term + gradient_weight * grad
    sem_term = semantic_loss(logits, labels_gt)
    return LossTerms(depth_term + semantic_weight * sem_term, depth_term, sem_term, silog, grad)

"""Inference with the depth + semantic network: one RGB image in, metric depth and class probabilities out.

The network's pixel scale is that of its training images (``train_size``, focal length ``train_focal``). An image of
another size is resized to ``train_size`` before the network (area averaging when shrinking, as the training images
were made) and the outputs are resized back bilinearly, so the network always sees the pixel scale it was trained at;
the focal-length adjustment (CNN-SLAM eq. 5) then compares f_cur, brought to ``train_size``, with f_tr. The shipped
network has ``train_size`` (160, 120): a 320x240 frame is halved on the way in and its outputs doubled on the way out.

Floating point across machines: the network's float32 outputs differ in their last bits between CPUs and math
back-ends (measured on office0's first frame with oneDNN off against on: 74 % of the depth pixels differ, by a median
of 0.9, a 99th percentile of 3.6 and at most 7.4 float32 ulps), and the SLAM system amplifies such differences.
Explicit parameters of the predictor reproduce that here (agents take them as ``predictor_options``, so they are
part of a run's method definition and its fingerprint; see ``docs/benchmarks.md``, "Determinism"):

- ``jitter_seed``: multiply every output (depth and class probabilities) by ``1 + e``, e ~ N(0, (2 ulp)^2) per pixel,
  drawn from a generator seeded with ``jitter_seed`` (new draws per frame, the same sequence for the same seed): what
  another CPU does to the outputs. The benchmark's seeds 1, 2, ... set it; 0 or None leaves the outputs as computed,
  unless ``jitter_seed_fallback`` gives a seed for that case (the calibration's "another CPU": every run perturbed,
  seed 0 included);
- ``onednn=False``: torch's oneDNN (MKL-DNN) kernels off for this predictor's inference (a second math back-end;
  scoped to each forward pass, the process's setting is left as it was). ``num_threads`` likewise applies to this
  predictor's forward passes only.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from numba import njit

from cnnslam.depth.depth_prediction import (
    JITTER_STD_ULPS,
    focal_at_train_size,
    focal_length_adjustment,
    perturb_last_bits,
)
from cnnslam.depthnet.model import DepthSemanticNet, fold_batch_norms, normalize_rgb
from cnnslam.depthnet.weights_io import DEFAULT_WEIGHTS, load_weights
from cnnslam.errors import CnnSlamError


@dataclass(frozen=True)
class Prediction:
    """One image's prediction.

    depth: (H, W) float32 metres, > 0 everywhere; label_probs: (H, W, C) float32 softmax over the classes of
    :class:`sim_envs.frames.SemanticClass` (C = 4), summing to 1 per pixel.
    """

    depth: np.ndarray
    label_probs: np.ndarray

    @property
    def labels(self) -> np.ndarray:
        """(H, W) uint8 most probable class per pixel."""
        return np.argmax(self.label_probs, axis=-1).astype(np.uint8)


@njit(cache=True, nogil=True, error_model="numpy")
def _normalised_short_rows(p: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``p / p.sum(axis=-1, keepdims=True)`` of an (H, W, C) float32 array with C < 8, in one pass: each sum in the
    order NumPy adds a row that short (left to right, from 0), so the same bits."""
    h, w, c = p.shape
    out = np.empty((h, w, c), np.float32)
    for y in range(h):
        for x in range(w):
            s = np.float32(0.0)
            for k in range(c):
                s += p[y, x, k]
            for k in range(c):
                out[y, x, k] = p[y, x, k] / s
    return out


def normalised_rows(p: np.ndarray) -> np.ndarray:
    """(H, W, C) float32 ``p / p.sum(axis=-1, keepdims=True)``: class scores made distributions per pixel (a
    compiled pass for the network's few classes, NumPy otherwise; the same bits either way)."""
    if p.dtype == np.float32 and p.ndim == 3 and p.shape[2] < 8:
        return _normalised_short_rows(np.ascontiguousarray(p))
    return (p / p.sum(axis=-1, keepdims=True)).astype(np.float32)


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3 or min(rgb.shape[:2]) < 1:
        raise CnnSlamError(f"rgb must be an (H, W, 3) uint8 image, got shape {rgb.shape} dtype {rgb.dtype}")
    return rgb


class DepthNetPredictor:
    """A trained :class:`DepthSemanticNet` with its training camera.

    train_focal: f_tr, pixels at ``train_size``; train_size: (W, H) of the training images. ``num_threads`` (if given)
    is torch's intra-op thread count during this predictor's forward passes. ``jitter_seed`` (if given; else
    ``jitter_seed_fallback``): perturb the outputs in their last bits as another CPU would, and ``onednn=False``: infer
    without torch's oneDNN kernels (see the module docstring); ``output_scale``: multiply the depth by this factor (a
    deliberate scale bias, for sensitivity studies and for proving that the regression gate catches one).
    The forward passes run an inference copy of ``model`` made once, here (:func:`fold_batch_norms`): later changes
    to ``model``'s weights do not reach it.
    """

    def __init__(
        self,
        model: DepthSemanticNet,
        train_focal: float,
        train_size: tuple[int, int],
        num_threads: int | None = None,
        jitter_seed: int | None = None,
        output_scale: float = 1.0,
        jitter_seed_fallback: int | None = None,
        onednn: bool = True,
    ) -> None:
        if not (np.isfinite(output_scale) and output_scale > 0):
            raise CnnSlamError(f"output_scale must be a positive number, got {output_scale!r}")
        if num_threads is not None and num_threads < 1:
            raise CnnSlamError(f"num_threads must be >= 1, got {num_threads}")
        self.num_threads = None if num_threads is None else int(num_threads)
        self.onednn = bool(onednn)
        self.model = model.eval()
        # what runs: the batch norms folded into the convolutions and, with oneDNN, the feature maps channels-last
        # (oneDNN's native layout: no reorder around each convolution); outputs within a few float32 ulps of
        # ``model``'s (tests/cnnslam/test_depthnet_predict.py)
        self._net = fold_batch_norms(self.model)
        if self.onednn:
            self._net = self._net.to(memory_format=torch.channels_last)
        self.train_focal = float(train_focal)
        self.train_size = (int(train_size[0]), int(train_size[1]))
        self.output_scale = float(output_scale)
        if not jitter_seed:
            jitter_seed = jitter_seed_fallback
        self._jitter = np.random.default_rng(int(jitter_seed)) if jitter_seed else None

    @torch.inference_mode()
    def _forward(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = normalize_rgb(torch.from_numpy(np.ascontiguousarray(rgb)).permute(2, 0, 1)[None])
        threads = torch.get_num_threads()
        if self.num_threads is not None:
            torch.set_num_threads(self.num_threads)
        try:
            if self.onednn:
                depth, logits = self._net(x.contiguous(memory_format=torch.channels_last))
            else:
                with torch.backends.mkldnn.flags(enabled=False):
                    depth, logits = self._net(x)
        finally:
            if self.num_threads is not None:
                torch.set_num_threads(threads)
        probs = torch.softmax(logits, dim=1)
        depth_np = depth[0, 0].numpy().astype(np.float32)
        probs_np = probs[0].permute(1, 2, 0).numpy().astype(np.float32)
        if self._jitter is not None:
            depth_np = perturb_last_bits(depth_np, self._jitter, JITTER_STD_ULPS)
            probs_np = perturb_last_bits(probs_np, self._jitter, JITTER_STD_ULPS)
        if self.output_scale != 1.0:
            depth_np = (depth_np * np.float32(self.output_scale)).astype(np.float32)
        return depth_np, probs_np

    def predict_raw(self, rgb: np.ndarray) -> Prediction:
        """The network's output for ``rgb`` ((H, W, 3) uint8, any size), at (H, W), WITHOUT focal adjustment.

        depth: metres as the network regresses them, i.e. for a camera with the training focal length.
        """
        rgb = _check_rgb(rgb)
        h, w = rgb.shape[:2]
        tw, th = self.train_size
        if (w, h) == (tw, th):
            depth, probs = self._forward(rgb)
            return Prediction(depth, probs)
        shrink = w * h > tw * th
        small = cv2.resize(rgb, (tw, th), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        depth, probs = self._forward(small)
        depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_LINEAR)
        probs = cv2.resize(probs, (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, -1)
        return Prediction(depth.astype(np.float32), normalised_rows(probs))

    def current_focal(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> float:
        """f_cur of an image of ``image_size`` (H, W) with ``intrinsics`` [fx, fy, cx, cy] (pixels), brought to the
        network's resolution ``train_size``: ``(fx * W_tr / W + fy * H_tr / H) / 2``."""
        return focal_at_train_size(intrinsics, image_size, self.train_size)

    def predict(self, rgb: np.ndarray, intrinsics: np.ndarray) -> Prediction:
        """Depth for THIS camera: the raw output scaled by f_cur / f_tr (CNN-SLAM eq. 5), labels unchanged.

        rgb: (H, W, 3) uint8; intrinsics: (4,) [fx, fy, cx, cy] of this image in pixels (OpenCV convention).
        f = (fx + fy) / 2, both focal lengths at ``train_size``.
        """
        rgb = _check_rgb(rgb)
        f_cur = self.current_focal(intrinsics, rgb.shape[:2])
        raw = self.predict_raw(rgb)
        return Prediction(focal_length_adjustment(raw.depth, f_cur, self.train_focal), raw.label_probs)


def load_predictor(weights: str | Path | None = None, num_threads: int | None = None,
                   jitter_seed: int | None = None, output_scale: float = 1.0, jitter_seed_fallback: int | None = None,
                   onednn: bool = True) -> DepthNetPredictor:
    """The predictor of a weights file (``None``: the shipped ``cnnslam/depthnet/weights/default.pt``); the other
    keywords are :class:`DepthNetPredictor`'s."""
    loaded = load_weights(DEFAULT_WEIGHTS if weights is None else weights)
    return DepthNetPredictor(loaded.model, loaded.train_focal, loaded.train_size, num_threads=num_threads,
                             jitter_seed=jitter_seed, output_scale=output_scale,
                             jitter_seed_fallback=jitter_seed_fallback, onednn=onednn)

"""CNN-based depth prediction for key-frames (CNN-SLAM Sec. 3.2 and the focal-length adjustment of Sec. 3.3).

- :func:`focal_length_adjustment` is eq. 5.
- :class:`DepthPredictor` is what the SLAM system needs from a depth network (the trained one is
  ``cnnslam.depthnet.predict.DepthNetPredictor``, loaded by :func:`cnnslam.predictors.make_predictor`
  ``("network")``).
- :func:`predict_keyframe_depth` runs a predictor on a key-frame image and applies eq. 5 or not: the raw/adjusted
  switch of the paper's Fig. 3 (a)/(b) (``DepthConfig.focal_adjustment``).
- :class:`DegradedGroundTruthPredictor` is a DEVELOPMENT and ABLATION tool, not part of the method: it imitates a
  CNN by degrading ground-truth depth (blurred depth edges, smoothed-away small objects, a wrong global scale, a
  focal-length bias that eq. 5 undoes, low-frequency and pixel noise). It needs ground truth, so the SLAM system can
  use it only through an agent that declares ``uses_ground_truth = True``
  (:class:`cnnslam.agent.GroundTruthAidedAgent`); the real agent never sees ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError

# std of the last-bit perturbation in float32 ulps: the size of the difference another CPU or math back-end makes to
# the network's outputs (oneDNN on/off, office0's first frame: median 0.9, p99 3.6, max 7.4 ulps)
JITTER_STD_ULPS = 2.0


def perturb_last_bits(values: np.ndarray, rng: np.random.Generator, std_ulps: float = JITTER_STD_ULPS) -> np.ndarray:
    """``values`` x (1 + e), e ~ N(0, (``std_ulps`` float32 ulp)^2) per element, as float32: what another CPU does to a
    float32 result in its last bits. The benchmark's seeds 1, 2, ... apply it where a method's only randomness would
    be the machine's (the network's outputs; LSD-BS's bootstrapped depth), so a cell's runs show that spread.

    The draws are ``rng.standard_normal(values.shape)``'s (the same numbers, in C order, leaving ``rng`` in the same
    state) and each product is float32(float64(v) (1 + e)), as NumPy's ``(v * (1 + e)).astype(float32)``; one compiled
    pass without the float64 temporaries (the same bits)."""
    v = np.asarray(values, dtype=np.float32)
    scale = float(std_ulps) * float(np.finfo(np.float32).eps)
    if not isinstance(rng, np.random.Generator):  # e.g. a legacy RandomState: NumPy's expression, the same definition
        return (v * (1.0 + rng.standard_normal(v.shape) * scale)).astype(np.float32)
    return _perturbed(np.ascontiguousarray(v).reshape(-1), rng, scale).reshape(v.shape)


@njit(cache=True, nogil=True)
def _perturbed(flat: np.ndarray, rng: np.random.Generator, scale: float) -> np.ndarray:  # pragma: no cover - compiled
    out = np.empty(flat.size, np.float32)
    for i in range(flat.size):
        out[i] = np.float32(np.float64(flat[i]) * (1.0 + rng.standard_normal() * scale))
    return out


def focal_length_adjustment(depth_raw: np.ndarray, f_cur: float, f_tr: float) -> np.ndarray:
    """CNN-SLAM eq. 5: D(u) = (f_cur / f_tr) * D~(u), the CNN's depth rescaled to the current camera.

    depth_raw: (H, W) float32 metres, the depth regressed by the network (0 = no estimate stays 0).
    f_cur: focal length of the current camera, pixels; f_tr: focal length of the camera the network was trained
    with, pixels. Both must be measured at the SAME image resolution (the one the network runs at).
    Returns (H, W) float32 metres.
    """
    for name, f in (("f_cur", f_cur), ("f_tr", f_tr)):
        if not (isinstance(f, int | float | np.floating | np.integer) and math.isfinite(float(f)) and f > 0):
            raise CnnSlamError(f"{name} must be a finite positive focal length in pixels, got {f!r}")
    return (np.asarray(depth_raw, dtype=np.float32) * np.float32(float(f_cur) / float(f_tr))).astype(np.float32)


# ------------------------------------------------------------------------------------------- predictor protocols


@runtime_checkable
class PredictionLike(Protocol):
    """One network output: depth (H, W) float32 metres > 0; label_probs (H, W, C) float32 softmax (C = 4)."""

    depth: np.ndarray
    label_probs: np.ndarray


@runtime_checkable
class DepthPredictor(Protocol):
    """What the SLAM system needs from a depth network (``cnnslam.depthnet.predict.DepthNetPredictor`` has it).

    ``train_focal``: f_tr in pixels at the resolution the network works at; ``predict_raw(rgb)``: the network's
    output for an (H, W, 3) uint8 image, at (H, W), without eq. 5. Optionally ``current_focal(intrinsics,
    image_size)`` gives f_cur at the network's resolution (else f_cur = (fx + fy) / 2 of the image).
    """

    train_focal: float

    def predict_raw(self, rgb: np.ndarray) -> PredictionLike: ...


@dataclass(frozen=True)
class GroundTruthHint:
    """Ground truth of one frame, for development predictors and the LSD-BS bootstrap only.

    depth: (H, W) float32 metres, 0 = no surface; labels: (H, W) uint8 semantic classes (255 = none) or None;
    sensor_depth: (H, W) float32 metres, 0 = no measurement, the world's depth sensor where it has one (a simulated
    Kinect), or None.
    """

    depth: np.ndarray
    labels: np.ndarray | None = None
    sensor_depth: np.ndarray | None = None

    @classmethod
    def from_info(cls, info: dict[str, Any] | None) -> GroundTruthHint | None:
        """The hint in an environment step's ``info`` (``gt_depth``, optional ``gt_labels`` and ``sensor_depth``),
        or None without one."""
        if info is None or "gt_depth" not in info:
            return None
        sensor = info.get("sensor_depth")
        return cls(np.asarray(info["gt_depth"], dtype=np.float32), info.get("gt_labels"),
                   None if sensor is None else np.asarray(sensor, dtype=np.float32))  # fmt: skip

    @property
    def measured_depth(self) -> np.ndarray:
        """The depth an RGB-D camera measured: ``sensor_depth`` where the world has a depth sensor, else ``depth``
        (a real folder's depth channel is already the sensor's). LSD-BS bootstraps from it, as the paper's LSD-BS
        does from the Kinect depth of TUM's first frame."""
        return self.depth if self.sensor_depth is None else self.sensor_depth


@dataclass(frozen=True)
class KeyframePrediction:
    """A key-frame's CNN output as the SLAM system uses it.

    depth: (H, W) float32 metres (eq. 5 applied when ``focal_adjusted``); raw_depth: (H, W) float32 metres, the
    network's output before eq. 5; label_probs: (H, W, C) float32 class probabilities or None; focal_ratio:
    f_cur / f_tr (1.0 when eq. 5 was not applied).
    """

    depth: np.ndarray
    raw_depth: np.ndarray
    label_probs: np.ndarray | None
    focal_adjusted: bool
    focal_ratio: float


def _checked_intrinsics(intrinsics: np.ndarray) -> np.ndarray:
    k = np.asarray(intrinsics, dtype=np.float64).reshape(-1)
    if k.shape != (4,) or not np.isfinite(k).all() or k[0] <= 0 or k[1] <= 0:
        raise CnnSlamError(f"intrinsics must be [fx, fy, cx, cy] with positive focal lengths, got {intrinsics!r}")
    return k


def focal_at_train_size(intrinsics: np.ndarray, image_size: tuple[int, int], train_size: tuple[int, int]) -> float:
    """f_cur of eq. 5 for a network that sees images resized to ``train_size`` (W_tr, H_tr): the focal length (pixels)
    of an image of ``image_size`` (H, W) with ``intrinsics`` [fx, fy, cx, cy], brought to the network's resolution,
    ``(fx * W_tr / W + fy * H_tr / H) / 2``. :class:`CnnSlamError` for intrinsics that are not four finite values
    with positive focal lengths."""
    k = _checked_intrinsics(intrinsics)
    h, w = image_size
    tw, th = train_size
    return float((k[0] * tw / w + k[1] * th / h) / 2.0)


def _current_focal(predictor: Any, intrinsics: np.ndarray, image_size: tuple[int, int]) -> float:
    k = _checked_intrinsics(intrinsics)
    method = getattr(predictor, "current_focal", None)
    if callable(method):
        return float(method(k, image_size))
    return float((k[0] + k[1]) / 2.0)


def predict_keyframe_depth(
    predictor: Any,
    rgb: np.ndarray,
    intrinsics: np.ndarray,
    focal_adjustment: bool,
    ground_truth: GroundTruthHint | None = None,
) -> KeyframePrediction:
    """Run the predictor on a key-frame image; apply eq. 5 when ``focal_adjustment`` (paper Fig. 3 (b)) or keep the
    raw output (Fig. 3 (a)).

    rgb: (H, W, 3) uint8; intrinsics: [fx, fy, cx, cy] pixels. A predictor with ``needs_ground_truth = True``
    (:class:`DegradedGroundTruthPredictor`) also needs ``ground_truth``; :class:`CnnSlamError` otherwise.
    """
    h, w = np.asarray(rgb).shape[:2]
    if getattr(predictor, "needs_ground_truth", False):
        if ground_truth is None:
            raise CnnSlamError(
                f"the predictor {type(predictor).__name__} imitates a CNN from ground truth and needs the frame's "
                "ground-truth depth: use it through cnnslam.agent:GroundTruthAidedAgent (uses_ground_truth = True)"
            )
        out = predictor.predict_raw_from_ground_truth(rgb, ground_truth, intrinsics)
    else:
        out = predictor.predict_raw(rgb)
    raw = np.asarray(out.depth, dtype=np.float32)
    if raw.shape != (h, w):
        raise CnnSlamError(f"the predictor returned depth of shape {raw.shape} for an image of {(h, w)}")
    probs = getattr(out, "label_probs", None)
    probs = None if probs is None else np.asarray(probs, dtype=np.float32)
    if focal_adjustment:
        f_cur, f_tr = _current_focal(predictor, intrinsics, (h, w)), float(predictor.train_focal)
        depth = focal_length_adjustment(raw, f_cur, f_tr)
        ratio = f_cur / f_tr
    else:
        ratio, depth = 1.0, raw
    return KeyframePrediction(depth=depth, raw_depth=raw, label_probs=probs, focal_adjusted=bool(focal_adjustment),
                              focal_ratio=float(ratio))


# ---------------------------------------------------------------------------- the development predictor


@dataclass(frozen=True)
class DepthPrediction:
    """One image's prediction by a predictor of this package (:class:`DegradedGroundTruthPredictor`, a model file):
    depth (H, W) float32 metres > 0; label_probs (H, W, C) float32 per-pixel class distributions, or None when the
    predictor gives no class scores."""

    depth: np.ndarray
    label_probs: np.ndarray | None


DegradedPrediction = DepthPrediction  # the development predictor's output under its own name


# f_tr of the paper's network: NYU Depth v2's Kinect, (518.8579 + 519.4696) / 2 at 640x480, halved for 320x240
NYU_FOCAL_320: float = (518.8579 + 519.4696) / 4.0


class DegradedGroundTruthPredictor:
    """A stand-in for the depth CNN that degrades ground truth like a CNN does (development / ablation only).

    Per call, from the frame's ground-truth depth D (metres):

    1. holes (no surface) are filled from their neighbours (a CNN predicts depth everywhere);
    2. objects narrower than ``small_object_px`` are smoothed away (grey closing: near, small things vanish);
    3. depth edges are blurred (Gaussian, ``edge_blur_px``, in log depth), as the up-sampling part of FCRN does;
    4. a global scale error: ``scale`` times a per-frame factor exp(N(0, ``scale_jitter``));
    5. low-frequency multiplicative noise exp(``lowfreq_noise`` * smooth field) and pixel noise ``pixel_noise``;
    6. the training-camera bias that eq. 5 undoes: raw = D' * f_tr / f_cur, so that ``predict_raw`` (and the
       system's raw-depth ablation) is off by f_tr / f_cur like a real network applied to another camera.

    Labels: ground-truth one-hot (when given) blurred by ``label_blur_px`` and mixed with ``label_uniform`` of a
    uniform distribution; uniform when the frame has no labels. ``seed`` seeds a numpy Generator: the same call
    order gives the same bytes. ``train_focal`` is f_tr in pixels at the image resolution (default NYU at 320x240).
    """

    needs_ground_truth = True
    name = "degraded_ground_truth"

    def __init__(
        self,
        train_focal: float = NYU_FOCAL_320,
        scale: float = 1.03,
        scale_jitter: float = 0.02,
        edge_blur_px: float = 4.0,
        small_object_px: int = 7,
        lowfreq_noise: float = 0.05,
        pixel_noise: float = 0.01,
        label_blur_px: float = 3.0,
        label_uniform: float = 0.1,
        seed: int = 0,
    ) -> None:
        if not (math.isfinite(train_focal) and train_focal > 0 and scale > 0):
            raise CnnSlamError(f"train_focal and scale must be positive, got {train_focal!r}, {scale!r}")
        for name, value in (("scale_jitter", scale_jitter), ("edge_blur_px", edge_blur_px),
                            ("small_object_px", small_object_px), ("lowfreq_noise", lowfreq_noise),
                            ("pixel_noise", pixel_noise), ("label_blur_px", label_blur_px)):
            if not value >= 0:
                raise CnnSlamError(f"{name} must be >= 0, got {value!r}")
        if not 0 <= label_uniform <= 1:
            raise CnnSlamError(f"label_uniform must be in [0, 1], got {label_uniform!r}")
        self.train_focal = float(train_focal)
        self.scale = float(scale)
        self.scale_jitter = float(scale_jitter)
        self.edge_blur_px = float(edge_blur_px)
        self.small_object_px = int(small_object_px)
        self.lowfreq_noise = float(lowfreq_noise)
        self.pixel_noise = float(pixel_noise)
        self.label_blur_px = float(label_blur_px)
        self.label_uniform = float(label_uniform)
        self.rng = np.random.default_rng(seed)

    def degrade_depth(self, gt_depth: np.ndarray) -> np.ndarray:
        """Steps 1-5 on an (H, W) float32 ground-truth depth (metres, 0 = none); (H, W) float32 metres > 0."""
        d = np.asarray(gt_depth, dtype=np.float32)
        valid = d > 0
        if not valid.any():
            raise CnnSlamError("ground-truth depth has no valid pixel; nothing to degrade")
        if not valid.all():  # 1. fill holes with the nearest valid depth
            far = float(d[valid].max())
            filled = np.where(valid, d, 0).astype(np.float32)
            mask = (~valid).astype(np.uint8)
            filled = cv2.inpaint(filled / far, mask, 3, cv2.INPAINT_NS) * far
            d = np.where(valid, d, np.maximum(filled, 1e-3)).astype(np.float32)
        if self.small_object_px > 1:  # 2. grey closing removes near objects narrower than the kernel
            k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (self.small_object_px, self.small_object_px))
            d = cv2.morphologyEx(d, cv2.MORPH_CLOSE, k)
        log_d = np.log(d)
        if self.edge_blur_px > 0:  # 3. blurred depth edges
            log_d = cv2.GaussianBlur(log_d, (0, 0), self.edge_blur_px, borderType=cv2.BORDER_REPLICATE)
        h, w = d.shape
        log_scale = math.log(self.scale) + self.scale_jitter * float(self.rng.standard_normal())  # 4.
        field = np.zeros((h, w), np.float32)
        if self.lowfreq_noise > 0:  # 5. smooth multiplicative noise
            coarse = self.rng.standard_normal((max(h // 40, 2), max(w // 40, 2))).astype(np.float32)
            field = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
            field *= self.lowfreq_noise / max(float(field.std()), 1e-6)
        pixel = self.pixel_noise * self.rng.standard_normal((h, w)).astype(np.float32)
        return np.exp(log_d + log_scale + field + pixel).astype(np.float32)

    def degrade_labels(self, gt_labels: np.ndarray | None, shape: tuple[int, int], n_classes: int = 4) -> np.ndarray:
        """(H, W, n_classes) float32 probabilities from ground-truth labels (uniform where none)."""
        h, w = shape
        if gt_labels is None:
            return np.full((h, w, n_classes), 1.0 / n_classes, np.float32)
        labels = np.asarray(gt_labels)
        probs = np.stack([(labels == c).astype(np.float32) for c in range(n_classes)], axis=-1)
        none = probs.sum(axis=-1) == 0
        probs[none] = 1.0 / n_classes
        if self.label_blur_px > 0:
            probs = cv2.GaussianBlur(probs, (0, 0), self.label_blur_px, borderType=cv2.BORDER_REPLICATE)
            probs = probs.reshape(h, w, n_classes)
        probs = (1.0 - self.label_uniform) * probs + self.label_uniform / n_classes
        return (probs / probs.sum(axis=-1, keepdims=True)).astype(np.float32)

    def predict_raw_from_ground_truth(
        self, rgb: np.ndarray, ground_truth: GroundTruthHint, intrinsics: np.ndarray
    ) -> DepthPrediction:
        """The imitated raw network output for one frame (steps 1-6 of the class docstring; no eq. 5)."""
        h, w = np.asarray(rgb).shape[:2]
        if ground_truth.depth.shape != (h, w):
            raise CnnSlamError(f"ground-truth depth {ground_truth.depth.shape} does not match the image {(h, w)}")
        f_cur = _current_focal(self, intrinsics, (h, w))
        depth = self.degrade_depth(ground_truth.depth) * np.float32(self.train_focal / f_cur)  # 6.
        return DepthPrediction(depth=depth.astype(np.float32),
                                  label_probs=self.degrade_labels(ground_truth.labels, (h, w)))

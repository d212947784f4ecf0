"""Image statistics that tell a camera's character, for calibrating the simulated camera against real frames.

Measured on 8-bit RGB frames (H, W, 3) uint8, each on the grey image ``(R + G + B) / 3`` in intensity levels
(0-255). Numpy / OpenCV only; the command line is :mod:`sim_envs.tools.cli_camera_calibration`.

- noise: Immerkaer's noise estimate (Immerkaer 1996, "Fast noise variance estimation") restricted to flat regions:
  the image convolved with the Laplacian-difference mask [[1,-2,1],[-2,4,-2],[1,-2,1]] (which cancels planar
  intensity and passes white noise with gain 6), its mean absolute value over the quarter of the pixels with the
  smallest smoothed gradient, scaled by sqrt(pi / 2) / 6 (Immerkaer's formula; a median would be quantised by the
  8-bit levels) -> noise std in intensity levels;
- gradient energy: the mean Sobel gradient magnitude (levels per pixel) and the variance of the Laplacian
  (a focus / blur measure: blur lowers both);
- brightness: the mean grey level, and the std of the change of log mean brightness between consecutive frames
  (auto-exposure and lighting changes);
- vignetting: the mean brightness of the four corner patches (each 1/8 of the width and height) over that of the
  central patch (1/4 of the width and height), averaged over frames (scene content averages out over a moving
  camera; 1 = none).

:func:`depth_statistics` describes the depths a sequence sees (the room and the camera path, not the camera): the
10th, 50th and 90th percentiles of every valid depth pixel of the frames pooled, and the share of valid pixels.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass

import cv2
import numpy as np

from sim_envs.errors import SimEnvError

_IMMERKAER = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float32)
FLAT_SHARE: float = 0.25  # the share of pixels (lowest smoothed gradient) the noise is measured on (ours)


@dataclass(frozen=True)
class CameraStatistics:
    """Statistics of a frame sequence (see the module docstring); medians over frames unless said otherwise.

    noise_std: levels; gradient_mean: levels / px; laplacian_var: levels^2; brightness_mean: levels (mean over
    frames); log_brightness_change_std: std over consecutive pairs; vignette_ratio: corners / centre (mean over
    frames); frames: how many frames were measured.
    """

    noise_std: float
    gradient_mean: float
    laplacian_var: float
    brightness_mean: float
    log_brightness_change_std: float
    vignette_ratio: float
    frames: int

    def as_dict(self) -> dict[str, float | int]:
        """The statistics as a dict (field order)."""
        return asdict(self)


@dataclass(frozen=True)
class DepthStatistics:
    """The depths seen over a sequence (:func:`depth_statistics`): p10, median, p90 in metres over every valid pixel
    of the frames pooled; valid_share: mean share of valid pixels per frame; frames: how many frames."""

    p10: float
    median: float
    p90: float
    valid_share: float
    frames: int

    def as_dict(self) -> dict[str, float | int]:
        """The statistics as a dict (field order)."""
        return asdict(self)


def depth_statistics(depths: Iterable[np.ndarray]) -> DepthStatistics:
    """Percentiles of the valid depths of frames (each (H, W) metres; valid: finite and > 0, so 0 = none)."""
    pooled, shares = [], []
    for depth in depths:
        d = np.asarray(depth, dtype=np.float32)
        valid = np.isfinite(d) & (d > 0)
        pooled.append(d[valid])
        shares.append(float(valid.mean()))
    values = np.concatenate(pooled) if pooled else np.empty(0, np.float32)
    if values.size == 0:
        raise SimEnvError(f"depth statistics need at least one valid depth, got {len(shares)} frames without one")
    p10, median, p90 = (float(v) for v in np.percentile(values, [10, 50, 90]))
    return DepthStatistics(p10, median, p90, float(np.mean(shares)), len(shares))


def grey(rgb: np.ndarray) -> np.ndarray:
    """(H, W) float32 mean of the three channels of an (H, W, 3) uint8 image, in levels."""
    return np.asarray(rgb, dtype=np.float32).mean(axis=2)


def noise_std(image: np.ndarray, flat_share: float = FLAT_SHARE) -> float:
    """Noise std (levels) of a grey image (H, W) on its flattest ``flat_share`` of pixels (Immerkaer 1996)."""
    residual = np.abs(cv2.filter2D(image, cv2.CV_32F, _IMMERKAER))[1:-1, 1:-1]
    gx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)
    smooth = cv2.GaussianBlur(np.hypot(gx, gy), (0, 0), 2.0)[1:-1, 1:-1]
    flat = smooth <= np.quantile(smooth, flat_share)
    return float(np.sqrt(np.pi / 2) * residual[flat].mean() / 6.0)


def gradient_mean(image: np.ndarray) -> float:
    """Mean Sobel gradient magnitude of a grey image, levels per pixel (Sobel / 8)."""
    gx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    return float(np.hypot(gx, gy)[1:-1, 1:-1].mean())


def laplacian_var(image: np.ndarray) -> float:
    """Variance of the 3x3 Laplacian of a grey image (levels^2): the usual focus measure."""
    return float(cv2.Laplacian(image, cv2.CV_32F, ksize=1)[1:-1, 1:-1].var())


def vignette_ratio(image: np.ndarray) -> float:
    """Mean of the four corner patches (1/8 x 1/8 of the image each) over the central patch (1/4 x 1/4)."""
    h, w = image.shape
    ch, cw = max(h // 8, 1), max(w // 8, 1)
    corners = [image[:ch, :cw], image[:ch, -cw:], image[-ch:, :cw], image[-ch:, -cw:]]
    centre = image[h // 2 - h // 8 : h // 2 + h // 8, w // 2 - w // 8 : w // 2 + w // 8]
    return float(np.mean([c.mean() for c in corners]) / max(float(centre.mean()), 1e-6))


def depth_edge_alignment(rgb: np.ndarray, depth: np.ndarray, log_step: float = 0.15) -> float:
    """How well a depth map is registered to its colour image: the mean Sobel gradient magnitude of the grey image
    on the depth map's discontinuities (pixels where the Sobel gradient of log depth exceeds ``log_step``) over its
    mean on every pixel with depth (both 2 px inside the measured area). 1: the depth edges fall anywhere; larger:
    they fall on colour edges, as a registered pair's do. rgb: (H, W, 3) uint8; depth: (H, W) metres, 0 = none."""
    d = np.asarray(depth, dtype=np.float32)
    if d.shape != np.asarray(rgb).shape[:2]:
        raise SimEnvError(f"depth of shape {d.shape} for an image of {np.asarray(rgb).shape[:2]}")
    image = grey(rgb)
    edges = np.hypot(cv2.Sobel(image, cv2.CV_32F, 1, 0), cv2.Sobel(image, cv2.CV_32F, 0, 1))
    inside = cv2.erode((d > 0).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    log_d = np.log(np.where(d > 0, d, 1.0)).astype(np.float32)
    steps = np.hypot(cv2.Sobel(log_d, cv2.CV_32F, 1, 0), cv2.Sobel(log_d, cv2.CV_32F, 0, 1))
    at_steps = (steps > log_step) & inside
    if not at_steps.any() or float(edges[inside].mean()) <= 0:
        return float("nan")  # no depth edge or a blank image: nothing to measure
    return float(edges[at_steps].mean() / edges[inside].mean())


def camera_statistics(frames: Iterable[np.ndarray]) -> CameraStatistics:
    """The statistics of consecutive frames ((H, W, 3) uint8 each; at least two)."""
    noise, grad, lap, mean, vig = [], [], [], [], []
    for rgb in frames:
        g = grey(rgb)
        noise.append(noise_std(g))
        grad.append(gradient_mean(g))
        lap.append(laplacian_var(g))
        mean.append(float(g.mean()))
        vig.append(vignette_ratio(g))
    if len(mean) < 2:
        raise SimEnvError(f"camera statistics need at least two frames, got {len(mean)}")
    log_change = np.diff(np.log(np.maximum(mean, 1e-3)))
    return CameraStatistics(
        noise_std=float(np.median(noise)),
        gradient_mean=float(np.median(grad)),
        laplacian_var=float(np.median(lap)),
        brightness_mean=float(np.mean(mean)),
        log_brightness_change_std=float(np.std(log_change)),
        vignette_ratio=float(np.mean(vig)),
        frames=len(mean),
    )

"""Optional sensor effects on rendered RGB images: noise, motion blur (sub-frame averaging), exposure changes.

Pure image operations on (H, W, 3) uint8 arrays; randomness only from a ``numpy.random.Generator`` passed in. All
effects are off by default. Motion blur needs renders at several poses inside the shutter interval: the sequence
code renders at the times :func:`blur_offsets` gives and averages them with :func:`average_frames`. Ground truth
(depth, labels) never gets effects.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim_envs.errors import SimEnvError


@dataclass(frozen=True)
class SensorEffects:
    """Sensor effects applied to RGB.

    noise_std: std of zero-mean Gaussian noise in intensity levels (0-255 scale), 0 = off; blur_subframes: renders
    averaged per frame, 1 = off; shutter_s: seconds the shutter is open (sub-frames spread over the ``shutter_s``
    before the frame's timestamp); exposure_jitter: std of the relative gain per frame (gain = 1 + N(0, jitter),
    clipped to [0.2, 3]), 0 = off.
    """

    noise_std: float = 0.0
    blur_subframes: int = 1
    shutter_s: float = 1.0 / 60.0
    exposure_jitter: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.noise_std) and self.noise_std >= 0):
            raise SimEnvError(f"noise_std must be >= 0 intensity levels, got {self.noise_std}")
        if int(self.blur_subframes) != self.blur_subframes or self.blur_subframes < 1:
            raise SimEnvError(f"blur_subframes must be an integer >= 1 (1 = no blur), got {self.blur_subframes}")
        if not (np.isfinite(self.shutter_s) and self.shutter_s >= 0):
            raise SimEnvError(f"shutter_s must be >= 0 seconds, got {self.shutter_s}")
        if not (np.isfinite(self.exposure_jitter) and self.exposure_jitter >= 0):
            raise SimEnvError(f"exposure_jitter must be >= 0, got {self.exposure_jitter}")

    @property
    def any(self) -> bool:
        """Whether any effect is on."""
        return self.noise_std > 0 or self.blur_subframes > 1 or self.exposure_jitter > 0


def apply_noise(rgb: np.ndarray, std: float, rng: np.random.Generator) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 plus N(0, ``std``) noise per pixel and channel, rounded and clipped (a new array)."""
    if std <= 0:
        return rgb.copy()
    noisy = rgb.astype(np.float32) + rng.normal(0.0, std, size=rgb.shape).astype(np.float32)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def apply_exposure(rgb: np.ndarray, gain: float) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 scaled by ``gain`` (a relative exposure), rounded and clipped: a new uint8 array."""
    if gain == 1.0:
        return rgb.copy()
    return np.clip(np.rint(rgb.astype(np.float32) * np.float32(gain)), 0, 255).astype(np.uint8)


def average_frames(rgbs: Sequence[np.ndarray]) -> np.ndarray:
    """The rounded mean of renders (K of (H, W, 3) uint8) at sub-frame poses: a motion-blurred (H, W, 3) uint8 image."""
    if len(rgbs) == 0:
        raise SimEnvError("average_frames needs at least one image")
    stack = np.stack([np.asarray(f, dtype=np.float32) for f in rgbs])
    return np.clip(np.rint(stack.mean(0)), 0, 255).astype(np.uint8)


def blur_offsets(effects: SensorEffects) -> np.ndarray:
    """(K,) float64 time offsets in seconds (<= 0, the last one 0) at which to render the sub-frames of one frame."""
    k = int(effects.blur_subframes)
    if k == 1:
        return np.zeros(1)
    return np.linspace(-effects.shutter_s, 0.0, k)


def exposure_gain(effects: SensorEffects, rng: np.random.Generator) -> float:
    """One frame's relative gain: 1 + N(0, exposure_jitter) clipped to [0.2, 3]; exactly 1 (no draw) when off."""
    if effects.exposure_jitter <= 0:
        return 1.0
    return float(np.clip(1.0 + rng.normal(0.0, effects.exposure_jitter), 0.2, 3.0))


def apply_sensor_effects(rgb: np.ndarray, effects: SensorEffects | None, rng: np.random.Generator) -> np.ndarray:
    """Exposure change then noise on one (possibly already blurred) (H, W, 3) uint8 image; a new array.

    The generator is used for the gain first (if jitter is on), then the noise (if on): the same generator state gives
    the same bytes.
    """
    if effects is None:
        return rgb.copy()
    out = apply_exposure(rgb, exposure_gain(effects, rng))
    return apply_noise(out, effects.noise_std, rng)

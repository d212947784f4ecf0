"""The physics the camera's stages compute (:mod:`sim_envs.sensor.camera_stages`), as functions of explicit parameters:
sRGB encoding and decoding, the vignetting fall-off, lens-distortion maps, the rows' exposure times and the blur's
render weights, and a Kinect-like sensor depth (simkinect); with the published constants they use (ICL-NUIM's noise,
the Kinect's geometry, the nominal frame rate).

Conventions: images H x W, uint8 RGB (H, W, 3); linear images float32 in [0, 1]; depth metric planar z; camera x
right, y down, z forward; times in seconds.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from sim_envs.camera import Intrinsics

FPS_NOMINAL: float = 30.0  # Kinect v1 / TUM RGB-D / ICL-NUIM frame rate

# ICL-NUIM RGB noise as reimplemented in ShudaLi/rgbd_simulation (../shared/notes/real-cameras.md, section 4):
# per channel (R, G, B), on linear intensities in [0, 1].
ICL_SHOT_NOISE: tuple[float, float, float] = (0.0104, 0.0066, 0.0106)
ICL_READ_NOISE: tuple[float, float, float] = (0.0045, 0.0038, 0.0050)
# simkinect (ankurhanda/simkinect, part of ICL-NUIM): the Kinect's IR camera focal length, projector baseline,
# disparity quantisation and lateral jitter.
KINECT_FOCAL_PX: float = 480.0
KINECT_BASELINE_M: float = 0.075
KINECT_SUBPIXEL: float = 8.0  # disparity quantised to 1/8 px
KINECT_SHIFT_STD_PX: float = 0.5


# ------------------------------------------------------------------------------------------------ response curves
def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1] to linear intensities in [0, 1] (same shape, float)."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding of linear intensities in [0, 1] to values in [0, 1] (same shape, float)."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


@lru_cache(maxsize=4)
def _decode_lut() -> np.ndarray:
    lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    lut.setflags(write=False)
    return lut


def decode_render(rgb: np.ndarray) -> np.ndarray:
    """A renderer's (H, W, 3) uint8 image read as sRGB: (H, W, 3) float32 linear radiance in [0, 1]."""
    return cv2.LUT(np.asarray(rgb, dtype=np.uint8), _decode_lut().reshape(256, 1))  # = lut[rgb], 10x faster


# ------------------------------------------------------------------------------------------------------ vignetting
def vignette(intrinsics: Intrinsics, corner: float) -> np.ndarray:
    """(H, W) float32 relative irradiance, 1 at the principal point and ``corner`` at the farthest image corner.

    cos^4-shaped fall-off ``V(rho) = 1 / (1 + a rho^2)^2`` (the cos^4 law of a thin lens, whose tan(theta) grows
    linearly with the distance from the principal point), rho = distance / the farthest corner's distance, and
    ``a = corner^(-1/2) - 1`` so that V(1) = corner.
    """
    K = intrinsics
    u = np.arange(K.width, dtype=np.float64) - K.cx
    v = np.arange(K.height, dtype=np.float64) - K.cy
    r2 = u[None, :] ** 2 + v[:, None] ** 2
    corners = [(x - K.cx) ** 2 + (y - K.cy) ** 2 for x in (-0.5, K.width - 0.5) for y in (-0.5, K.height - 0.5)]
    a = corner**-0.5 - 1.0
    return (1.0 / (1.0 + a * r2 / max(corners)) ** 2).astype(np.float32)


# ------------------------------------------------------------------------------------------------------ distortion
def distortion_maps(intrinsics: Intrinsics, distortion: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` that turn a pinhole render into the distorted image of the same K.

    For each pixel (u, v) of the distorted image: the pinhole pixel ``K undistort(K^-1 (u, v))`` to read, computed
    with ``cv2.undistortPoints`` (OpenCV radial-tangential model, iterative inverse). Returns ``(map_u, map_v)``,
    each (H, W) float32. Back to a pinhole image: :meth:`sim_envs.camera.CameraModel.undistort_maps`.
    """
    K = intrinsics
    u, v = np.meshgrid(np.arange(K.width, dtype=np.float64), np.arange(K.height, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
    und = cv2.undistortPoints(pts, K.K, np.asarray(distortion, dtype=np.float64), P=K.K)
    und = und.reshape(K.height, K.width, 2).astype(np.float32)
    return np.ascontiguousarray(und[..., 0]), np.ascontiguousarray(und[..., 1])


# ------------------------------------------------------------------------------------ exposure timing over the rows
def row_times(height: int, readout_s: float) -> np.ndarray:
    """(H,) float64 centre of each sensor row's exposure relative to the frame's timestamp:
    ``readout_s * (r / (H - 1) - 1/2)`` (the middle row at the timestamp, rows read top to bottom)."""
    if height < 2 or readout_s == 0:
        return np.zeros(height)
    return readout_s * (np.arange(height) / (height - 1) - 0.5)


def row_weights(times: np.ndarray, row_centres: np.ndarray, exposure_s: float, samples: int = 32) -> np.ndarray:
    """(K, H) float32 weights of the K renders at ``times`` for each row: the mean over the row's exposure box
    (width ``exposure_s`` around ``row_centres``) of the linear-interpolation basis functions of ``times`` (a box
    filter through a piecewise-linear signal in time). Each column sums to 1; times outside ``times``' span are
    clamped to it. ``samples`` quadrature points per row."""
    times = np.asarray(times, dtype=np.float64)
    n = times.shape[0]
    if n == 1:
        return np.ones((1, row_centres.shape[0]), dtype=np.float32)
    offsets = (np.arange(samples) + 0.5) / samples - 0.5 if exposure_s > 0 else np.zeros(1)
    tau = row_centres[:, None] + exposure_s * offsets[None, :]  # (H, S)
    pos = np.interp(tau, times, np.arange(n, dtype=np.float64))  # fractional index in the render list
    lo = np.clip(np.floor(pos).astype(int), 0, n - 2)
    frac = pos - lo
    weights = np.zeros((n, row_centres.shape[0]))
    rows = np.broadcast_to(np.arange(row_centres.shape[0])[:, None], tau.shape)
    np.add.at(weights, (lo, rows), 1.0 - frac)
    np.add.at(weights, (lo + 1, rows), frac)
    return (weights / tau.shape[1]).astype(np.float32)


# ----------------------------------------------------------------------------------------------------- depth noise
def kinect_depth(
    depth: np.ndarray,
    rng: np.random.Generator,
    *,
    focal_px: float = KINECT_FOCAL_PX,
    baseline_m: float = KINECT_BASELINE_M,
    shift_std_px: float = KINECT_SHIFT_STD_PX,
    edge_disparity_px: float = 0.5,
) -> np.ndarray:
    """A Kinect-like sensor depth from exact planar depth (H, W) float32 metres (0 = none), after simkinect
    (ankurhanda/simkinect, ICL-NUIM): (H, W) float32 metres, 0 = no measurement. A new array; ``depth`` is not
    changed.

    1. lateral jitter: the depth is resampled at positions shifted by N(0, ``shift_std_px``) per pixel and axis
       (bilinear, as simkinect's ``add_gaussian_shifts``);
    2. disparity ``focal_px * baseline_m / z`` quantised to 1/8 px;
    3. holes at depth edges: where the disparity over a pixel's 3x3 neighbourhood spans more than
       ``edge_disparity_px`` (simkinect uses a 9x9 dot-pattern filter, whose pattern image is not shipped here;
       this keeps its effect of dropping measurements across depth discontinuities), and where there was no depth;
    4. simkinect's final step ``35130 / round(35130 / z_cm + N(0, 1/6) + 0.5)`` with z in centimetres.
    """
    depth = np.asarray(depth, dtype=np.float32)
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    shifts = rng.normal(0.0, shift_std_px, size=(2, h, w)).astype(np.float32)
    map_u = np.clip(u + shifts[0], 0, w - 1)
    map_v = np.clip(v + shifts[1], 0, h - 1)
    jittered = cv2.remap(depth, map_u, map_v, cv2.INTER_LINEAR)
    valid = jittered > 0
    disp = np.where(valid, focal_px * baseline_m / np.where(valid, jittered, 1.0), 0.0)
    disp = np.round(disp * KINECT_SUBPIXEL) / KINECT_SUBPIXEL
    kernel = np.ones((3, 3), np.uint8)
    spread = cv2.dilate(disp.astype(np.float32), kernel) - cv2.erode(disp.astype(np.float32), kernel)
    valid &= (spread <= edge_disparity_px) & (disp > 0)
    z = np.where(valid, focal_px * baseline_m / np.where(valid, disp, 1.0), 0.0)
    z_cm = np.round(z * 100.0)
    noisy = rng.normal(0.0, 1.0 / 6.0, size=(h, w))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 35130.0 / np.round(35130.0 / z_cm + noisy + 0.5) / 100.0
    return np.where(valid & (z_cm > 0) & np.isfinite(out), out, 0.0).astype(np.float32)

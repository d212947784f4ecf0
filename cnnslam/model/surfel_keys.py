"""The global model's voxel keys and measurement weights (CNN-SLAM Sec. 3.5 with Keller et al. 3DV 2013 [11]):
the 64-bit key of a surfel's voxel and normal direction (every key holds at most one surfel, the bound on the
model's size) and Keller et al.'s radial confidence of a pixel. Used by :mod:`cnnslam.model.global_model`, which
re-exports these names.
"""

from __future__ import annotations

import numpy as np

N_NORMAL_DIRECTIONS: int = 6  # +-x, +-y, +-z: the dominant axis of a surfel normal, part of its voxel key
KEY_BITS: int = 20  # bits per voxel coordinate in the 64-bit key: +-2^19 voxels per axis (10 km at 2 cm)
KEY_OFFSET: int = 1 << (KEY_BITS - 1)  # added to voxel coordinates: keys are non-negative


def voxel_keys(positions: np.ndarray, normals: np.ndarray, voxel_size: float) -> np.ndarray:
    """The (N,) int64 hash keys of points (N, 3) metres with normals (N, 3): 20 bits per voxel coordinate and 3 bits
    for the normal's dominant axis and sign (0..5)."""
    vox = np.floor(np.asarray(positions, dtype=np.float64) / voxel_size).astype(np.int64) + KEY_OFFSET
    vox = np.clip(vox, 0, (1 << KEY_BITS) - 1)
    n = np.asarray(normals)
    axis = np.argmax(np.abs(n), axis=1)
    negative = n[np.arange(n.shape[0]), axis] < 0
    direction = (2 * axis + negative).astype(np.int64)
    return (vox[:, 0] << (2 * KEY_BITS + 3)) | (vox[:, 1] << (KEY_BITS + 3)) | (vox[:, 2] << 3) | direction


def radial_confidence(image_size: tuple[int, int], intrinsics: np.ndarray, sigma: float = 0.6) -> np.ndarray:
    """Keller et al.'s measurement confidence alpha = exp(-gamma^2 / (2 sigma^2)) per pixel, (H, W) float32; gamma is
    the pixel's distance from the principal point divided by the distance of the farthest image corner."""
    h, w = image_size
    _, _, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    du = np.arange(w) - cx
    dv = np.arange(h) - cy
    r2 = dv[:, None] ** 2 + du[None, :] ** 2
    corner2 = max(cx, w - 1 - cx) ** 2 + max(cy, h - 1 - cy) ** 2
    return np.exp(-(r2 / max(corner2, 1e-12)) / (2.0 * sigma**2)).astype(np.float32)

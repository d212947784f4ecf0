"""The image pyramid of one frame (LSD-SLAM): grey images halved level by level by 2x2 averaging, their
central-difference gradients and the intrinsics of every level, interleaved per level for the tracking kernel.
Used by tracking (:mod:`cnnslam.track.tracking`, which re-exports these names), refinement and the key-frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import pyramid_intrinsics


@dataclass(frozen=True)
class ImagePyramid:
    """Grey images of one frame at every pyramid level, with central-difference gradients (LSD-SLAM).

    images[l], grad_x[l], grad_y[l]: (H / 2^l, W / 2^l) float32, intensities 0..255 and their derivative per pixel
    (0 on the one-pixel border), strided views into ``stacked``; intrinsics[l]: (4,) float64 [fx, fy, cx, cy] of
    level l; stacked[l]: (H / 2^l, W / 2^l, 3) float32 [I, dI/dx, dI/dy] interleaved, so that the tracking kernel
    reads a pixel's three values from one cache line.
    """

    images: tuple[np.ndarray, ...]
    grad_x: tuple[np.ndarray, ...]
    grad_y: tuple[np.ndarray, ...]
    intrinsics: tuple[np.ndarray, ...]
    stacked: tuple[np.ndarray, ...]

    @property
    def levels(self) -> int:
        return len(self.images)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of level 0."""
        return self.images[0].shape  # type: ignore[return-value]


def to_gray(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB -> (H, W) float32 intensities 0..255 (OpenCV's BT.601 weights)."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise CnnSlamError(f"expected an (H, W, 3) uint8 RGB image, got shape {rgb.shape} dtype {rgb.dtype}")
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)


def central_gradients(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central differences (I(x+1) - I(x-1)) / 2 of an (H, W) float32 image; 0 on the border (LSD-SLAM)."""
    gx = np.zeros_like(image, dtype=np.float32)
    gy = np.zeros_like(image, dtype=np.float32)
    gx[:, 1:-1] = 0.5 * (image[:, 2:] - image[:, :-2])
    gy[1:-1, :] = 0.5 * (image[2:, :] - image[:-2, :])
    return gx, gy


def build_image_pyramid(gray: np.ndarray, intrinsics: np.ndarray, levels: int) -> ImagePyramid:
    """The pyramid of an (H, W) float32 grey image: each level halves the previous by 2x2 averaging (LSD-SLAM).

    H and W must be divisible by 2^(levels - 1).
    """
    gray = np.ascontiguousarray(gray, dtype=np.float32)
    h, w = gray.shape
    if h % (1 << (levels - 1)) or w % (1 << (levels - 1)):
        raise CnnSlamError(f"image size {w}x{h} must be divisible by 2^{levels - 1} for a {levels}-level pyramid")
    images, gxs, gys, intr = [], [], [], []
    img = gray
    for level in range(levels):
        if level:
            img = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA)
        gx, gy = central_gradients(img)
        images.append(img)
        gxs.append(gx)
        gys.append(gy)
        intr.append(pyramid_intrinsics(intrinsics, level))
    # one interleaved array per level; images and gradients are views into it (no second copy is kept)
    stacked = tuple(np.ascontiguousarray(np.stack([i, gx, gy], axis=-1)) for i, gx, gy in zip(images, gxs, gys,
                                                                                               strict=True))
    return ImagePyramid(tuple(s[..., 0] for s in stacked), tuple(s[..., 1] for s in stacked),
                        tuple(s[..., 2] for s in stacked), tuple(intr), stacked)

"""Shared fixtures of the cnnslam tests: an analytic, exactly known textured scene (no OpenGL), and rendered
sequences of the simulated world when its renderer is available.

The analytic room: camera 0 at the origin looking down +z (OpenCV axes, world = camera 0); textured planes for a
back wall at z = 4 m, side walls at x = +-2 m, floor at y = 1.2 m, ceiling at y = -1.5 m and the front face of a box
at z = 2.5 m. Each pixel is ray-cast exactly (2x2 super-sampled), so depth and the image are known to float
precision for any pose.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

INTRINSICS_320 = np.array([240.6, 240.0, 159.5, 119.5])  # the ICL preset at 320x240
SIZE = (240, 320)


def _texture(seed: int, size: int = 512) -> np.ndarray:
    """A multi-scale random texture (float32, 0..255)."""
    rng = np.random.default_rng(seed)
    tex = np.zeros((size, size), np.float32)
    for sigma, amp in ((24.0, 1.0), (8.0, 0.7), (3.0, 0.5), (1.2, 0.35)):
        noise = rng.standard_normal((size, size)).astype(np.float32)
        blurred = cv2.GaussianBlur(noise, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        tex += amp * blurred / blurred.std()
    tex = (tex - tex.min()) / (tex.max() - tex.min())
    return (30 + 200 * tex).astype(np.float32)


class AnalyticRoom:
    """A box room of textured planes, ray-cast exactly. ``render(T_world_cam)`` -> (rgb uint8, depth float32)."""

    # (axis, value, bounds on the other two axes as ((lo, hi), (lo, hi)) or None, texture seed)
    PLANES = (
        (2, 4.0, None, 1),
        (0, -2.0, None, 2),
        (0, 2.0, None, 3),
        (1, 1.2, None, 4),
        (1, -1.5, None, 5),
        (2, 2.5, ((-0.6, 0.3), (-0.3, 0.7)), 6),
    )
    TEXELS_PER_M = 120.0

    def __init__(self, intrinsics: np.ndarray = INTRINSICS_320, size: tuple[int, int] = SIZE,
                 texture_scale: float = 1.0) -> None:
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64)
        self.size = size
        self.textures = {seed: _texture(seed) for *_, seed in self.PLANES}
        self.texel_scale = self.TEXELS_PER_M * texture_scale

    def render(self, T_world_cam: np.ndarray, supersample: int = 2) -> tuple[np.ndarray, np.ndarray]:
        h, w = self.size
        s = supersample
        fx, fy, cx, cy = self.intrinsics
        us = (np.arange(w * s) + 0.5) / s - 0.5
        vs = (np.arange(h * s) + 0.5) / s - 0.5
        U, V = np.meshgrid(us, vs)
        rays_cam = np.stack([(U - cx) / fx, (V - cy) / fy, np.ones_like(U)], axis=-1)
        R, o = T_world_cam[:3, :3], T_world_cam[:3, 3]
        rays = rays_cam @ R.T
        best_t = np.full(U.shape, np.inf)
        intensity = np.zeros(U.shape, np.float32)
        for axis, value, bounds, seed in self.PLANES:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (value - o[axis]) / rays[..., axis]
            p = o + t[..., None] * rays
            others = [a for a in range(3) if a != axis]
            ok = np.isfinite(t) & (t > 1e-6)
            if bounds is not None:
                for a, (lo, hi) in zip(others, bounds, strict=True):
                    ok &= (p[..., a] >= lo) & (p[..., a] <= hi)
            closer = ok & (t < best_t)
            if not closer.any():
                continue
            tex = self.textures[seed]
            tu = (p[..., others[0]] * self.texel_scale).astype(np.float32)
            tv = (p[..., others[1]] * self.texel_scale).astype(np.float32)
            tu = np.where(closer, tu, 0).astype(np.float32)
            tv = np.where(closer, tv, 0).astype(np.float32)
            size = tex.shape[0]
            sampled = cv2.remap(tex, np.mod(tu, size), np.mod(tv, size), cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_WRAP)
            intensity = np.where(closer, sampled, intensity)
            best_t = np.where(closer, t, best_t)
        img = cv2.resize(intensity, (w, h), interpolation=cv2.INTER_AREA)
        # planar depth at the pixel centre (ray z = 1 in the camera): a second, non-super-sampled pass
        if s != 1:
            _, depth = self.render(T_world_cam, supersample=1)
        else:
            depth = np.where(np.isfinite(best_t), best_t, 0.0).astype(np.float32)
        rgb = np.repeat(np.clip(np.rint(img), 0, 255).astype(np.uint8)[..., None], 3, axis=2)
        return rgb, depth.astype(np.float32)


def pose(t: tuple[float, float, float] = (0, 0, 0), rotvec_deg: tuple[float, float, float] = (0, 0, 0)) -> np.ndarray:
    """A (4, 4) T_world_cam from a translation (m) and a rotation vector (degrees)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


@pytest.fixture(scope="session")
def room() -> AnalyticRoom:
    return AnalyticRoom()


AnalyticRoom.pose = staticmethod(pose)  # tests reach the pose helper through the fixture


@pytest.fixture(scope="session")
def room_sequence(room: AnalyticRoom) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """24 frames of a camera sliding sideways (1.5 cm per frame) and panning in the analytic room:
    (rgb, depth, T_world_cam) per frame."""
    frames = []
    for k in range(24):
        T = pose((0.015 * k, -0.003 * k, 0.004 * k), (0.05 * k, -0.15 * k, 0.0))
        rgb, depth = room.render(T, supersample=1)
        frames.append((rgb, depth, T))
    return frames

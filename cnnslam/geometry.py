"""Rigid-body geometry of CNN-SLAM: SE(3) exp/log, the projection of eq. 3, the vertex map of eq. 4, and warps.

Conventions: camera x right, y down, z forward (OpenCV); pixel (u, v) = (column, row) with pixel centres at
integers; poses are (4, 4) float64 and named by their frames: ``T_a_b`` maps b-coordinates into a-coordinates
(``T_kf_cur`` maps current-camera points into the key-frame's camera). Twists ``xi`` are (6,) float64
``[v (translation), w (rotation vector)]`` (Sophus' order, as in LSD-SLAM) and act by left multiplication:
``T_new = se3_exp(xi) @ T``. Depth is metric planar z (metres, float32), 0 = no estimate.

Rotations go through :class:`scipy.spatial.transform.Rotation` (rotation vector <-> matrix); the rest is numpy. One
twist at a time (the tracking loops' case), :func:`se3_exp` runs a compiled copy of the same arithmetic.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

from slamcommon.fused import fma as _fma  # a * b + c rounded once, as the BLAS kernels behind numpy's 3x3 matmul sum
from slamcommon.se3 import relative_pose, se3_inverse  # noqa: F401 - the shared definitions, re-exported

_SMALL_ANGLE = 1e-2  # rad; below this the series of V and V^-1 are used (error < 1e-17 there) (ours)


def intrinsics_matrix(intrinsics: np.ndarray) -> np.ndarray:
    """The (3, 3) float64 K of ``[fx, fy, cx, cy]`` (pixels)."""
    fx, fy, cx, cy = (float(x) for x in np.asarray(intrinsics, dtype=np.float64).reshape(4))
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def pyramid_intrinsics(intrinsics: np.ndarray, level: int) -> np.ndarray:
    """``[fx, fy, cx, cy]`` (float64) of pyramid level ``level`` (each level halves the image by 2x2 averaging).

    f' = f / 2^level and c' = (c + 0.5) / 2^level - 0.5, so that pixel centres stay at integers.
    """
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    s = 0.5**level
    return np.array([fx * s, fy * s, (cx + 0.5) * s - 0.5, (cy + 0.5) * s - 0.5])


def hat(w: np.ndarray) -> np.ndarray:
    """The skew-symmetric (..., 3, 3) matrix of (..., 3) vectors: ``hat(w) @ p == cross(w, p)``."""
    w = np.asarray(w, dtype=np.float64)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def _v_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(1 - cos t) / t^2 (as 2 sin^2(t/2) / t^2, free of cancellation) and (t - sin t) / t^3 (its series below
    ``_SMALL_ANGLE``)."""
    small = theta < _SMALL_ANGLE
    t = np.where(theta > 0, theta, 1.0)
    t2 = theta**2
    a = np.where(theta > 0, 2.0 * np.sin(0.5 * t) ** 2 / t**2, 0.5)
    b = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2**2 / 5040.0, (t - np.sin(t)) / t**3)
    return a, b


@njit(cache=True, nogil=True, inline="always")
def _v_row_term(W, a, b, xi, i, j):  # pragma: no cover - compiled
    """V[i, j] v[j], V = I + a W + b W^2 with W^2[i, j] fused as BLAS sums it."""
    ww = _fma(W[i, 2], W[2, j], _fma(W[i, 1], W[1, j], W[i, 0] * W[0, j]))
    return (((1.0 if i == j else 0.0) + a * W[i, j]) + b * ww) * xi[j]


@njit(cache=True, nogil=True)
def _se3_exp_one(xi):  # pragma: no cover - compiled
    """:func:`se3_exp` of one twist (6,) with a rotation below ``_SMALL_ANGLE`` (V's series: numpy's power, whose
    last bit is its own, is not needed), the same operations in the same order as the numpy path and scipy's
    from_rotvec / as_matrix (W^2 as BLAS sums it, fused; V v as einsum sums it), so the same bits where numpy's
    kernels are those (tests: within 2 ulp anywhere)."""
    w0, w1, w2 = xi[3], xi[4], xi[5]
    theta = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if theta > 0:  # _v_coefficients
        s = math.sin(0.5 * theta)
        a = 2.0 * (s * s) / (theta * theta)
    else:
        a = 0.5
    t2 = theta * theta
    b = 1.0 / 6.0 - t2 / 120.0 + (t2 * t2) / 5040.0  # the series: callers pass theta < _SMALL_ANGLE only
    W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
    T = np.zeros((4, 4))
    for i in range(3):
        # row i of V times v, summed in einsum's order (0, 2, 1)
        T[i, 3] = (_v_row_term(W, a, b, xi, i, 0) + _v_row_term(W, a, b, xi, i, 2)) + _v_row_term(W, a, b, xi, i, 1)
    if theta <= 1e-3:  # scipy's from_rotvec: the quaternion
        ang2 = theta * theta
        scale = 0.5 - ang2 / 48.0 + ang2 * ang2 / 3840.0
    else:
        scale = math.sin(theta / 2.0) / theta
    x, y, z, w = scale * w0, scale * w1, scale * w2, math.cos(theta / 2.0)
    x2, y2, z2, ww2 = x * x, y * y, z * z, w * w  # scipy's as_matrix
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    T[0, 0] = x2 - y2 - z2 + ww2
    T[1, 0] = 2.0 * (xy + zw)
    T[2, 0] = 2.0 * (xz - yw)
    T[0, 1] = 2.0 * (xy - zw)
    T[1, 1] = -x2 + y2 - z2 + ww2
    T[2, 1] = 2.0 * (yz + xw)
    T[0, 2] = 2.0 * (xz + yw)
    T[1, 2] = 2.0 * (yz - xw)
    T[2, 2] = -x2 - y2 + z2 + ww2
    T[3, 3] = 1.0
    return T


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """SE(3) exponential: (..., 6) twists ``[v, w]`` -> (..., 4, 4) float64 rigid transforms.

    R = exp(hat(w)) (scipy Rotation.from_rotvec), t = V v with V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2.
    """
    xi = np.asarray(xi, dtype=np.float64)
    if xi.shape == (6,) and math.sqrt(xi[3] * xi[3] + xi[4] * xi[4] + xi[5] * xi[5]) < _SMALL_ANGLE:
        return _se3_exp_one(xi)  # |w| as np.linalg.norm sums it
    batch = xi.shape[:-1]
    flat = xi.reshape(-1, 6)
    w = flat[:, 3:]
    theta = np.linalg.norm(w, axis=1)
    W = hat(w)
    a, b = _v_coefficients(theta)
    V = np.eye(3) + a[:, None, None] * W + b[:, None, None] * (W @ W)
    T = np.zeros((flat.shape[0], 4, 4))
    T[:, :3, :3] = Rotation.from_rotvec(w).as_matrix()
    T[:, :3, 3] = np.einsum("nij,nj->ni", V, flat[:, :3])
    T[:, 3, 3] = 1.0
    return T.reshape(batch + (4, 4))


def se3_log(T: np.ndarray) -> np.ndarray:
    """SE(3) logarithm: (..., 4, 4) rigid transforms -> (..., 6) float64 twists ``[v, w]`` (inverse of se3_exp).

    w = log(R) (scipy Rotation.as_rotvec, |w| <= pi), v = V^-1 t with
    V^-1 = I - W/2 + (1 - t sin t / (2 (1 - cos t))) / t^2 W^2.
    """
    T = np.asarray(T, dtype=np.float64)
    batch = T.shape[:-2]
    flat = T.reshape(-1, 4, 4)
    w = Rotation.from_matrix(flat[:, :3, :3]).as_rotvec()
    theta = np.linalg.norm(w, axis=1)
    W = hat(w)
    small = theta < _SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta**2
    c = np.where(small, 1.0 / 12.0 + t2 / 720.0 + t2**2 / 30240.0,
                 (1.0 - t * np.sin(t) / (4.0 * np.sin(0.5 * t) ** 2)) / t**2)
    V_inv = np.eye(3) - 0.5 * W + c[:, None, None] * (W @ W)
    v = np.einsum("nij,nj->ni", V_inv, flat[:, :3, 3])
    return np.concatenate([v, w], axis=1).reshape(batch + (6,))


def adjoint(T_a_b: np.ndarray) -> np.ndarray:
    """The (..., 6, 6) adjoint of (..., 4, 4) transforms for twists [v, w]: [[R, hat(t) R], [0, R]].

    exp(Ad(T) xi) = T exp(xi) T^-1.
    """
    T_a_b = np.asarray(T_a_b, dtype=np.float64)
    R = T_a_b[..., :3, :3]
    out = np.zeros(T_a_b.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = hat(T_a_b[..., :3, 3]) @ R
    return out


def rotation_angle_deg(T: np.ndarray) -> float:
    """Angle of the rotation part of a (4, 4) transform, degrees."""
    return float(np.degrees(np.linalg.norm(Rotation.from_matrix(np.asarray(T)[:3, :3]).as_rotvec())))


def orthonormalize(T: np.ndarray) -> np.ndarray:
    """The nearest rigid transform of a (4, 4) matrix whose rotation block drifted (SVD projection)."""
    T = np.array(T, dtype=np.float64)
    U, _, Vt = np.linalg.svd(T[:3, :3])
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    T[:3, :3] = R
    T[3] = [0.0, 0.0, 0.0, 1.0]
    return T


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """(..., 3) points in b-coordinates -> a-coordinates with ``T_a_b`` (4, 4)."""
    T_a_b = np.asarray(T_a_b, dtype=np.float64)
    return np.asarray(points_b) @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def perspective_projection(points: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 3: pi([x y z]^T) = (x / z, y / z)^T for (..., 3) points; returns (..., 2).

    Points with z <= 0 give non-finite or meaningless values: callers mask them (``points[..., 2] > 0``).
    """
    points = np.asarray(points, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return points[..., :2] / points[..., 2:3]


def project_to_pixels(points_cam: np.ndarray, intrinsics: np.ndarray) -> np.ndarray:
    """pi(K p) of eq. 2, 3 and 6: (..., 3) camera points -> (..., 2) pixel coordinates (u, v), float64."""
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return perspective_projection(np.asarray(points_cam, dtype=np.float64) @ K.T)


def pixel_rays(image_size: tuple[int, int], intrinsics: np.ndarray) -> np.ndarray:
    """K^-1 u_dot for every pixel: (H, W, 3) float64 rays with z = 1 (u_dot = (u, v, 1), pixel centres at integers)."""
    h, w = image_size
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    u = (np.arange(w, dtype=np.float64) - cx) / fx
    v = (np.arange(h, dtype=np.float64) - cy) / fy
    rays = np.ones((h, w, 3))
    rays[..., 0] = u[None, :]
    rays[..., 1] = v[:, None]
    return rays


def vertex_map(depth: np.ndarray, intrinsics: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 4: V(u) = K^-1 u_dot D(u), the 3D point of every pixel in its camera's coordinates.

    depth: (H, W) metres (0 = none). Returns (H, W, 3) float64 metres; pixels without depth get (0, 0, 0).
    """
    depth = np.asarray(depth, dtype=np.float64)
    return pixel_rays(depth.shape, intrinsics) * depth[..., None]


def sample_nearest(image: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-pixel lookup of ``image`` (H, W) at (..., 2) positions (u, v).

    Returns (values (...), inside (...) bool); values are 0 where the position rounds outside the image. Depth maps
    are sampled this way so that no value is blended across a depth edge.
    """
    h, w = image.shape[:2]
    uv = np.asarray(uv, dtype=np.float64)
    finite = np.isfinite(uv).all(axis=-1)
    ui = np.rint(np.where(finite, uv[..., 0], -1.0))
    vi = np.rint(np.where(finite, uv[..., 1], -1.0))
    inside = finite & (ui >= 0) & (ui <= w - 1) & (vi >= 0) & (vi <= h - 1)
    ui = np.where(inside, ui, 0).astype(np.intp)
    vi = np.where(inside, vi, 0).astype(np.intp)
    values = np.where(inside, image[vi, ui], 0)
    return values, inside


def warp_keyframe_pixels(
    depth_i: np.ndarray, intrinsics: np.ndarray, T_j_i: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel of key-frame i lands in camera j: v = pi(K T_j_i V_i(u)) (the warp of eq. 2, 6 and 7).

    depth_i: (H, W) metres, 0 = none; T_j_i: (4, 4) maps i-coordinates into j-coordinates. Returns
    (uv_j (H, W, 2) float64 pixel positions in j, z_j (H, W) float64 depth of the point in j); pixels without
    depth or behind camera j get uv = NaN.
    """
    points_j = transform_points(T_j_i, vertex_map(depth_i, intrinsics))
    z_j = points_j[..., 2]
    uv = project_to_pixels(points_j, intrinsics)
    bad = (np.asarray(depth_i) <= 0) | ~(z_j > 1e-9)
    uv[bad] = np.nan
    return uv, z_j


def depth_of_neighbour_in(
    depth_i: np.ndarray, depth_j: np.ndarray, intrinsics: np.ndarray, T_j_i: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each pixel u of key-frame i, key-frame j's surface point at v = pi(K T_j_i V_i(u)), seen from i.

    This is the warped neighbour depth of CNN-SLAM eq. 6-8. The paper writes D_kj(v); we return that point's depth
    in i's camera (z of T_i_j V_j(v)), which equals D_kj(v) when the key-frames differ by a rotation only and is
    what LSD-SLAM's depth propagation uses, so that a forward motion does not read as a depth disagreement.

    depth_i, depth_j: (H, W) metres (0 = none); T_j_i: (4, 4). Returns (depth_j_in_i (H, W) float64 metres,
    depth_j_at_v (H, W) float64 metres = D_kj(v), valid (H, W) bool: v inside j's image with depth in both).
    """
    uv, _ = warp_keyframe_pixels(depth_i, intrinsics, T_j_i)
    d_j_at_v, inside = sample_nearest(np.asarray(depth_j, dtype=np.float64), uv)
    valid = inside & (d_j_at_v > 0)
    u = np.nan_to_num(uv[..., 0], nan=0.0)
    v = np.nan_to_num(uv[..., 1], nan=0.0)
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    # The neighbour's point on the ray through v at depth D_kj(v), in j's camera, then in i's.
    p_j = np.stack([(u - cx) / fx * d_j_at_v, (v - cy) / fy * d_j_at_v, d_j_at_v], axis=-1)
    z_in_i = transform_points(se3_inverse(T_j_i), p_j)[..., 2]
    valid &= z_in_i > 0
    return np.where(valid, z_in_i, 0.0), np.where(valid, d_j_at_v, 0.0), valid

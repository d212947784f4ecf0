"""Camera pose estimation against a key-frame (CNN-SLAM Sec. 3.1, eq. 1-4), in LSD-SLAM's SE3Tracker manner.

The pose ``T_kf_cur`` (current-camera coordinates into the key-frame's) minimises eq. 1, the Huber norm of the
photometric residuals of eq. 2 normalised by their standard deviation, over the key-frame pixels with a high
intensity gradient (3x3 max of |grad I| >= 5, LSD-SLAM) and a depth. The residual variance is LSD-SLAM's
``sigma_I^2 + var(D) (dr/dD)^2``: photometric noise plus the key-frame's depth variance propagated through the warp.
The minimisation is Levenberg-Marquardt on an image pyramid, coarse to fine, with LSD-SLAM's constants
(:class:`cnnslam.config.TrackingConfig`); the world pose follows as T_world_cur = T_world_kf T_kf_cur (the paper's
T_t = T_t^ki T_ki in our direction convention).

Tracking quality is LSD-SLAM's: the share of "good" residuals (r^2 < 40^2 + 0.5^2 |grad I|^2) among those computed,
and their number relative to the image size; plus (ours) eq. 1's energy per point, which must be well below that
of the key-frame's own contrast (``TrackingConfig.max_energy_ratio``). A frame failing any bound is reported lost.

Hot loops are numba kernels (``@njit(cache=True, nogil=True)``) that fuse eq. 2-4 with the accumulation of the
normal equations, in vectorised blocks (:func:`_normal_equations_core`); :func:`photometric_residual`,
:func:`residual_variance` and :func:`tracking_energy` are the plain numpy forms of the same equations (used for
key-frame-level checks and in the tests against the kernel).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from cnnslam.config import TrackingConfig
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import (
    orthonormalize,
    project_to_pixels,
    se3_exp,
    se3_inverse,
    transform_points,
    vertex_map,
)
from cnnslam.track.pyramid import (
    ImagePyramid as ImagePyramid,  # re-exported: the pyramid's home is cnnslam.track.pyramid
)
from cnnslam.track.pyramid import build_image_pyramid as build_image_pyramid
from cnnslam.track.pyramid import central_gradients as central_gradients
from cnnslam.track.pyramid import to_gray as to_gray

# ------------------------------------------------------------------------------------------- the key-frame reference


@dataclass(frozen=True)
class ReferenceLevel:
    """Key-frame points used for tracking at one pyramid level.

    points: (N, 3) float32 metres in key-frame coordinates (eq. 4's vertex map at the selected pixels);
    intensity: (N,) float32 key-frame intensities I_kf(u); depth_variance: (N,) float32 m^2; pixel count of the
    level: ``n_pixels``; null_energy: eq. 1's energy per point of the intensities about their median with
    sigma = sigma_I (what an alignment that explains nothing would leave; the scale of the lost-frame test).
    """

    points: np.ndarray
    intensity: np.ndarray
    depth_variance: np.ndarray
    n_pixels: int
    null_energy: float


@dataclass(frozen=True)
class TrackingReference:
    """What a frame is tracked against: a key-frame's high-gradient pixels with depth, per pyramid level.

    levels[l]: :class:`ReferenceLevel`; mean_inverse_depth: 1/m over the level-0 points (LSD's meanIdepth, used by
    the key-frame score).
    """

    levels: tuple[ReferenceLevel, ...]
    mean_inverse_depth: float


@njit(cache=True, nogil=True, error_model="numpy")
def _downsample_depth(depth: np.ndarray, variance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2x2 down-sampling of depth (m) and depth variance (m^2) in inverse depth, weighted by inverse-depth
    information (LSD-SLAM's idepth pyramid). 0 depth = none; a block without depth stays 0."""
    h, w = depth.shape[0] // 2, depth.shape[1] // 2
    out_d = np.zeros((h, w), np.float32)
    out_v = np.zeros((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            info_sum = 0.0
            id_sum = 0.0
            n = 0
            for dy in range(2):
                for dx in range(2):
                    d = depth[2 * y + dy, 2 * x + dx]
                    var = variance[2 * y + dy, 2 * x + dx]
                    if d > 0.0 and var > 0.0 and np.isfinite(var):
                        idep = 1.0 / d
                        id_var = var * idep**4
                        info_sum += 1.0 / id_var
                        id_sum += idep / id_var
                        n += 1
            if n > 0:
                idep = id_sum / info_sum
                id_var = n / info_sum
                out_d[y, x] = 1.0 / idep
                out_v[y, x] = id_var / idep**4
    return out_d, out_v


def gradient_masks(pyramid: ImagePyramid, min_gradient: float) -> tuple[np.ndarray, ...]:
    """Per level, (H_l, W_l) bool: the 3x3 max of |grad I| reaches ``min_gradient`` (LSD-SLAM's pixel selection).
    They depend on the image only, so a key-frame computes them once."""
    kernel = np.ones((3, 3), np.uint8)
    masks = []
    for gx, gy in zip(pyramid.grad_x, pyramid.grad_y, strict=True):
        masks.append(cv2.dilate(np.sqrt(gx * gx + gy * gy), kernel) >= min_gradient)
    return tuple(masks)


@njit(cache=True, nogil=True, error_model="numpy")
def _select_points(depth: np.ndarray, variance: np.ndarray, image: np.ndarray, mask: np.ndarray, intr: np.ndarray,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (N, 3), intensities (N,) and depth variances (N,) of the masked pixels with depth (eq. 4)."""
    h, w = depth.shape
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    n = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x] and depth[y, x] > 0.0 and variance[y, x] > 0.0 and np.isfinite(variance[y, x]):
                n += 1
    points = np.empty((n, 3), np.float32)
    intensity = np.empty(n, np.float32)
    var = np.empty(n, np.float32)
    k = 0
    for y in range(h):
        for x in range(w):
            d = depth[y, x]
            if mask[y, x] and d > 0.0 and variance[y, x] > 0.0 and np.isfinite(variance[y, x]):
                points[k, 0] = (x - cx) / fx * d
                points[k, 1] = (y - cy) / fy * d
                points[k, 2] = d
                intensity[k] = image[y, x]
                var[k] = variance[y, x]
                k += 1
    return points, intensity, var


def build_tracking_reference(
    pyramid: ImagePyramid, depth: np.ndarray, variance: np.ndarray, config: TrackingConfig,
    masks: tuple[np.ndarray, ...] | None = None,
) -> TrackingReference:
    """The tracking points of a key-frame: pixels with depth whose 3x3 max of |grad I| reaches
    ``config.min_gradient`` (LSD-SLAM), at every pyramid level.

    pyramid: the key-frame's :class:`ImagePyramid`; depth: (H, W) float32 metres (0 = none); variance: (H, W)
    float32 depth variance m^2 (the key-frame's uncertainty map U); masks: :func:`gradient_masks` of the pyramid
    (computed here when not given).
    """
    if masks is None:
        masks = gradient_masks(pyramid, config.min_gradient)
    depth_l = np.ascontiguousarray(depth, dtype=np.float32)
    var_l = np.ascontiguousarray(np.where(depth_l > 0, variance, 0), dtype=np.float32)
    levels = []
    for level in range(pyramid.levels):
        if level:
            depth_l, var_l = _downsample_depth(depth_l, var_l)
        points, intensity, var = _select_points(depth_l, var_l, pyramid.images[level], masks[level],
                                                pyramid.intrinsics[level])
        null = (float(np.mean(huber((intensity - np.median(intensity)) / np.sqrt(config.photometric_variance),
                                    config.huber_threshold))) if intensity.size else 0.0)
        levels.append(ReferenceLevel(points=points, intensity=intensity, depth_variance=var,
                                     n_pixels=int(depth_l.size), null_energy=null))
    d0 = levels[0].points[:, 2]
    mean_idepth = float(np.mean(1.0 / d0)) if d0.size else 1.0
    return TrackingReference(tuple(levels), mean_idepth)


# ---------------------------------------------------------------------------------- the equations, in numpy form


def bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples of an (H, W) float32 image at (N, 2) float positions (u, v) (OpenCV remap, border 0)."""
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    n = uv.shape[0]
    cols = 1024  # cv2.remap needs maps narrower than 32767
    rows = max(1, -(-n // cols))
    padded = np.zeros((rows * cols, 2), np.float32)
    padded[:n] = uv
    padded = padded.reshape(rows, cols, 2)
    out = cv2.remap(image, padded[..., 0], padded[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=0)
    return out.reshape(-1)[:n]


def photometric_residual(
    image_kf: np.ndarray,
    depth_kf: np.ndarray,
    image_cur: np.ndarray,
    intrinsics: np.ndarray,
    T_cur_kf: np.ndarray,
    pixels: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CNN-SLAM eq. 2: r(u, T) = I_kf(u) - I_cur(pi(K T V_kf(u))) at the given key-frame pixels.

    image_kf, image_cur: (H, W) float32 intensities; depth_kf: (H, W) metres; T_cur_kf: (4, 4) maps key-frame
    coordinates into the current camera's (the inverse of T_kf_cur); pixels: (N, 2) int (u, v) key-frame pixels.
    Returns (r (N,) float64, uv_cur (N, 2) float64 warped positions, valid (N,) bool: inside the current image,
    with depth, in front of the camera).
    """
    pixels = np.asarray(pixels, dtype=np.intp)
    u, v = pixels[:, 0], pixels[:, 1]
    points_kf = vertex_map(depth_kf, intrinsics)[v, u]  # eq. 4
    points_cur = transform_points(T_cur_kf, points_kf)
    uv = project_to_pixels(points_cur, intrinsics)  # eq. 3
    h, w = image_cur.shape
    valid = (depth_kf[v, u] > 0) & (points_cur[:, 2] > 0) & np.isfinite(uv).all(axis=1)
    valid &= (uv[:, 0] > 1) & (uv[:, 0] < w - 2) & (uv[:, 1] > 1) & (uv[:, 1] < h - 2)
    r = image_kf[v, u].astype(np.float64) - bilinear(image_cur, np.where(valid[:, None], uv, 0.0))
    return np.where(valid, r, 0.0), uv, valid


def residual_variance(
    grad_cur: np.ndarray,
    points_cur: np.ndarray,
    depth_kf: np.ndarray,
    depth_variance: np.ndarray,
    t_cur_kf: np.ndarray,
    intrinsics: np.ndarray,
    photometric_variance: float,
) -> np.ndarray:
    """sigma(r)^2 of CNN-SLAM eq. 1 as in LSD-SLAM [4]: sigma_I^2 + var(D) (dr/dD)^2.

    dr/dD is the change of the residual with the key-frame depth D through the warp:
    g . du/dD with du/dD = (fx (x t_z - t_x z), fy (y t_z - t_y z)) / (D z^2) for the warped point (x, y, z).
    grad_cur: (N, 2) current-image gradient at the warped positions (intensity / px); points_cur: (N, 3) warped
    points in the current camera; depth_kf: (N,) key-frame depth D (m); depth_variance: (N,) m^2; t_cur_kf: (3,)
    translation of T_cur_kf. Returns (N,) float64 variances (intensity^2).
    """
    fx, fy = float(intrinsics[0]), float(intrinsics[1])
    x, y, z = points_cur[:, 0], points_cur[:, 1], points_cur[:, 2]
    tx, ty, tz = t_cur_kf
    denom = depth_kf * z * z
    drdd = (grad_cur[:, 0] * fx * (x * tz - tx * z) + grad_cur[:, 1] * fy * (y * tz - ty * z)) / denom
    return photometric_variance + depth_variance * drdd * drdd


@njit(cache=True, nogil=True)
def _huber(x: np.ndarray, k: float) -> np.ndarray:  # pragma: no cover - compiled
    out = np.empty(x.size, np.float64)
    flat = x.ravel()
    for i in range(x.size):
        a = abs(np.float64(flat[i]))
        out[i] = 0.5 * a * a if a <= k else k * (a - 0.5 * k)
    return out.reshape(x.shape)


def huber(x: np.ndarray, k: float) -> np.ndarray:
    """The Huber norm rho(x) = x^2 / 2 for |x| <= k, k (|x| - k / 2) beyond (eq. 1's rho), element-wise in float64
    (one compiled pass)."""
    return _huber(np.ascontiguousarray(x, dtype=np.float64), float(k))


def tracking_energy(residuals: np.ndarray, variances: np.ndarray, huber_threshold: float) -> float:
    """CNN-SLAM eq. 1: E(T) = sum_u rho(r(u, T) / sigma(r(u, T))) over the used pixels (float)."""
    return float(np.sum(huber(np.asarray(residuals) / np.sqrt(variances), huber_threshold)))


# ------------------------------------------------------------------------------------------------ the numba kernel


# Rows of the per-block work buffer (one flat float64 array, rows _BLOCK apart: constant offsets let the compiler
# see that rows never overlap, so that the per-block loops vectorise without run-time alias checks).
_BLOCK = 256  # points per block: the block's rows (22 x 256 float64, 44 KiB) stay in L1/L2
_R_OK, _R_X, _R_Y, _R_Z, _R_IZ, _R_AU, _R_AV, _R_IC, _R_GX, _R_GY, _R_W, _R_R, _R_WJ, _R_J = range(14)
_ROWS = _R_J + 8


@njit(cache=True, nogil=True, fastmath=True, error_model="numpy", inline="always")
def _accumulate_block(H: np.ndarray, b: np.ndarray, buf: np.ndarray, m: int, n_params: int) -> None:
    """H += sum_i w_i J_i J_i^T, b += sum_i w_i J_i r_i over the first m points of a block (upper triangle of H).
    Each entry is one dot product over the block's points, which the compiler vectorises (DSO's SSE blocks)."""
    B = _BLOCK
    for a in range(n_params):
        for i in range(m):
            buf[_R_WJ * B + i] = buf[_R_W * B + i] * buf[(_R_J + a) * B + i]
        s = 0.0
        for i in range(m):
            s += buf[_R_WJ * B + i] * buf[_R_R * B + i]
        b[a] += s
        for c in range(a, n_params):
            s = 0.0
            for i in range(m):
                s += buf[_R_WJ * B + i] * buf[(_R_J + c) * B + i]
            H[a, c] += s


# One numba kernel over 120 lines on purpose: its per-block passes (warp and projection, bilinear samples, residual,
# variance, weight and Jacobian) share one flat buffer whose constant row offsets let LLVM vectorise each pass
# without alias checks, and it is compiled with fastmath, under which LLVM may reorder sums differently once the
# passes are separate functions: split, every tracked pose's bytes and the kernel's speed would have to be shown
# again. The accumulation, which needs no shared state, is already its own step (:func:`_accumulate_block`).
@njit(cache=True, nogil=True, fastmath=True, error_model="numpy", inline="always")
def _normal_equations_core(
    points: np.ndarray,
    ref_intensity: np.ndarray,
    ref_variance: np.ndarray,
    stacked: np.ndarray,
    T_cur_kf: np.ndarray,
    t_weight: np.ndarray,
    intr: np.ndarray,
    sigma_i2: float,
    var_weight: float,
    huber_k: float,
    max_diff_constant: float,
    max_diff_grad_mult: float,
    gain: float,
    offset: float,
    n_params: int,
) -> tuple[np.ndarray, np.ndarray, float, int, int, int, float]:
    """Eq. 1-4 fused: warp every reference point, compute its residual (eq. 2), its LSD-SLAM variance, its Huber
    weight, and accumulate the Gauss-Newton system H = sum w J^T J, b = sum w J^T r of eq. 1 for a left-multiplied
    twist of T_cur_kf.

    ``t_weight`` (3,) is the translation of T_cur_kf used in the variance's dr/dD. The tracker holds it fixed over
    a pyramid level (the translation the level started from): were it the pose being evaluated, the energy would
    fall merely by growing the translation (a larger translation inflates sigma(r) wherever the depth is uncertain)
    and the minimum would be biased; with it fixed, eq. 1 is a fixed function of the pose within a level, as the
    iteratively re-weighted scheme of LSD-SLAM assumes.

    Brightness (ours, DSO's affine model, :func:`affine_brightness`): the current image is compared as
    ``gain * I_cur + offset``; with ``n_params`` 8 the system also holds the derivatives by log gain and offset
    (``gain * I_cur`` and 1), with 6 (gain 1, offset 0: plain eq. 2) it is the pose's alone.

    Speed (DSO's way, ours in numba): points go in blocks of ``_BLOCK``. Per block, (a) the warp and projection
    and (c) the residual, its variance, the Huber weight and the Jacobian are branch-free loops over rows of one
    flat buffer, which the compiler vectorises (a point behind the camera or outside the image gets a safe pixel and
    weight 0); (b) the bilinear samples are scalar loads (gathers are slow on the CPUs we measured); then each entry
    of H and b is one dot product over the block (:func:`_accumulate_block`). Per-point Jacobians never outlive
    their block. Sums are in another order than a scalar loop's, so figures agree with it to ~1e-14 relative, not
    to the byte.

    Returns (H (n, n), b (n,), energy = sum rho(r / sigma) (eq. 1), points used, good, bad, usage); usage sums
    min(z_kf / z_cur, 1) over the used points (LSD-SLAM's pointUsage numerator).
    """
    B = _BLOCK
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    h, w = stacked.shape[0], stacked.shape[1]
    flat = stacked.reshape(-1)  # [I, dI/dx, dI/dy] per pixel, row-major
    npts = points.shape[0]
    H = np.zeros((n_params, n_params))
    b = np.zeros(n_params)
    buf = np.empty(_ROWS * B)
    K = np.empty(B, np.int64)
    energy = 0.0
    n_used = 0.0
    n_good = 0.0
    usage = 0.0
    r00, r01, r02, t0 = T_cur_kf[0, 0], T_cur_kf[0, 1], T_cur_kf[0, 2], T_cur_kf[0, 3]
    r10, r11, r12, t1 = T_cur_kf[1, 0], T_cur_kf[1, 1], T_cur_kf[1, 2], T_cur_kf[1, 3]
    r20, r21, r22, t2 = T_cur_kf[2, 0], T_cur_kf[2, 1], T_cur_kf[2, 2], T_cur_kf[2, 3]
    tw0, tw1, tw2 = t_weight[0], t_weight[1], t_weight[2]
    umax = w - 2.0
    vmax = h - 2.0
    for start in range(0, npts, B):
        m = min(B, npts - start)
        P = points[start:start + m]
        I_ref = ref_intensity[start:start + m]
        V_ref = ref_variance[start:start + m]
        # (a) warp and project (eq. 3-4), branch-free: a point behind the camera or outside the image gets a safe
        # pixel and weight 0
        for j in range(m):
            px = np.float64(P[j, 0])
            py = np.float64(P[j, 1])
            pz = np.float64(P[j, 2])
            x = r00 * px + r01 * py + r02 * pz + t0
            y = r10 * px + r11 * py + r12 * pz + t1
            z = r20 * px + r21 * py + r22 * pz + t2
            front = z > 1e-6
            zs = z if front else 1.0
            iz = 1.0 / zs
            u = fx * x * iz + cx
            v = fy * y * iz + cy
            ok = front and u > 1.0 and v > 1.0 and u < umax and v < vmax
            uc = u if ok else 2.0
            vc = v if ok else 2.0
            iu = np.int64(uc)
            iv = np.int64(vc)
            buf[_R_OK * B + j] = 1.0 if ok else 0.0
            buf[_R_X * B + j] = x
            buf[_R_Y * B + j] = y
            buf[_R_Z * B + j] = zs
            buf[_R_IZ * B + j] = iz
            buf[_R_AU * B + j] = uc - iu
            buf[_R_AV * B + j] = vc - iv
            K[j] = (iv * w + iu) * 3
        # (b) bilinear samples of [I, dI/dx, dI/dy] at the warped points (scalar loads)
        for j in range(m):
            k0 = K[j]
            k1 = k0 + 3 * w
            au = buf[_R_AU * B + j]
            av = buf[_R_AV * B + j]
            w00 = (1.0 - au) * (1.0 - av)
            w01 = au * (1.0 - av)
            w10 = (1.0 - au) * av
            w11 = au * av
            buf[_R_IC * B + j] = w00 * flat[k0] + w01 * flat[k0 + 3] + w10 * flat[k1] + w11 * flat[k1 + 3]
            buf[_R_GX * B + j] = gain * (w00 * flat[k0 + 1] + w01 * flat[k0 + 4] + w10 * flat[k1 + 1]
                                         + w11 * flat[k1 + 4])
            buf[_R_GY * B + j] = gain * (w00 * flat[k0 + 2] + w01 * flat[k0 + 5] + w10 * flat[k1 + 2]
                                         + w11 * flat[k1 + 5])
        # (c) residual (eq. 2), its variance, Huber weight, energy (eq. 1) and Jacobian, branch-free
        for j in range(m):
            ok = buf[_R_OK * B + j]
            x = buf[_R_X * B + j]
            y = buf[_R_Y * B + j]
            z = buf[_R_Z * B + j]
            iz = buf[_R_IZ * B + j]
            gx = buf[_R_GX * B + j]
            gy = buf[_R_GY * B + j]
            i_cur = buf[_R_IC * B + j]
            pz = np.float64(P[j, 2])
            r = I_ref[j] - (gain * i_cur + offset)  # eq. 2 (with the frame's affine brightness)
            n_used += ok
            usage += ok * min(pz * iz, 1.0)
            n_good += ok if r * r < max_diff_constant + max_diff_grad_mult * (gx * gx + gy * gy) else 0.0
            gxf = gx * fx
            gyf = gy * fy
            # residual variance (LSD-SLAM): sigma_I^2 + var(D) (dr/dD)^2
            drdd = (gxf * (x * tw2 - tw0 * z) + gyf * (y * tw2 - tw1 * z)) * (iz * iz) / pz
            wp = 1.0 / (sigma_i2 + var_weight * V_ref[j] * drdd * drdd)
            nr = abs(r) * np.sqrt(wp)
            inlier = nr <= huber_k
            hw = 1.0 if inlier else huber_k / nr
            energy += ok * (0.5 * nr * nr if inlier else huber_k * (nr - 0.5 * huber_k))
            buf[_R_W * B + j] = ok * hw * wp
            buf[_R_R * B + j] = r
            # J = dI_cur(warp) / dxi for T_cur_kf <- exp(xi) T_cur_kf; the residual's Jacobian is -J
            xz = x * iz
            yz = y * iz
            buf[_R_J * B + j] = gxf * iz
            buf[(_R_J + 1) * B + j] = gyf * iz
            buf[(_R_J + 2) * B + j] = -(gxf * xz + gyf * yz) * iz
            buf[(_R_J + 3) * B + j] = -(gxf * xz * yz + gyf * (1.0 + yz * yz))
            buf[(_R_J + 4) * B + j] = gxf * (1.0 + xz * xz) + gyf * xz * yz
            buf[(_R_J + 5) * B + j] = -gxf * yz + gyf * xz
            buf[(_R_J + 6) * B + j] = gain * i_cur
            buf[(_R_J + 7) * B + j] = 1.0
        _accumulate_block(H, b, buf, m, n_params)
    for a in range(n_params):
        for c in range(a):
            H[a, c] = H[c, a]
    nu = int(n_used)
    ng = int(n_good)
    return H, b, energy, nu, ng, nu - ng, usage


# The core is inlined into one kernel per system size, so that n_params is a compile-time constant: the loops over the
# Jacobian unroll and J stays in registers (a run-time size cost 1.5x per point). Same arithmetic, same bytes.
@njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _normal_equations_pose(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr, sigma_i2,
                           var_weight, huber_k, max_diff_constant, max_diff_grad_mult):
    return _normal_equations_core(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr, sigma_i2,
                                  var_weight, huber_k, max_diff_constant, max_diff_grad_mult, 1.0, 0.0, 6)


@njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _normal_equations_affine(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr, sigma_i2,
                             var_weight, huber_k, max_diff_constant, max_diff_grad_mult, gain, offset):
    return _normal_equations_core(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr, sigma_i2,
                                  var_weight, huber_k, max_diff_constant, max_diff_grad_mult, gain, offset, 8)


def _normal_equations(
    points: np.ndarray, ref_intensity: np.ndarray, ref_variance: np.ndarray, stacked: np.ndarray,
    T_cur_kf: np.ndarray, t_weight: np.ndarray, intr: np.ndarray, sigma_i2: float, var_weight: float,
    huber_k: float, max_diff_constant: float, max_diff_grad_mult: float, gain: float = 1.0, offset: float = 0.0,
    n_params: int = 6,
) -> tuple[np.ndarray, np.ndarray, float, int, int, int, float]:
    """:func:`_normal_equations_core` through the kernel compiled for ``n_params``: 6 (the pose alone, eq. 2 as
    written: gain 1 and offset 0 required) or 8 (the pose and the affine brightness)."""
    if n_params == 6:
        if gain != 1.0 or offset != 0.0:
            raise CnnSlamError(f"the pose-only system (n_params 6) compares I_cur as it is; got gain {gain}, "
                               f"offset {offset}: use n_params 8")
        return _normal_equations_pose(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr,
                                      sigma_i2, var_weight, huber_k, max_diff_constant, max_diff_grad_mult)
    if n_params == 8:
        return _normal_equations_affine(points, ref_intensity, ref_variance, stacked, T_cur_kf, t_weight, intr,
                                        sigma_i2, var_weight, huber_k, max_diff_constant, max_diff_grad_mult,
                                        gain, offset)
    raise CnnSlamError(f"n_params must be 6 (pose) or 8 (pose and affine brightness), got {n_params}")


# ------------------------------------------------------------------------------------------------------ the tracker


@dataclass(frozen=True)
class TrackingResult:
    """The outcome of tracking one frame against one key-frame.

    T_kf_cur: (4, 4) float64, maps current-camera coordinates into the key-frame's. tracked: False when the frame
    is lost (LSD-SLAM's bounds on good residuals, or divergence). good_share: good / (good + bad) residuals at the
    finest level; good_count, bad_count: their numbers; usage: LSD-SLAM's pointUsage (share of key-frame points
    still seen, weighted by depth change); mean_energy: eq. 1's energy per used point at the finest level (the
    "tracking residual" of LSD-SLAM's stereo error model); hessian: (6, 6) float64 Gauss-Newton H at the solution
    (information of T_cur_kf under left perturbation, used by the pose graph); iterations: LM iterations per level
    (finest last); diverged: a level had too few points in the image; affine: the frame's (log gain, offset)
    against the key-frame (:func:`affine_brightness`; (0, 0) when not estimated).
    """

    T_kf_cur: np.ndarray
    tracked: bool
    good_share: float
    good_count: int
    bad_count: int
    usage: float
    mean_energy: float
    hessian: np.ndarray
    iterations: tuple[int, ...]
    diverged: bool
    affine: tuple[float, float] = (0.0, 0.0)


def _evaluate(ref: ReferenceLevel, frame: ImagePyramid, level: int, T_cur_kf: np.ndarray, t_weight: np.ndarray,
              cfg: TrackingConfig, affine: tuple[float, float] | None = None):
    # None: eq. 2 as written, the pose alone (gain 1, offset 0, 6 parameters)
    gain, offset, n_params = (1.0, 0.0, 6) if affine is None else (float(np.exp(affine[0])), float(affine[1]), 8)
    return _normal_equations(
        ref.points, ref.intensity, ref.depth_variance, frame.stacked[level], T_cur_kf, t_weight,
        frame.intrinsics[level], cfg.photometric_variance,
        cfg.depth_variance_weight, cfg.huber_threshold, cfg.max_diff_constant, cfg.max_diff_grad_mult,
        gain, offset, n_params,
    )


def affine_brightness(image: np.ndarray, log_gain: float, offset: float) -> np.ndarray:
    """A frame's intensities in its key-frame's brightness: ``exp(log_gain) * I + offset`` (float32).

    Ours, after DSO's affine brightness model (Engel et al. 2018, eq. 4, without exposure times): between a
    key-frame and a frame an auto-exposure camera changes its gain and offset; eq. 2 then compares
    I_kf(u) with exp(a) I_cur(w(u)) + b, (a, b) estimated with the pose (:func:`track_frame`).
    """
    return np.float32(np.exp(log_gain)) * np.asarray(image, dtype=np.float32) + np.float32(offset)


def pose_information(H: np.ndarray) -> np.ndarray:
    """The (6, 6) information of the pose from an (n, n) Gauss-Newton H whose last n - 6 parameters are nuisance
    (the affine brightness): the Schur complement H_pp - H_pa H_aa^-1 H_ap (H itself when n = 6)."""
    H = np.asarray(H, dtype=np.float64)
    if H.shape[0] == 6:
        return H
    Hpp, Hpa, Haa = H[:6, :6], H[:6, 6:], H[6:, 6:]
    try:
        return Hpp - Hpa @ np.linalg.solve(Haa, Hpa.T)
    except np.linalg.LinAlgError:
        return Hpp


def track_frame(
    reference: TrackingReference,
    frame: ImagePyramid,
    T_kf_cur_init: np.ndarray,
    config: TrackingConfig,
    finest_level: int | None = None,
    affine_init: tuple[float, float] = (0.0, 0.0),
) -> TrackingResult:
    """Estimate ``T_kf_cur`` by minimising eq. 1 coarse to fine with Levenberg-Marquardt (LSD-SLAM's schedule).

    reference: the key-frame's :class:`TrackingReference`; frame: the current :class:`ImagePyramid`;
    T_kf_cur_init: (4, 4) initial guess; finest_level: stop at this level (default ``config.finest_level``; the
    pose graph's key-frame alignment stops earlier); affine_init: (log gain, offset) to start from when
    ``config.affine_brightness`` estimates them with the pose (:func:`affine_brightness`). Never raises on bad
    data: a frame that cannot be tracked comes back with ``tracked=False``.
    """
    finest = config.finest_level if finest_level is None else int(finest_level)
    T = se3_inverse(orthonormalize(T_kf_cur_init))  # T_cur_kf, LSD's referenceToFrame
    affine = (float(affine_init[0]), float(affine_init[1])) if config.affine_brightness else None
    n = 6 if affine is None else 8
    iterations: list[int] = []
    diverged = False
    stats = (np.zeros((n, n)), np.zeros(n), np.inf, 0, 0, 0, 0.0)
    for level in range(len(reference.levels) - 1, finest - 1, -1):
        ref = reference.levels[level]
        min_points = max(6, int(config.min_points_per_all * ref.n_pixels))
        t_weight = T[:3, 3].copy()
        stats = _evaluate(ref, frame, level, T, t_weight, config, affine)
        if stats[3] < min_points:
            diverged = True
            iterations.append(0)
            break
        H, b, energy, n_used = stats[0], stats[1], stats[2] / stats[3], stats[3]
        lam = 0.0
        its = 0
        converged = False
        while its < config.max_iterations[level] and not converged:
            its += 1
            while True:
                A = H.copy()
                A[np.diag_indices(n)] *= 1.0 + lam
                try:
                    inc = np.linalg.solve(A, b)
                except np.linalg.LinAlgError:
                    converged = True
                    break
                T_new = se3_exp(inc[:6]) @ T
                affine_new = None if affine is None else (affine[0] + float(inc[6]), affine[1] + float(inc[7]))
                new_stats = _evaluate(ref, frame, level, T_new, t_weight, config, affine_new)
                n_new = new_stats[3]
                new_energy = new_stats[2] / n_new if n_new >= min_points else np.inf
                if new_energy < energy:
                    ratio = new_energy / energy
                    T, stats, H, b, energy, n_used = T_new, new_stats, new_stats[0], new_stats[1], new_energy, n_new
                    affine = affine_new
                    lam = 0.0 if lam <= config.lambda_first_fail else lam * config.lambda_success_factor
                    if ratio > config.convergence_eps:
                        converged = True
                    break
                # LSD-SLAM's stepSizeMin bounds the pose's update (rad, m); the affine offset is in intensity
                # levels, and in the norm it kept a converged frame rejecting steps until lambda grew ~2^9
                if float(inc[:6] @ inc[:6]) < config.step_size_min:
                    converged = True
                    break
                lam = config.lambda_first_fail if lam == 0.0 else lam * config.lambda_fail_factor
        iterations.append(its)
    _, _, energy_sum, n_used, n_good, n_bad, usage = stats
    finest_ref = reference.levels[finest]
    good_share = n_good / max(n_good + n_bad, 1)
    tracked = (
        not diverged
        and np.isfinite(T).all()
        and good_share >= config.min_good_per_good_bad
        and n_good >= config.min_good_per_all * finest_ref.n_pixels
        and energy_sum / max(n_used, 1) <= max(config.energy_floor, config.max_energy_ratio * finest_ref.null_energy)
    )
    return TrackingResult(
        T_kf_cur=orthonormalize(se3_inverse(T)),
        tracked=bool(tracked),
        good_share=float(good_share),
        good_count=int(n_good),
        bad_count=int(n_bad),
        usage=float(usage / max(finest_ref.points.shape[0], 1)),
        mean_energy=float(energy_sum / max(n_used, 1)),
        hessian=pose_information(stats[0]),
        iterations=tuple(iterations),
        diverged=bool(diverged),
        affine=(0.0, 0.0) if affine is None else affine,
    )

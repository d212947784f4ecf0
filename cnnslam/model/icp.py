"""Projective point-to-plane ICP (KinectFusion, Newcombe et al. ISMAR 2011; the tracking of point-based fusion,
Keller et al. 3DV 2013 [11]) for the Laina baseline: a depth map used as if from an RGB-D sensor.

The reference is a surface seen from a reference camera: per-pixel vertices and normals in that camera's coordinates
(rendered from the global model at the previous pose: frame-to-model tracking; or computed from a depth map:
frame-to-frame). The current frame is a depth map. ``T_ref_cur`` (current-camera coordinates into the reference
camera's) minimises

    E(T) = sum_u rho( n_ref(u')^T (T V_cur(u) - V_ref(u')) ),    u' = pi(K T V_cur(u))  (projective association)

over the current pixels u whose association passes KinectFusion's tests (distance |T V_cur - V_ref| < 10 cm, normal
angle < 20 degrees: the values of PCL's KinectFusion implementation, KinFu). rho is a Huber weight (ours, against the
CNN's depth outliers). Gauss-Newton with the twist
``xi = [v, w]`` acting on the left (``T <- se3_exp(xi) T``, the convention of :mod:`cnnslam.geometry`): the Jacobian
row of a residual is ``[n_ref^T, (T V_cur x n_ref)^T]``. Coarse to fine on a 3-level pyramid (KinFu: 4, 5 and 10
iterations from the coarsest level down). Directions the geometry does not constrain get no update (truncated
eigen-decomposition of the normal equations, ours).

Pyramid levels halve the image by 2x2 averaging of the valid vertices (a block whose depths spread by more than
``max_relative_depth_jump`` is invalid), so level intrinsics follow :func:`cnnslam.geometry.pyramid_intrinsics`.
Normals of a vertex map are cross products of central differences (KinectFusion), oriented towards the camera.

One ICP, its per-pixel work compiled: one numba kernel accumulates the 6x6 normal equations over the pixels in a
single pass (as in :mod:`cnnslam.track.tracking`), and the pyramids are built by kernels too (:func:`depth_pyramid`,
:func:`reference_pyramid`: :func:`depth_surface_pyramid`, :func:`maps_surface_pyramid`). The numpy functions
(:func:`surface_maps_from_depth`, :func:`downsample_surface_maps`, :func:`surface_pyramid`) are the definition the
kernels follow, and the path taken with pre-smoothing; the kernels give the same maps up to float rounding (float32
stays float32 where the numpy form computes in float32, so that masks decided by thresholds agree; sums may be added
in another order), which the tests check.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import orthonormalize, pyramid_intrinsics, se3_exp, vertex_map
from cnnslam.model.surfel_kernels import normal_map_kernel


@dataclass(frozen=True)
class IcpConfig:
    """Projective point-to-plane ICP (KinectFusion's constants as PCL's KinFu sets them, unless marked ours)."""

    # KinFu: a 3-level pyramid, iterations {10, 5, 4} on levels 0 (finest), 1, 2.
    levels: int = 3
    iterations: tuple[int, ...] = (10, 5, 4)
    # KinFu distance threshold 10 cm: an association farther apart is rejected.
    max_distance: float = 0.10
    # KinFu angle threshold 20 degrees: associations whose normals differ more are rejected.
    max_normal_angle_deg: float = 20.0
    # Ours: Huber threshold on the point-to-plane residual (m); CNN depth has outliers at blurred edges.
    huber_delta: float = 0.02
    # Ours: a level stops when the update is below this (|xi|, metres and radians together).
    convergence: float = 1e-6
    # Ours: directions whose Gauss-Newton eigenvalue is below this fraction of the largest are left unchanged
    # (degenerate geometry, e.g. only one wall in view, must not send the pose sliding along it).
    min_eigenvalue_ratio: float = 1e-5
    # Ours: the frame is tracked when at least this share of the finest level's valid current pixels associate ...
    min_inlier_share: float = 0.25
    # ... and at least this many pixels do (6 degrees of freedom need some margin) ...
    min_inliers: int = 200
    # ... and the inliers' RMS point-to-plane residual is below this (m).
    max_rmse: float = 0.05
    # Ours: neighbouring pixels whose depths differ by more than this fraction are a depth edge (no normal there).
    max_relative_depth_jump: float = 0.05
    # KinectFusion bilateral-filters the depth before computing vertices and normals; ours: in log depth, spatial
    # sigma in pixels (0 = off) and range sigma as a fraction of depth (:func:`smooth_depth`).
    smoothing_px: float = 2.0
    smoothing_relative: float = 0.05

    def __post_init__(self) -> None:
        if not 1 <= self.levels <= 6:
            raise CnnSlamError(f"icp.levels must be in 1..6, got {self.levels}")
        if len(self.iterations) != self.levels or min(self.iterations) < 1:
            raise CnnSlamError(
                f"icp.iterations needs one positive count per level ({self.levels}), finest first; got "
                f"{self.iterations}")
        if not (self.smoothing_px >= 0 and self.smoothing_relative > 0):
            raise CnnSlamError(f"icp.smoothing_px must be >= 0 and smoothing_relative > 0, got {self.smoothing_px}, "
                               f"{self.smoothing_relative}")
        for name in ("max_distance", "huber_delta", "convergence", "max_rmse", "max_relative_depth_jump",
                     "min_eigenvalue_ratio"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CnnSlamError(f"icp.{name} must be positive, got {value!r}")
        if not 0 < self.max_normal_angle_deg <= 180:
            raise CnnSlamError(f"icp.max_normal_angle_deg must be in (0, 180], got {self.max_normal_angle_deg}")
        if not 0 <= self.min_inlier_share <= 1 or self.min_inliers < 6:
            raise CnnSlamError(
                f"icp.min_inlier_share must be in [0, 1] and min_inliers >= 6, got {self.min_inlier_share}, "
                f"{self.min_inliers}")


@dataclass(frozen=True)
class SurfaceMaps:
    """A surface seen from one camera at one pyramid level.

    vertices: (H, W, 3) float32 camera coordinates (m); normals: (H, W, 3) float32 unit, facing the camera;
    valid: (H, W) bool (a vertex and a normal exist); intrinsics: (4,) float64 [fx, fy, cx, cy] of this level.
    """

    vertices: np.ndarray
    normals: np.ndarray
    valid: np.ndarray
    intrinsics: np.ndarray


@dataclass(frozen=True)
class IcpResult:
    """The outcome of aligning a depth map to a reference surface.

    T_ref_cur: (4, 4) float64, maps current-camera coordinates into the reference camera's; tracked: the inlier and
    residual bounds of :class:`IcpConfig` hold at the finest level; inliers: associated pixels at the finest level;
    inlier_share: inliers / valid current pixels there; rmse: RMS point-to-plane residual of the inliers (m);
    iterations: Gauss-Newton iterations per level, finest first; hessian: (6, 6) J^T W J at the solution (left
    perturbation of T_ref_cur).
    """

    T_ref_cur: np.ndarray
    tracked: bool
    inliers: int
    inlier_share: float
    rmse: float
    iterations: tuple[int, ...]
    hessian: np.ndarray


# ----------------------------------------------------------------------------------------------- surface maps


def normal_map(vertices: np.ndarray, max_relative_depth_jump: float = 0.05, step: int = 1) -> np.ndarray:
    """Unit normals (H, W, 3) float32 of a vertex map (H, W, 3) (camera coordinates, z = depth, 0 = none).

    n = (V(u + s, v) - V(u - s, v)) x (V(u, v + s) - V(u, v - s)), normalised and flipped to face the camera
    (n . V < 0). Zero where a neighbour lacks depth or differs from the centre by more than
    ``max_relative_depth_jump * step`` of its depth (a depth edge), and on the ``step``-pixel border.
    """
    V = np.asarray(vertices, dtype=np.float32)
    if V.ndim != 3 or V.shape[2] != 3:
        raise CnnSlamError(f"a vertex map must be (H, W, 3), got {V.shape}")
    h, w = V.shape[:2]
    s = int(step)
    out = np.zeros_like(V)
    if h <= 2 * s or w <= 2 * s:
        return out
    z = V[..., 2]
    c = z[s:-s, s:-s]
    left, right = z[s:-s, :-2 * s], z[s:-s, 2 * s:]
    up, down = z[:-2 * s, s:-s], z[2 * s:, s:-s]
    tol = max_relative_depth_jump * s * c
    ok = (c > 0)
    for nb in (left, right, up, down):
        ok &= (nb > 0) & (np.abs(nb - c) <= tol)
    dx = V[s:-s, 2 * s:] - V[s:-s, :-2 * s]
    dy = V[2 * s:, s:-s] - V[:-2 * s, s:-s]
    n = np.cross(dx, dy)
    norm = np.linalg.norm(n, axis=2)
    ok &= norm > 1e-12
    n = n / np.where(ok, norm, 1.0)[..., None]
    flip = np.einsum("ijk,ijk->ij", n, V[s:-s, s:-s]) > 0
    n[flip] *= -1.0
    n[~ok] = 0.0
    out[s:-s, s:-s] = n
    return out


# a raw normal is kept where the mean of its 3x3 neighbours' normals is at least this long
ADAPTIVE_NORMAL_CONSISTENCY: float = 0.98


def adaptive_normal_map(vertices: np.ndarray, smoothed_vertices: np.ndarray, max_relative_depth_jump: float = 0.05,
                        step: int = 2, consistency: float = ADAPTIVE_NORMAL_CONSISTENCY) -> np.ndarray:
    """Normals (H, W, 3) float32 that are sharp where the depth is clean and smoothed where it is noisy (ours).

    The normal of the raw vertex map (:func:`normal_map`, 1-pixel step) is kept where it agrees with its 3x3
    neighbours (the length of their mean unit normal is at least ``consistency``: a plane, also right next to a
    crease); elsewhere (noise, or exactly on a crease) the normal of ``smoothed_vertices`` with ``step`` is used.
    """
    raw = normal_map(vertices, max_relative_depth_jump, 1)
    smooth = normal_map(smoothed_vertices, max_relative_depth_jump, step)
    valid = (raw != 0).any(axis=2)
    mean = cv2.blur(raw, (3, 3), borderType=cv2.BORDER_CONSTANT)
    full = cv2.blur(valid.astype(np.float32), (3, 3), borderType=cv2.BORDER_CONSTANT) > 0.999
    sharp = valid & full & (np.linalg.norm(mean, axis=2) >= consistency)
    return np.where(sharp[..., None], raw, smooth).astype(np.float32)


def smooth_depth(depth: np.ndarray, sigma_px: float, sigma_relative: float) -> np.ndarray:
    """Edge-preserving smoothing of a depth map (H, W) metres (0 = none): a bilateral filter on log depth (spatial
    sigma ``sigma_px`` pixels, range sigma ``sigma_relative``, i.e. relative to depth), pixels without depth kept at
    0 and not smoothed into their neighbours' depth. ``sigma_px`` = 0 returns the depth unchanged."""
    d = np.asarray(depth, dtype=np.float32)
    if sigma_px <= 0:
        return d.copy()
    valid = np.isfinite(d) & (d > 0)
    if not valid.any():
        return np.zeros_like(d)
    log_d = np.where(valid, np.log(np.where(valid, d, 1.0)), 0.0).astype(np.float32)
    # holes get a far-away value (+10 in log depth) so that the range kernel ignores them
    log_d[~valid] = float(log_d[valid].max()) + 10.0
    radius = max(1, int(math.ceil(2.0 * sigma_px)))
    out = cv2.bilateralFilter(log_d, 2 * radius + 1, float(sigma_relative), float(sigma_px))
    return np.where(valid, np.exp(out), 0.0).astype(np.float32)


def surface_maps_from_depth(depth: np.ndarray, intrinsics: np.ndarray, max_relative_depth_jump: float = 0.05,
                            smoothing_px: float = 0.0, smoothing_relative: float = 0.05) -> SurfaceMaps:
    """Vertices (eq. 4, :func:`cnnslam.geometry.vertex_map`) and normals of a depth map (H, W) metres (0 = none),
    after :func:`smooth_depth` with ``smoothing_px`` / ``smoothing_relative`` (0 = no smoothing)."""
    d = np.asarray(depth, dtype=np.float32)
    if d.ndim != 2:
        raise CnnSlamError(f"depth must be (H, W) metres, got {d.shape}")
    d = np.where(np.isfinite(d) & (d > 0), d, 0.0).astype(np.float32)
    d = smooth_depth(d, smoothing_px, smoothing_relative)
    V = vertex_map(d, intrinsics).astype(np.float32)
    N = normal_map(V, max_relative_depth_jump)
    valid = (d > 0) & (np.abs(N).sum(axis=2) > 0)
    return SurfaceMaps(V, N, valid, np.asarray(intrinsics, dtype=np.float64).reshape(4).copy())


def downsample_surface_maps(maps: SurfaceMaps, max_relative_depth_jump: float = 0.05) -> SurfaceMaps:
    """The next pyramid level: 2x2 block means of the valid vertices and normals (renormalised); a block is valid when
    one of its pixels is and the valid depths spread by at most ``max_relative_depth_jump`` of their mean (a sparse
    map, e.g. a splatted model, keeps its coarse levels)."""
    h, w = maps.valid.shape
    h2, w2 = h // 2, w // 2
    V = maps.vertices[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2, 3).astype(np.float64)
    N = maps.normals[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2, 3).astype(np.float64)
    valid = maps.valid[: 2 * h2, : 2 * w2].reshape(h2, 2, w2, 2)
    count = valid.sum(axis=(1, 3))
    ok = count > 0
    z = V[..., 2]
    z_max = np.where(valid, z, -np.inf).max(axis=(1, 3))
    z_min = np.where(valid, z, np.inf).min(axis=(1, 3))
    mean_z = np.where(valid, z, 0.0).sum(axis=(1, 3)) / np.maximum(count, 1)
    ok &= (z_max - z_min) <= max_relative_depth_jump * np.maximum(mean_z, 1e-9)
    Vd = (V * valid[..., None]).sum(axis=(1, 3)) / np.maximum(count, 1)[..., None]
    Nd = (N * valid[..., None]).sum(axis=(1, 3))
    norm = np.linalg.norm(Nd, axis=2)
    ok &= norm > 1e-6
    Nd = Nd / np.where(ok, norm, 1.0)[..., None]
    Vd[~ok] = 0.0
    Nd[~ok] = 0.0
    return SurfaceMaps(Vd.astype(np.float32), Nd.astype(np.float32), ok,
                       pyramid_intrinsics(maps.intrinsics, 1))


def surface_pyramid(maps: SurfaceMaps, levels: int, max_relative_depth_jump: float = 0.05) -> tuple[SurfaceMaps, ...]:
    """``levels`` levels starting with ``maps`` (level 0), each half the size of the previous one."""
    out = [maps]
    for _ in range(1, levels):
        out.append(downsample_surface_maps(out[-1], max_relative_depth_jump))
    return tuple(out)


@njit(cache=True, nogil=True)
def _depth_surface_kernel(depth, fx, fy, cx, cy, tol_factor):  # pragma: no cover - compiled
    """Vertices (eq. 4, float32 of the float64 product), 1-pixel normals and validity of a depth map."""
    h, w = depth.shape
    V = np.zeros((h, w, 3), np.float32)
    for y in range(h):
        ry = (y - cy) / fy
        for x in range(w):
            d = depth[y, x]
            if not (d > 0 and math.isfinite(d)):
                continue
            d64 = np.float64(d)
            V[y, x, 0] = np.float32((x - cx) / fx * d64)
            V[y, x, 1] = np.float32(ry * d64)
            V[y, x, 2] = np.float32(d64)
    N, valid = normal_map_kernel(V, tol_factor)
    return V, N, valid


@njit(cache=True, nogil=True)
def _downsample_kernel(V, N, valid, jump):  # pragma: no cover - compiled
    """:func:`downsample_surface_maps` at once: 2x2 means of the valid vertices and normals (float64 sums)."""
    h2, w2 = valid.shape[0] // 2, valid.shape[1] // 2
    Vd = np.zeros((h2, w2, 3), np.float32)
    Nd = np.zeros((h2, w2, 3), np.float32)
    ok = np.zeros((h2, w2), np.bool_)
    for y in range(h2):
        for x in range(w2):
            count = 0
            z_max, z_min = -np.inf, np.inf
            v0 = v1 = v2 = m0 = m1 = m2 = 0.0
            for dy in range(2):
                for dx in range(2):
                    yy, xx = 2 * y + dy, 2 * x + dx
                    if not valid[yy, xx]:
                        continue
                    count += 1
                    z = np.float64(V[yy, xx, 2])
                    z_max, z_min = max(z_max, z), min(z_min, z)
                    v0 += V[yy, xx, 0]
                    v1 += V[yy, xx, 1]
                    v2 += z
                    m0 += N[yy, xx, 0]
                    m1 += N[yy, xx, 1]
                    m2 += N[yy, xx, 2]
            if count == 0 or (z_max - z_min) > jump * max(v2 / count, 1e-9):
                continue
            norm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            if not norm > 1e-6:
                continue
            ok[y, x] = True
            Vd[y, x, 0], Vd[y, x, 1], Vd[y, x, 2] = v0 / count, v1 / count, v2 / count
            Nd[y, x, 0], Nd[y, x, 1], Nd[y, x, 2] = m0 / norm, m1 / norm, m2 / norm
    return Vd, Nd, ok


def maps_surface_pyramid(maps: SurfaceMaps, levels: int, max_relative_depth_jump: float = 0.05
                         ) -> tuple[SurfaceMaps, ...]:
    """:func:`surface_pyramid` compiled: ``levels`` levels starting with ``maps``, each half the previous one."""
    out = [maps]
    for _ in range(1, levels):
        prev = out[-1]
        V, N, ok = _downsample_kernel(prev.vertices, prev.normals, prev.valid, float(max_relative_depth_jump))
        out.append(SurfaceMaps(V, N, ok, pyramid_intrinsics(prev.intrinsics, 1)))
    return tuple(out)


def depth_surface_pyramid(depth: np.ndarray, intrinsics: np.ndarray, levels: int,
                          max_relative_depth_jump: float = 0.05) -> tuple[SurfaceMaps, ...]:
    """``surface_pyramid(surface_maps_from_depth(depth, intrinsics, jump), levels, jump)`` compiled (no smoothing):
    vertices, 1-pixel normals and their pyramid of a depth map (H, W) metres (0 / NaN = none)."""
    d = np.asarray(depth, dtype=np.float32)
    if d.ndim != 2:
        raise CnnSlamError(f"depth must be (H, W) metres, got {d.shape}")
    k = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    V, N, valid = _depth_surface_kernel(np.ascontiguousarray(d), k[0], k[1], k[2], k[3],
                                        np.float32(max_relative_depth_jump * 1))
    return maps_surface_pyramid(SurfaceMaps(V, N, valid, k.copy()), levels, max_relative_depth_jump)


def depth_pyramid(depth: np.ndarray, intrinsics: np.ndarray, config: IcpConfig) -> tuple[SurfaceMaps, ...]:
    """The current frame's ICP pyramid of a depth map (H, W) metres: the compiled path
    (:func:`depth_surface_pyramid`) unless ``config`` smooths the depth first (``smoothing_px > 0``: the numpy
    :func:`surface_maps_from_depth` with :func:`smooth_depth`, then :func:`surface_pyramid`)."""
    jump = config.max_relative_depth_jump
    if config.smoothing_px > 0:
        return surface_pyramid(surface_maps_from_depth(depth, intrinsics, jump, config.smoothing_px,
                                                       config.smoothing_relative), config.levels, jump)
    return depth_surface_pyramid(depth, intrinsics, config.levels, jump)


def reference_pyramid(maps: SurfaceMaps, config: IcpConfig) -> tuple[SurfaceMaps, ...]:
    """The reference surface's ICP pyramid (e.g. a model rendered at the previous pose), compiled
    (:func:`maps_surface_pyramid`)."""
    return maps_surface_pyramid(maps, config.levels, config.max_relative_depth_jump)



# ------------------------------------------------------------------------------------------------------- ICP


@njit(cache=True, nogil=True)
def _normal_equations(cur_v, cur_n, cur_valid, ref_v, ref_n, ref_valid, R, t, fx, fy, cx, cy, max_dist2, min_cos,
                      huber):  # pragma: no cover - compiled
    """Accumulate J^T W J (6, 6), J^T W r (6,), sum of r^2 and the inlier count over the current pixels, in one
    pass with the 27 sums in local variables (J of a residual: ``[n_ref, T V_cur x n_ref]``, module docstring)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0],
                                                   R[2, 1], R[2, 2])
    t0, t1, t2 = t[0], t[1], t[2]
    h00 = h01 = h02 = h03 = h04 = h05 = h11 = h12 = h13 = h14 = h15 = 0.0
    h22 = h23 = h24 = h25 = h33 = h34 = h35 = h44 = h45 = h55 = 0.0
    g0 = g1 = g2 = g3 = g4 = g5 = 0.0
    err = 0.0
    count = 0
    h, w = cur_valid.shape
    rh, rw = ref_valid.shape
    for y in range(h):
        for x in range(w):
            if not cur_valid[y, x]:
                continue
            vx, vy, vz = cur_v[y, x, 0], cur_v[y, x, 1], cur_v[y, x, 2]
            px = r00 * vx + r01 * vy + r02 * vz + t0
            py = r10 * vx + r11 * vy + r12 * vz + t1
            pz = r20 * vx + r21 * vy + r22 * vz + t2
            if pz <= 1e-6:
                continue
            ui = int(math.floor(fx * px / pz + cx + 0.5))
            vi = int(math.floor(fy * py / pz + cy + 0.5))
            if ui < 0 or vi < 0 or ui >= rw or vi >= rh or not ref_valid[vi, ui]:
                continue
            dx = px - ref_v[vi, ui, 0]
            dy = py - ref_v[vi, ui, 1]
            dz = pz - ref_v[vi, ui, 2]
            if dx * dx + dy * dy + dz * dz > max_dist2:
                continue
            nx, ny, nz = ref_n[vi, ui, 0], ref_n[vi, ui, 1], ref_n[vi, ui, 2]
            cx_, cy_, cz_ = cur_n[y, x, 0], cur_n[y, x, 1], cur_n[y, x, 2]
            cnx = r00 * cx_ + r01 * cy_ + r02 * cz_
            cny = r10 * cx_ + r11 * cy_ + r12 * cz_
            cnz = r20 * cx_ + r21 * cy_ + r22 * cz_
            if cnx * nx + cny * ny + cnz * nz < min_cos:
                continue
            r = nx * dx + ny * dy + nz * dz
            j0, j1, j2 = np.float64(nx), np.float64(ny), np.float64(nz)
            j3 = py * nz - pz * ny
            j4 = pz * nx - px * nz
            j5 = px * ny - py * nx
            ar = abs(r)
            wgt = 1.0 if ar <= huber else huber / ar
            w0, w1, w2, w3, w4, w5 = wgt * j0, wgt * j1, wgt * j2, wgt * j3, wgt * j4, wgt * j5
            g0 += w0 * r
            g1 += w1 * r
            g2 += w2 * r
            g3 += w3 * r
            g4 += w4 * r
            g5 += w5 * r
            h00 += w0 * j0
            h01 += w0 * j1
            h02 += w0 * j2
            h03 += w0 * j3
            h04 += w0 * j4
            h05 += w0 * j5
            h11 += w1 * j1
            h12 += w1 * j2
            h13 += w1 * j3
            h14 += w1 * j4
            h15 += w1 * j5
            h22 += w2 * j2
            h23 += w2 * j3
            h24 += w2 * j4
            h25 += w2 * j5
            h33 += w3 * j3
            h34 += w3 * j4
            h35 += w3 * j5
            h44 += w4 * j4
            h45 += w4 * j5
            h55 += w5 * j5
            err += r * r
            count += 1
    H = np.empty((6, 6))
    H[0, 0], H[0, 1], H[0, 2], H[0, 3], H[0, 4], H[0, 5] = h00, h01, h02, h03, h04, h05
    H[1, 1], H[1, 2], H[1, 3], H[1, 4], H[1, 5] = h11, h12, h13, h14, h15
    H[2, 2], H[2, 3], H[2, 4], H[2, 5] = h22, h23, h24, h25
    H[3, 3], H[3, 4], H[3, 5] = h33, h34, h35
    H[4, 4], H[4, 5] = h44, h45
    H[5, 5] = h55
    for i in range(6):
        for j in range(i):
            H[i, j] = H[j, i]
    g = np.empty(6)
    g[0], g[1], g[2], g[3], g[4], g[5] = g0, g1, g2, g3, g4, g5
    return H, g, err, count


def _truncated_step(H: np.ndarray, g: np.ndarray, min_ratio: float) -> np.ndarray | None:
    """The Gauss-Newton step -H^-1 g restricted to the directions the data constrain: eigen-directions of H whose
    eigenvalue is below ``min_ratio`` times the largest get no update (a scene of planes that all share one normal
    does not fix the motion along them). None when nothing is constrained."""
    try:
        lam, V = np.linalg.eigh(H)
    except np.linalg.LinAlgError:
        return None
    if not np.isfinite(lam).all() or lam[-1] <= 0:
        return None
    keep = lam > min_ratio * lam[-1]
    xi = -(V[:, keep] @ ((V[:, keep].T @ g) / lam[keep]))
    return xi if np.isfinite(xi).all() else None


def _evaluate(cur: SurfaceMaps, ref: SurfaceMaps, T: np.ndarray, cfg: IcpConfig):
    fx, fy, cx, cy = ref.intrinsics
    return _normal_equations(cur.vertices, cur.normals, cur.valid, ref.vertices, ref.normals, ref.valid,
                             np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]), fx, fy, cx, cy,
                             cfg.max_distance**2, math.cos(math.radians(cfg.max_normal_angle_deg)), cfg.huber_delta)


def point_to_plane_residuals(cur_vertices: np.ndarray, ref: SurfaceMaps, T_ref_cur: np.ndarray,
                             max_distance: float = np.inf) -> np.ndarray:
    """The residuals n_ref^T (T V_cur - V_ref) of projectively associated points (numpy form of the kernel, without
    the normal test); cur_vertices: (N, 3) current-camera points. Returns (N,) float64, NaN where none associates."""
    p = np.asarray(cur_vertices, dtype=np.float64) @ T_ref_cur[:3, :3].T + T_ref_cur[:3, 3]
    fx, fy, cx, cy = ref.intrinsics
    out = np.full(p.shape[0], np.nan)
    z = p[:, 2]
    front = z > 1e-6
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(fx * p[:, 0] / z + cx + 0.5)
        v = np.floor(fy * p[:, 1] / z + cy + 0.5)
    h, w = ref.valid.shape
    ok = front & (u >= 0) & (v >= 0) & (u < w) & (v < h)
    ui, vi = u[ok].astype(np.intp), v[ok].astype(np.intp)
    idx = np.flatnonzero(ok)
    valid = ref.valid[vi, ui]
    idx, ui, vi = idx[valid], ui[valid], vi[valid]
    d = p[idx] - ref.vertices[vi, ui]
    close = np.linalg.norm(d, axis=1) <= max_distance
    out[idx[close]] = np.einsum("ij,ij->i", d[close], ref.normals[vi[close], ui[close]])
    return out


def icp_point_to_plane(reference: SurfaceMaps | tuple[SurfaceMaps, ...], current: SurfaceMaps | tuple[SurfaceMaps, ...],
                       T_ref_cur_init: np.ndarray, config: IcpConfig | None = None,
                       evaluate: Callable[..., tuple] | None = None) -> IcpResult:
    """Align the current surface to the reference surface, coarse to fine (module docstring).

    reference, current: level-0 :class:`SurfaceMaps` or pyramids from :func:`surface_pyramid` (built here when a
    single level is given; :func:`depth_pyramid` and :func:`reference_pyramid` build them with the compiled kernels);
    T_ref_cur_init: (4, 4) initial guess; evaluate: the normal equations ``(cur, ref, T, config) -> (H, g, error, n)``
    (default: this module's compiled kernel). Never raises on bad data: a frame that cannot be aligned comes back with
    ``tracked=False``.
    """
    cfg = config or IcpConfig()
    evaluate = evaluate or _evaluate
    ref_pyr = reference if isinstance(reference, tuple) else surface_pyramid(reference, cfg.levels,
                                                                              cfg.max_relative_depth_jump)
    cur_pyr = current if isinstance(current, tuple) else surface_pyramid(current, cfg.levels,
                                                                          cfg.max_relative_depth_jump)
    if len(ref_pyr) < cfg.levels or len(cur_pyr) < cfg.levels:
        raise CnnSlamError(f"ICP needs {cfg.levels} pyramid levels, got {len(ref_pyr)} and {len(cur_pyr)}")
    T = orthonormalize(np.asarray(T_ref_cur_init, dtype=np.float64))
    iterations = [0] * cfg.levels
    for level in range(cfg.levels - 1, -1, -1):
        ref, cur = ref_pyr[level], cur_pyr[level]
        for _ in range(cfg.iterations[level]):
            H, g, _, n = evaluate(cur, ref, T, cfg)
            if n < 6:
                break
            iterations[level] += 1
            xi = _truncated_step(H, g, cfg.min_eigenvalue_ratio)
            if xi is None:
                break
            T = orthonormalize(se3_exp(xi) @ T)
            if float(np.linalg.norm(xi)) < cfg.convergence:
                break
    H, _, err, n = evaluate(cur_pyr[0], ref_pyr[0], T, cfg)
    n_valid = int(np.count_nonzero(cur_pyr[0].valid))
    share = n / n_valid if n_valid else 0.0
    rmse = math.sqrt(err / n) if n else math.inf
    tracked = bool(np.isfinite(T).all() and n >= cfg.min_inliers and share >= cfg.min_inlier_share
                   and rmse <= cfg.max_rmse)
    return IcpResult(T, tracked, int(n), float(share), float(rmse), tuple(iterations), H)

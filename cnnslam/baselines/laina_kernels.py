"""One-core numba kernels for the Laina baseline's projective ICP (:mod:`cnnslam.baselines.laina`, KinectFusion):
the per-pixel work in single passes over the image, instead of the whole-image numpy expressions of
:mod:`cnnslam.icp`. Same method, same parameters, same results up to float rounding (the tests compare each one with
its reference):

- :func:`depth_surface_pyramid` is ``surface_pyramid(surface_maps_from_depth(depth, K, jump), levels, jump)`` of
  :mod:`cnnslam.icp` (without pre-smoothing, the Laina setting), :func:`maps_surface_pyramid` its
  ``surface_pyramid``;
- :func:`evaluate_icp` is the normal equations of :func:`cnnslam.icp.icp_point_to_plane` as a kernel that
  keeps its 27 sums in local variables.

The model Laina fuses into and tracks against is CNN-SLAM's :class:`cnnslam.global_model.GlobalModel` itself (its
ray-cast is :meth:`~cnnslam.global_model.GlobalModel.render_surface`), whose steps run in
:mod:`cnnslam.surfel_kernels`.

Rounding: float32 stays float32 where the reference computes in float32 (vertices, normals), so that masks decided
by thresholds agree with it; sums may be added in another order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import pyramid_intrinsics
from cnnslam.icp import IcpConfig, SurfaceMaps
from cnnslam.surfel_kernels import normal_map_kernel

# ------------------------------------------------------------------------------------------ surface maps (ICP)


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
    """cnnslam.icp.downsample_surface_maps: 2x2 means of the valid vertices and normals (float64 sums)."""
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
    """:func:`cnnslam.icp.surface_pyramid`: ``levels`` levels starting with ``maps``, each half the previous one."""
    out = [maps]
    for _ in range(1, levels):
        prev = out[-1]
        V, N, ok = _downsample_kernel(prev.vertices, prev.normals, prev.valid, float(max_relative_depth_jump))
        out.append(SurfaceMaps(V, N, ok, pyramid_intrinsics(prev.intrinsics, 1)))
    return tuple(out)


def depth_surface_pyramid(depth: np.ndarray, intrinsics: np.ndarray, levels: int,
                          max_relative_depth_jump: float = 0.05) -> tuple[SurfaceMaps, ...]:
    """``surface_pyramid(surface_maps_from_depth(depth, intrinsics, jump), levels, jump)`` (:mod:`cnnslam.icp`, no
    smoothing): vertices, 1-pixel normals and their pyramid of a depth map (H, W) metres (0 / NaN = none)."""
    d = np.asarray(depth, dtype=np.float32)
    if d.ndim != 2:
        raise CnnSlamError(f"depth must be (H, W) metres, got {d.shape}")
    k = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    V, N, valid = _depth_surface_kernel(np.ascontiguousarray(d), k[0], k[1], k[2], k[3],
                                        np.float32(max_relative_depth_jump * 1))
    return maps_surface_pyramid(SurfaceMaps(V, N, valid, k.copy()), levels, max_relative_depth_jump)


# ------------------------------------------------------------------------------------------ ICP


@njit(cache=True, nogil=True)
def _normal_equations_fast(cur_v, cur_n, cur_valid, ref_v, ref_n, ref_valid, R, t, fx, fy, cx, cy, max_dist2,
                           min_cos, huber):  # pragma: no cover - compiled
    """cnnslam.icp._normal_equations with its sums in local variables: (J^T W J (6, 6), J^T W r (6,), sum r^2,
    inliers)."""
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


def evaluate_icp(cur: SurfaceMaps, ref: SurfaceMaps, T: np.ndarray, cfg: IcpConfig):
    fx, fy, cx, cy = ref.intrinsics
    return _normal_equations_fast(cur.vertices, cur.normals, cur.valid, ref.vertices, ref.normals, ref.valid,
                                  np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]), fx, fy, cx, cy,
                                  cfg.max_distance**2, math.cos(math.radians(cfg.max_normal_angle_deg)),
                                  cfg.huber_delta)

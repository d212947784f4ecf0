"""One-core numba kernels for the Laina baseline (:mod:`cnnslam.baselines.laina`): the per-pixel work of its projective
ICP (KinectFusion) and point-based fusion (Keller et al. 3DV 2013 [11]) in single passes over the image, instead of
the whole-image numpy expressions of the shared reference code. Same method, same parameters, same results (up to
float rounding; the tests compare each one with its reference):

- :func:`depth_surface_pyramid` is ``surface_pyramid(surface_maps_from_depth(depth, K, jump), levels, jump)`` of
  :mod:`cnnslam.icp` (without pre-smoothing, the Laina setting), :func:`maps_surface_pyramid` its
  ``surface_pyramid``;
- :class:`LainaModel` is :class:`cnnslam.global_model.GlobalModel` with :meth:`LainaModel.render_surface` (``render``
  splatted straight into ICP's :class:`cnnslam.icp.SurfaceMaps`) and the per-element steps of ``integrate`` in
  kernels: step 1's measurements with their adaptive normals (computed at the fused pixels only, every
  ``pixel_stride``-th), step 2's projective association and free-space test, step 3's grouping and merging, the
  class-probability map and the compaction after removals. It overrides private steps of ``GlobalModel``: a change
  there must be made here too (``tests/cnnslam/test_baseline_laina.py`` runs both side by side);
- :func:`evaluate_icp` is the normal equations of :func:`cnnslam.icp.icp_point_to_plane` as a kernel that
  keeps its 27 sums in local variables.

Rounding: float32 stays float32 where the reference computes in float32 (vertices, normals, projections), so that
masks decided by thresholds agree with it; sums may be added in another order. The one known difference: numpy
multiplies the surfel positions by the float32 rotation through BLAS, which may round a product differently, so
where two surfels tie in depth to the last bit another one may win a pixel (about 6 of 76800 pixels per frame).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import pyramid_intrinsics, se3_inverse
from cnnslam.global_model import GlobalModel, _Measurements, _PixelMeasurements, _splat_one
from cnnslam.icp import IcpConfig, SurfaceMaps, smooth_depth

# cnnslam.icp.adaptive_normal_map's default: a raw normal is kept where the mean of its 3x3 neighbours is this long.
ADAPTIVE_NORMAL_CONSISTENCY = 0.98


# ------------------------------------------------------------------------------------------ surface maps (ICP)


@njit(cache=True, nogil=True, inline="always")
def _normal_at(V, y, x, s, tol_factor):  # pragma: no cover - compiled
    """cnnslam.icp.normal_map at one pixel (float32, central differences ``s`` apart); (0, 0, 0) = none."""
    zero = np.float32(0.0)
    h, w = V.shape[0], V.shape[1]
    if y < s or x < s or y >= h - s or x >= w - s:
        return zero, zero, zero
    c = V[y, x, 2]
    if not c > 0:
        return zero, zero, zero
    tol = tol_factor * c
    for nb in (V[y, x - s, 2], V[y, x + s, 2], V[y - s, x, 2], V[y + s, x, 2]):
        if not (nb > 0 and abs(nb - c) <= tol):
            return zero, zero, zero
    dx0 = V[y, x + s, 0] - V[y, x - s, 0]
    dx1 = V[y, x + s, 1] - V[y, x - s, 1]
    dx2 = V[y, x + s, 2] - V[y, x - s, 2]
    dy0 = V[y + s, x, 0] - V[y - s, x, 0]
    dy1 = V[y + s, x, 1] - V[y - s, x, 1]
    dy2 = V[y + s, x, 2] - V[y - s, x, 2]
    n0 = dx1 * dy2 - dx2 * dy1
    n1 = dx2 * dy0 - dx0 * dy2
    n2 = dx0 * dy1 - dx1 * dy0
    norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not norm > 1e-12:
        return zero, zero, zero
    n0, n1, n2 = n0 / norm, n1 / norm, n2 / norm
    if n0 * V[y, x, 0] + n1 * V[y, x, 1] + n2 * V[y, x, 2] > 0:
        return -n0, -n1, -n2
    return n0, n1, n2


@njit(cache=True, nogil=True)
def _normal_map(V, tol):  # pragma: no cover - compiled
    """:func:`_normal_at` (one-pixel step) at every pixel of the vertex map ``V``: (normals (h, w, 3) float32, zero
    where none; valid (h, w) bool)."""
    h, w = V.shape[:2]
    N = np.zeros((h, w, 3), np.float32)
    valid = np.zeros((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            n0, n1, n2 = _normal_at(V, y, x, 1, tol)
            if n0 != 0 or n1 != 0 or n2 != 0:
                N[y, x, 0], N[y, x, 1], N[y, x, 2] = n0, n1, n2
                valid[y, x] = True
    return N, valid


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
    N, valid = _normal_map(V, tol_factor)
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


# ------------------------------------------------------------------------------------------ the model


@njit(cache=True, nogil=True, inline="always")
def _project_one(pos, i, R32, t32, fx, fy, cx, cy):  # pragma: no cover - compiled
    """GlobalModel._project for surfel i: camera point (float32 product, as float64) and its pixel (u, v)."""
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    q0 = np.float64(R32[0, 0] * x + R32[0, 1] * y + R32[0, 2] * z + t32[0])
    q1 = np.float64(R32[1, 0] * x + R32[1, 1] * y + R32[1, 2] * z + t32[1])
    q2 = np.float64(R32[2, 0] * x + R32[2, 1] * y + R32[2, 2] * z + t32[2])
    if not q2 > np.float32(1e-3):
        return q0, q1, q2, 0.0, 0.0
    return q0, q1, q2, fx * q0 / q2 + cx, fy * q1 / q2 + cy


@njit(cache=True, nogil=True)
def _render_kernel(pos, nrm, conf, radius, min_conf, R32, t32, R, t, fx, fy, cx, cy, h, w, cap,
                   min_radius):  # pragma: no cover - compiled
    """GlobalModel.render (front-most surfel per pixel, the point of its disc plane on the pixel ray) into ICP maps:
    (vertices, normals (h, w, 3) float32, valid (h, w), index (h, w) int32)."""
    index = np.full((h, w), -1, np.int32)
    best = np.full((h, w), np.inf, np.float32)
    observed = np.zeros((1, 1), np.float32)
    margin = cap + 1.0
    f_mean = 0.5 * (fx + fy)
    for i in range(pos.shape[0]):
        if min_conf > 0 and not conf[i] >= min_conf:
            continue
        q0, q1, z, u, v = _project_one(pos, i, R32, t32, fx, fy, cx, cy)
        if not z > np.float32(1e-3):
            continue
        if not (u > -margin and u < w - 1 + margin and v > -margin and v < h - 1 + margin):
            continue
        r_px = min(f_mean * max(radius[i], min_radius) / z, cap)
        _splat_one(index, best, i, u, v, z, r_px, observed, False)
    V = np.zeros((h, w, 3), np.float32)
    N = np.zeros((h, w, 3), np.float32)
    valid = np.zeros((h, w), np.bool_)
    for y in range(h):
        ry = (y - cy) / fy
        for x in range(w):
            i = index[y, x]
            if i < 0:
                continue
            p0, p1, p2 = np.float64(pos[i, 0]), np.float64(pos[i, 1]), np.float64(pos[i, 2])
            m0, m1, m2 = np.float64(nrm[i, 0]), np.float64(nrm[i, 1]), np.float64(nrm[i, 2])
            c0 = R[0, 0] * p0 + R[0, 1] * p1 + R[0, 2] * p2 + t[0]
            c1 = R[1, 0] * p0 + R[1, 1] * p1 + R[1, 2] * p2 + t[1]
            c2 = R[2, 0] * p0 + R[2, 1] * p1 + R[2, 2] * p2 + t[2]
            n0 = R[0, 0] * m0 + R[0, 1] * m1 + R[0, 2] * m2
            n1 = R[1, 0] * m0 + R[1, 1] * m1 + R[1, 2] * m2
            n2 = R[2, 0] * m0 + R[2, 1] * m1 + R[2, 2] * m2
            rx = (x - cx) / fx
            denom = n0 * rx + n1 * ry + n2
            if abs(denom) < 0.2 * math.sqrt(rx * rx + ry * ry + 1.0):  # grazing: the disc centre
                V[y, x, 0], V[y, x, 1], V[y, x, 2] = c0, c1, c2
            else:
                ray_z = (n0 * c0 + n1 * c1 + n2 * c2) / denom
                V[y, x, 0], V[y, x, 1], V[y, x, 2] = rx * ray_z, ry * ray_z, ray_z
            N[y, x, 0], N[y, x, 1], N[y, x, 2] = n0, n1, n2
            valid[y, x] = N[y, x, 0] != 0 or N[y, x, 1] != 0 or N[y, x, 2] != 0
    return V, N, valid, index


@njit(cache=True, nogil=True)
def _sampled_normals(d, rays, smoothed, jump, step, stride, consistency, adaptive):  # pragma: no cover - compiled
    """The normals of GlobalModel._measure at the pixels it samples (every ``stride``-th row and column):
    cnnslam.icp.adaptive_normal_map(rays d, rays smoothed, jump, step) there (``adaptive``), or the raw
    cnnslam.icp.normal_map(rays d, jump, 1). Returns (ceil(h / stride), ceil(w / stride), 3) float32."""
    h, w = d.shape
    V = np.empty((h, w, 3), np.float32)
    for y in range(h):
        for x in range(w):
            for k in range(3):
                V[y, x, k] = rays[y, x, k] * d[y, x]
    raw, ok = _normal_map(V, np.float32(jump * 1))
    hs, ws = (h + stride - 1) // stride, (w + stride - 1) // stride
    out = np.zeros((hs, ws, 3), np.float32)
    if adaptive:
        Vs = np.empty((h, w, 3), np.float32)
        for y in range(h):
            for x in range(w):
                for k in range(3):
                    Vs[y, x, k] = rays[y, x, k] * smoothed[y, x]
    else:
        Vs = V
    tol_s = np.float32(jump * step)
    for ys in range(hs):
        y = ys * stride
        for xs in range(ws):
            x = xs * stride
            if not adaptive:
                out[ys, xs, 0], out[ys, xs, 1], out[ys, xs, 2] = raw[y, x, 0], raw[y, x, 1], raw[y, x, 2]
                continue
            sharp = ok[y, x] and 1 <= y < h - 1 and 1 <= x < w - 1
            if sharp:  # all 3x3 neighbours have a normal, and their mean (cv2.blur) is long
                m0 = m1 = m2 = 0.0
                for yy in range(y - 1, y + 2):
                    for xx in range(x - 1, x + 2):
                        if not ok[yy, xx]:
                            sharp = False
                        m0 += raw[yy, xx, 0]
                        m1 += raw[yy, xx, 1]
                        m2 += raw[yy, xx, 2]
                if sharp:  # cv2.blur: float64 sums times 1/9, to float32
                    ninth = 1.0 / 9.0
                    a0, a1, a2 = np.float32(m0 * ninth), np.float32(m1 * ninth), np.float32(m2 * ninth)
                    sharp = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2) >= consistency
            if sharp:
                out[ys, xs, 0], out[ys, xs, 1], out[ys, xs, 2] = raw[y, x, 0], raw[y, x, 1], raw[y, x, 2]
            else:
                n0, n1, n2 = _normal_at(Vs, y, x, step, tol_s)
                out[ys, xs, 0], out[ys, xs, 1], out[ys, xs, 2] = n0, n1, n2
    return out


@njit(cache=True, nogil=True)
def _measure_kernel(N, d, rays, alpha_map, variance, has_variance, stride, default_rel_sigma, min_sigma2,
                    max_rel_sigma, min_cos_incidence, f):  # pragma: no cover - compiled
    """The rest of GlobalModel._measure at the sampled pixels with a normal: (rows, columns, camera points,
    normals, z, sigma_d^2, disc radius, alpha) of the pixels that pass the incidence and sigma tests."""
    hs, ws = N.shape[0], N.shape[1]
    cap = hs * ws
    vs = np.empty(cap, np.int64)
    us = np.empty(cap, np.int64)
    x_cam = np.empty((cap, 3))
    n_cam = np.empty((cap, 3))
    z_out = np.empty(cap)
    sigma2_out = np.empty(cap)
    radius = np.empty(cap)
    alpha = np.empty(cap)
    sqrt2_f = math.sqrt(2.0) * f
    m = 0
    for ys in range(hs):
        for xs in range(ws):
            if N[ys, xs, 0] == 0 and N[ys, xs, 1] == 0 and N[ys, xs, 2] == 0:
                continue
            y, x = ys * stride, xs * stride
            dd = np.float64(d[y, x])
            if not dd > 0:
                continue
            x0 = np.float64(rays[y, x, 0]) * dd
            x1 = np.float64(rays[y, x, 1]) * dd
            x2 = np.float64(rays[y, x, 2]) * dd
            n0, n1, n2 = np.float64(N[ys, xs, 0]), np.float64(N[ys, xs, 1]), np.float64(N[ys, xs, 2])
            cos_inc = abs(n0 * x0 + n1 * x1 + n2 * x2) / math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            sigma2 = (default_rel_sigma * x2) ** 2
            if has_variance:
                var = np.float64(variance[y, x])
                if math.isfinite(var) and var > 0:
                    sigma2 = var
            sigma2 = max(sigma2, min_sigma2)
            if not (cos_inc >= min_cos_incidence and sigma2 <= (max_rel_sigma * x2) ** 2):
                continue
            vs[m], us[m] = y, x
            x_cam[m, 0], x_cam[m, 1], x_cam[m, 2] = x0, x1, x2
            n_cam[m, 0], n_cam[m, 1], n_cam[m, 2] = n0, n1, n2
            z_out[m] = x2
            sigma2_out[m] = sigma2
            radius[m] = stride * x2 / (sqrt2_f * cos_inc)
            alpha[m] = alpha_map[y, x]
            m += 1
    return (vs[:m].copy(), us[:m].copy(), x_cam[:m].copy(), n_cam[:m].copy(), z_out[:m].copy(),
            sigma2_out[:m].copy(), radius[:m].copy(), alpha[:m].copy())


@njit(cache=True, nogil=True)
def _group_kernel(inverse, n_groups, rows, x_world, n_world, colour, radius, weight, alpha, probs, has_probs,
                  label_weight):  # pragma: no cover - compiled
    """GlobalModel._group: per group the weighted means of the rows (sums in row order, as np.bincount)."""
    C = probs.shape[1]
    count = np.zeros(n_groups)
    wsum = np.zeros(n_groups)
    asum = np.zeros(n_groups)
    lsum = np.zeros(n_groups)
    position = np.zeros((n_groups, 3))
    normal = np.zeros((n_groups, 3))
    col = np.zeros((n_groups, 3))
    rad = np.zeros(n_groups)
    pr = np.zeros((n_groups, C))
    for k in range(rows.size):
        g, r = inverse[k], rows[k]
        wt, al, lw = weight[r], alpha[r], label_weight[r]
        count[g] += 1.0
        wsum[g] += wt
        asum[g] += al
        lsum[g] += lw
        for j in range(3):
            position[g, j] += wt * x_world[r, j]
            normal[g, j] += wt * n_world[r, j]
            col[g, j] += al * np.float64(colour[r, j])
        rad[g] += al * radius[r]
        if has_probs:
            for j in range(C):
                pr[g, j] += lw * np.float64(probs[r, j])
    col32 = np.empty((n_groups, 3), np.float32)
    pr32 = np.empty((n_groups, C), np.float32)
    for g in range(n_groups):
        for j in range(3):
            position[g, j] /= wsum[g]
            normal[g, j] /= wsum[g]
            col32[g, j] = col[g, j] / asum[g]
        norm = max(math.sqrt(normal[g, 0] ** 2 + normal[g, 1] ** 2 + normal[g, 2] ** 2), 1e-12)
        for j in range(3):
            normal[g, j] /= norm
        rad[g] /= asum[g]
        for j in range(C):
            pr32[g, j] = pr[g, j] / lsum[g]
    return position, normal, col32, rad, wsum / count, asum / count, pr32, lsum / count


@njit(cache=True, nogil=True)
def _merge_kernel(ids, position, normal, colour, radius, weight, confidence, n_obs, last_seen, anchor_ids,
                  anchor_weight, labels, m_position, m_normal, m_colour, m_radius, m_weight, m_alpha, m_probs,
                  has_probs, m_label_weight, frame, anchor, has_anchor):  # pragma: no cover - compiled
    """GlobalModel._merge_into: step 3's weighted update of the surfels ``ids`` (unique) in place."""
    for k in range(ids.size):
        i = ids[k]
        W, c = np.float64(weight[i]), np.float64(confidence[i])
        w, a = m_weight[k], m_alpha[k]
        W_new, c_new = W + w, c + a
        n0 = W * normal[i, 0] + w * m_normal[k, 0]
        n1 = W * normal[i, 1] + w * m_normal[k, 1]
        n2 = W * normal[i, 2] + w * m_normal[k, 2]
        norm = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        for j in range(3):
            position[i, j] = (W * position[i, j] + w * m_position[k, j]) / W_new
            colour[i, j] = (c * colour[i, j] + a * m_colour[k, j]) / c_new
        if norm > 1e-9:
            d = max(norm, 1e-12)
            normal[i, 0], normal[i, 1], normal[i, 2] = n0 / d, n1 / d, n2 / d
        radius[i] = (c * radius[i] + a * m_radius[k]) / c_new
        weight[i] = W_new
        confidence[i] = c_new
        n_obs[i] += 1
        last_seen[i] = frame
        if has_anchor and w > anchor_weight[i]:
            anchor_ids[i] = anchor
            anchor_weight[i] = w
        if has_probs:
            for j in range(labels.shape[1]):
                labels[i, j] += np.float32(m_label_weight[k] * m_probs[k, j])


@njit(cache=True, nogil=True)
def _associate_kernel(pos, radius, nrm, conf, weight, R32, t32, R, fx, fy, cx, cy, cap, min_radius, depth,
                      vs, us, x_cam, n_cam, z_m, sigma2, find_misses, miss_margin, assoc_sigmas, min_tol, max_tol,
                      min_cos):  # pragma: no cover - compiled
    """GlobalModel._associate: (target surfel per measurement, -1 = none; ids of the surfels in view that the frame
    sees through)."""
    h, w = depth.shape
    m = vs.size
    observed = np.zeros((h, w), np.float32)
    for k in range(m):
        observed[vs[k], us[k]] = z_m[k]
    index = np.full((h, w), -1, np.int32)
    best = np.full((h, w), np.inf, np.float32)
    in_view = np.empty(pos.shape[0], np.int64)
    n_view = 0
    margin = cap + 1.0
    f_mean = 0.5 * (fx + fy)
    for i in range(pos.shape[0]):
        q0, q1, z, u, v = _project_one(pos, i, R32, t32, fx, fy, cx, cy)
        if not z > np.float32(1e-3):
            continue
        if not (u > -margin and u < w - 1 + margin and v > -margin and v < h - 1 + margin):
            continue
        if find_misses:
            ui, vi = int(np.rint(u)), int(np.rint(v))
            if 0 <= ui < w and 0 <= vi < h:
                d_at = np.float64(depth[vi, ui])
                if d_at > 0 and d_at > z + miss_margin:
                    in_view[n_view] = i
                    n_view += 1
        r_px = min(f_mean * max(radius[i], min_radius) / z, cap)
        _splat_one(index, best, i, u, v, z, r_px, observed, True)
    target = np.full(m, -1, np.int64)
    for k in range(m):
        i = index[vs[k], us[k]]
        if i < 0:
            continue
        q0, q1, q2, _, _ = _project_one(pos, i, R32, t32, fx, fy, cx, cy)
        m0, m1, m2 = np.float64(nrm[i, 0]), np.float64(nrm[i, 1]), np.float64(nrm[i, 2])
        n0 = m0 * R[0, 0] + m1 * R[1, 0] + m2 * R[2, 0]  # n @ R: the surfel normal in camera coordinates
        n1 = m0 * R[0, 1] + m1 * R[1, 1] + m2 * R[2, 1]
        n2 = m0 * R[0, 2] + m1 * R[1, 2] + m2 * R[2, 2]
        zk = z_m[k]
        rx, ry, rz = x_cam[k, 0] / zk, x_cam[k, 1] / zk, x_cam[k, 2] / zk
        denom = n0 * rx + n1 * ry + n2 * rz
        if abs(denom) > 0.2 * math.sqrt(rx * rx + ry * ry + rz * rz):
            plane_z = (n0 * q0 + n1 * q1 + n2 * q2) / (1.0 if denom == 0 else denom)
        else:
            plane_z = q2
        sigma2_s = np.float64(conf[i] / max(weight[i], np.float32(1e-12)))
        tol = min(max(assoc_sigmas * math.sqrt(sigma2[k] + sigma2_s), min_tol), max_tol)
        if abs(zk - plane_z) <= tol and n0 * n_cam[k, 0] + n1 * n_cam[k, 1] + n2 * n_cam[k, 2] >= min_cos:
            target[k] = i
    return target, in_view[:n_view].copy()


@njit(cache=True, nogil=True)
def _probability_kernel(p):  # pragma: no cover - compiled
    """GlobalModel._probability_map of (H, W, C) probabilities: NaN -> 0, +-inf -> +-float32 max, each pixel divided
    by its sum (0 where the sum is not positive); the second value says whether any entry is negative."""
    h, w, c = p.shape
    out = np.zeros((h, w, c), np.float32)
    big = np.float32(3.4028235e38)
    negative = False
    for y in range(h):
        for x in range(w):
            s = np.float32(0.0)
            for k in range(c):
                v = np.float32(p[y, x, k])
                if math.isnan(v):
                    v = np.float32(0.0)
                elif math.isinf(v):
                    v = big if v > 0 else -big
                if v < 0:
                    negative = True
                out[y, x, k] = v
                s += v
            if s > 0:
                for k in range(c):
                    out[y, x, k] = out[y, x, k] / s
            else:
                for k in range(c):
                    out[y, x, k] = 0.0
    return out, negative


@njit(cache=True, nogil=True)
def _compact_1d(arr, keep):  # pragma: no cover - compiled
    """arr[:k] = arr[keep] in place (``keep`` strictly increasing, so no row is read after it is overwritten)."""
    for j in range(keep.size):
        arr[j] = arr[keep[j]]


@njit(cache=True, nogil=True)
def _compact_2d(arr, keep):  # pragma: no cover - compiled
    """arr[:k] = arr[keep] in place, rows (``keep`` strictly increasing)."""
    for j in range(keep.size):
        i = keep[j]
        for c in range(arr.shape[1]):
            arr[j, c] = arr[i, c]


class LainaModel(GlobalModel):
    """:class:`cnnslam.global_model.GlobalModel` (the same model, fusion and parameters) with the pixel work of
    ``render`` and ``integrate`` in the kernels above (module docstring)."""

    def render_surface(self, T_world_cam: np.ndarray, intrinsics: np.ndarray, image_size: tuple[int, int],
                       min_confidence: float = 0.0) -> SurfaceMaps:
        """``render`` (surfels with confidence >= ``min_confidence``) as ICP's reference surface: the
        :class:`SurfaceMaps` of the view's vertices and normals, valid where a surfel with a normal covers the
        pixel."""
        h, w = int(image_size[0]), int(image_size[1])
        k = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        T_cam_world = se3_inverse(np.asarray(T_world_cam, dtype=np.float64))
        R, t = np.ascontiguousarray(T_cam_world[:3, :3]), np.ascontiguousarray(T_cam_world[:3, 3])
        V, N, valid, _ = _render_kernel(
            self._col("position"), self._col("normal"), self._col("confidence"), self._col("radius"),
            float(min_confidence), R.astype(np.float32), t.astype(np.float32), R, t, k[0], k[1], k[2], k[3], h, w,
            float(self.config.max_splat_radius_px), np.float32(0.75 * self.config.voxel_size))
        return SurfaceMaps(V, N, valid, k.copy())

    def _measure(self, depth: np.ndarray, intr: np.ndarray, variance: np.ndarray | None) -> _PixelMeasurements:
        """GlobalModel._measure with the normals computed at the sampled pixels only (:func:`_sampled_normals`)."""
        cfg = self.config
        h, w = depth.shape
        rays, alpha_map = self._camera_tables((h, w), intr)
        d = np.where(np.isfinite(depth) & (depth >= cfg.min_depth) & (depth <= cfg.max_depth), depth, 0.0)
        d = np.ascontiguousarray(d, dtype=np.float32)
        adaptive = cfg.normal_smoothing_px > 0
        smoothed = smooth_depth(d, cfg.normal_smoothing_px, cfg.normal_smoothing_relative) if adaptive else d
        s = cfg.pixel_stride
        N = _sampled_normals(d, rays, np.ascontiguousarray(smoothed, dtype=np.float32),
                             float(cfg.max_relative_depth_jump), int(cfg.normal_step_px), s,
                             ADAPTIVE_NORMAL_CONSISTENCY, adaptive)
        var = np.zeros((1, 1)) if variance is None else np.ascontiguousarray(variance, dtype=np.float64)
        vs, us, x_cam, n_cam, z, sigma2, radius, alpha = _measure_kernel(
            N, d, rays, alpha_map, var, variance is not None, s, float(cfg.default_relative_sigma),
            float(cfg.min_depth_sigma**2), float(cfg.max_relative_sigma), math.cos(math.radians(cfg.max_incidence_deg)),
            float(0.5 * (intr[0] + intr[1])))
        return _PixelMeasurements(d, vs, us, x_cam, n_cam, z, sigma2, radius, alpha)

    @staticmethod
    def _group(inverse: np.ndarray, n_groups: int, rows: np.ndarray, x_world: np.ndarray, n_world: np.ndarray,
               colour: np.ndarray, radius: np.ndarray, weight: np.ndarray, alpha: np.ndarray,
               probs: np.ndarray | None, label_weight: np.ndarray) -> _Measurements:
        """GlobalModel._group (one averaged measurement per target) in one kernel."""
        has_probs = probs is not None
        p = np.ascontiguousarray(probs, dtype=np.float32) if has_probs else np.zeros((1, 1), np.float32)
        position, normal, col, rad, w, a, pr, lw = _group_kernel(
            np.ascontiguousarray(inverse, dtype=np.int64), int(n_groups), np.ascontiguousarray(rows, dtype=np.int64),
            np.ascontiguousarray(x_world, dtype=np.float64), np.ascontiguousarray(n_world, dtype=np.float64),
            np.ascontiguousarray(colour, dtype=np.float32), np.ascontiguousarray(radius, dtype=np.float64),
            np.ascontiguousarray(weight, dtype=np.float64), np.ascontiguousarray(alpha, dtype=np.float64), p,
            has_probs, np.ascontiguousarray(label_weight, dtype=np.float64))
        return _Measurements(position, normal, col, rad, w, a, pr if has_probs else None, lw)

    def _merge_into(self, ids: np.ndarray, meas: _Measurements, frame: int, anchor: int | None) -> None:
        """GlobalModel._merge_into (step 3 on the surfels ``ids``, unique) in one kernel."""
        D = self._data
        has_probs = meas.probs is not None
        probs = np.ascontiguousarray(meas.probs, dtype=np.float32) if has_probs else np.zeros((1, 1), np.float32)
        _merge_kernel(np.ascontiguousarray(ids, dtype=np.int64), D["position"], D["normal"], D["colour"], D["radius"],
                      D["weight"], D["confidence"], D["n_obs"], D["last_seen"], D["anchor"], D["anchor_weight"],
                      self._labels, np.ascontiguousarray(meas.position, dtype=np.float64),
                      np.ascontiguousarray(meas.normal, dtype=np.float64),
                      np.ascontiguousarray(meas.colour, dtype=np.float32),
                      np.ascontiguousarray(meas.radius, dtype=np.float64),
                      np.ascontiguousarray(meas.weight, dtype=np.float64),
                      np.ascontiguousarray(meas.alpha, dtype=np.float64), probs, has_probs,
                      np.ascontiguousarray(meas.label_weight, dtype=np.float64), int(frame),
                      -1 if anchor is None else int(anchor), anchor is not None)

    def _associate(self, px: _PixelMeasurements, T: np.ndarray, intr: np.ndarray,
                   find_misses: bool) -> tuple[np.ndarray, np.ndarray]:
        """GlobalModel._associate (Keller's projective association and the free-space test) in one kernel."""
        cfg = self.config
        m = px.vs.size
        if not (self._size and m):
            return np.full(m, -1, np.int64), np.zeros(0, np.int64)
        k = np.asarray(intr, dtype=np.float64).reshape(4)
        T_cam_world = se3_inverse(np.asarray(T, dtype=np.float64))
        R = np.ascontiguousarray(T[:3, :3], dtype=np.float64)
        return _associate_kernel(
            self._col("position"), self._col("radius"), self._col("normal"), self._col("confidence"),
            self._col("weight"), T_cam_world[:3, :3].astype(np.float32), T_cam_world[:3, 3].astype(np.float32), R,
            k[0], k[1], k[2], k[3], float(cfg.max_splat_radius_px), np.float32(0.75 * cfg.voxel_size),
            np.ascontiguousarray(px.depth, dtype=np.float32), px.vs, px.us, np.ascontiguousarray(px.x_cam),
            np.ascontiguousarray(px.n_cam), np.ascontiguousarray(px.z), np.ascontiguousarray(px.sigma2),
            bool(find_misses), float(cfg.miss_margin), float(cfg.association_sigmas),
            float(cfg.min_association_distance), float(cfg.max_association_distance),
            math.cos(math.radians(cfg.max_normal_angle_deg)))

    def _compact(self, keep: np.ndarray) -> None:
        """GlobalModel._compact (keep the surfels ``keep``, in order) in place, without temporary copies."""
        keep = np.asarray(keep, dtype=np.int64)
        if keep.size > 1 and not bool(np.all(keep[1:] > keep[:-1])):
            super()._compact(keep)
            return
        for arr in (*self._data.values(), self._labels):
            (_compact_1d if arr.ndim == 1 else _compact_2d)(arr, keep)
        self._size = keep.size

    def _probability_map(self, label_probs: np.ndarray | None, size: tuple[int, int]) -> np.ndarray | None:
        """GlobalModel._probability_map; (H, W, C) probabilities normalised in one kernel."""
        if label_probs is None or np.ndim(label_probs) != 3:
            return super()._probability_map(label_probs, size)
        C = self.config.num_classes
        p = np.asarray(label_probs)
        if p.shape != (*size, C):
            raise CnnSlamError(f"label probabilities must be (H, W, C) = {(*size, C)}, got {p.shape}")
        out, negative = _probability_kernel(np.ascontiguousarray(p, dtype=np.float32))
        if negative:
            raise CnnSlamError("label probabilities must be >= 0")
        return out

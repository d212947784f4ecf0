"""The numba kernels of the global model (:mod:`cnnslam.model.global_model`, CNN-SLAM Sec. 3.5 with Keller et al.'s
point-based fusion [11]): each per-pixel or per-surfel step of :meth:`~cnnslam.model.global_model.GlobalModel.integrate`
and :meth:`~cnnslam.model.global_model.GlobalModel.render` as one pass over the image or the surfels, on one core.

The model has one implementation of each step, and these are they: CNN-SLAM's key-frame fusion and the Laina
baseline's frame-rate fusion (:mod:`cnnslam.baselines.laina`) run the same code. What each step computes is stated in
the module docstring of :mod:`cnnslam.model.global_model` (steps 1-5); here, how.

Rounding: float32 stays float32 where the surfels are stored in float32 (positions, normals, projections), so that
masks decided by thresholds see the stored values; sums run in row order (as ``np.bincount``). Numeric cores only: no
I/O, no Python objects.

Conventions: surfel positions and normals in the world frame, ``R32, t32`` (float32) and ``R, t`` (float64) the
world-to-camera rotation and translation (``T_cam_world``), intrinsics fx, fy, cx, cy in pixels, images (h, w),
OpenCV camera axes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---------------------------------------------------------------------------------------- normals


@njit(cache=True, nogil=True, inline="always")
def normal_at(V, y, x, s, tol_factor):  # pragma: no cover - compiled
    """cnnslam.model.icp.normal_map at one pixel (float32, central differences ``s`` apart); (0, 0, 0) = none."""
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
def normal_map_kernel(V, tol):  # pragma: no cover - compiled
    """:func:`normal_at` (one-pixel step) at every pixel of the vertex map ``V``: (normals (h, w, 3) float32, zero
    where none; valid (h, w) bool)."""
    h, w = V.shape[:2]
    N = np.zeros((h, w, 3), np.float32)
    valid = np.zeros((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            n0, n1, n2 = normal_at(V, y, x, 1, tol)
            if n0 != 0 or n1 != 0 or n2 != 0:
                N[y, x, 0], N[y, x, 1], N[y, x, 2] = n0, n1, n2
                valid[y, x] = True
    return N, valid



# ---------------------------------------------------------------------------------------- splatting


@njit(cache=True, nogil=True, inline="always")
def _splat_one(index, best, i, u, v, z, r, observed, closest, grid=1):  # pragma: no cover - compiled
    """:func:`_splat` for the one point i at (u, v), depth z, radius r pixels, into ``index`` and ``best``; with
    ``grid`` > 1 only the pixels whose row and column are multiples of ``grid`` (where ``closest`` has all its
    observations, when they were sampled on that grid)."""
    h, w = best.shape
    uc = int(math.floor(u + 0.5))
    vc = int(math.floor(v + 0.5))
    ri = int(math.ceil(r))
    r2 = r * r
    y_lo = max(vc - ri, 0)
    x_lo = max(uc - ri, 0)
    if grid > 1:
        y_lo = (y_lo + grid - 1) // grid * grid
        x_lo = (x_lo + grid - 1) // grid * grid
    for y in range(y_lo, min(vc + ri, h - 1) + 1, grid):
        dv = y - vc
        for x in range(x_lo, min(uc + ri, w - 1) + 1, grid):
            du = x - uc
            if closest and observed[y, x] <= 0:
                continue
            if (du != 0 or dv != 0) and (x - u) ** 2 + (y - v) ** 2 > r2:
                continue
            cost = abs(z - observed[y, x]) if closest else z
            if cost < best[y, x]:
                best[y, x] = cost
                index[y, x] = i


@njit(cache=True, nogil=True)
def _splat(u, v, z, radius_px, observed, closest):  # pragma: no cover - compiled
    """Per pixel the point of least cost among those whose disc covers it: cost z (front-most) or, with
    ``closest``, |z - observed[y, x]| and no point where observed <= 0. Returns (index (h, w) int32, -1 = none;
    cost (h, w) float32, inf = none); ``observed`` (h, w) also gives the image size.

    u, v: (N,) float pixel positions of the points; z: (N,) camera depth; radius_px: (N,) disc radius in pixels. A
    point covers the pixel centres within its radius of (u, v), and always the pixel it falls in.
    """
    h, w = observed.shape
    index = np.full((h, w), -1, np.int32)
    best = np.full((h, w), np.inf, np.float32)
    for i in range(u.shape[0]):
        _splat_one(index, best, i, u[i], v[i], z[i], radius_px[i], observed, closest)
    return index, best


def splat_index_map(u: np.ndarray, v: np.ndarray, z: np.ndarray, radius_px: np.ndarray, h: int,
                    w: int) -> tuple[np.ndarray, np.ndarray]:
    """Front-most point per pixel: (index (h, w) int32, -1 = none; zbuf (h, w) float32, inf = none).

    u, v: (N,) float pixel positions of the points; z: (N,) camera depth; radius_px: (N,) disc radius in pixels. A
    point covers the pixel centres within its radius of (u, v), and always the pixel it falls in.
    """
    return _splat(u, v, z, radius_px, np.zeros((h, w), np.float32), False)


# ------------------------------------------------------------------------------------ the steps of fusion


@njit(cache=True, nogil=True, inline="always")
def _project_one(pos, i, R32, t32, fx, fy, cx, cy):  # pragma: no cover - compiled
    """Surfel i in the camera: camera point (float32 product, as float64) and its pixel (u, v); (.., 0, 0) behind the
    camera (z <= 1 mm)."""
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    q0 = np.float64(R32[0, 0] * x + R32[0, 1] * y + R32[0, 2] * z + t32[0])
    q1 = np.float64(R32[1, 0] * x + R32[1, 1] * y + R32[1, 2] * z + t32[1])
    q2 = np.float64(R32[2, 0] * x + R32[2, 1] * y + R32[2, 2] * z + t32[2])
    if not q2 > np.float32(1e-3):
        return q0, q1, q2, 0.0, 0.0
    return q0, q1, q2, fx * q0 / q2 + cx, fy * q1 / q2 + cy


@njit(cache=True, nogil=True)
def render_kernel(pos, nrm, conf, radius, min_conf, R32, t32, R, t, fx, fy, cx, cy, h, w, cap,
                  min_radius):  # pragma: no cover - compiled
    """Ray-cast of the surfels (confidence >= ``min_conf``): the front-most disc per pixel and the point where the
    pixel's ray meets its plane (the disc centre at grazing angles), camera coordinates:
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
def sampled_normals(d, rays, smoothed, jump, step, stride, consistency, adaptive):  # pragma: no cover - compiled
    """Step 1's normals at the pixels fusion samples (every ``stride``-th row and column):
    cnnslam.model.icp.adaptive_normal_map(rays d, rays smoothed, jump, step) there (``adaptive``), or the raw
    cnnslam.model.icp.normal_map(rays d, jump, 1). Returns (ceil(h / stride), ceil(w / stride), 3) float32."""
    h, w = d.shape
    V = np.empty((h, w, 3), np.float32)
    for y in range(h):
        for x in range(w):
            for k in range(3):
                V[y, x, k] = rays[y, x, k] * d[y, x]
    raw, ok = normal_map_kernel(V, np.float32(jump * 1))
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
                n0, n1, n2 = normal_at(Vs, y, x, step, tol_s)
                out[ys, xs, 0], out[ys, xs, 1], out[ys, xs, 2] = n0, n1, n2
    return out


@njit(cache=True, nogil=True)
def measure_kernel(N, d, rays, alpha_map, variance, has_variance, stride, default_rel_sigma, min_sigma2,
                    max_rel_sigma, min_cos_incidence, f):  # pragma: no cover - compiled
    """Step 1 at the sampled pixels with a normal: (rows, columns, camera points,
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
def group_kernel(inverse, n_groups, rows, x_world, n_world, colour, radius, weight, alpha, probs, has_probs,
                  label_weight):  # pragma: no cover - compiled
    """Step 3's one observation per frame and target: per group the weighted means of the rows (position and normal
    by alpha / sigma^2, colour and radius by alpha, class probabilities by the label weight; sums in row order, as
    np.bincount)."""
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
def merge_kernel(ids, position, normal, colour, radius, weight, confidence, n_obs, anchor_ids, anchor_weight,
                 m_position, m_normal, m_colour, m_radius, m_weight, m_alpha, anchor, has_anchor
                 ):  # pragma: no cover - compiled
    """Step 3's weighted update of the geometry of the surfels ``ids`` (unique) in place; their labels are fused
    apart (:func:`cnnslam.model.label_fusion.fuse_labels`)."""
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
        if has_anchor and w > anchor_weight[i]:
            anchor_ids[i] = anchor
            anchor_weight[i] = w


@njit(cache=True, nogil=True)
def associate_kernel(pos, radius, nrm, conf, weight, R32, t32, R, fx, fy, cx, cy, cap, min_radius, depth,
                      vs, us, x_cam, n_cam, z_m, sigma2, find_misses, miss_margin, assoc_sigmas, min_tol, max_tol,
                      min_cos, grid=1):  # pragma: no cover - compiled
    """Step 2, Keller's projective data association, and step 5's free-space test: (target surfel per measurement,
    -1 = none; ids of the surfels in view that the frame sees through, when ``find_misses``). ``grid``: the
    measurements' pixel stride (every row and column a multiple of it: the splat visits those pixels only, the same
    association; checked, 1 when they are not)."""
    h, w = depth.shape
    m = vs.size
    observed = np.zeros((h, w), np.float32)
    for k in range(m):
        observed[vs[k], us[k]] = z_m[k]
        if grid > 1 and (vs[k] % grid != 0 or us[k] % grid != 0):
            grid = 1
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
        _splat_one(index, best, i, u, v, z, r_px, observed, True, grid)
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
def probability_kernel(p, vs, us):  # pragma: no cover - compiled
    """Class probabilities (H, W, C) made valid at the pixels (vs[k], us[k]): NaN -> 0, +-inf -> +-float32 max,
    each pixel divided by its sum (0 where the sum is not positive); (M, C) float32 rows, one per pixel."""
    m = vs.shape[0]
    c = p.shape[2]
    out = np.zeros((m, c), np.float32)
    big = np.float32(3.4028235e38)
    for i in range(m):
        y, x = vs[i], us[i]
        s = np.float32(0.0)
        for k in range(c):
            v = np.float32(p[y, x, k])
            if math.isnan(v):
                v = np.float32(0.0)
            elif math.isinf(v):
                v = big if v > 0 else -big
            out[i, k] = v
            s += v
        if s > 0:
            for k in range(c):
                out[i, k] = out[i, k] / s
        else:
            for k in range(c):
                out[i, k] = 0.0
    return out


@njit(cache=True, nogil=True)
def compact_1d(arr, keep):  # pragma: no cover - compiled
    """arr[:k] = arr[keep] in place (``keep`` strictly increasing, so no row is read after it is overwritten)."""
    for j in range(keep.size):
        arr[j] = arr[keep[j]]


@njit(cache=True, nogil=True)
def compact_2d(arr, keep):  # pragma: no cover - compiled
    """arr[:k] = arr[keep] in place, rows (``keep`` strictly increasing)."""
    for j in range(keep.size):
        i = keep[j]
        for c in range(arr.shape[1]):
            arr[j, c] = arr[i, c]


"""One-core numba kernels of the ORB baseline's bundle adjustment (:func:`cnnslam.baselines.orb_ba.bundle_adjust`):
the normal equations of the reprojection problem and their solution by the Schur complement on the points, as g2o's
block solver does it for ORB-SLAM (points marginalised).

Conventions as in :mod:`cnnslam.baselines.orb_ba`: cameras are world -> camera rotations R (K, 3, 3) and
translations t (K, 3); residuals ``e = (pi(K (R X + t)) - uv) * inv_sigma`` (2-vectors, pixels / sigma); camera
updates are left twists ``[v, w]`` (d p_cam / d xi = [I, -hat(p_cam)]); points are updated additively. The robust
kernel is g2o's Huber on the squared error chi2 = |e|^2 at delta = sqrt(5.991): rho(s) = s inside delta^2,
2 delta sqrt(s) - delta^2 beyond; its first derivative rho'(s) = min(1, delta / sqrt(s)) weights each observation's
block of the normal equations (g2o's robustified linearisation).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _project(R, t, X, o_cam, o_pt, k):  # pragma: no cover - compiled
    """Camera coordinates of observation k's point in its camera."""
    c, p = o_cam[k], o_pt[k]
    x = R[c, 0, 0] * X[p, 0] + R[c, 0, 1] * X[p, 1] + R[c, 0, 2] * X[p, 2] + t[c, 0]
    y = R[c, 1, 0] * X[p, 0] + R[c, 1, 1] * X[p, 1] + R[c, 1, 2] * X[p, 2] + t[c, 1]
    z = R[c, 2, 0] * X[p, 0] + R[c, 2, 1] * X[p, 1] + R[c, 2, 2] * X[p, 2] + t[c, 2]
    return x, y, z


@njit(cache=True, nogil=True, inline="always")
def _to_camera(T, pts, k):  # pragma: no cover - compiled
    """Camera coordinates of point k of ``pts`` under the (4, 4) world -> camera ``T``."""
    x = T[0, 0] * pts[k, 0] + T[0, 1] * pts[k, 1] + T[0, 2] * pts[k, 2] + T[0, 3]
    y = T[1, 0] * pts[k, 0] + T[1, 1] * pts[k, 1] + T[1, 2] * pts[k, 2] + T[1, 3]
    z = T[2, 0] * pts[k, 0] + T[2, 1] * pts[k, 1] + T[2, 2] * pts[k, 2] + T[2, 3]
    return x, y, z


@njit(cache=True, nogil=True, inline="always")
def _linearise(x, y, zr, u, v, s, fx, fy, cx, cy, min_depth, Jc):  # pragma: no cover - compiled
    """The normalised residual (e0, e1) of camera point (x, y, zr) observed at pixel (u, v) with 1 / sigma ``s``,
    and its derivatives: d e / d p_cam's non-zero entries (a00, a02, a11, a12) returned, d e / d xi for a left twist
    written to Jc (2, 6): (d e / d p_cam) [I, -hat(p_cam)] (p_cam's own depth in hat, the clamped one in the
    division)."""
    z = max(zr, min_depth)
    iz = 1.0 / z
    e0 = (fx * x * iz + cx - u) * s
    e1 = (fy * y * iz + cy - v) * s
    a00 = fx * iz * s
    a02 = -fx * x * iz * iz * s
    a11 = fy * iz * s
    a12 = -fy * y * iz * iz * s
    Jc[0, 0], Jc[0, 1], Jc[0, 2] = a00, 0.0, a02
    Jc[1, 0], Jc[1, 1], Jc[1, 2] = 0.0, a11, a12
    # -hat(p) = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
    Jc[0, 3] = a02 * y
    Jc[0, 4] = a00 * zr - a02 * x
    Jc[0, 5] = -a00 * y
    Jc[1, 3] = -a11 * zr + a12 * y
    Jc[1, 4] = -a12 * x
    Jc[1, 5] = a11 * x
    return e0, e1, a00, a02, a11, a12


@njit(cache=True, nogil=True)
def robust_cost(R, t, X, o_cam, o_pt, uv, inv_sigma, intr, delta, min_depth):  # pragma: no cover - compiled
    """(sum of rho(chi2) over the observations, chi2 (O,)) at the estimate (R, t, X)."""
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    n = o_cam.shape[0]
    chi2 = np.empty(n)
    d2 = delta * delta
    cost = 0.0
    for k in range(n):
        x, y, z = _project(R, t, X, o_cam, o_pt, k)
        z = max(z, min_depth)
        ex = (fx * x / z + cx - uv[k, 0]) * inv_sigma[k]
        ey = (fy * y / z + cy - uv[k, 1]) * inv_sigma[k]
        s = ex * ex + ey * ey
        chi2[k] = s
        cost += s if s <= d2 else 2.0 * delta * math.sqrt(s) - d2
    return cost, chi2


@njit(cache=True, nogil=True)
def normal_equations(R, t, X, o_cam, o_pt, uv, inv_sigma, intr, free_col, n_free, delta,
                     min_depth):  # pragma: no cover - compiled
    """Huber-weighted Gauss-Newton blocks at (R, t, X).

    free_col: (K,) index of each camera among the free ones (-1: held fixed). Returns H_cc (6F, 6F) and g_c (6F,)
    of the free cameras, H_pp (P, 3, 3) and g_p (P, 3) of the points, W (O, 6, 3) = w J_c^T J_p of each observation
    (zero for a fixed camera): H = J^T diag(w) J, g = J^T diag(w) e.
    """
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    n = o_cam.shape[0]
    P = X.shape[0]
    Hcc = np.zeros((6 * n_free, 6 * n_free))
    gc = np.zeros(6 * n_free)
    Hpp = np.zeros((P, 3, 3))
    gp = np.zeros((P, 3))
    W = np.zeros((n, 6, 3))
    Jp = np.empty((2, 3))
    Jc = np.empty((2, 6))
    for k in range(n):
        c, p = o_cam[k], o_pt[k]
        x, y, zr = _project(R, t, X, o_cam, o_pt, k)
        e0, e1, a00, a02, a11, a12 = _linearise(x, y, zr, uv[k, 0], uv[k, 1], inv_sigma[k], fx, fy, cx, cy,
                                                min_depth, Jc)
        norm = math.sqrt(e0 * e0 + e1 * e1)
        w = 1.0 if norm <= delta else delta / norm
        # d e / d X = (d e / d p_cam) R
        for j in range(3):
            Jp[0, j] = a00 * R[c, 0, j] + a02 * R[c, 2, j]
            Jp[1, j] = a11 * R[c, 1, j] + a12 * R[c, 2, j]
        # the blocks are symmetric entry by entry (the same products, commuted): the upper triangles are summed
        # here and mirrored at the end
        for i in range(3):
            for j in range(i, 3):
                Hpp[p, i, j] += w * (Jp[0, i] * Jp[0, j] + Jp[1, i] * Jp[1, j])
            gp[p, i] += w * (Jp[0, i] * e0 + Jp[1, i] * e1)
        col = free_col[c]
        if col < 0:
            continue
        b = 6 * col
        for i in range(6):
            for j in range(i, 6):
                Hcc[b + i, b + j] += w * (Jc[0, i] * Jc[0, j] + Jc[1, i] * Jc[1, j])
            gc[b + i] += w * (Jc[0, i] * e0 + Jc[1, i] * e1)
            for j in range(3):
                W[k, i, j] = w * (Jc[0, i] * Jp[0, j] + Jc[1, i] * Jp[1, j])
    for p in range(P):
        for i in range(3):
            for j in range(i):
                Hpp[p, i, j] = Hpp[p, j, i]
    for col in range(n_free):
        b = 6 * col
        for i in range(6):
            for j in range(i):
                Hcc[b + i, b + j] = Hcc[b + j, b + i]
    return Hcc, gc, Hpp, gp, W


@njit(cache=True, nogil=True)
def _inverse_3x3(A, lam):  # pragma: no cover - compiled
    """(A + lam I)^-1 of a symmetric 3x3 block by cofactors; ok False when it is not positive definite."""
    a, b, c = A[0, 0] + lam, A[0, 1], A[0, 2]
    d, e, f = A[1, 1] + lam, A[1, 2], A[2, 2] + lam
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    det = a * c00 + b * c01 + c * c02
    inv = np.empty((3, 3))
    if not (det > 0 and a > 0 and a * d - b * b > 0):
        return inv, False
    inv[0, 0] = c00 / det
    inv[0, 1] = inv[1, 0] = c01 / det
    inv[0, 2] = inv[2, 0] = c02 / det
    inv[1, 1] = (a * f - c * c) / det
    inv[1, 2] = inv[2, 1] = (b * c - a * e) / det
    inv[2, 2] = (a * d - b * b) / det
    return inv, True


@njit(cache=True, nogil=True)
def _cholesky_solve(S, r):  # pragma: no cover - compiled
    """x with S x = r for symmetric positive definite S (Cholesky); ok False when S is not positive definite."""
    n = S.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0:
            return np.zeros(n), False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            v = S[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / L[j, j]
    y = np.empty(n)
    for i in range(n):
        v = r[i]
        for k in range(i):
            v -= L[i, k] * y[k]
        y[i] = v / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        v = y[i]
        for k in range(i + 1, n):
            v -= L[k, i] * x[k]
        x[i] = v / L[i, i]
    return x, True


@njit(cache=True, nogil=True)
def schur_step(Hcc, gc, Hpp, gp, W, o_cam, free_col, by_point, point_start, lam):  # pragma: no cover - compiled
    """The damped Gauss-Newton step (H + lam I) dx = -g, cameras by the Schur complement on the points.

    by_point: observation indices grouped by point, point_start (P + 1,) the start of each point's group. Returns
    (camera step (6F,), point step (P, 3), ok): with V_p = H_pp + lam I,
    S = H_cc + lam I - sum_p H_cp V_p^-1 H_pc, S dc = -g_c + sum_p H_cp V_p^-1 g_p, dp = V_p^-1 (-g_p - H_pc dc).
    """
    nc = Hcc.shape[0]
    P = Hpp.shape[0]
    S = Hcc.copy()
    for i in range(nc):
        S[i, i] += lam
    r = -gc
    Vinv = np.empty((P, 3, 3))
    Y = np.empty((6, 3))  # H_cp V_p^-1 of the observation in hand
    for p in range(P):
        inv, ok = _inverse_3x3(Hpp[p], lam)
        if not ok:
            return np.zeros(nc), np.zeros((P, 3)), False
        Vinv[p] = inv
        for ia in range(point_start[p], point_start[p + 1]):
            a = by_point[ia]
            ca = free_col[o_cam[a]]
            if ca < 0:
                continue
            for i in range(6):
                for j in range(3):
                    Y[i, j] = W[a, i, 0] * inv[0, j] + W[a, i, 1] * inv[1, j] + W[a, i, 2] * inv[2, j]
                r[6 * ca + i] += Y[i, 0] * gp[p, 0] + Y[i, 1] * gp[p, 1] + Y[i, 2] * gp[p, 2]
            # the pairs (b, a) with b up to a; (a, b) adds the same values to the transposed entries. A value goes to
            # the block at or below the diagonal (mirrored after the loop: the same values in the same order as
            # writing both) and, in a diagonal block, to its transposed entry too; a point's own pair (b = a) once
            for ib in range(point_start[p], ia + 1):
                b = by_point[ib]
                cb = free_col[o_cam[b]]
                if cb < 0:
                    continue
                for i in range(6):
                    y0, y1, y2 = Y[i, 0], Y[i, 1], Y[i, 2]
                    for j in range(6):
                        v = y0 * W[b, j, 0] + y1 * W[b, j, 1] + y2 * W[b, j, 2]
                        if ca >= cb:
                            S[6 * ca + i, 6 * cb + j] -= v
                        if ca <= cb and ib != ia:
                            S[6 * cb + j, 6 * ca + i] -= v
    for ca in range(nc // 6):
        for cb in range(ca):
            for i in range(6):
                for j in range(6):
                    S[6 * cb + j, 6 * ca + i] = S[6 * ca + i, 6 * cb + j]
    if nc:
        dc, ok = _cholesky_solve(S, r)
        if not ok:
            return np.zeros(nc), np.zeros((P, 3)), False
    else:
        dc = np.zeros(0)
    dp = np.empty((P, 3))
    for p in range(P):
        q0, q1, q2 = -gp[p, 0], -gp[p, 1], -gp[p, 2]
        for ia in range(point_start[p], point_start[p + 1]):
            a = by_point[ia]
            ca = free_col[o_cam[a]]
            if ca < 0:
                continue
            for i in range(6):
                d = dc[6 * ca + i]
                q0 -= W[a, i, 0] * d
                q1 -= W[a, i, 1] * d
                q2 -= W[a, i, 2] * d
        for j in range(3):
            dp[p, j] = Vinv[p, j, 0] * q0 + Vinv[p, j, 1] * q1 + Vinv[p, j, 2] * q2
    return dc, dp, True


@njit(cache=True, nogil=True)
def _left_update(T, xi):  # pragma: no cover - compiled
    """exp(xi) T for a twist xi = [v, w] (Rodrigues; V = I + a W + b W^2 as cnnslam.geometry.se3_exp)."""
    w0, w1, w2 = xi[3], xi[4], xi[5]
    th2 = w0 * w0 + w1 * w1 + w2 * w2
    th = math.sqrt(th2)
    if th > 0:
        s = math.sin(th) / th
        a = 2.0 * math.sin(0.5 * th) ** 2 / th2
    else:
        s, a = 1.0, 0.5
    b = 1.0 / 6.0 - th2 / 120.0 + th2 * th2 / 5040.0 if th < 1e-2 else (th - math.sin(th)) / (th2 * th)
    Wm = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
    W2 = Wm @ Wm
    E = np.eye(4)
    for i in range(3):
        for j in range(3):
            I = 1.0 if i == j else 0.0
            E[i, j] = I + s * Wm[i, j] + a * W2[i, j]
        E[i, 3] = 0.0
        for j in range(3):
            I = 1.0 if i == j else 0.0
            E[i, 3] += (I + a * Wm[i, j] + b * W2[i, j]) * xi[j]
    return E @ T


@njit(cache=True, nogil=True)
def pose_only(T_cam_world, pts, uv, inv_sigma, intr, use, rounds, iterations, delta, chi2_max,
              min_depth):  # pragma: no cover - compiled
    """ORB-SLAM's PoseOptimization of one camera against fixed points: ``rounds`` rounds of at most ``iterations``
    Gauss-Newton steps (left twists) on the observations marked ``use``, Huber-weighted except in the last round;
    after each round every observation is classified again (inlier: chi2 <= chi2_max and in front of the camera).
    Returns (T_cam_world (4, 4), inlier mask (M,))."""
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    T = T_cam_world.copy()
    use = use.copy()
    m = pts.shape[0]
    Jc = np.empty((2, 6))
    for r in range(rounds):
        robust = r < rounds - 1
        for _ in range(iterations):
            if use.sum() < 3:
                break
            H = np.zeros((6, 6))
            g = np.zeros(6)
            for k in range(m):
                if not use[k]:
                    continue
                x, y, zr = _to_camera(T, pts, k)
                e0, e1, _, _, _, _ = _linearise(x, y, zr, uv[k, 0], uv[k, 1], inv_sigma[k], fx, fy, cx, cy,
                                                min_depth, Jc)
                norm = math.sqrt(e0 * e0 + e1 * e1)
                w = delta / max(norm, 1e-12) if (robust and norm > delta) else 1.0
                for i in range(6):
                    for j in range(6):
                        H[i, j] += w * (Jc[0, i] * Jc[0, j] + Jc[1, i] * Jc[1, j])
                    g[i] += w * (Jc[0, i] * e0 + Jc[1, i] * e1)
            for i in range(6):
                H[i, i] = H[i, i] * (1.0 + 1e-6) + 1e-12
            xi, ok = _cholesky_solve(H, -g)
            if not ok:
                break
            T = _left_update(T, xi)
            if xi @ xi < 1e-16:
                break
        for k in range(m):
            x, y, zr = _to_camera(T, pts, k)
            z = max(zr, min_depth)
            e0 = (fx * x / z + cx - uv[k, 0]) * inv_sigma[k]
            e1 = (fy * y / z + cy - uv[k, 1]) * inv_sigma[k]
            use[k] = (e0 * e0 + e1 * e1 <= chi2_max) and zr > min_depth
    return T, use

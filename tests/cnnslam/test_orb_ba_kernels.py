"""Known answers for the ORB baseline's bundle-adjustment kernels: the normal equations against a finite-difference
Jacobian of the residuals, and the Schur-complement step against the dense solve of the same damped system."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.baselines.orb_ba import HUBER_DELTA, MIN_DEPTH, huber_weights, project
from cnnslam.baselines.orb_ba_kernels import _left_update, normal_equations, robust_cost, schur_step
from cnnslam.geometry import se3_exp, se3_inverse

INTR = np.array([240.6, 240.0, 159.5, 119.5])


def _problem(seed: int = 0) -> tuple:
    """4 cameras (the first fixed), 40 points, every point seen by every camera, noisy pixels and 3 outliers."""
    rng = np.random.default_rng(seed)
    X = rng.uniform([-1.5, -1.0, 3.0], [1.5, 1.0, 5.0], (40, 3))
    T = np.stack([se3_inverse(se3_exp(np.r_[0.1 * k, 0.03 * k, 0.0, 0.01 * k, 0.03 * k, 0.0])) for k in range(4)])
    oc = np.repeat(np.arange(4), 40)
    op = np.tile(np.arange(40), 4)
    uv = np.concatenate([project(T[k], X, INTR)[0] for k in range(4)]) + rng.normal(0, 0.5, (160, 2))
    uv[[5, 70, 133]] += 15.0  # outliers: their Huber weights are below 1
    inv_sigma = 1.0 / 1.2 ** rng.integers(0, 3, 160)
    T_est = T.copy()
    T_est[1:] = se3_exp(rng.normal(0, 0.01, (3, 6))) @ T[1:]
    X_est = X + rng.normal(0, 0.05, X.shape)
    return T_est, X_est, oc, op, uv, inv_sigma


def _residuals(T: np.ndarray, X: np.ndarray, oc, op, uv, inv_sigma) -> np.ndarray:
    p = np.einsum("oij,oj->oi", T[oc, :3, :3], X[op]) + T[oc, :3, 3]
    fx, fy, cx, cy = INTR
    return np.stack([fx * p[:, 0] / p[:, 2] + cx - uv[:, 0], fy * p[:, 1] / p[:, 2] + cy - uv[:, 1]],
                    axis=1) * inv_sigma[:, None]


def _dense_system(T, X, oc, op, uv, inv_sigma, free):
    """J (2 O, 6 F + 3 P) by central differences (left twists for cameras), e, and the Huber weights."""
    e0 = _residuals(T, X, oc, op, uv, inv_sigma)
    cols = []
    h = 1e-6
    for k in free:
        for i in range(6):
            d = np.zeros(6)
            d[i] = h
            Tp, Tm = T.copy(), T.copy()
            Tp[k] = se3_exp(d) @ T[k]
            Tm[k] = se3_exp(-d) @ T[k]
            cols.append(((_residuals(Tp, X, oc, op, uv, inv_sigma) - _residuals(Tm, X, oc, op, uv, inv_sigma))
                         / (2 * h)).reshape(-1))
    for p in range(len(X)):
        for i in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[p, i] += h
            Xm[p, i] -= h
            cols.append(((_residuals(T, Xp, oc, op, uv, inv_sigma) - _residuals(T, Xm, oc, op, uv, inv_sigma))
                         / (2 * h)).reshape(-1))
    w = huber_weights((e0 * e0).sum(axis=1))
    return np.stack(cols, axis=1), e0.reshape(-1), np.repeat(w, 2)


def test_normal_equations_match_a_finite_difference_jacobian() -> None:
    T, X, oc, op, uv, inv_sigma = _problem()
    free = [1, 2, 3]
    free_col = np.array([-1, 0, 1, 2])
    Hcc, gc, Hpp, gp, W = normal_equations(T[:, :3, :3], T[:, :3, 3], X, oc, op, uv, inv_sigma, INTR, free_col, 3,
                                           HUBER_DELTA, MIN_DEPTH)
    J, e, w = _dense_system(T, X, oc, op, uv, inv_sigma, free)
    H = J.T @ (w[:, None] * J)
    g = J.T @ (w * e)
    assert (w < 1).sum() >= 3  # the outliers are down-weighted
    np.testing.assert_allclose(Hcc, H[:18, :18], rtol=1e-5, atol=1e-4 * np.abs(H).max())
    np.testing.assert_allclose(gc, g[:18], rtol=1e-5, atol=1e-5 * np.abs(g).max())
    for p in range(len(X)):
        s = slice(18 + 3 * p, 21 + 3 * p)
        np.testing.assert_allclose(Hpp[p], H[s, s], rtol=1e-5, atol=1e-5 * np.abs(H).max())
        np.testing.assert_allclose(gp[p], g[s], rtol=1e-5, atol=1e-5 * np.abs(g).max())
        for o in np.flatnonzero((op == p) & (oc > 0)):
            c = 6 * free_col[oc[o]]
            np.testing.assert_allclose(W[o], H[c:c + 6, s], rtol=1e-5, atol=1e-5 * np.abs(H).max())
    assert np.all(W[oc == 0] == 0)  # the fixed camera has no block
    cost, chi2 = robust_cost(T[:, :3, :3], T[:, :3, 3], X, oc, op, uv, inv_sigma, INTR, HUBER_DELTA, MIN_DEPTH)
    np.testing.assert_allclose(chi2, (e.reshape(-1, 2) ** 2).sum(axis=1), rtol=1e-12)


@pytest.mark.parametrize("free_col", [[-1, 0, 1, 2], [-1, 2, 1, 0]])
def test_schur_step_solves_the_damped_dense_system(free_col: list[int]) -> None:
    # the second order puts each point's later observation in an earlier block column: the kernel's off-diagonal
    # blocks are then filled from the other side of the diagonal
    T, X, oc, op, uv, inv_sigma = _problem(1)
    free_col = np.array(free_col)
    Hcc, gc, Hpp, gp, W = normal_equations(T[:, :3, :3], T[:, :3, 3], X, oc, op, uv, inv_sigma, INTR, free_col, 3,
                                           HUBER_DELTA, MIN_DEPTH)
    n = 18 + 3 * len(X)
    H = np.zeros((n, n))
    H[:18, :18] = Hcc
    for p in range(len(X)):
        s = slice(18 + 3 * p, 21 + 3 * p)
        H[s, s] = Hpp[p]
        for o in np.flatnonzero((op == p) & (oc > 0)):
            c = 6 * free_col[oc[o]]
            H[c:c + 6, s] += W[o]
            H[s, c:c + 6] += W[o].T
    g = np.r_[gc, gp.reshape(-1)]
    by_point = np.argsort(op, kind="stable")
    start = np.searchsorted(op[by_point], np.arange(len(X) + 1))
    # (lam > 0: with one camera fixed the monocular scale is free, so the undamped system is singular)
    for lam in (1e-5 * np.diag(H).max(), 1e-2 * np.diag(H).max(), 10.0):
        dc, dp, ok = schur_step(Hcc, gc, Hpp, gp, W, oc, free_col, by_point, start, lam)
        assert ok
        ref = np.linalg.solve(H + lam * np.eye(n), -g)
        np.testing.assert_allclose(np.r_[dc, dp.reshape(-1)], ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())


def test_left_update_is_se3_exp_times_the_pose() -> None:
    rng = np.random.default_rng(2)
    T = se3_exp(rng.normal(0, 0.5, 6))
    for scale in (0.0, 1e-9, 1e-3, 0.3, 2.5):  # zero, the series branch, and large angles
        xi = rng.normal(0, 1, 6) * scale
        np.testing.assert_allclose(_left_update(T, xi), se3_exp(xi) @ T, atol=1e-13)

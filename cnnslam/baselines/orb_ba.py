"""Pose-only optimisation and (local) bundle adjustment of the ORB-SLAM baseline (ORB-SLAM's ``Optimizer``).

Reprojection residuals are ``e = (pi(K (R_cam_world X + t)) - uv) / sigma`` per observation, with ``sigma =
1.2 ** octave`` pixels of the observing keypoint's pyramid level (ORB-SLAM's information matrix), and a robust
Huber kernel at ``sqrt(5.991)`` (chi-square 95 %, 2 degrees of freedom). Extrinsics are ``T_cam_world`` (world ->
camera), the inverse of this project's ``T_world_cam``; they are updated by left-multiplied twists ``[v, w]``
(:func:`cnnslam.geometry.se3_exp`): ``T <- exp(xi) T``.

- :func:`optimize_pose`: motion-only refinement of one frame against fixed map points (ORB-SLAM's
  PoseOptimization: 4 rounds of 10 Gauss-Newton iterations with Huber weights, observations re-classified as
  outliers at chi2 > 5.991 between rounds): a 6x6 problem, one numba kernel
  (:func:`~cnnslam.baselines.orb_ba_kernels.pose_only`).
- :func:`bundle_adjust`: key-frame poses (some held fixed) and points jointly, by g2o's Levenberg-Marquardt with
  the points marginalised (Schur complement: ORB-SLAM's LocalBundleAdjustment), in numba kernels
  (:mod:`cnnslam.baselines.orb_ba_kernels`); the Huber kernel weights each linearisation as in g2o.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnnslam.baselines.orb_ba_kernels import normal_equations, pose_only, robust_cost, schur_step
from cnnslam.baselines.orb_config import CHI2_2DOF
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import se3_exp

HUBER_DELTA: float = float(np.sqrt(CHI2_2DOF))  # ORB: robust kernel delta sqrt(5.991) on normalised errors
MIN_DEPTH: float = 1e-6  # points closer than this (map units) to a camera plane give no usable residual (ours)
_LM_TAU: float = 1e-5  # g2o OptimizationAlgorithmLevenberg: initial lambda = tau * max diagonal of H
_LM_TRIALS: int = 10  # g2o: tries (lambda raised each time) before an iteration gives up


def project(T_cam_world: np.ndarray, points_world: np.ndarray, intrinsics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (M, 2) and camera depths z (M,) of world points (M, 3) seen by ``T_cam_world`` ((4, 4)).

    intrinsics: [fx, fy, cx, cy]. Points with z <= 0 get NaN pixels.
    """
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    p = np.asarray(points_world, dtype=np.float64) @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = np.where(z > MIN_DEPTH, z, np.nan)
        uv = np.stack([fx * p[:, 0] / zs + cx, fy * p[:, 1] / zs + cy], axis=1)
    return uv, z


def optimize_pose(
    T_cam_world: np.ndarray, points_world: np.ndarray, uv: np.ndarray, inv_sigma: np.ndarray, intrinsics: np.ndarray,
    rounds: int = 4, iterations: int = 10, inliers: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Motion-only bundle adjustment of one camera (ORB-SLAM's PoseOptimization).

    T_cam_world: (4, 4) initial world -> camera; points_world: (M, 3) fixed map points; uv: (M, 2) observed pixels;
    inv_sigma: (M,) 1 / sigma of each observation (pixels^-1); inliers: optional (M,) bool start classification.
    Returns (optimised T_cam_world (4, 4), inlier mask (M,) bool: chi2 <= 5.991 and in front of the camera after
    the last round).
    """
    intr = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    pts = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    m = len(pts)
    use = np.ones(m, bool) if inliers is None else np.asarray(inliers, bool).copy()
    if m == 0:
        return np.array(T_cam_world, dtype=np.float64), use
    return pose_only(np.asarray(T_cam_world, dtype=np.float64), pts, np.asarray(uv, dtype=np.float64),
                     np.asarray(inv_sigma, dtype=np.float64), intr, use, int(rounds), int(iterations), HUBER_DELTA,
                     float(CHI2_2DOF), MIN_DEPTH)


@dataclass(frozen=True)
class BundleResult:
    """Output of :func:`bundle_adjust`.

    T_cam_world: (K, 4, 4) optimised world -> camera of every camera (fixed ones unchanged); points: (P, 3)
    optimised world points; chi2: (O,) squared normalised reprojection error of each observation afterwards;
    cost_initial, cost_final: robust cost sum of rho(chi2) (Huber at sqrt(5.991), g2o's form) before and after;
    iterations: Levenberg-Marquardt iterations run (each one solve that was accepted, or the last rejected one).
    """

    T_cam_world: np.ndarray
    points: np.ndarray
    chi2: np.ndarray
    cost_initial: float
    cost_final: float
    iterations: int


def huber_weights(chi2: np.ndarray, delta: float = HUBER_DELTA) -> np.ndarray:
    """IRLS weights of the Huber kernel on the error norm |e| = sqrt(chi2): 1 inside ``delta``, delta / |e| beyond."""
    norm = np.sqrt(np.asarray(chi2, dtype=np.float64))
    return np.where(norm <= delta, 1.0, delta / np.maximum(norm, 1e-300))


def huber_cost(chi2: np.ndarray, delta: float = HUBER_DELTA) -> float:
    """sum rho(chi2) with g2o's Huber rho(s) = s inside delta^2, 2 delta sqrt(s) - delta^2 beyond."""
    chi2 = np.asarray(chi2, dtype=np.float64)
    return float(np.where(chi2 <= delta**2, chi2, 2 * delta * np.sqrt(chi2) - delta**2).sum())


def bundle_adjust(
    T_cam_world: np.ndarray, fixed: np.ndarray, points: np.ndarray, obs_cam: np.ndarray, obs_point: np.ndarray,
    obs_uv: np.ndarray, obs_inv_sigma: np.ndarray, intrinsics: np.ndarray, iterations: int = 10,
) -> BundleResult:
    """Bundle adjustment of cameras and points by g2o's Levenberg-Marquardt with the points marginalised (Schur
    complement), as ORB-SLAM runs it.

    T_cam_world: (K, 4, 4) initial world -> camera; fixed: (K,) bool cameras held constant (the gauge: at least one
    should be fixed); points: (P, 3) initial world points; obs_cam, obs_point: (O,) int indices of each
    observation's camera and point; obs_uv: (O, 2) pixels; obs_inv_sigma: (O,) 1 / sigma (pixels^-1); intrinsics:
    [fx, fy, cx, cy]; iterations: Levenberg-Marquardt iterations (ORB: 5 before its outlier check, 10 after).

    Each iteration linearises at the current estimate with the Huber kernel's weights (g2o's robustified
    linearisation), solves (H + lambda I) dx = -g through the Schur complement on the points
    (:func:`~cnnslam.baselines.orb_ba_kernels.schur_step`) and keeps the step when the robust cost falls; g2o's
    OptimizationAlgorithmLevenberg: lambda starts at 1e-5 of H's largest diagonal entry, a kept step with gain
    ratio rho scales it by clamp(1 - (2 rho - 1)^3, 1/3, 2/3), a rejected one by 2, 4, 8, ... (at most 10 tries an
    iteration, then the optimisation stops). Cameras move by left twists, points additively.
    """
    T0 = np.asarray(T_cam_world, dtype=np.float64)
    fixed = np.asarray(fixed, dtype=bool)
    X = np.array(points, dtype=np.float64)
    obs_cam = np.asarray(obs_cam, dtype=np.int64)
    obs_point = np.asarray(obs_point, dtype=np.int64)
    uv = np.asarray(obs_uv, dtype=np.float64)
    inv_sigma = np.asarray(obs_inv_sigma, dtype=np.float64)
    intr = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    k, p, o = len(T0), len(X), len(obs_cam)
    if fixed.shape != (k,) or obs_point.shape != (o,) or uv.shape != (o, 2) or inv_sigma.shape != (o,):
        raise CnnSlamError(f"bundle_adjust: inconsistent shapes (cameras {T0.shape}, fixed {fixed.shape}, points "
                           f"{X.shape}, observations {obs_cam.shape} / {obs_point.shape} / {uv.shape})")
    if o and (obs_cam.min() < 0 or obs_cam.max() >= k or obs_point.min() < 0 or obs_point.max() >= p):
        raise CnnSlamError(f"bundle_adjust: observation indices out of range ({k} cameras, {p} points)")
    if o == 0:
        return BundleResult(T0.copy(), X, np.zeros(0), 0.0, 0.0, 0)
    free = np.flatnonzero(~fixed)
    free_col = np.full(k, -1, dtype=np.int64)
    free_col[free] = np.arange(len(free))
    by_point = np.argsort(obs_point, kind="stable")
    point_start = np.searchsorted(obs_point[by_point], np.arange(p + 1))
    T = T0.copy()
    args = (obs_cam, obs_point, uv, inv_sigma, intr)
    cost, chi2 = robust_cost(T[:, :3, :3], T[:, :3, 3], X, *args, HUBER_DELTA, MIN_DEPTH)
    cost0 = float(cost)
    lam, done = 0.0, 0
    for it in range(int(iterations)):
        Hcc, gc, Hpp, gp, W = normal_equations(T[:, :3, :3], T[:, :3, 3], X, *args, free_col, len(free),
                                               HUBER_DELTA, MIN_DEPTH)
        if it == 0:
            diag = np.r_[np.diagonal(Hcc), np.diagonal(Hpp, axis1=1, axis2=2).reshape(-1)]
            lam = _LM_TAU * float(diag.max())
        ni, accepted = 2.0, False
        done += 1
        for _ in range(_LM_TRIALS):
            dc, dp, ok = schur_step(Hcc, gc, Hpp, gp, W, obs_cam, free_col, by_point, point_start, lam)
            if ok:
                T_new = T.copy()
                T_new[free] = se3_exp(dc.reshape(-1, 6)) @ T[free]
                X_new = X + dp
                cost_new, chi2_new = robust_cost(T_new[:, :3, :3], T_new[:, :3, 3], X_new, *args, HUBER_DELTA,
                                                 MIN_DEPTH)
                dx = np.r_[dc, dp.reshape(-1)]
                scale = float(dx @ (lam * dx - np.r_[gc, gp.reshape(-1)])) + 1e-3
                rho = (cost - cost_new) / scale
            if ok and rho > 0 and np.isfinite(cost_new):
                T, X, cost, chi2 = T_new, X_new, cost_new, chi2_new
                lam *= min(max(1.0 - (2.0 * rho - 1.0) ** 3, 1.0 / 3.0), 2.0 / 3.0)
                accepted = True
                break
            lam *= ni
            ni *= 2.0
        if not accepted:
            break
    return BundleResult(T, X, chi2, cost0, float(cost), done)

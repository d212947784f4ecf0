"""Aligning an estimated trajectory onto ground truth before measuring its error.

The estimate is moved onto the ground truth (never the reverse), by the similarity x -> s R x + t of its world
frame, fitted on associated pairs:

- ``se3`` (default): rotation + translation, no scale (Umeyama 1991 with c = 1; identical to Horn's method and to
  the TUM tools' ``evaluate_ate.align``). The paper's ATE is measured this way: recovering absolute scale is the
  point of CNN-SLAM, so scale errors must show.
- ``sim3``: rotation + translation + scale (Umeyama 1991); the scale s is reported.
- ``origin``: the first associated estimated pose is put on the first ground-truth pose (T = T_gt0 T_est0^-1).
- ``none``: the estimate is taken as it is.

Umeyama's fit needs positions that span a plane. When the positions coincide or are collinear (pure rotation, a
straight dolly) the rotation about the line is undetermined; evo raises there. Here se3/sim3 then fall back to
``rotation_only`` (orientations aligned, centroids put together, scale 1), and the :class:`Alignment` says so in
``used`` and ``warning``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from eval.errors import EvalError
from eval.trajectory import se3_inverse, sim3_matrix, transform_poses

MIN_SPREAD_M: float = 0.005  # ours: ground-truth RMS extent along the 2nd principal axis below this = degenerate
MIN_SPREAD_RATIO: float = 0.01  # ours: 2nd / 1st principal extent below this = collinear (either trajectory)


class AlignmentError(EvalError):
    """An alignment that cannot be computed (unknown method, too few pairs, degenerate positions)."""


class AlignmentMethod(StrEnum):
    """How the estimate is aligned onto the ground truth (see the module docstring)."""

    SE3 = "se3"
    SIM3 = "sim3"
    ORIGIN = "origin"
    NONE = "none"


ROTATION_ONLY = "rotation_only"  # the fallback's name in Alignment.used


def parse_method(method: str | AlignmentMethod) -> AlignmentMethod:
    """Validate an alignment method name once."""
    try:
        return AlignmentMethod(method)
    except ValueError:
        valid = ", ".join(m.value for m in AlignmentMethod)
        raise AlignmentError(f"unknown alignment {method!r}; valid alignments: {valid}") from None


@dataclass(frozen=True, eq=False)
class Alignment:
    """The similarity applied to the estimate's world frame: x -> scale * rotation @ x + translation.

    ``requested``: what the caller asked for; ``used``: what was done (``"rotation_only"`` after a degenerate
    fallback); ``warning``: None, or why ``used`` differs from ``requested``.
    """

    requested: AlignmentMethod
    used: str
    rotation: np.ndarray  # (3, 3)
    translation: np.ndarray  # (3,) metres
    scale: float
    warning: str | None = None

    @property
    def matrix(self) -> np.ndarray:
        """4x4 [s R t; 0 1]."""
        return sim3_matrix(self.rotation, self.translation, self.scale)

    def apply(self, T_world_cam: np.ndarray) -> np.ndarray:
        """The aligned poses (N, 4, 4): R' = R R_i, t' = s R t_i + t."""
        return transform_poses(T_world_cam, self.rotation, self.translation, self.scale)

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "requested": self.requested.value,
            "used": self.used,
            "scale": self.scale,
            "warning": self.warning,
        }


# -------------------------------------------------------------------------------------------------------- the fits
def umeyama_alignment(x: np.ndarray, y: np.ndarray, with_scale: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity y ~ c R x + t (Umeyama, "Least-squares estimation of transformation parameters
    between two point patterns", PAMI 1991).

    x, y: (N, 3) corresponding points (x: estimate, y: ground truth). Returns R (3, 3), t (3,), c (1.0 unless
    ``with_scale``). Raises :class:`AlignmentError` if the covariance has rank < 2 (the fit is not unique).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = x.shape[0]
    mean_x, mean_y = x.mean(axis=0), y.mean(axis=0)  # eq. 34, 35
    xc, yc = x - mean_x, y - mean_y
    sigma_x = float((xc**2).sum()) / n  # eq. 36
    cov_xy = yc.T @ xc / n  # eq. 38
    U, d, Vt = np.linalg.svd(cov_xy)
    if np.count_nonzero(d > np.finfo(np.float64).eps * max(d[0], 1.0)) < 2:
        raise AlignmentError("degenerate covariance rank: the positions do not span a plane")
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:  # eq. 39: a reflection is not a rotation
        S[2, 2] = -1.0
    R = U @ S @ Vt  # eq. 40
    c = float(np.trace(np.diag(d) @ S) / sigma_x) if with_scale else 1.0  # eq. 42
    t = mean_y - c * R @ mean_x  # eq. 41
    return R, t, c


def rotation_only_alignment(
    R_gt: np.ndarray, R_est: np.ndarray, p_gt: np.ndarray, p_est: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The world rotation R minimising sum_i |R R_est_i - R_gt_i|_F^2 (chordal mean of R_gt_i R_est_i^T, projected
    onto SO(3) by SVD), and the translation putting the centroids together: t = mean(p_gt) - R mean(p_est)."""
    M = np.einsum("nij,nkj->ik", R_gt, R_est)  # sum_i R_gt_i R_est_i^T
    U, _, Vt = np.linalg.svd(M)
    S = np.eye(3)
    S[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = U @ S @ Vt
    return R, p_gt.mean(axis=0) - R @ p_est.mean(axis=0)


def principal_spreads(positions: np.ndarray) -> np.ndarray:
    """RMS extent (3,) in metres of positions (N, 3) along their principal axes, largest first."""
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 2:
        return np.zeros(3)
    centred = p - p.mean(axis=0)
    eigenvalues = np.linalg.eigvalsh(centred.T @ centred / p.shape[0])  # variances along the principal axes
    return np.sqrt(np.clip(eigenvalues[::-1], 0.0, None))


def degeneracy(
    p_gt: np.ndarray, p_est: np.ndarray, min_spread: float = MIN_SPREAD_M, min_ratio: float = MIN_SPREAD_RATIO
) -> str | None:
    """Why a position-based fit is not determined, or None: fewer than 3 pairs, ground-truth positions that do not
    spread ``min_spread`` metres along a second axis, or either set collinear (2nd / 1st extent < ``min_ratio``)."""
    if p_gt.shape[0] < 3:
        return f"only {p_gt.shape[0]} pose pair(s); a position fit needs 3 or more"
    s_gt, s_est = principal_spreads(p_gt), principal_spreads(p_est)
    if s_gt[1] < min_spread:
        return (
            f"the ground-truth positions span {s_gt[0]:.4g} m x {s_gt[1]:.4g} m (RMS), less than {min_spread} m "
            "across (pure rotation or a straight line)"
        )
    for name, s in (("ground-truth", s_gt), ("estimated", s_est)):
        if s[1] <= min_ratio * s[0]:
            return f"the {name} positions are collinear (principal extents {s[0]:.4g} and {s[1]:.4g})"
    return None


def align(
    T_gt: np.ndarray,
    T_est: np.ndarray,
    method: str | AlignmentMethod = AlignmentMethod.SE3,
    *,
    min_spread: float = MIN_SPREAD_M,
    min_ratio: float = MIN_SPREAD_RATIO,
) -> Alignment:
    """Fit the alignment of associated estimated poses T_est (M, 4, 4) onto ground-truth poses T_gt (M, 4, 4)."""
    method = parse_method(method)
    T_gt = np.asarray(T_gt, dtype=np.float64)
    T_est = np.asarray(T_est, dtype=np.float64)
    if T_gt.shape != T_est.shape or T_gt.ndim != 3 or T_gt.shape[0] == 0:
        raise AlignmentError(f"need two equal, non-empty (M, 4, 4) stacks, got {T_gt.shape} and {T_est.shape}")
    if method == AlignmentMethod.NONE:
        return Alignment(method, method.value, np.eye(3), np.zeros(3), 1.0)
    if method == AlignmentMethod.ORIGIN:
        T = T_gt[0] @ se3_inverse(T_est[0])
        return Alignment(method, method.value, T[:3, :3], T[:3, 3], 1.0)
    p_gt, p_est = T_gt[:, :3, 3], T_est[:, :3, 3]
    reason = degeneracy(p_gt, p_est, min_spread, min_ratio)
    if reason is None:
        try:
            R, t, s = umeyama_alignment(p_est, p_gt, with_scale=method == AlignmentMethod.SIM3)
            return Alignment(method, method.value, R, t, s)
        except AlignmentError as exc:
            reason = str(exc)
    R, t = rotation_only_alignment(T_gt[:, :3, :3], T_est[:, :3, :3], p_gt, p_est)
    warning = f"{method.value} alignment is not determined: {reason}; used rotation-only alignment instead"
    scale = 1.0
    if method == AlignmentMethod.SIM3:
        scale = line_scale(p_gt, p_est, R, min_spread)
        if scale is None:
            warning += " (scale not observable, kept at 1)"
            scale = 1.0
        else:  # positions along a line still fix the scale once the rotation comes from the orientations
            warning += " (scale fitted along the line of motion)"
            t = p_gt.mean(axis=0) - scale * R @ p_est.mean(axis=0)
    return Alignment(method, ROTATION_ONLY, R, t, scale, warning)


def line_scale(p_gt: np.ndarray, p_est: np.ndarray, R: np.ndarray, min_spread: float = MIN_SPREAD_M) -> float | None:
    """Least-squares scale s of y ~ s R x + t for a FIXED rotation R: s = sum(y_c . R x_c) / sum(|x_c|^2), with
    centred positions (N, 3). Defined when the ground truth moves at least ``min_spread`` metres (RMS) along some
    axis (a straight line is enough) and the fit is positive; None otherwise (pure rotation)."""
    if p_gt.shape[0] < 2 or principal_spreads(p_gt)[0] < min_spread:
        return None
    xc = (p_est - p_est.mean(axis=0)) @ R.T
    yc = p_gt - p_gt.mean(axis=0)
    denominator = float((xc**2).sum())
    if denominator <= 0.0:
        return None
    s = float((yc * xc).sum()) / denominator
    return s if s > 0.0 else None

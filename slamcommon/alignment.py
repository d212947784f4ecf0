"""Aligning an estimated trajectory onto ground truth before measuring its error.

The estimate is moved onto the ground truth (never the reverse), by the similarity x -> s R x + t of its world
frame (poses T_world_cam, 4x4 camera-to-world, OpenCV camera axes), fitted on associated pairs:

- ``se3`` (default): rotation + translation, no scale: Umeyama 1991 with c = 1 on the positions, exactly evo's
  ``evo_ape -a`` (``evo.core.geometry.umeyama_alignment``) and the TUM tools' ``evaluate_ate.align`` (Horn). The
  paper's ATE is measured this way: recovering absolute scale is the point of CNN-SLAM, so scale errors must show.
- ``sim3``: rotation + translation + scale (Umeyama 1991), evo's ``evo_ape -as``; the scale s is reported.
- ``origin``: the first associated estimated pose is put on the first ground-truth pose (T = T_gt0 T_est0^-1),
  evo's ``--align_origin``.
- ``none``: the estimate is taken as it is.

Degenerate positions, and where we differ from evo:

- Umeyama's fit is *defined* when the 3x3 cross-covariance of the centred positions has rank >= 2 (evo's test: at
  least two singular values above machine epsilon). Whenever it is defined, se3/sim3 use it, so the figures equal
  evo's, even when the positions are nearly collinear or tiny. Such a fit is *ill-conditioned* (ours, see
  :func:`degeneracy`): the rotation about the line of motion is then decided by noise, which barely moves the ATE
  but makes any rotation error measured after it arbitrary. The :class:`Alignment` then has ``degenerate=True`` and
  a ``warning``; rotation verdicts should read the orientation-only and the RPE rotation figures
  (:mod:`eval.metrics.trajectory_metrics`: ``rot_deg_orient_*``, ``rpe_rot_deg_*``), never ``rot_deg_*``.
- Where Umeyama is *not defined* (all positions coincide, as in a pure-rotation simulation, or lie exactly on a
  line) evo raises; we fall back to ``rotation_only`` (orientations aligned by their chordal mean, centroids put
  together, scale 1; for sim3 a straight line still fixes the scale along it), with ``degenerate=True``,
  ``fallback=True`` and a warning. ``used`` names what was done.
- One difference: when either position set is a single point up to rounding (RMS extent below
  ``COINCIDENT_SPREAD`` relative to the coordinates: a simulated pure rotation whose stored positions differ in the
  last bits), evo's rank test may pass on rounding noise and its rotation is then noise. Every rotation gives the
  same se3 ATE there, so we take the rotation-only fallback: the ATE is evo's, the rotation error meaningful. (For
  sim3 evo would shrink the estimate to a point, scale ~0; we keep scale 1 and report the scale as not observable.)
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from slamcommon.errors import MetricError
from slamcommon.se3 import se3_inverse, sim3_matrix, transform_poses

MIN_SPREAD_M: float = 0.005  # ours: ground-truth RMS extent along the 2nd principal axis below this = degenerate
MIN_SPREAD_RATIO: float = 0.01  # ours: 2nd / 1st principal extent below this = collinear (either trajectory)
MAX_RESIDUAL_RATIO: float = 1.0  # ours: fit residual RMS above this x the 2nd ground-truth extent = noise decides
COINCIDENT_SPREAD: float = 1e-9  # RMS extent below this x max(1, |coordinates|) = one point up to rounding


class AlignmentError(MetricError):
    """An alignment that cannot be computed (unknown method, too few pairs, degenerate positions)."""


class AlignmentMethod(StrEnum):
    """How the estimate is aligned onto the ground truth (see the module docstring)."""

    SE3 = "se3"
    SIM3 = "sim3"
    ORIGIN = "origin"
    NONE = "none"


ROTATION_ONLY = "rotation_only"  # the fallback's name in Alignment.used

ALIGNMENT_TITLES: dict[str, str] = {
    "se3": "SE(3) Umeyama alignment, no scale (= evo_ape -a)",
    "sim3": "Sim(3) Umeyama alignment, with scale (= evo_ape -as)",
    "origin": "first poses aligned (= evo_ape --align_origin)",
    "none": "no alignment",
    ROTATION_ONLY: "rotation-only alignment: positions too degenerate for Umeyama (evo_ape -a would raise)",
}


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

    ``requested``: what the caller asked for; ``used``: what was done (``"rotation_only"`` after a fallback);
    ``degenerate``: the positions do not determine the fit well (ill-conditioned Umeyama, or a fallback);
    ``fallback``: Umeyama was not defined and ``rotation_only`` was used (evo would have refused);
    ``scale_fitted``: ``scale`` was estimated (sim3, or the straight-line fallback), not fixed at 1;
    ``warning``: None, or what is wrong with the fit.
    """

    requested: AlignmentMethod
    used: str
    rotation: np.ndarray  # (3, 3)
    translation: np.ndarray  # (3,) metres
    scale: float
    warning: str | None = None
    degenerate: bool = False
    fallback: bool = False
    scale_fitted: bool = False

    @property
    def matrix(self) -> np.ndarray:
        """4x4 [s R t; 0 1]."""
        return sim3_matrix(self.rotation, self.translation, self.scale)

    @property
    def title(self) -> str:
        """What was done, in words (for reports and tables)."""
        return ALIGNMENT_TITLES[self.used]

    def apply(self, T_world_cam: np.ndarray) -> np.ndarray:
        """The aligned poses (N, 4, 4): R' = R R_i, t' = s R t_i + t."""
        return transform_poses(T_world_cam, self.rotation, self.translation, self.scale)

    def describe(self) -> dict:
        """JSON-ready summary."""
        return {
            "requested": self.requested.value,
            "used": self.used,
            "title": self.title,
            "scale": self.scale,
            "degenerate": self.degenerate,
            "fallback": self.fallback,
            "warning": self.warning,
        }


# -------------------------------------------------------------------------------------------------------- the fits
def umeyama_alignment(x: np.ndarray, y: np.ndarray, with_scale: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity y ~ c R x + t (Umeyama, "Least-squares estimation of transformation parameters
    between two point patterns", PAMI 1991), as evo's ``umeyama_alignment``.

    x, y: (N, 3) corresponding points (x: estimate, y: ground truth). Returns R (3, 3), t (3,), c (1.0 unless
    ``with_scale``). Raises :class:`AlignmentError` when fewer than two singular values of the cross-covariance
    exceed machine epsilon (evo's test, absolute: the fit is not unique).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = x.shape[0]
    mean_x, mean_y = x.mean(axis=0), y.mean(axis=0)  # eq. 34, 35
    xc, yc = x - mean_x, y - mean_y
    sigma_x = float((xc**2).sum()) / n  # eq. 36
    cov_xy = yc.T @ xc / n  # eq. 38
    U, d, Vt = np.linalg.svd(cov_xy)
    if np.count_nonzero(d > np.finfo(np.float64).eps) < 2:
        raise AlignmentError("degenerate covariance rank: the positions do not span a plane")
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:  # eq. 39: a reflection is not a rotation
        S[2, 2] = -1.0
    R = U @ S @ Vt  # eq. 40
    c = float(np.trace(np.diag(d) @ S) / sigma_x) if with_scale else 1.0  # eq. 42
    t = mean_y - c * R @ mean_x  # eq. 41
    return R, t, c


def orientation_alignment(R_gt: np.ndarray, R_est: np.ndarray) -> np.ndarray:
    """The world rotation R (3, 3) minimising sum_i |R R_est_i - R_gt_i|_F^2 over camera-to-world rotations
    (M, 3, 3): the chordal L2 mean of R_gt_i R_est_i^T, i.e. their sum projected onto SO(3) by SVD (Hartley et al.,
    "Rotation averaging", IJCV 2013). Uses orientations only: positions, their spread and the scale play no part.
    """
    M = np.einsum("nij,nkj->ik", np.asarray(R_gt, dtype=np.float64), np.asarray(R_est, dtype=np.float64))
    U, _, Vt = np.linalg.svd(M)  # M = sum_i R_gt_i R_est_i^T
    S = np.eye(3)
    S[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ S @ Vt


def rotation_only_alignment(
    R_gt: np.ndarray, R_est: np.ndarray, p_gt: np.ndarray, p_est: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`orientation_alignment`'s rotation R, and the translation putting the centroids together:
    t = mean(p_gt) - R mean(p_est)."""
    R = orientation_alignment(R_gt, R_est)
    return R, p_gt.mean(axis=0) - R @ p_est.mean(axis=0)


def principal_spreads(positions: np.ndarray) -> np.ndarray:
    """RMS extent (3,) in metres of positions (N, 3) along their principal axes, largest first."""
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 2:
        return np.zeros(3)
    centred = p - p.mean(axis=0)
    eigenvalues = np.linalg.eigvalsh(centred.T @ centred / p.shape[0])  # variances along the principal axes
    return np.sqrt(np.clip(eigenvalues[::-1], 0.0, None))


def coincident(positions: np.ndarray, tol: float = COINCIDENT_SPREAD) -> bool:
    """True when positions (N, 3) are one point up to rounding: RMS extent <= tol * max(1, max |coordinate|)."""
    p = np.asarray(positions, dtype=np.float64)
    return bool(principal_spreads(p)[0] <= tol * max(1.0, float(np.abs(p).max(initial=0.0))))


def degeneracy(
    p_gt: np.ndarray,
    p_est: np.ndarray,
    min_spread: float = MIN_SPREAD_M,
    min_ratio: float = MIN_SPREAD_RATIO,
    residual_rms: float | None = None,
    max_residual_ratio: float = MAX_RESIDUAL_RATIO,
) -> str | None:
    """Why a position-based fit is not (well) determined, or None (ours; evo has no such test).

    Degenerate: fewer than 3 pairs; ground-truth positions that do not spread ``min_spread`` metres (RMS) along a
    second principal axis; either set collinear (2nd / 1st extent < ``min_ratio``); or, given ``residual_rms``
    (metres, what the Sim(3) fit leaves), a residual larger than ``max_residual_ratio`` times the ground truth's 2nd
    extent: the rotation about the main axis of motion is then decided by the estimate's noise (a 0.2 m cloud of
    estimated positions on a nearly pure rotation).
    """
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
    if residual_rms is not None and residual_rms > max_residual_ratio * s_gt[1]:
        return (
            f"the fit's residual ({residual_rms:.4g} m RMS) exceeds the ground truth's extent across its main axis "
            f"({s_gt[1]:.4g} m RMS)"
        )
    return None


def align(
    T_gt: np.ndarray,
    T_est: np.ndarray,
    method: str | AlignmentMethod = AlignmentMethod.SE3,
    *,
    min_spread: float = MIN_SPREAD_M,
    min_ratio: float = MIN_SPREAD_RATIO,
) -> Alignment:
    """Fit the alignment of associated estimated poses T_est (M, 4, 4) onto ground-truth poses T_gt (M, 4, 4).

    se3/sim3: Umeyama on the positions whenever it is defined (the figures equal evo's), flagged ``degenerate`` when
    ill-conditioned (:func:`degeneracy`); ``rotation_only`` fallback where evo would raise (module docstring).
    """
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
    with_scale = method == AlignmentMethod.SIM3
    point = next((name for name, p in (("ground-truth", p_gt), ("estimated", p_est)) if coincident(p)), None)
    if point is not None:
        reason = (
            f"the {point} positions are one point up to rounding, so every rotation gives the same ATE (evo's fit "
            "would rotate by rounding noise)"
        )
        return _rotation_only(T_gt, T_est, method, reason, min_spread)
    try:
        R, t, s = umeyama_alignment(p_est, p_gt, with_scale=with_scale)
    except AlignmentError as exc:
        reason = (degeneracy(p_gt, p_est, min_spread, min_ratio) or str(exc)) + " (evo_ape raises here)"
        return _rotation_only(T_gt, T_est, method, reason, min_spread)
    # R does not depend on the scale, so the noise that decides it is what the best SIMILARITY leaves: a
    # monocular estimate of the wrong size is not ill-conditioned for that
    t_sim, c = (t, s) if with_scale else umeyama_alignment(p_est, p_gt, with_scale=True)[1:]
    residual = float(np.sqrt(np.mean(np.sum((p_gt - (c * p_est @ R.T + t_sim)) ** 2, axis=1))))
    reason = degeneracy(p_gt, p_est, min_spread, min_ratio, residual_rms=residual)
    warning = None
    if reason is not None:
        warning = (
            f"{method.value} alignment is ill-conditioned: {reason}; the fit (as evo's) is kept, but its rotation "
            "is poorly determined: for rotation read rot_deg_orient_* and rpe_rot_deg_*, not rot_deg_*"
        )
    return Alignment(method, method.value, R, t, s, warning, degenerate=reason is not None, scale_fitted=with_scale)


def _rotation_only(
    T_gt: np.ndarray, T_est: np.ndarray, method: AlignmentMethod, reason: str, min_spread: float
) -> Alignment:
    """The fallback where Umeyama is not defined: orientations aligned, centroids together, scale 1 (or, for
    sim3, the scale along a straight line of motion)."""
    p_gt, p_est = T_gt[:, :3, 3], T_est[:, :3, 3]
    R, t = rotation_only_alignment(T_gt[:, :3, :3], T_est[:, :3, :3], p_gt, p_est)
    warning = (
        f"{method.value} alignment is not defined: {reason}; used rotation-only alignment instead"
    )
    scale, fitted = 1.0, False
    if method == AlignmentMethod.SIM3:
        line = line_scale(p_gt, p_est, R, min_spread)
        if line is None:
            warning += " (scale not observable, kept at 1)"
        else:  # positions along a line still fix the scale once the rotation comes from the orientations
            warning += " (scale fitted along the line of motion)"
            scale, fitted = line, True
            t = p_gt.mean(axis=0) - scale * R @ p_est.mean(axis=0)
    return Alignment(method, ROTATION_ONLY, R, t, scale, warning, degenerate=True, fallback=True, scale_fitted=fitted)


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

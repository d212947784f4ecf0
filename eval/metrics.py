"""Trajectory metrics: ATE, RPE, rotation error, scale error, tracked share, trajectory length.

Definitions (all computed on associated pose pairs k = 0..M-1, ground truth Q_k, aligned estimate P_k):

- ATE (absolute trajectory error, Sturm et al. IROS 2012, as the TUM tools and evo_ape compute it): the translation
  error |t(Q_k) - t(P_k)| in metres after :mod:`eval.alignment`; statistics rmse, mean, median, std (population),
  min, max over the M pairs.
- rotation error: the angle of R(Q_k)^T R(P_k) in degrees, after the same alignment.
- RPE (relative pose error, TUM ``evaluate_rpe.py``): E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) over pairs (i, j) a fixed
  delta apart; translational part |t(E)| in metres, rotational part angle(R(E)) in degrees. The delta is counted in
  ``frames`` (associated pairs), ``s`` (seconds of ground-truth time) or ``m`` (metres travelled along the ground
  truth; the TUM script measures along the estimate, which is meaningless for a scale-free monocular estimate).
  j is the pair whose index value is closest to value_i + delta; pairs whose target lies past the end are dropped
  (the TUM script also drops every pair ending on the last pose). All pairs are used (the TUM script samples 10000
  at random). RPE sees the alignment's scale (sim3) but no rigid alignment can change it.
- scale: the Umeyama Sim(3) scale s mapping the estimate onto the ground truth (always fitted, whatever the
  alignment, when the positions allow it). The estimate's size relative to the truth is 1/s, so the scale error is
  |1/s - 1| (0.1 = the estimate is 10 % too large or too small).
- tracked share: frames the agent reported as tracked / all frames it returned.
- length: path length of the (associated) ground truth and of the aligned estimate, metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from eval.alignment import Alignment, AlignmentError, AlignmentMethod, align, degeneracy, umeyama_alignment
from eval.association import DEFAULT_MAX_DIFFERENCE, Association, AssociationRule, associate, associated_pair
from eval.errors import EvalError
from eval.trajectory import PoseTrajectory, distances_along_path, path_length, so3_angle


class RpeUnit(StrEnum):
    """What the RPE delta counts."""

    FRAMES = "frames"
    SECONDS = "s"
    METRES = "m"


_UNIT_ALIASES = {"f": "frames", "frame": "frames", "sec": "s", "seconds": "s", "metres": "m", "meters": "m"}


def parse_rpe_unit(unit: str | RpeUnit) -> RpeUnit:
    """Validate an RPE delta unit once (``frames``/``f``, ``s``, ``m``)."""
    try:
        return RpeUnit(_UNIT_ALIASES.get(str(unit), str(unit)))
    except ValueError:
        raise EvalError(f"unknown RPE delta unit {unit!r}; valid units: frames (f), s, m") from None


# ------------------------------------------------------------------------------------------------------ statistics
@dataclass(frozen=True)
class ErrorStatistics:
    """Summary of a set of errors (units of the errors). All NaN, pairs = 0, for an empty set."""

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    pairs: int

    def to_dict(self) -> dict[str, float | int]:
        return {
            "rmse": self.rmse,
            "mean": self.mean,
            "median": self.median,
            "std": self.std,
            "min": self.min,
            "max": self.max,
            "pairs": self.pairs,
        }


def error_statistics(errors: np.ndarray) -> ErrorStatistics:
    """rmse, mean, median, population std, min, max and count of errors (K,)."""
    e = np.asarray(errors, dtype=np.float64).reshape(-1)
    if e.size == 0:
        nan = math.nan
        return ErrorStatistics(nan, nan, nan, nan, nan, nan, 0)
    return ErrorStatistics(
        rmse=float(np.sqrt(np.mean(e * e))),
        mean=float(e.mean()),
        median=float(np.median(e)),
        std=float(e.std()),
        min=float(e.min()),
        max=float(e.max()),
        pairs=int(e.size),
    )


# ---------------------------------------------------------------------------------------------------------- errors
def translation_errors(T_gt: np.ndarray, T_est: np.ndarray) -> np.ndarray:
    """|t_gt - t_est| (M,) metres for pose stacks (M, 4, 4): the ATE per pair."""
    return np.linalg.norm(T_gt[:, :3, 3] - T_est[:, :3, 3], axis=1)


def rotation_errors_deg(T_gt: np.ndarray, T_est: np.ndarray) -> np.ndarray:
    """angle(R_gt^T R_est) (M,) degrees for pose stacks (M, 4, 4)."""
    return np.degrees(so3_angle(np.swapaxes(T_gt[:, :3, :3], 1, 2) @ T_est[:, :3, :3]))


def rpe_pair_indices(values: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j) with j the index whose value is closest to values[i] + delta (values (M,) non-decreasing).

    Pairs with j <= i, or whose target values[i] + delta lies past values[-1], are dropped.
    """
    v = np.asarray(values, dtype=np.float64)
    if not (delta > 0 and np.isfinite(delta)):
        raise EvalError(f"the RPE delta must be a positive number, got {delta!r}")
    if v.size < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    target = v + delta
    right = np.clip(np.searchsorted(v, target, side="left"), 0, v.size - 1)
    left = np.clip(right - 1, 0, v.size - 1)
    j = np.where(np.abs(v[left] - target) <= np.abs(v[right] - target), left, right)
    i = np.arange(v.size)
    keep = (j > i) & (target <= v[-1] + 1e-9 * max(1.0, abs(v[-1])))
    return i[keep], j[keep]


def relative_pose_errors(
    T_gt: np.ndarray, T_est: np.ndarray, i: np.ndarray, j: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) for pairs (K,); returns |t(E)| (K,) metres and angle(R(E)) (K,) degrees.

    Worked on the 3x3 / 3-vector blocks: with relative motions (R_q, t_q) = Q_i^-1 Q_j and (R_p, t_p) = P_i^-1 P_j,
    E = (R_q^T R_p, R_q^T (t_p - t_q)), so |t(E)| = |t_p - t_q| (a rotation keeps lengths).
    """
    Q_i, Q_j, P_i, P_j = T_gt[i], T_gt[j], T_est[i], T_est[j]
    Rq_iT, Rp_iT = np.swapaxes(Q_i[:, :3, :3], 1, 2), np.swapaxes(P_i[:, :3, :3], 1, 2)
    tq = (Rq_iT @ (Q_j[:, :3, 3] - Q_i[:, :3, 3])[:, :, None])[:, :, 0]  # R_qi^T (t_qj - t_qi)
    tp = (Rp_iT @ (P_j[:, :3, 3] - P_i[:, :3, 3])[:, :, None])[:, :, 0]
    R_q = Rq_iT @ Q_j[:, :3, :3]  # R_qi^T R_qj
    R_p = Rp_iT @ P_j[:, :3, :3]
    return np.linalg.norm(tp - tq, axis=1), np.degrees(so3_angle(np.swapaxes(R_q, 1, 2) @ R_p))


def scale_error(scale: float) -> float:
    """|1/s - 1| for the Sim(3) scale s that maps the estimate onto the truth (NaN if s is not positive)."""
    return abs(1.0 / scale - 1.0) if scale > 0 and np.isfinite(scale) else math.nan


def tracked_share(tracked: np.ndarray) -> float:
    """Share (0..1) of frames reported tracked, tracked (N,) bool."""
    t = np.asarray(tracked).reshape(-1)
    return float(np.count_nonzero(t) / t.size) if t.size else math.nan


def sim3_scale(p_gt: np.ndarray, p_est: np.ndarray) -> float:
    """The Umeyama Sim(3) scale fitting positions p_est (M, 3) onto p_gt (M, 3); NaN if positions are degenerate."""
    if degeneracy(p_gt, p_est) is not None:
        return math.nan
    try:
        return umeyama_alignment(p_est, p_gt, with_scale=True)[2]
    except AlignmentError:
        return math.nan


# -------------------------------------------------------------------------------------------------- the evaluation
@dataclass(frozen=True, eq=False)
class TrajectoryMetrics:
    """Everything measured on one estimated trajectory. Arrays are kept for plots.

    ``gt`` and ``est_aligned``: the associated ground truth and the aligned estimate (M poses each);
    ``ate_errors``: (M,) metres; ``rotation_errors``: (M,) degrees.
    """

    association: Association
    alignment: Alignment
    ate: ErrorStatistics  # metres
    rotation_deg: ErrorStatistics  # degrees
    rpe_translation: ErrorStatistics  # metres
    rpe_rotation_deg: ErrorStatistics  # degrees
    rpe_delta: float
    rpe_unit: RpeUnit
    scale: float  # Umeyama Sim(3) scale (NaN when degenerate)
    scale_error: float  # |1/scale - 1|
    length_gt: float  # metres
    length_est: float  # metres, aligned estimate
    tracked_share: float | None  # 0..1, None when not known
    gt: PoseTrajectory
    est_aligned: PoseTrajectory
    ate_errors: np.ndarray
    rotation_errors: np.ndarray

    @property
    def warnings(self) -> list[str]:
        return [self.alignment.warning] if self.alignment.warning else []

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ATE statistics at the top level (like evo_ape's), then the rest in named blocks."""
        out: dict[str, Any] = dict(self.ate.to_dict())
        out.update(
            {
                "alignment": self.alignment.describe(),
                "association": self.association.describe(),
                "scale": self.scale,
                "scale_error": self.scale_error,
                "rotation_deg": self.rotation_deg.to_dict(),
                "rpe": {
                    "delta": self.rpe_delta,
                    "unit": self.rpe_unit.value,
                    "translation": self.rpe_translation.to_dict(),
                    "rotation_deg": self.rpe_rotation_deg.to_dict(),
                },
                "length_gt_m": self.length_gt,
                "length_est_m": self.length_est,
                "tracked_share": self.tracked_share,
                "warnings": self.warnings,
            }
        )
        return out

    def flat_metrics(self, prefix: str = "") -> dict[str, float]:
        """Scalar metrics under flat names (``ate_rmse``, ``rpe_trans_rmse``, ...), for tables and the gate."""
        m: dict[str, float] = {}
        for block, stats in (
            ("ate", self.ate),
            ("rot_deg", self.rotation_deg),
            ("rpe_trans", self.rpe_translation),
            ("rpe_rot_deg", self.rpe_rotation_deg),
        ):
            for key, value in stats.to_dict().items():
                m[f"{block}_{key}"] = float(value)
        m.update(
            {
                "scale": self.scale,
                "scale_error": self.scale_error,
                "length_gt_m": self.length_gt,
                "length_est_m": self.length_est,
            }
        )
        if self.tracked_share is not None:
            m["tracked_share"] = self.tracked_share
        return {prefix + k: v for k, v in m.items()}


def rpe_index_values(gt: PoseTrajectory, unit: RpeUnit) -> np.ndarray:
    """What the RPE delta is measured along, per associated pair: frame index, ground-truth seconds or metres."""
    if unit == RpeUnit.FRAMES:
        return np.arange(len(gt), dtype=np.float64)
    if unit == RpeUnit.SECONDS:
        return np.asarray(gt.timestamps, dtype=np.float64)
    return distances_along_path(gt.positions)


def evaluate_trajectory(
    gt: PoseTrajectory,
    est: PoseTrajectory,
    *,
    alignment: str | AlignmentMethod = AlignmentMethod.SE3,
    association: str | AssociationRule = AssociationRule.TUM,
    max_difference: float = DEFAULT_MAX_DIFFERENCE,
    offset: float = 0.0,
    rpe_delta: float = 1.0,
    rpe_unit: str | RpeUnit = RpeUnit.SECONDS,
    tracked: np.ndarray | None = None,
) -> TrajectoryMetrics:
    """Associate, align and measure an estimated trajectory against ground truth (see the module docstring).

    ``tracked``: optional (len(est),) bool, what the agent reported per frame.
    """
    unit = parse_rpe_unit(rpe_unit)
    if tracked is not None and np.asarray(tracked).reshape(-1).size != len(est):
        raise EvalError(f"tracked has {np.asarray(tracked).size} entries for an estimate of {len(est)} poses")
    assoc = associate(gt, est, association, max_difference, offset)
    gt_m, est_m = associated_pair(gt, est, assoc)
    fit = align(gt_m.T_world_cam, est_m.T_world_cam, alignment)
    est_aligned = PoseTrajectory(est_m.timestamps, fit.apply(est_m.T_world_cam))
    ate_e = translation_errors(gt_m.T_world_cam, est_aligned.T_world_cam)
    rot_e = rotation_errors_deg(gt_m.T_world_cam, est_aligned.T_world_cam)
    i, j = rpe_pair_indices(rpe_index_values(gt_m, unit), rpe_delta)
    rpe_t, rpe_r = relative_pose_errors(gt_m.T_world_cam, est_aligned.T_world_cam, i, j)
    s = fit.scale if fit.used == AlignmentMethod.SIM3.value else sim3_scale(gt_m.positions, est_m.positions)
    return TrajectoryMetrics(
        association=assoc,
        alignment=fit,
        ate=error_statistics(ate_e),
        rotation_deg=error_statistics(rot_e),
        rpe_translation=error_statistics(rpe_t),
        rpe_rotation_deg=error_statistics(rpe_r),
        rpe_delta=float(rpe_delta),
        rpe_unit=unit,
        scale=float(s),
        scale_error=scale_error(s),
        length_gt=path_length(gt_m.positions),
        length_est=path_length(est_aligned.positions),
        tracked_share=None if tracked is None else tracked_share(np.asarray(tracked, dtype=bool)),
        gt=gt_m,
        est_aligned=est_aligned,
        ate_errors=ate_e,
        rotation_errors=rot_e,
    )

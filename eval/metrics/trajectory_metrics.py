"""Trajectory metrics: ATE (SE(3) and Sim(3)), rotation error, RPE, scale error, tracked share, trajectory length.

Poses are T_world_cam (4x4 camera-to-world, OpenCV camera axes). Definitions (all computed on associated pose pairs
k = 0..M-1, ground truth Q_k, aligned estimate P_k); flat names as in :meth:`TrajectoryMetrics.flat_metrics`:

- ATE (absolute trajectory error, Sturm et al. IROS 2012, as the TUM tools and evo_ape compute it): the translation
  error |t(Q_k) - t(P_k)| in metres after the run's alignment (:mod:`slamcommon.alignment`, default SE(3));
  ``ate_{rmse,mean,median,std,min,max,pairs}``. Whatever the run's alignment, ``ate_se3_rmse`` (metric ATE, SE(3)
  Umeyama = ``evo_ape -a``) and ``ate_sim3_rmse`` (scale-aligned ATE, Sim(3) Umeyama = ``evo_ape -as``) are also
  reported. ``ate_alignment_degenerate`` is 1 when the positions determine the SE(3)/Sim(3) fit badly or not at
  all (:func:`slamcommon.alignment.degeneracy`), ``ate_alignment_fallback`` 1 when Umeyama was not defined and the
  rotation-only fallback was used (evo raises there), else 0.
- rotation error ``rot_deg_*``: the angle of R(Q_k)^T R(P_k) in degrees after the run's alignment. Its rotation
  comes from the POSITIONS: when ``ate_alignment_degenerate`` is 1 (nearly pure rotation, a short straight run) it
  is arbitrary.
- orientation error ``rot_deg_orient_*``: the angle of R(Q_k)^T R_o R(E_k) in degrees, E_k the unaligned estimate,
  after the orientation-only alignment R_o = chordal L2 mean of R(Q_k) R(E_k)^T projected onto SO(3)
  (:func:`slamcommon.alignment.orientation_alignment`): uses orientations only, independent of positions and scale.
- RPE (relative pose error, TUM ``evaluate_rpe.py``): E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) over pairs (i, j) a fixed
  delta apart; translational part |t(E)| in metres (``rpe_trans_*``), rotational part angle(R(E)) in degrees
  (``rpe_rot_deg_*``). The delta is counted in ``frames`` (associated pairs), ``s`` (seconds of ground-truth time)
  or ``m`` (metres travelled along the ground truth; the TUM script measures along the estimate, which is
  meaningless for a scale-free monocular estimate). j is the pair whose index value is closest to value_i + delta;
  pairs whose target lies past the end are dropped (the TUM script also drops every pair ending on the last pose).
  All pairs are used (the TUM script samples 10000 at random). No world-frame alignment changes the RPE: the
  rotational part is alignment-free, the translational part sees only the alignment's scale (sim3).
- relative error at several distances (rpg_trajectory_evaluation's boxplots, Zhang and Scaramuzza IROS 2018;
  ``evo_rpe --delta D --delta_unit m --all_pairs --pairs_from_reference``): the RPE above over pairs (i, j) whose
  ground-truth path distance is D, for D = 10, 20, 30, 40 and 50 % of the ground truth's path length
  (:data:`RELATIVE_PATH_SHARES`, rounded to two significant digits: ``rpe_dist_m_p<share>``); for every i, j > i is
  the pose whose distance along the path from i is nearest to D (the first such), kept when it is within
  :data:`RELATIVE_TOLERANCE` x D of it (rpg's 20 %); ``rpe_trans_rmse_p<share>`` (m) and ``rpe_rot_deg_rmse_p<share>``
  (deg) over those pairs, after the run's alignment as the RPE (a monocular estimate aligned with SE(3) pays for
  its scale here too); NaN when no pair qualifies (a path too short or a tolerance too tight).
- scale ``scale``: the Sim(3) scale s of the ``ate_sim3`` fit (Umeyama whenever defined, as evo's; along the line of
  motion for a straight line; NaN when not observable), whatever the run's alignment. The estimate's size relative
  to the truth is 1/s, so ``scale_error`` = |1/s - 1| (0.1 = the estimate is 10 % too large or too small).
- ``tracked_share``: frames the agent reported as tracked / all frames it returned.
- ``length_gt_m``, ``length_est_m``: path length of the (associated) ground truth and of the aligned estimate.

Which figure to read for a verdict: position accuracy ``ate_rmse`` (metric, the paper's) and ``ate_sim3_rmse``
(shape, up to scale); ROTATION accuracy ``rot_deg_orient_rmse`` (absolute orientation) and ``rpe_rot_deg_rmse``
(drift), never ``rot_deg_rmse`` on rotation-dominant sequences or when ``ate_alignment_degenerate`` is 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from eval.errors import BrokenRunError, EvalError
from eval.metrics.association import DEFAULT_MAX_DIFFERENCE, Association, AssociationRule, associate, associated_pair
from eval.metrics.catalogue import (
    ATE_ALIGNMENT_DEGENERATE,
    ATE_ALIGNMENT_FALLBACK,
    ATE_SE3_RMSE,
    ATE_SIM3_RMSE,
    LENGTH_EST_M,
    LENGTH_GT_M,
    SCALE,
    SCALE_ERROR,
    TRACKED_SHARE,
    relative_keys,
)
from eval.metrics.trajectory import PoseTrajectory, distances_along_path, path_length, so3_angle
from slamcommon.alignment import (
    Alignment,
    AlignmentError,
    AlignmentMethod,
    align,
    degeneracy,
    orientation_alignment,
    umeyama_alignment,
)

MIN_POSE_PAIRS = 2  # a trajectory to align and score: one pose always aligns onto its ground truth (ATE 0)
# relative error at several distances: these percentages of the ground truth's path length (rpg_trajectory_evaluation's
# preset_boxplot_percentages), a pair kept when its path distance is within RELATIVE_TOLERANCE x the distance (rpg's
# max_dist_diff = 0.2 x the distance; evo_rpe's --delta_tol)
RELATIVE_PATH_SHARES: tuple[int, ...] = (10, 20, 30, 40, 50)
RELATIVE_TOLERANCE = 0.2


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


def path_distance_pairs(distances: np.ndarray, delta: float, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j) a path distance ``delta`` apart (evo's ``filter_pairs_by_path`` with ``all_pairs``): for every
    i, j > i is the index whose ``distances[j] - distances[i]`` is nearest to ``delta`` (the first of equals), kept
    when it differs from ``delta`` by at most ``tolerance``. ``distances`` (M,): non-decreasing distance travelled
    (:func:`eval.metrics.trajectory.distances_along_path`), metres; ``delta``, ``tolerance`` metres."""
    d = np.asarray(distances, dtype=np.float64).reshape(-1)
    if not (delta > 0 and np.isfinite(delta)):
        raise EvalError(f"a relative-error distance must be a positive number of metres, got {delta!r}")
    if d.size < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    i = np.arange(d.size - 1)
    target = d[:-1] + delta
    right = np.clip(np.searchsorted(d, target, side="left"), i + 1, d.size - 1)  # first j with d[j] >= target
    left = np.searchsorted(d, d[right - 1], side="left")  # the first index holding the value just below the target
    has_left = right - 1 >= i + 1
    left = np.where(has_left, np.maximum(left, i + 1), right)
    start = d[:-1]  # the misses as evo computes them, (d[j] - d[i]) - delta, so that the same pairs pass
    miss_left, miss_right = np.abs((d[left] - start) - delta), np.abs((d[right] - start) - delta)
    j = np.where(miss_left <= miss_right, left, right)
    keep = np.minimum(miss_left, miss_right) <= tolerance
    return i[keep], j[keep]


def relative_distance(length_m: float, share: int) -> float:
    """``share`` percent of a path ``length_m`` metres long, rounded to two significant digits (metres; 0 for no
    path)."""
    value = length_m * share / 100.0
    return float(f"{value:.2g}") if value > 0 and np.isfinite(value) else 0.0


@dataclass(frozen=True, eq=False)
class RelativeErrors:
    """The relative error at one distance: ``share`` (percent of the ground truth's path length), ``distance_m``
    (metres), and per pair ``translation`` (K,) metres and ``rotation_deg`` (K,) degrees (K = 0: no pair)."""

    share: int
    distance_m: float
    translation: np.ndarray
    rotation_deg: np.ndarray


def relative_errors(gt: PoseTrajectory, est: PoseTrajectory, shares: tuple[int, ...] = RELATIVE_PATH_SHARES,
                    tolerance: float = RELATIVE_TOLERANCE) -> tuple[RelativeErrors, ...]:
    """The relative error (module docstring) of ``est`` against ``gt`` (associated: pair k = k; ``est`` aligned as
    it is to be scored) at ``shares`` percent of ``gt``'s path length, pairs measured along ``gt``'s path and kept
    within ``tolerance`` x the distance."""
    if len(gt) != len(est):
        raise EvalError(f"associated trajectories must have the same length, got {len(gt)} and {len(est)}")
    distances = distances_along_path(gt.positions)
    out = []
    for share in shares:
        delta = relative_distance(float(distances[-1]) if distances.size else 0.0, share)
        if delta > 0:
            i, j = path_distance_pairs(distances, delta, tolerance * delta)
            trans, rot = relative_pose_errors(gt.T_world_cam, est.T_world_cam, i, j)
        else:
            trans, rot = np.zeros(0), np.zeros(0)
        out.append(RelativeErrors(int(share), delta, trans, rot))
    return tuple(out)


def rotation_angle_ratio(
    gt: PoseTrajectory, est: PoseTrajectory, delta_s: float = 0.5, min_angle_deg: float = 2.0
) -> tuple[float, int]:
    """How far the estimate turns per turn of the reference: sum of angle(P_i^-1 P_j) / sum of angle(Q_i^-1 Q_j)
    over pairs (i, j) about ``delta_s`` seconds apart (:func:`rpe_pair_indices` on ``gt``'s timestamps) whose
    reference rotation exceeds ``min_angle_deg``. ``gt`` and ``est`` are already associated (same length).
    Returns (ratio, pairs used); ratio NaN when no pair turns enough.

    A ratio below 1 that every method shares (feature-based and direct) points at the camera model or at the
    reference, not at a tracker: an angle read through a too-long focal length comes out too small.
    """
    if len(gt) != len(est):
        raise EvalError(f"associated trajectories must have the same length, got {len(gt)} and {len(est)}")
    i, j = rpe_pair_indices(gt.timestamps, delta_s)
    Rg, Re = gt.rotations, est.rotations
    angle_gt = np.degrees(so3_angle(np.swapaxes(Rg[i], 1, 2) @ Rg[j]))
    angle_est = np.degrees(so3_angle(np.swapaxes(Re[i], 1, 2) @ Re[j]))
    turning = angle_gt > min_angle_deg
    n = int(turning.sum())
    if n == 0:
        return math.nan, 0
    return float(angle_est[turning].sum() / angle_gt[turning].sum()), n


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
    """Everything measured on one estimated trajectory (see the module docstring). Arrays are kept for plots.

    ``alignment``: the run's alignment (ATE, rotation error, RPE, length); ``se3_alignment``, ``sim3_alignment``:
    the SE(3) and Sim(3) Umeyama fits behind ``ate_se3_rmse`` and ``ate_sim3_rmse`` (the same object as
    ``alignment`` when that is one of them); ``orientation_rotation``: R_o (3, 3) of the orientation-only alignment.
    ``gt``, ``est`` and ``est_aligned``: the associated ground truth, estimate and aligned estimate (M poses each);
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
    scale: float  # Sim(3) scale of sim3_alignment (NaN when not observable)
    scale_error: float  # |1/scale - 1|
    length_gt: float  # metres
    length_est: float  # metres, aligned estimate
    tracked_share: float | None  # 0..1, None when not known
    gt: PoseTrajectory
    est_aligned: PoseTrajectory
    ate_errors: np.ndarray
    rotation_errors: np.ndarray
    se3_alignment: Alignment
    sim3_alignment: Alignment
    ate_se3_rmse: float  # metres
    ate_sim3_rmse: float  # metres
    orientation_rotation: np.ndarray  # (3, 3)
    rotation_orient_deg: ErrorStatistics  # degrees, after the orientation-only alignment
    relative: tuple[RelativeErrors, ...] = ()  # the relative error at several distances (module docstring)
    est: PoseTrajectory | None = None  # the associated estimate before any alignment

    def aligned(self, alignment: str | AlignmentMethod) -> PoseTrajectory:
        """The associated estimate after ``alignment``: ``se3`` or ``sim3`` (the fits behind ``ate_se3_rmse`` and
        ``ate_sim3_rmse``), or the run's own (:attr:`alignment`'s requested method)."""
        method = AlignmentMethod(str(alignment))
        if method == self.alignment.requested:
            return self.est_aligned
        fits = {AlignmentMethod.SE3: self.se3_alignment, AlignmentMethod.SIM3: self.sim3_alignment}
        if method not in fits or self.est is None:
            raise EvalError(f"no {method.value} fit kept for this trajectory; the kept ones: se3, sim3 and the run's "
                            f"own ({self.alignment.requested.value})")  # fmt: skip
        return PoseTrajectory(self.est.timestamps, fits[method].apply(self.est.T_world_cam))

    @property
    def degenerate(self) -> bool:
        """The positions determine the SE(3)/Sim(3) fit badly or not at all."""
        return any(a.degenerate for a in (self.alignment, self.se3_alignment, self.sim3_alignment))

    @property
    def fallback(self) -> bool:
        """Umeyama was not defined on these positions and a rotation-only fallback was used."""
        return any(a.fallback for a in (self.alignment, self.se3_alignment, self.sim3_alignment))

    @property
    def warnings(self) -> list[str]:
        """The run's alignment's warning, else the SE(3) or Sim(3) fit's (one line: they share the positions)."""
        for fit in (self.alignment, self.se3_alignment, self.sim3_alignment):
            if fit.warning:
                return [fit.warning]
        return []

    def describe_alignment(self) -> dict[str, Any]:
        """JSON-ready: the run's alignment (requested, used, title, scale, degenerate, fallback, warning), with the
        SE(3) and Sim(3) fits behind ``ate_se3_rmse`` / ``ate_sim3_rmse`` under ``se3`` and ``sim3``, and the
        orientation-only alignment behind ``rot_deg_orient_*`` under ``orientation``."""
        out: dict[str, Any] = self.alignment.describe()
        out["se3"] = self.se3_alignment.describe()
        out["sim3"] = self.sim3_alignment.describe()
        out["orientation"] = "chordal L2 mean of R_gt_k R_est_k^T projected onto SO(3) (orientations only)"
        return out

    def describe_rpe(self) -> dict[str, Any]:
        """JSON-ready: the RPE pair distance."""
        return {"delta": self.rpe_delta, "unit": self.rpe_unit.value}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, in the run record's names (:mod:`eval.metrics.results`): ``alignment``, ``association``, ``rpe``,
        ``warnings`` and ``metrics`` (:meth:`flat_metrics`)."""
        return {
            "alignment": self.describe_alignment(),
            "association": self.association.describe(),
            "rpe": self.describe_rpe(),
            "warnings": self.warnings,
            "metrics": self.flat_metrics(),
        }

    def flat_metrics(self, prefix: str = "") -> dict[str, float]:
        """Scalar metrics under flat names (``ate_rmse``, ``rpe_trans_rmse``, ...), for tables and the gate; every
        value a float (flags 0.0 / 1.0). Names and meanings: the module docstring."""
        m: dict[str, float] = {}
        for block, stats in (
            ("ate", self.ate),
            ("rot_deg", self.rotation_deg),
            ("rpe_trans", self.rpe_translation),
            ("rpe_rot_deg", self.rpe_rotation_deg),
            ("rot_deg_orient", self.rotation_orient_deg),
        ):
            for key, value in stats.to_dict().items():
                if block == "rot_deg_orient" and key == "pairs":  # = ate_pairs
                    continue
                m[f"{block}_{key}"] = float(value)
        m.update(
            {
                ATE_SE3_RMSE.key: self.ate_se3_rmse,
                ATE_SIM3_RMSE.key: self.ate_sim3_rmse,
                ATE_ALIGNMENT_DEGENERATE.key: float(self.degenerate),
                ATE_ALIGNMENT_FALLBACK.key: float(self.fallback),
                SCALE.key: self.scale,
                SCALE_ERROR.key: self.scale_error,
                LENGTH_GT_M.key: self.length_gt,
                LENGTH_EST_M.key: self.length_est,
            }
        )
        for rel in self.relative:
            distance, translation, rotation = relative_keys(rel.share)
            m[distance] = rel.distance_m
            m[translation] = error_statistics(rel.translation).rmse
            m[rotation] = error_statistics(rel.rotation_deg).rmse
        if self.tracked_share is not None:
            m[TRACKED_SHARE.key] = self.tracked_share
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

    ``tracked``: optional (len(est),) bool, what the agent reported per frame. Fewer than :data:`MIN_POSE_PAIRS`
    associated poses is no trajectory to align or compare (one pose always aligns onto its ground truth: ATE 0):
    :class:`~eval.errors.BrokenRunError`, never a figure.
    """
    unit = parse_rpe_unit(rpe_unit)
    if tracked is not None and np.asarray(tracked).reshape(-1).size != len(est):
        raise EvalError(f"tracked has {np.asarray(tracked).size} entries for an estimate of {len(est)} poses")
    assoc = associate(gt, est, association, max_difference, offset)
    if len(assoc) < MIN_POSE_PAIRS:
        raise BrokenRunError(f"only {len(assoc)} pose(s) of the estimate ({len(est)} given) match the ground truth's "
                             f"{len(gt)}: a trajectory needs at least {MIN_POSE_PAIRS} to be aligned and scored")
    gt_m, est_m = associated_pair(gt, est, assoc)
    T_gt, T_est = gt_m.T_world_cam, est_m.T_world_cam
    fit = align(T_gt, T_est, alignment)
    both = (AlignmentMethod.SE3, AlignmentMethod.SIM3)
    fits = {m: fit if fit.requested == m else align(T_gt, T_est, m) for m in both}
    est_aligned = PoseTrajectory(est_m.timestamps, fit.apply(T_est))
    ate_e = translation_errors(T_gt, est_aligned.T_world_cam)
    ate_rmse = {m: float(np.sqrt(np.mean(translation_errors(T_gt, f.apply(T_est)) ** 2))) for m, f in fits.items()}
    rot_e = rotation_errors_deg(T_gt, est_aligned.T_world_cam)
    R_o = orientation_alignment(T_gt[:, :3, :3], T_est[:, :3, :3])
    orient_e = np.degrees(so3_angle(np.swapaxes(T_gt[:, :3, :3], 1, 2) @ R_o @ T_est[:, :3, :3]))
    i, j = rpe_pair_indices(rpe_index_values(gt_m, unit), rpe_delta)
    rpe_t, rpe_r = relative_pose_errors(T_gt, est_aligned.T_world_cam, i, j)
    sim3 = fits[AlignmentMethod.SIM3]
    s = sim3.scale if sim3.scale_fitted else math.nan
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
        se3_alignment=fits[AlignmentMethod.SE3],
        sim3_alignment=sim3,
        ate_se3_rmse=ate_rmse[AlignmentMethod.SE3],
        ate_sim3_rmse=ate_rmse[AlignmentMethod.SIM3],
        orientation_rotation=R_o,
        rotation_orient_deg=error_statistics(orient_e),
        relative=relative_errors(gt_m, est_aligned),
        est=est_m,
    )

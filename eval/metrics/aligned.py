"""A trajectory aligned onto its ground truth as a TUM file, the way evo users overlay and score it (``evo_traj tum
ALIGNED --ref GROUNDTRUTH``, ``evo_ape tum GROUNDTRUTH ALIGNED`` without ``-a``): each benchmark run folder keeps its
estimate aligned with SE(3) (``evo_ape -a``) and, for a monocular method, with Sim(3) (``evo_ape -as``: a monocular
trajectory has no scale of its own), beside the unaligned ``trajectory.tum``; ``cnnslam eval --save-aligned`` writes
the same for any pair of files.

The text is made here (no I/O); the callers write it. Timestamps are the associated estimate's, poses
``T_world_cam`` in the ground truth's world frame and metres (TUM: ``timestamp tx ty tz qx qy qz qw``)."""

from __future__ import annotations

from collections.abc import Sequence

from eval.metrics.catalogue import ATE_SE3_RMSE, ATE_SIM3_RMSE
from eval.metrics.trajectory_metrics import TrajectoryMetrics
from slamcommon.alignment import ALIGNMENT_TITLES, AlignmentMethod
from slamcommon.formats import format_tum_trajectory

# the aligned files of a run folder, by alignment
ALIGNED_FILES: dict[str, str] = {"se3": "trajectory_aligned_se3.tum", "sim3": "trajectory_aligned_sim3.tum"}


def aligned_alignments(sensor: str | None) -> tuple[str, ...]:
    """The alignments a run folder keeps its trajectory under: SE(3) always, Sim(3) too for a monocular method
    (``sensor`` mono, or not known)."""
    return ("se3", "sim3") if sensor in (None, "mono") else ("se3",)


def aligned_tum_text(metrics: TrajectoryMetrics, alignment: str, title: str = "") -> str:
    """The associated estimate of ``metrics`` after ``alignment`` (``se3``, ``sim3`` or the run's own) as the text of
    a TUM file, with a header saying what it is (``title``), how it was aligned and its ATE RMSE (m)."""
    method = AlignmentMethod(str(alignment))
    aligned = metrics.aligned(method)
    fit = metrics.alignment if method == metrics.alignment.requested else (
        metrics.se3_alignment if method == AlignmentMethod.SE3 else metrics.sim3_alignment)
    flat = metrics.flat_metrics()
    rmse = {AlignmentMethod.SE3: flat[ATE_SE3_RMSE.key], AlignmentMethod.SIM3: flat[ATE_SIM3_RMSE.key]}.get(
        method, metrics.ate.rmse)
    lines = [title] if title else []
    lines.append(f"aligned onto the ground truth: {ALIGNMENT_TITLES.get(fit.used, fit.used)}"
                 + (f", scale {fit.scale:.6f}" if fit.scale_fitted else "") + f"; ATE RMSE {rmse:.6f} m")
    if fit.warning:
        lines.append(f"warning: {fit.warning}")
    return format_tum_trajectory(aligned.timestamps, aligned.T_world_cam, header="\n".join(lines))


def aligned_files(metrics: TrajectoryMetrics, alignments: Sequence[str], title: str = "") -> dict[str, str]:
    """File name (:data:`ALIGNED_FILES`) -> TUM text for each of ``alignments`` (``se3``, ``sim3``)."""
    return {ALIGNED_FILES[a]: aligned_tum_text(metrics, a, title) for a in alignments}

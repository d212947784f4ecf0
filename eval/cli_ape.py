"""``cnnslam eval GROUNDTRUTH ESTIMATE``: score an estimated trajectory against ground truth, like evo_ape.

Prints the association and alignment used, the ATE statistics (metres), the rotation error (degrees), the RPE and
the Sim(3) scale. ``--json`` prints exactly one JSON object instead (keys: rmse, mean, median, std, min, max, pairs,
alignment, association, scale, scale_error, rotation_deg, rpe, length_gt_m, length_est_m, warnings, files).
Exit status: 0 on success, 1 when the files cannot be scored (the message says why), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import json
import sys

from eval.alignment import AlignmentMethod
from eval.association import DEFAULT_MAX_DIFFERENCE, AssociationRule
from eval.errors import EvalError
from eval.metrics import ErrorStatistics, RpeUnit, TrajectoryMetrics, evaluate_trajectory
from eval.results import json_ready
from eval.trajectory import PoseTrajectory
from sim_envs.formats import DUPLICATE_POLICIES

_ALIGN_TITLES = {
    "se3": "SE(3) Umeyama alignment (no scale)",
    "sim3": "Sim(3) Umeyama alignment (with scale)",
    "origin": "origin alignment (first poses)",
    "none": "no alignment",
    "rotation_only": "rotation-only alignment (positions degenerate)",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("groundtruth", help="ground-truth trajectory file")
    parser.add_argument("estimate", help="estimated trajectory file")
    parser.add_argument("--format", choices=("tum", "kitti"), default="tum", help="file format (default: tum)")
    parser.add_argument(
        "--align",
        choices=[m.value for m in AlignmentMethod],
        default=AlignmentMethod.SE3.value,
        help="alignment of the estimate onto the ground truth (default: se3)",
    )
    parser.add_argument(
        "--association",
        choices=[AssociationRule.TUM.value, AssociationRule.NEAREST.value],
        default=AssociationRule.TUM.value,
        help="timestamp association: tum = TUM tools' greedy one-to-one (default), nearest = evo's nearest match",
    )
    parser.add_argument(
        "--max-diff",
        type=float,
        default=DEFAULT_MAX_DIFFERENCE,
        metavar="SECONDS",
        help=f"max. timestamp difference for a pair (default: {DEFAULT_MAX_DIFFERENCE})",
    )
    parser.add_argument("--offset", type=float, default=0.0, metavar="SECONDS", help="added to the estimate's stamps")
    parser.add_argument(
        "--duplicates",
        choices=DUPLICATE_POLICIES,
        default="error",
        help="a repeated timestamp in a file: error (default), or keep the first / last pose (the TUM tools: last)",
    )
    parser.add_argument("--rpe-delta", type=float, default=1.0, help="RPE pair distance (default: 1.0)")
    parser.add_argument(
        "--rpe-unit",
        choices=[u.value for u in RpeUnit],
        default=RpeUnit.SECONDS.value,
        help="unit of --rpe-delta: frames, s (default) or m (along the ground truth)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the text report")
    parser.add_argument("--plot", metavar="FILE", help="save a figure (trajectories, x/y/z, ATE over time) to FILE")


def run(args: argparse.Namespace) -> int:
    try:
        gt, est = _load(args.groundtruth, args), _load(args.estimate, args)
        metrics = evaluate_trajectory(
            gt,
            est,
            alignment=args.align,
            association=AssociationRule.INDEX if args.format == "kitti" else args.association,
            max_difference=args.max_diff,
            offset=args.offset,
            rpe_delta=args.rpe_delta,
            rpe_unit=args.rpe_unit,
        )
    except EvalError as exc:
        print(f"cnnslam eval: error: {exc}", file=sys.stderr)
        return 1
    if args.plot:
        from eval.plots import save_trajectory_figure

        save_trajectory_figure(
            args.plot,
            metrics.gt.timestamps,
            metrics.gt.positions,
            metrics.est_aligned.positions,
            metrics.ate_errors,
            title=f"{args.estimate}: ATE RMSE {metrics.ate.rmse:.4f} m ({metrics.alignment.used})",
        )
    if args.json:
        out = metrics.to_dict()
        out["files"] = {"groundtruth": args.groundtruth, "estimate": args.estimate}
        print(json.dumps(json_ready(out), allow_nan=False))
    else:
        print(format_report(metrics, args.groundtruth, args.estimate))
        if args.plot:
            print(f"\nfigure: {args.plot}")
    for warning in metrics.warnings:
        print(f"cnnslam eval: warning: {warning}", file=sys.stderr)
    return 0


def _load(path: str, args: argparse.Namespace) -> PoseTrajectory:
    if args.format == "kitti":
        return PoseTrajectory.from_kitti_file(path)
    return PoseTrajectory.from_tum_file(path, duplicate_timestamps=args.duplicates)


def _stats_lines(stats: ErrorStatistics, digits: int = 6) -> list[str]:
    return [f"{k:>10}  {v:.{digits}f}" if isinstance(v, float) else f"{k:>10}  {v}" for k, v in stats.to_dict().items()]


def format_report(m: TrajectoryMetrics, gt_path: str, est_path: str) -> str:
    """The text report printed by ``cnnslam eval`` (evo_ape-like)."""
    a = m.association
    lines = [
        f"ground truth: {gt_path}",
        f"estimate:     {est_path}",
        f"association:  {a.rule.value}, max. difference {a.max_difference} s, offset {a.offset} s, {len(a)} pairs",
        f"alignment:    {_ALIGN_TITLES[m.alignment.used]}"
        + (f", scale {m.alignment.scale:.4f}" if m.alignment.used == "sim3" else ""),
        "",
        "APE w.r.t. translation part (m)",
        *_stats_lines(m.ate),
        "",
        "rotation error after alignment (deg)",
        *_stats_lines(m.rotation_deg, 4),
        "",
        f"RPE over {m.rpe_delta:g} {m.rpe_unit.value}: translation (m)",
        *_stats_lines(m.rpe_translation),
        f"RPE over {m.rpe_delta:g} {m.rpe_unit.value}: rotation (deg)",
        *_stats_lines(m.rpe_rotation_deg, 4),
        "",
        f"Sim(3) scale {m.scale:.4f} (scale error |1/s - 1| = {m.scale_error:.4f})",
        f"length: ground truth {m.length_gt:.3f} m, aligned estimate {m.length_est:.3f} m",
    ]
    return "\n".join(lines)

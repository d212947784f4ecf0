"""``cnnslam eval GROUNDTRUTH ESTIMATE``: score an estimated trajectory against ground truth, like evo_ape.

Prints the association and alignment used, the ATE statistics (metres) after the requested alignment, the metric
(SE(3)) and scale-aligned (Sim(3)) ATE RMSE, the rotation error after that alignment and after orientation-only
alignment (degrees), the RPE and the Sim(3) scale. Repeated timestamps in a TUM file (the official fr2/desk ground
truth has one) keep the last pose, as the TUM tools and evo do, with one warning line on stderr
(``--duplicates error|first`` for other policies). ``--save-aligned FILE`` writes the estimate after the alignment
as a TUM file (the associated poses at the estimate's timestamps, in the ground truth's frame:
:mod:`eval.metrics.aligned`), for ``evo_traj tum FILE --ref GROUNDTRUTH`` and ``evo_ape`` without ``-a``.

``--json`` prints exactly one JSON object instead, schema ``cnnslam-eval/1``::

    {"schema": "cnnslam-eval/1", "files": {"groundtruth": str, "estimate": str},
     "alignment": {...}, "association": {...}, "rpe": {"delta": float, "unit": str}, "warnings": [str, ...],
     "metrics": {name: float, ...}}

``alignment``, ``association``, ``rpe``, ``warnings`` and ``metrics`` have the names and meaning of the same keys
of a run record (``metrics.json``, schema ``cnnslam-run/1``, :mod:`eval.metrics.results`); ``metrics`` holds its
trajectory metrics under the names of the metric catalogue (:mod:`eval.metrics.catalogue`; each statistic of the
ATE, the rotation errors and the RPE under its block's prefix; defined in :mod:`eval.metrics.trajectory_metrics`),
without the run-only ones (the tracked share, frames, depth, semantic, timing). NaN is written as null.

Exit status: 0 on success; 2 on bad input, found before anything is computed (an option out of its range, a file
that is missing or malformed, an output path that cannot be written), with one line naming the value and what is
valid; 1 when two readable files cannot be scored together (too few matching timestamps: the message says why).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

# Set before numpy loads its BLAS, so only where this module brings numpy in (the ``cnnslam eval`` process; a process
# that imported numpy first keeps its own setting) and only where the caller set nothing: every product here is 3x3
# or (N, 3) x (3, 3), where BLAS threads only wait on each other (on a busy 2-core machine an (N, 3) x (3, 3)
# product took 36 ms of CPU threaded and 1 ms on one thread, with the same bits). The pool's workers do the same
# (:data:`slamcommon.threads.THREAD_VARIABLES`, of which these are the BLAS ones).
from slamcommon.threads import BLAS_THREAD_VARIABLES  # imports no numpy

if "numpy" not in sys.modules:
    for _name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(_name, "1")

from eval.errors import EvalError, InputError
from eval.metrics.association import DEFAULT_MAX_DIFFERENCE, AssociationRule
from eval.metrics.catalogue import ATE_SE3_RMSE, ATE_SIM3_RMSE, SCALE_ERROR
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import (
    RELATIVE_TOLERANCE,
    ErrorStatistics,
    RpeUnit,
    TrajectoryMetrics,
    error_statistics,
    evaluate_trajectory,
)
from slamcommon.alignment import ALIGNMENT_TITLES, AlignmentMethod
from slamcommon.errors import MetricError, ProjectError
from slamcommon.formats import DUPLICATE_POLICIES
from slamcommon.output_paths import check_output_file
from slamcommon.strict_json import json_ready

EVAL_SCHEMA = "cnnslam-eval/1"


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
        default="last",
        help="a repeated timestamp in a TUM file: keep the last pose (default; the TUM tools and evo), the first, "
        "or error",
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
    parser.add_argument("--save-aligned", metavar="FILE", help="write the estimate after --align (the associated "
                        "poses, in the ground truth's frame) as a TUM file, e.g. for evo_traj")


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse, before any file is read, an option out of its range (``--max-diff`` and ``--rpe-delta`` positive and
    finite, a whole number of frames with ``--rpe-unit frames``; ``--offset`` finite) and an output path that cannot
    be written (``--plot``, ``--save-aligned``, which must not be one of the input files):
    :class:`~eval.errors.InputError` or
    :class:`~slamcommon.output_paths.OutputPathError`, one line naming the option, its value and what is valid."""
    if not (math.isfinite(args.max_diff) and args.max_diff > 0):
        raise InputError(f"--max-diff {args.max_diff:g}: must be a positive number of seconds (default "
                         f"{DEFAULT_MAX_DIFFERENCE:g})")
    if not math.isfinite(args.offset):
        raise InputError(f"--offset {args.offset:g}: must be a finite number of seconds")
    if not (math.isfinite(args.rpe_delta) and args.rpe_delta > 0):
        unit = {"frames": "frames", "s": "seconds", "m": "metres"}[args.rpe_unit]
        raise InputError(f"--rpe-delta {args.rpe_delta:g}: must be a positive number of {unit} (default 1)")
    if args.rpe_unit == RpeUnit.FRAMES.value and args.rpe_delta != int(args.rpe_delta):
        raise InputError(f"--rpe-delta {args.rpe_delta:g}: with --rpe-unit frames it must be a whole number of "
                         "frames >= 1")
    if args.plot:
        from eval.reports.plots import check_figure_path

        try:
            check_figure_path(args.plot)
        except EvalError as exc:
            raise InputError(f"--plot: {exc}") from None
        check_output_file(args.plot, "--plot")
    if args.save_aligned:
        check_output_file(args.save_aligned, "--save-aligned")
        for role, given in (("ground truth", args.groundtruth), ("estimate", args.estimate)):
            if Path(given).resolve() == Path(args.save_aligned).resolve():
                raise InputError(f"--save-aligned {args.save_aligned}: that is the {role} file, which it would "
                                 "overwrite; name another file")


def run(args: argparse.Namespace) -> int:
    try:  # bad options, unreadable or malformed files and unwritable outputs: refused before anything is computed
        check_arguments(args)
        gt, est = _load(args.groundtruth, args), _load(args.estimate, args)
    except ProjectError as exc:
        print(f"cnnslam eval: error: {exc}", file=sys.stderr)
        return 2
    try:
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
    except (EvalError, MetricError) as exc:
        print(f"cnnslam eval: error: {exc}", file=sys.stderr)
        return 1
    if args.plot:
        from eval.reports.plots import save_trajectory_figure

        save_trajectory_figure(
            args.plot,
            metrics.gt.timestamps,
            metrics.gt.positions,
            metrics.est_aligned.positions,
            metrics.ate_errors,
            title=f"{args.estimate}: ATE RMSE {metrics.ate.rmse:.4f} m ({metrics.alignment.used})",
        )
    if args.save_aligned:
        from eval.metrics.aligned import aligned_tum_text

        Path(args.save_aligned).parent.mkdir(parents=True, exist_ok=True)
        Path(args.save_aligned).write_text(aligned_tum_text(metrics, args.align, f"estimate: {args.estimate}"))
    if args.json:
        out = {"schema": EVAL_SCHEMA, "files": {"groundtruth": args.groundtruth, "estimate": args.estimate}}
        out.update(metrics.to_dict())
        print(json.dumps(json_ready(out), allow_nan=False))
    else:
        print(format_report(metrics, args.groundtruth, args.estimate))
        if args.plot:
            print(f"\nfigure: {args.plot}")
        if args.save_aligned:
            print(f"aligned estimate: {args.save_aligned}")
    for warning in metrics.warnings:
        _warn(warning)
    return 0


def _load(path: str, args: argparse.Namespace) -> PoseTrajectory:
    """The trajectory file at ``path``; a path that is no readable file is refused in one line naming it (the
    readers' own errors name the line of a malformed file)."""
    if not Path(path).is_file():
        what = "a folder" if Path(path).is_dir() else "no such file"
        raise InputError(f"{path}: {what}; give a {args.format.upper()} trajectory file")
    if args.format == "kitti":
        return PoseTrajectory.from_kitti_file(path)
    return PoseTrajectory.from_tum_file(path, duplicate_timestamps=args.duplicates, on_duplicates=_warn)


def _warn(message: str) -> None:
    print(f"cnnslam eval: warning: {message}", file=sys.stderr)


def _stats_lines(stats: ErrorStatistics, digits: int = 6) -> list[str]:
    return [f"{k:>10}  {v:.{digits}f}" if isinstance(v, float) else f"{k:>10}  {v}" for k, v in stats.to_dict().items()]


def format_report(m: TrajectoryMetrics, gt_path: str, est_path: str) -> str:
    """The text report printed by ``cnnslam eval`` (evo_ape-like)."""
    a = m.association
    fit = m.alignment
    flat = m.flat_metrics()
    flag = "fallback" if fit.fallback else "ill-conditioned" if fit.degenerate else ""
    lines = [
        f"ground truth: {gt_path}",
        f"estimate:     {est_path}",
        f"association:  {a.rule.value}, max. difference {a.max_difference} s, offset {a.offset} s, {len(a)} pairs",
        f"alignment:    {ALIGNMENT_TITLES[fit.used]}"
        + (f", scale {fit.scale:.4f}" if fit.scale_fitted else "")
        + (f" [{flag}: see the warning]" if flag else ""),
        "",
        "APE w.r.t. translation part (m)",
        *_stats_lines(m.ate),
        "",
        *(
            f"{label:<58}{rmse:.6f} m" + (" (rotation-only fallback)" if f.fallback else "")
            for label, rmse, f in (
                ("ATE RMSE after SE(3) alignment (metric, = evo_ape -a):", flat[ATE_SE3_RMSE.key], m.se3_alignment),
                ("ATE RMSE after Sim(3) alignment (scaled, = evo_ape -as):", flat[ATE_SIM3_RMSE.key],
                 m.sim3_alignment),
            )
        ),
        "",
        "rotation error after orientation-only alignment (deg; independent of positions: read this for rotation)",
        *_stats_lines(m.rotation_orient_deg, 4),
        "",
        f"rotation error after the {fit.used} alignment (deg)",
        *_stats_lines(m.rotation_deg, 4),
        "",
        f"RPE over {m.rpe_delta:g} {m.rpe_unit.value}: translation (m)",
        *_stats_lines(m.rpe_translation),
        f"RPE over {m.rpe_delta:g} {m.rpe_unit.value}: rotation (deg, alignment-free)",
        *_stats_lines(m.rpe_rotation_deg, 4),
        "",
        "relative error at 10-50 % of the ground truth's path (rpg_trajectory_evaluation's distances; pairs within "
        f"{100 * RELATIVE_TOLERANCE:.0f} % of the distance, after the {fit.used} alignment)",
        *(f"{r.share:>10} %  {r.distance_m:>7.3g} m  {r.translation.size:>7} pairs  translation RMSE "
          f"{error_statistics(r.translation).rmse:.6f} m  rotation RMSE {error_statistics(r.rotation_deg).rmse:.4f} deg"
          for r in m.relative),
        "",
        f"Sim(3) scale {m.scale:.4f} (scale error |1/s - 1| = {flat[SCALE_ERROR.key]:.4f})",
        f"length: ground truth {m.length_gt:.3f} m, aligned estimate {m.length_est:.3f} m",
    ]
    return "\n".join(lines)

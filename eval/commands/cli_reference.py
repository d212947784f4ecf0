"""``cnnslam reference FOLDER``: a structure-from-motion reference for a real RGB-D folder, and how far the folder's
own ground truth is from it.

Runs COLMAP (pycolmap) on every ``--step``-th colour image as it is on disk (before any undistortion), with one
shared camera whose focal length and radial distortion are self-calibrated, scales the model to metres by the
folder's depth images (not its poses), and writes to ``--out`` (default ``results/reference/<name>``):

- ``reference.tum``: the SfM camera poses ``T_world_cam`` (colour camera, OpenCV axes, metres), TUM format; score
  any estimate against it with ``cnnslam eval OUT/reference.tum ESTIMATE.tum``;
- ``camera.toml``: the self-calibrated camera at the images' size (a camera file for ``--camera`` or a dataset
  list's ``camera``);
- ``reference.json`` and ``reference.md``: the camera, the model's size, and the folder's ground truth scored
  against the SfM reference (SE(3) and Sim(3) ATE, orientation-aligned rotation RMSE, rotation-angle ratio, RPE);
- ``reference.png``: both trajectories and their distance over time.

FOLDER: a path, or a name of the dataset list (``datasets.toml`` / ``$CNNSLAM_DATASETS``). Exit status 0; 2 on bad
arguments, refused in one line naming the value and what is valid before COLMAP starts (an option out of its range, a
folder that is missing or not an RGB-D folder, a selection of fewer than 3 images, a stated camera the camera model
cannot hold with ``--fixed-camera``, an ``--out`` or ``--workdir`` that cannot be written); 1 when COLMAP could
make no reference (the message says why).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from eval.errors import EvalError, InputError
from eval.metrics.catalogue import (
    ATE_MAX,
    ATE_SE3_RMSE,
    ATE_SIM3_RMSE,
    ROT_DEG_ORIENT_RMSE,
    RPE_ROT_DEG_RMSE,
    RPE_TRANS_RMSE,
    SCALE,
    MetricSpec,
)
from eval.metrics.results import json_ready
from eval.metrics.sfm_reference import (
    CAMERA_MODELS,
    COLMAP_PIXEL_OFFSET,
    DEFAULT_CAMERA_MODEL,
    DEFAULT_OVERLAP,
    SfmReference,
    nearest_depth,
    reconstruct,
    reference_trajectory,
)
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import TrajectoryMetrics, evaluate_trajectory, rotation_angle_ratio
from slamcommon.errors import MetricError, ProjectError
from slamcommon.output_paths import check_output_folder

REFERENCE_SCHEMA = "cnnslam-reference/1"
DEFAULT_OUT = Path("results/reference")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("folder", help="an RGB-D folder (TUM, ICL-NUIM, 7-Scenes layouts) or a dataset-list name")
    parser.add_argument("--step", type=int, default=2, help="use every STEP-th image (default 2)")
    parser.add_argument("--first", type=int, default=0, help="first image index (default 0)")
    parser.add_argument("--frames", type=int, default=None, help="at most this many images after --step")
    parser.add_argument("--camera-model", choices=CAMERA_MODELS, default=DEFAULT_CAMERA_MODEL,
                        help=f"COLMAP camera model to self-calibrate (default {DEFAULT_CAMERA_MODEL})")
    parser.add_argument("--fixed-camera", action="store_true",
                        help="hold the folder's stated camera fixed instead of self-calibrating it (a check: does "
                        "the verdict depend on the self-calibration?)")
    parser.add_argument("--overlap", type=int, default=DEFAULT_OVERLAP,
                        help=f"sequential matching: each image against its next N (default {DEFAULT_OVERLAP})")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default results/reference/<name>)")
    parser.add_argument("--workdir", type=Path, default=None, help="keep COLMAP's database and model here")
    parser.add_argument("--rpe-delta", type=float, default=1.0, help="RPE delta in seconds (default 1)")
    parser.add_argument("--no-plot", action="store_true", help="do not write reference.png")
    parser.add_argument("--verbose", action="store_true", help="show COLMAP's own log")


# the figures of the ground truth scored against the reference (the maximum ATE among them)
REFERENCE_FIGURES: tuple[MetricSpec, ...] = (ATE_SE3_RMSE, ATE_SIM3_RMSE, ATE_MAX, SCALE, ROT_DEG_ORIENT_RMSE,
                                             RPE_TRANS_RMSE, RPE_ROT_DEG_RMSE)  # fmt: skip


def compare_with_ground_truth(gt: PoseTrajectory, reference: SfmReference,
                              rpe_delta: float = 1.0) -> tuple[dict[str, Any], TrajectoryMetrics]:  # fmt: skip
    """The folder's ground truth ``gt`` scored against the SfM reference (the reference plays the ground truth's
    role: errors are in the reference's metres). Returns the figures of :data:`REFERENCE_FIGURES` under their
    catalogue keys (the Sim(3) scale maps the ground truth onto the reference), ``rotation_ratio`` (ground-truth
    angle / reference angle over 0.5 s), ``pairs``; and the metrics behind them (SE(3)-aligned ground truth and ATE
    per pose, for the plot)."""
    ref = PoseTrajectory(reference.timestamps, reference.T_world_cam)
    metrics = evaluate_trajectory(ref, gt, rpe_delta=rpe_delta)
    flat = metrics.flat_metrics()
    ratio, ratio_pairs = rotation_angle_ratio(metrics.gt, metrics.est_aligned, 0.5)  # angles: alignment-free
    out = {s.key: float(flat[s.key]) for s in REFERENCE_FIGURES if s.key in flat}
    out.update(rotation_ratio=ratio, rotation_ratio_pairs=ratio_pairs, pairs=len(metrics.gt))
    return out, metrics


def _markdown(name: str, summary: dict[str, Any]) -> str:
    cam, ref, cmp = summary["camera"], summary["reference"], summary.get("ground_truth_vs_reference")
    stated = summary.get("stated_camera")
    how = "held fixed" if summary.get("camera_fixed") else "self-calibrated"
    lines = [
        f"# SfM reference: {name}",
        "",
        f"COLMAP {summary['colmap']} on {ref['images']} images (one in {summary['step']}, from {summary['first']}), "
        f"{ref['registered']} registered, {ref['points']} points, "
        f"mean reprojection error {ref['reprojection_px']:.3f} px, "
        f"scale: {ref['scale_source']}. {summary['seconds']:.0f} s.",
        "",
        "| camera | fx [px] | fy [px] | cx [px] | cy [px] | k1 | k2 |",
        "|---|---:|---:|---:|---:|---:|---:|",
        f"| {how} ({cam['model']}) | {cam['fx']:.2f} | {cam['fy']:.2f} | {cam['cx']:.2f} | {cam['cy']:.2f} "
        f"| {cam['k1']:.4f} | {cam['k2']:.4f} |",
    ]
    if stated:
        lines.append(f"| stated ({stated['source']}) | {stated['fx']:.2f} | {stated['fy']:.2f} | {stated['cx']:.2f} "
                     f"| {stated['cy']:.2f} | {stated['k1']:.4f} | {stated['k2']:.4f} |")
    if cmp:
        lines += [
            "",
            "The folder's ground truth scored against the SfM reference (how far the two references disagree):",
            "",
            "| SE(3) ATE [m] | Sim(3) ATE [m] | scale | rotation RMSE, orientation-aligned [deg] | RPE rot [deg] "
            "| RPE trans [m] | rotation ratio (GT / SfM, 0.5 s) |",
            "|---:|---:|---:|---:|---:|---:|---:|",
            f"| {cmp[ATE_SE3_RMSE.key]:.4f} | {cmp[ATE_SIM3_RMSE.key]:.4f} | {cmp[SCALE.key]:.4f} "
            f"| {cmp[ROT_DEG_ORIENT_RMSE.key]:.3f} | {cmp[RPE_ROT_DEG_RMSE.key]:.3f} | {cmp[RPE_TRANS_RMSE.key]:.4f} "
            f"| {cmp['rotation_ratio']:.4f} ({cmp['rotation_ratio_pairs']} pairs) |",
        ]
    return "\n".join(lines) + "\n"


def check_options(args: argparse.Namespace) -> None:
    """Refuse an option out of its range (``--step``, ``--overlap`` >= 1, ``--first`` >= 0, ``--frames`` >= 3,
    ``--rpe-delta`` a positive number of seconds) and a ``--workdir`` folder that cannot be written: one line naming
    the option, its value and what is valid."""
    for flag, value, low, what in (
        ("--step", args.step, 1, "use every STEP-th image"),
        ("--overlap", args.overlap, 1, "match each image against its next N"),
        ("--first", args.first, 0, "an image index"),
        ("--frames", args.frames, 3, "COLMAP needs at least 3 images"),
    ):
        if value is not None and value < low:
            raise InputError(f"{flag} {value}: must be >= {low} ({what})")
    if not (math.isfinite(args.rpe_delta) and args.rpe_delta > 0):
        raise InputError(f"--rpe-delta {args.rpe_delta:g}: must be a positive number of seconds (default 1)")
    if args.workdir is not None:
        check_output_folder(args.workdir, "--workdir")


def select_images(n_images: int, args: argparse.Namespace) -> np.ndarray:
    """The indices of the images COLMAP gets: every ``--step``-th from ``--first``, at most ``--frames``; an
    :class:`~eval.errors.InputError` naming the options when that leaves fewer than 3 of the folder's ``n_images``."""
    selected = np.arange(n_images)[args.first :: args.step]
    if args.frames is not None:
        selected = selected[: args.frames]
    if len(selected) < 3:
        raise InputError(f"--first {args.first} --step {args.step} select {len(selected)} of the folder's {n_images} "
                         "images; COLMAP needs at least 3: lower --first or --step")  # fmt: skip
    return selected


def run(args: argparse.Namespace) -> int:
    from eval.bench.sequence_resolve import resolve_sequence
    from sim_envs.folders.datasets import load_rgbd_folder

    try:  # bad options, a folder that is no RGB-D folder, too few images, unwritable outputs: before COLMAP starts
        check_options(args)
        seq = resolve_sequence(args.folder, check_references=False)  # it makes a missing reference
        if seq.folder is None:
            raise InputError(f"{args.folder!r} is a simulated sequence; give a real RGB-D folder or dataset-list name")
        folder = load_rgbd_folder(seq.folder, seq.camera, size=None, depth_scale=seq.depth_scale)
        selected = select_images(len(folder), args)
        out = check_output_folder(args.out or DEFAULT_OUT / seq.name, "--out")
        fixed = _colmap_params(folder.camera, args.camera_model) if args.fixed_camera else None
    except ProjectError as exc:
        print(f"cnnslam reference: error: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    # one step per stage (features, matches) and per image the mapper registers
    stages = tqdm(total=len(selected) + 2, desc=f"COLMAP on {len(selected)} images", unit="step")

    def stage_done(name: str) -> None:
        stages.set_postfix_str(f"{name} done")
        stages.update(1 if name != "mapping" else stages.total - stages.n)

    def image_registered() -> None:
        stages.update(1)

    try:
        with tempfile.TemporaryDirectory() as scratch:
            work = args.workdir or Path(scratch)
            model = reconstruct([folder.rgb_paths[i] for i in selected], work, camera_model=args.camera_model,
                                overlap=args.overlap, fixed_camera=fixed, verbose=args.verbose,
                                on_stage=stage_done, on_image=image_registered)  # fmt: skip
            stages.close()
            depth_at = _depth_lookup(folder, selected) if folder.has_depth else None
            reference = reference_trajectory(model, folder.timestamps[selected], depth_at)
    except (EvalError, MetricError) as exc:
        stages.close()
        print(f"cnnslam reference: error: {exc}", file=sys.stderr)
        return 1
    reference.frame_indices = selected[reference.frame_indices]
    seconds = time.monotonic() - started
    _write_reference(out, folder, reference, args.fixed_camera)  # first: kept whatever fails after it
    summary, metrics = _summary(args, folder, reference, seconds)
    _write_report(out, seq.name, summary, metrics if not args.no_plot else None)
    from sim_envs.folders.folder_layouts import folder_fingerprint
    from slamcommon.provenance import record_outputs  # what made the files: `cnnslam results status`

    record_outputs([out / n for n in ("reference.tum", "camera.toml", "reference.json", "reference.md",
                                      "reference.png")], "cnnslam reference", ["eval.commands.cli_reference"],
                   folders={seq.folder: folder_fingerprint(seq.folder)["sha256"]}, seconds=seconds)
    print(_markdown(seq.name, summary))
    written = "reference.tum, camera.toml, reference.json, reference.md" + ("" if args.no_plot else ", reference.png")
    print(f"wrote {written} to {out}")
    return 0


def _colmap_params(camera: Any, model: str) -> list[float]:
    """The folder's stated camera as COLMAP parameters of ``model`` (pixel centres moved to COLMAP's +0.5)."""
    K, d = camera.intrinsics, camera.distortion
    cx, cy = K.cx + COLMAP_PIXEL_OFFSET, K.cy + COLMAP_PIXEL_OFFSET
    if model == "OPENCV":
        return [K.fx, K.fy, cx, cy, d[0], d[1], d[2], d[3]]
    if abs(K.fx - K.fy) > 1e-6 * K.fx or any(d[2:]) or (model == "SIMPLE_RADIAL" and d[1]):
        raise InputError(f"--fixed-camera --camera-model {model}: the stated camera (fx {K.fx:.6g}, fy {K.fy:.6g}, "
                         f"distortion {', '.join(f'{v:.6g}' for v in d)}) needs --camera-model OPENCV")
    return [K.fx, cx, cy, d[0]] if model == "SIMPLE_RADIAL" else [K.fx, cx, cy, d[0], d[1]]


def _depth_lookup(folder: Any, selected: np.ndarray) -> Any:
    """depth_at(i, uv) for :func:`reference_trajectory`: image ``selected[i]``'s delivered depth (native size,
    registered to the colour camera) at raw image pixels ``uv``, moved to the undistorted grid when the folder's
    camera has distortion."""
    import cv2

    cam = folder.camera

    def depth_at(i: int, uv: np.ndarray) -> np.ndarray:
        if cam.distorted:
            K = cam.intrinsics.K
            uv = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, np.asarray(cam.distortion), P=folder.native_intrinsics.K)
            uv = uv.reshape(-1, 2)
        return nearest_depth(folder.depth(int(selected[i])), uv)

    return depth_at


def _summary(args: argparse.Namespace, folder: Any, reference: SfmReference,
             seconds: float) -> tuple[dict[str, Any], TrajectoryMetrics]:  # fmt: skip
    import pycolmap

    from sim_envs.folders.datasets import camera_fields

    stated = folder.camera
    summary: dict[str, Any] = {
        "schema": REFERENCE_SCHEMA,
        "folder": str(folder.folder),
        "colmap": f"pycolmap {pycolmap.__version__}",
        "step": args.step,
        "first": args.first,
        "camera_fixed": bool(args.fixed_camera),
        "seconds": seconds,
        "camera": {"model": reference.camera_model, **camera_fields(reference.camera)},
        "stated_camera": {"source": folder.camera_source, **camera_fields(stated)},
        "reference": {
            "images": reference.images,
            "registered": len(reference.frame_indices),
            "points": reference.points,
            "reprojection_px": reference.reprojection_px,
            "scale": reference.scale,
            "scale_source": reference.scale_source,
        },
    }
    gt = PoseTrajectory(folder.timestamps, folder.poses)
    summary["ground_truth_vs_reference"], metrics = compare_with_ground_truth(gt, reference, args.rpe_delta)
    return summary, metrics


def _write_reference(out: Path, folder: Any, reference: SfmReference, fixed: bool) -> None:
    import pycolmap

    from sim_envs.folders.datasets import camera_file_text
    from slamcommon.formats import write_tum_trajectory

    how = "held fixed" if fixed else "self-calibrated"
    header = (
        f"SfM reference of {folder.folder} (pycolmap {pycolmap.__version__}, camera {how}, "
        f"{reference.camera_model}); T_world_cam colour camera, OpenCV axes; {reference.scale_source}"
    )
    write_tum_trajectory(out / "reference.tum", reference.timestamps, reference.T_world_cam, header=header)
    (out / "camera.toml").write_text(camera_file_text(
        reference.camera, f"{how} by COLMAP from the images of {folder.folder} (cnnslam reference)"))  # fmt: skip


def _write_report(out: Path, name: str, summary: dict[str, Any], metrics: TrajectoryMetrics | None) -> None:
    """reference.json, reference.md and (given the comparison's ``metrics``) reference.png: the SE(3)-aligned
    ground truth over the reference, with its ATE per pose."""
    (out / "reference.json").write_text(json.dumps(json_ready(summary), indent=2) + "\n")
    (out / "reference.md").write_text(_markdown(name, summary))
    if metrics is not None:
        from eval.reports.plots import save_trajectory_figure

        # compare_with_ground_truth aligns with SE(3) (evaluate_trajectory's default): est_aligned is that fit
        save_trajectory_figure(out / "reference.png", metrics.gt.timestamps, metrics.gt.positions,
                               metrics.est_aligned.positions, metrics.ate_errors,
                               title=f"{name}: the folder's ground truth against the SfM reference",
                               labels=("SfM reference", "ground truth, SE(3)-aligned"))  # fmt: skip

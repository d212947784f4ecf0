"""``python -m sim_envs.tools.cli_camera_calibration``: measure the camera statistics of real frames and of a simulated
sequence through each camera preset; write a Markdown table and a side-by-side picture of the simulated cameras.
With ``--motion``, also how the cameras move: :func:`sim_envs.motion.recorded.motion_statistics` of the real
folder's ground truth (a TUM ``groundtruth.txt``, resampled at 30 Hz) and of each simulated sequence's trajectory
(:func:`motion_table`).

The real frames are measured only: their images are never written (7-Scenes is research-only data, and the picture
is committed). The statistics are :mod:`sim_envs.sensor.camera_calibration`'s; frames are delivered at 320x240 (real
ones
area-averaged from 640x480 by :func:`sim_envs.folders.datasets.load_rgbd_folder`, as every run sees them).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from sim_envs.sensor.camera_calibration import CameraStatistics, DepthStatistics, camera_statistics, depth_statistics
from sim_envs.sequences import SequenceSpec, variant_spec

ROWS: dict[str, str] = {
    "noise_std": "noise std on flat regions [levels]",
    "gradient_mean": "mean gradient magnitude [levels/px]",
    "laplacian_var": "variance of the Laplacian [levels^2]",
    "brightness_mean": "mean grey level [levels]",
    "log_brightness_change_std": "std of frame-to-frame change of log mean brightness",
    "vignette_ratio": "corner / centre brightness",
}
DEPTH_ROWS: dict[str, str] = {
    "p10": "depth, 10th percentile of valid pixels [m]",
    "median": "depth, median of valid pixels [m]",
    "p90": "depth, 90th percentile of valid pixels [m]",
    "valid_share": "share of pixels with valid depth",
}


def _spec(name: str, frames: int, full_length: bool = False) -> SequenceSpec:
    """The sequence ``name`` (:func:`sim_envs.sequences.variant_spec`) made ``frames`` long (a trajectory generated
    for that length), or as registered when ``full_length`` (its first ``frames`` frames are those a suite runs)."""
    spec = variant_spec(name)
    return spec if full_length else spec.with_frames(frames)


def measure_sequence(name: str, preset: str, frames: int, renderer: str = "mujoco", full_length: bool = False,
                     step: int = 1) -> tuple[CameraStatistics, float]:  # fmt: skip
    """Statistics of the first ``frames`` frames of registered sequence ``name`` (maybe with ``+lit`` / ``+rich``
    marks, :func:`sim_envs.sequences.variant_spec`; made ``frames`` long unless ``full_length``) through camera
    preset ``preset``, and the seconds it took (rendering included). ``step`` > 1: frames 0, step, 2 step... of
    the registered sequence instead (spread over it; the frame-to-frame statistic then compares frames ``step``
    apart)."""
    from sim_envs.sequences import with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    start = time.perf_counter()
    with SimulatedSequence(with_camera(_spec(name, frames, full_length or step > 1), preset), renderer) as seq:
        stats = camera_statistics(seq.rgb(i) for i in range(0, frames * step, step))
    return stats, time.perf_counter() - start


def measure_depths(name: str, frames: int, renderer: str = "mujoco", full_length: bool = False,
                   step: int = 1) -> DepthStatistics:  # fmt: skip
    """:func:`sim_envs.sensor.camera_calibration.depth_statistics` of the exact depth of the frames
    :func:`measure_sequence` measures (the depths do not depend on the camera preset)."""
    from sim_envs.sources.simsource import SimulatedSequence

    with SimulatedSequence(_spec(name, frames, full_length or step > 1), renderer) as seq:
        return depth_statistics(seq.frame(i).depth for i in range(0, frames * step, step))


MOTION_ROWS: dict[str, str] = {
    "speed_mean": "speed, mean [m/s]",
    "speed_p90": "speed, 90th percentile [m/s]",
    "angular_speed_mean_deg": "angular speed, mean [deg/s]",
    "angular_speed_p90_deg": "angular speed, 90th percentile [deg/s]",
    "jerk_rms": "jerk, root mean square [m/s^3]",
    "angular_rate_share": "angular rate about camera x, y, z, over the largest",
    "velocity_share": "velocity along camera x, y, z, over the largest",
    "angular_rate_halftime_s": "angular rate x, y, z: autocorrelation half-time [s]",
    "velocity_halftime_s": "velocity x, y, z: autocorrelation half-time [s]",
}


def motion_table(columns: dict[str, Any]) -> str:
    """A Markdown table of :class:`sim_envs.motion.recorded.MotionStatistics`: one row per statistic of
    :data:`MOTION_ROWS`, one column per named measurement."""
    def cell(value: Any) -> str:
        return ", ".join(f"{v:.2f}" for v in value) if isinstance(value, tuple) else f"{value:.3g}"

    lines = ["| motion statistic | " + " | ".join(columns) + " |", "|---|" + "---:|" * len(columns)]
    for key, label in MOTION_ROWS.items():
        lines.append(f"| {label} | " + " | ".join(cell(getattr(m, key)) for m in columns.values()) + " |")
    return "\n".join(lines)


def measure_motion(real: str | Path | None, sequences: Sequence[str], frames: int | None = None) -> dict[str, Any]:
    """Motion statistics (:func:`sim_envs.motion.recorded.motion_statistics`) of ``real``'s
    ``groundtruth.txt`` when there is one (column ``real (<folder>)``) and of each registered sequence's trajectory
    (made ``frames`` long, or as registered when None)."""
    from sim_envs.motion.recorded import motion_statistics, recorded_motion
    from sim_envs.sources.simsource import SimulatedSequence

    out: dict[str, Any] = {}
    if real is not None and (Path(real) / "groundtruth.txt").is_file():
        out[f"real ({Path(real).name})"] = motion_statistics(recorded_motion(str(Path(real) / "groundtruth.txt")))
    for name in sequences:
        spec = variant_spec(name) if frames is None else _spec(name, frames)
        with SimulatedSequence(spec) as seq:
            out[name] = motion_statistics(seq.trajectory)
    return out


def _cell(value: float) -> str:
    return f"{value:.4f}" if abs(value) < 0.1 else f"{value:.2f}"


def markdown_table(columns: dict[str, CameraStatistics], depths: dict[str, DepthStatistics] | None = None) -> str:
    """A Markdown table: one row per statistic, one column per named measurement; with ``depths`` (column name ->
    its :class:`DepthStatistics`, missing columns left empty) also the :data:`DEPTH_ROWS`."""
    lines = ["| statistic | " + " | ".join(columns) + " |", "|---|" + "---:|" * len(columns)]
    for key, label in ROWS.items():
        lines.append(f"| {label} | " + " | ".join(_cell(getattr(s, key)) for s in columns.values()) + " |")
    for key, label in DEPTH_ROWS.items() if depths is not None else ():
        cells = [_cell(getattr(depths[c], key)) if c in depths else "" for c in columns]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def side_by_side(name: str, presets: Sequence[str], index: int, path: Path, crop: int = 2) -> None:
    """Write frame ``index`` of sequence ``name`` through each preset side by side (labelled), and a 2x enlarged
    crop of the centre of each under it, as a PNG."""
    from sim_envs.sequences import with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    tiles = []
    for preset in presets:
        with SimulatedSequence(with_camera(variant_spec(name).with_frames(index + 1), preset)) as seq:
            rgb = seq.rgb(index)
        h, w = rgb.shape[:2]
        zoom = rgb[
            h // 2 - h // (2 * crop) : h // 2 + h // (2 * crop), w // 2 - w // (2 * crop) : w // 2 + w // (2 * crop)
        ]
        zoom = cv2.resize(zoom, (w, h), interpolation=cv2.INTER_NEAREST)
        tile = np.vstack([rgb, zoom]).copy()
        cv2.putText(tile, preset, (6, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 0), 2)
        tiles.append(tile)
    image = np.hstack(tiles)
    cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))


def main(argv: Sequence[str] | None = None) -> int:
    """Measure, print the table, and write ``--out`` (Markdown) and ``--png``."""
    parser = argparse.ArgumentParser(
        prog="python -m sim_envs.tools.cli_camera_calibration", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--real", default="../shared/data/real/7scenes_redkitchen", help="a real RGB-D folder")
    parser.add_argument("--sequences", nargs="+", default=["office0", "living0"],
                        help="simulated sequences (name+lit: in its lit room; name+rich: in its rich room; "
                             "name+lit+rich: both)")
    parser.add_argument("--presets", nargs="+", default=["kinect", "clean", "hard"])
    parser.add_argument("--frames", type=int, default=100, help="first N frames of each")
    parser.add_argument("--out", default=None, help="Markdown file to write (default: print only)")
    parser.add_argument("--png", default=None, help="side-by-side picture to write")
    parser.add_argument("--depth", action="store_true", help="also the depths seen (percentiles of valid depth)")
    parser.add_argument("--full-length", action="store_true",
                        help="the first N frames of each sequence as registered (the frames a suite runs), not of "
                             "the sequence made N frames long (a trajectory generated for that length: the default)")
    parser.add_argument("--motion", action="store_true",
                        help="also how the cameras move: motion statistics of the real folder's groundtruth.txt and "
                             "of each simulated sequence's trajectory as registered")
    parser.add_argument("--step", type=int, default=1,
                        help="measure frames 0, STEP, 2 STEP... (N of them) of every sequence as registered and of "
                             "the real one, spread over them (default 1: the first N)")
    args = parser.parse_args(argv)
    if args.step < 1:
        parser.error(f"--step must be >= 1, got {args.step}")

    from sim_envs.folders.datasets import load_rgbd_folder

    real = load_rgbd_folder(args.real)
    real_name = f"real ({Path(args.real).name})"
    picked = range(0, args.frames * args.step, args.step)
    columns = {real_name: camera_statistics(real.frame(i).rgb for i in picked)}
    depths = {real_name: depth_statistics(real.frame(i).depth for i in picked)} if args.depth else None
    timing = []
    for name in args.sequences:
        seen = measure_depths(name, args.frames, full_length=args.full_length, step=args.step) if args.depth else None
        for preset in args.presets:
            stats, seconds = measure_sequence(name, preset, args.frames, full_length=args.full_length, step=args.step)
            columns[f"{name} {preset}"] = stats
            if depths is not None and seen is not None:
                depths[f"{name} {preset}"] = seen
            timing.append(f"{name} {preset}: {seconds:.1f} s")
    table = markdown_table(columns, depths)
    if args.motion:
        table += "\n\n" + motion_table(measure_motion(args.real, args.sequences))
    print(table)
    print("; ".join(timing))
    if args.out:
        Path(args.out).write_text(table + "\n")
    if args.png:
        side_by_side(args.sequences[0], args.presets, min(args.frames, 60) - 1, Path(args.png))
    from sim_envs.folders.folder_layouts import folder_fingerprint
    from slamcommon.provenance import record_outputs  # what made the files: `cnnslam results status`

    record_outputs([p for p in (args.out, args.png) if p], "python -m sim_envs.tools.cli_camera_calibration",
                   ["sim_envs.tools.cli_camera_calibration"],
                   folders={args.real: folder_fingerprint(args.real)["sha256"]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

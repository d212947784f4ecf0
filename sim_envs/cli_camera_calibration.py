"""``python -m sim_envs.cli_camera_calibration``: measure the camera statistics of real frames and of a simulated
sequence through each camera preset; write a Markdown table and a side-by-side picture of the simulated cameras.

The real frames are measured only: their images are never written (7-Scenes is research-only data, and the picture
is committed). The statistics are :mod:`sim_envs.camera_calibration`'s; frames are delivered at 320x240 (real ones
area-averaged from 640x480 by :func:`sim_envs.datasets.load_rgbd_folder`, as every run sees them).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from sim_envs.camera_calibration import CameraStatistics, camera_statistics
from sim_envs.sequences import SequenceSpec

ROWS: dict[str, str] = {
    "noise_std": "noise std on flat regions [levels]",
    "gradient_mean": "mean gradient magnitude [levels/px]",
    "laplacian_var": "variance of the Laplacian [levels^2]",
    "brightness_mean": "mean grey level [levels]",
    "log_brightness_change_std": "std of frame-to-frame change of log mean brightness",
    "vignette_ratio": "corner / centre brightness",
}


def sequence_spec(name: str) -> SequenceSpec:
    """The registered sequence ``name``, or ``<name>+lit``: the same in its lit room (:mod:`sim_envs.lighting`)."""
    from sim_envs.sequences import get_sequence

    base, plus, lighting = name.partition("+")
    return replace(get_sequence(base), lighting=lighting) if plus else get_sequence(base)


def measure_sequence(name: str, preset: str, frames: int, renderer: str = "mujoco") -> tuple[CameraStatistics, float]:
    """Statistics of the first ``frames`` frames of registered sequence ``name`` (maybe ``+lit``,
    :func:`sequence_spec`) through camera preset ``preset``, and the seconds it took (rendering included)."""
    from sim_envs.sequences import with_camera
    from sim_envs.simsource import SimulatedSequence

    start = time.perf_counter()
    with SimulatedSequence(with_camera(sequence_spec(name).with_frames(frames), preset), renderer) as seq:
        stats = camera_statistics(seq.rgb(i) for i in range(frames))
    return stats, time.perf_counter() - start


def markdown_table(columns: dict[str, CameraStatistics]) -> str:
    """A Markdown table: one row per statistic, one column per named measurement."""
    lines = ["| statistic | " + " | ".join(columns) + " |", "|---|" + "---:|" * len(columns)]
    for key, label in ROWS.items():
        cells = [f"{getattr(s, key):.4f}" if abs(getattr(s, key)) < 0.1 else f"{getattr(s, key):.2f}"
                 for s in columns.values()]  # fmt: skip
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def side_by_side(name: str, presets: Sequence[str], index: int, path: Path, crop: int = 2) -> None:
    """Write frame ``index`` of sequence ``name`` through each preset side by side (labelled), and a 2x enlarged
    crop of the centre of each under it, as a PNG."""
    from sim_envs.sequences import with_camera
    from sim_envs.simsource import SimulatedSequence

    tiles = []
    for preset in presets:
        with SimulatedSequence(with_camera(sequence_spec(name).with_frames(index + 1), preset)) as seq:
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
        prog="python -m sim_envs.cli_camera_calibration", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--real", default="../shared/data/real/7scenes_redkitchen", help="a real RGB-D folder")
    parser.add_argument("--sequences", nargs="+", default=["office0", "living0"],
                        help="simulated sequences (name+lit: in its lit room)")
    parser.add_argument("--presets", nargs="+", default=["kinect", "clean", "hard"])
    parser.add_argument("--frames", type=int, default=100, help="first N frames of each")
    parser.add_argument("--out", default=None, help="Markdown file to write (default: print only)")
    parser.add_argument("--png", default=None, help="side-by-side picture to write")
    args = parser.parse_args(argv)

    from sim_envs.datasets import load_rgbd_folder

    real = load_rgbd_folder(args.real)
    columns = {f"real ({Path(args.real).name})": camera_statistics(real.frame(i).rgb for i in range(args.frames))}
    timing = []
    for name in args.sequences:
        for preset in args.presets:
            stats, seconds = measure_sequence(name, preset, args.frames)
            columns[f"{name} {preset}"] = stats
            timing.append(f"{name} {preset}: {seconds:.1f} s")
    table = markdown_table(columns)
    print(table)
    print("; ".join(timing))
    if args.out:
        Path(args.out).write_text(table + "\n")
    if args.png:
        side_by_side(args.sequences[0], args.presets, min(args.frames, 60) - 1, Path(args.png))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

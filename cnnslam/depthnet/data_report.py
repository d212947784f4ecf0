"""The training data against the frames the network is used on: image statistics and depth distributions.

Each domain is described by :func:`sim_envs.sensor.camera_calibration.camera_statistics` (noise, gradient energy, focus,
brightness, vignetting; medians over frames) plus the mean saturation, and by
:func:`sim_envs.sensor.camera_calibration.depth_statistics` (10th, 50th, 90th percentile of the valid depths, metres).
Domains: the network's training rooms (a sample of the recipe's shards, at the stored 320x240), the simulated test
sequences through the world's camera, and real RGB-D folders (their sensor depth). Real frames are only measured
here, never trained or tuned on. ``cnnslam train data-statistics`` writes ``results/depthnet_data.md``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sim_envs.sensor.camera_calibration import CameraStatistics, DepthStatistics, camera_statistics, depth_statistics


@dataclass(frozen=True)
class DomainStatistics:
    """One domain's images and depths (module docstring). saturation_mean: mean HSV saturation (0-255) over frames."""

    name: str
    camera: CameraStatistics
    depth: DepthStatistics
    saturation_mean: float


def domain_statistics(name: str, frames: Iterable[tuple[np.ndarray, np.ndarray]]) -> DomainStatistics:
    """Statistics of (rgb (H, W, 3) uint8, depth (H, W) metres, 0 = none) pairs; at least two frames."""
    images, depths, sat = [], [], []
    for rgb, depth in frames:
        images.append(rgb)
        depths.append(depth)
        sat.append(float(cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2HSV)[..., 1].mean()))
    return DomainStatistics(name, camera_statistics(images), depth_statistics(depths), float(np.mean(sat)))


def evenly(n_total: int, k: int) -> list[int]:
    """``k`` indices spread evenly over ``range(n_total)`` (all of them when k >= n_total)."""
    return sorted({int(i) for i in np.linspace(0, n_total - 1, min(k, n_total)).round()})


def training_frames(root: str | Path, frames: int, split: str = "train") -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``frames`` frames spread over the shards under ``root/split`` at their stored resolution: the image and the
    depth the network is asked for (the room's depth divided by its focal scale)."""
    from cnnslam.depthnet.data import RenderedDataset

    ds = RenderedDataset(root, split, downsample=1)
    for i in evenly(len(ds), frames):
        sample = ds[i]
        yield sample.rgb, sample.depth


def source_frames(source: object, frames: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``frames`` frames spread over a frame source (a real folder or a simulated sequence): image and depth."""
    n = len(source)  # type: ignore[arg-type]
    for i in evenly(n, frames):
        frame = source.frame(i)  # type: ignore[attr-defined]
        yield frame.rgb, frame.depth


def data_statistics_markdown(rows: Sequence[DomainStatistics]) -> str:
    """The comparison table (one row per domain) with a short legend."""
    head = ("| domain | frames | noise std [levels] | gradient [levels/px] | Laplacian var | brightness | saturation "
            "| vignetting (corners / centre) | depth p10 [m] | depth median [m] | depth p90 [m] | valid depth |\n"
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    body = "".join(
        f"| {r.name} | {r.camera.frames} | {r.camera.noise_std:.2f} | {r.camera.gradient_mean:.2f} | "
        f"{r.camera.laplacian_var:.0f} | {r.camera.brightness_mean:.0f} | {r.saturation_mean:.0f} | "
        f"{r.camera.vignette_ratio:.2f} | {r.depth.p10:.2f} | {r.depth.median:.2f} | {r.depth.p90:.2f} | "
        f"{100 * r.depth.valid_share:.0f} % |\n"
        for r in rows
    )
    return (
        "# Depth network: its training data against the frames it is used on\n\n"
        "Image statistics (`sim_envs.sensor.camera_calibration`: Immerkaer noise on the flattest quarter of the "
        "pixels, "
        "mean Sobel gradient, variance of the Laplacian (focus), mean grey level, mean HSV saturation, corner over "
        "centre brightness; medians over frames) and the depths seen (percentiles of every valid depth pixel pooled), "
        "at 320x240. Training rooms: evenly spaced frames of the recipe's shards (the depth asked of the network). "
        "Real frames are test data: measured here, never trained or tuned on. Made by "
        "`cnnslam train data-statistics`.\n\n" + head + body
    )

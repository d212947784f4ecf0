"""The training data against the frames the network is used on: image statistics and depth distributions.

Each domain is described by :func:`sim_envs.sensor.camera_calibration.camera_statistics` (noise, gradient energy, focus,
brightness, vignetting; medians over frames) plus the mean saturation, and by
:func:`sim_envs.sensor.camera_calibration.depth_statistics` (10th, 50th, 90th percentile of the valid depths, metres)
and :func:`depth_distribution` (quantiles, share nearer than 1 m / 1.5 m, histogram, spread of the frames' medians).
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

# Edges [m] of the depth histogram of :func:`depth_distribution` (the last bin is open: 4 m and beyond).
HISTOGRAM_EDGES_M: tuple[float, ...] = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, float("inf"))
# Near-depth thresholds [m] whose share of valid pixels is reported.
NEAR_M: tuple[float, ...] = (1.0, 1.5)


@dataclass(frozen=True)
class DepthDistribution:
    """The distribution of the valid depths (finite, > 0; metres) of some frames (:func:`depth_distribution`).

    quantiles: the 5, 25, 50, 75, 95 % quantiles of every valid pixel pooled; near_share: per threshold of
    :data:`NEAR_M`, the share of the pooled valid pixels nearer than it; histogram: the share of the pooled valid
    pixels in each bin of :data:`HISTOGRAM_EDGES_M` (summing to 1); frame_median_quartiles: the 25, 50, 75 %
    quantiles over the frames of each frame's median valid depth; frames: frames with a valid depth (nan figures
    without any)."""

    quantiles: tuple[float, float, float, float, float]
    near_share: tuple[float, ...]
    histogram: tuple[float, ...]
    frame_median_quartiles: tuple[float, float, float]
    frames: int


def depth_distribution(depths: Iterable[np.ndarray]) -> DepthDistribution:
    """The :class:`DepthDistribution` of depth maps ((H, W) metres; 0, negative or non-finite = no depth).
    Pixels are pooled (every valid pixel weighs the same); a frame without a valid pixel adds nothing."""
    pooled, medians = [], []
    for depth in depths:
        d = np.asarray(depth, dtype=np.float64)
        v = d[np.isfinite(d) & (d > 0)]
        if v.size:
            pooled.append(v)
            medians.append(float(np.median(v)))
    nan = float("nan")
    if not pooled:
        return DepthDistribution((nan,) * 5, (nan,) * len(NEAR_M), (nan,) * (len(HISTOGRAM_EDGES_M) - 1),
                                 (nan,) * 3, 0)
    v = np.concatenate(pooled)
    q = tuple(float(x) for x in np.quantile(v, [0.05, 0.25, 0.5, 0.75, 0.95]))
    near = tuple(float(np.mean(v < t)) for t in NEAR_M)
    counts, _ = np.histogram(v, bins=np.asarray(HISTOGRAM_EDGES_M))
    hist = tuple(float(c) / v.size for c in counts)
    fm = tuple(float(x) for x in np.quantile(np.asarray(medians), [0.25, 0.5, 0.75]))
    return DepthDistribution(q, near, hist, fm, len(medians))  # type: ignore[arg-type]


@dataclass(frozen=True)
class DomainStatistics:
    """One domain's images and depths (module docstring). saturation_mean: mean HSV saturation (0-255) over frames;
    distribution: its depths' :class:`DepthDistribution`."""

    name: str
    camera: CameraStatistics
    depth: DepthStatistics
    saturation_mean: float
    distribution: DepthDistribution | None = None


def domain_statistics(name: str, frames: Iterable[tuple[np.ndarray, np.ndarray]]) -> DomainStatistics:
    """Statistics of (rgb (H, W, 3) uint8, depth (H, W) metres, 0 = none) pairs; at least two frames."""
    images, depths, sat = [], [], []
    for rgb, depth in frames:
        images.append(rgb)
        depths.append(depth)
        sat.append(float(cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2HSV)[..., 1].mean()))
    return DomainStatistics(name, camera_statistics(images), depth_statistics(depths), float(np.mean(sat)),
                            depth_distribution(depths))


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
        "`cnnslam train data-statistics`.\n\n" + head + body + depth_distribution_markdown(rows)
    )


def depth_distribution_markdown(rows: Sequence[DomainStatistics]) -> str:
    """The depth-distribution table (one row per domain with a :class:`DepthDistribution`), with its legend; empty
    without any."""
    rows = [r for r in rows if r.distribution is not None]
    if not rows:
        return ""
    edges = HISTOGRAM_EDGES_M
    bins = [f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">= {lo:g}" for lo, hi in zip(edges[:-1], edges[1:], strict=True)]
    head = ("| domain | frames | p5 [m] | p25 [m] | median [m] | p75 [m] | p95 [m] | "
            + " | ".join(f"< {t:g} m" for t in NEAR_M) + " | frame medians [m] (25 / 50 / 75 %) | "
            + " | ".join(f"{b} m" for b in bins) + " |\n"
            + "|---|" + "---:|" * (6 + len(NEAR_M)) + "---|" + "---:|" * len(bins) + "\n")
    body = ""
    for r in rows:
        d = r.distribution
        assert d is not None
        body += (f"| {r.name} | {d.frames} | " + " | ".join(f"{x:.2f}" for x in d.quantiles) + " | "
                 + " | ".join(f"{100 * x:.1f} %" for x in d.near_share) + " | "
                 + " / ".join(f"{x:.2f}" for x in d.frame_median_quartiles) + " | "
                 + " | ".join(f"{100 * x:.1f}" for x in d.histogram) + " |\n")
    return (
        "\n## Depth distribution\n\n"
        "Every valid depth pixel of the domain's frames pooled: its quantiles, the share nearer than 1 m and 1.5 m, "
        "and the share in each depth bin [%] (the last open); frame medians: quantiles over the frames of each "
        "frame's median depth.\n\n" + head + body
    )

"""Figures of the depth network's validation: one row per sample frame, drawn into axes the caller passes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import ListedColormap

from cnnslam.depthnet.validate import FolderValidation, SampleFrame

# floor, vertical structure, large structure, small structure; unlabelled pixels are drawn black
CLASS_COLOURS: tuple[tuple[float, float, float], ...] = (
    (0.55, 0.35, 0.17),
    (0.60, 0.75, 0.95),
    (0.95, 0.65, 0.15),
    (0.85, 0.20, 0.45),
)
SAMPLE_COLUMNS: tuple[str, ...] = (
    "input",
    "predicted depth (eq. 5)",
    "ground truth depth",
    "|error| / gt",
    "predicted labels",
    "ground truth labels",
)


def _labels_rgb(labels: np.ndarray) -> np.ndarray:
    lut = np.zeros((256, 3))
    lut[: len(CLASS_COLOURS)] = CLASS_COLOURS
    return lut[labels]


def plot_sample_row(axes: Sequence[Axes], sample: SampleFrame, max_depth: float | None = None,
                    titles: bool = False) -> None:
    """Draw one sample into 6 axes: input / predicted depth / ground truth / relative error / labels / gt labels.

    Depth maps share a colour scale 0..max_depth metres (default: the 98th percentile of the ground truth); the error
    map shows |d - g| / g clipped to 0..0.5, black where there is no ground truth.
    """
    if len(axes) != len(SAMPLE_COLUMNS):
        raise ValueError(f"need {len(SAMPLE_COLUMNS)} axes, got {len(axes)}")
    valid = sample.depth_gt > 0
    if max_depth is not None:
        vmax = float(max_depth)
    else:
        vmax = float(np.percentile(sample.depth_gt[valid], 98)) if valid.any() else 5.0
    rel = np.where(valid, np.abs(sample.depth_pred - sample.depth_gt) / np.where(valid, sample.depth_gt, 1.0), np.nan)
    within = float(np.mean(rel[valid] < 0.1)) if valid.any() else float("nan")
    err_cmap = ListedColormap(np.linspace([0.1, 0.3, 1.0], [1.0, 0.1, 0.1], 256))
    err_cmap.set_bad("black")
    axes[0].imshow(sample.rgb)
    axes[1].imshow(sample.depth_pred, cmap="viridis", vmin=0, vmax=vmax)
    axes[2].imshow(np.where(valid, sample.depth_gt, np.nan), cmap="viridis", vmin=0, vmax=vmax)
    axes[3].imshow(rel, cmap=err_cmap, vmin=0, vmax=0.5)
    axes[4].imshow(_labels_rgb(sample.labels_pred))
    axes[5].imshow(_labels_rgb(sample.labels_gt))
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    if titles:
        for ax, title in zip(axes, SAMPLE_COLUMNS, strict=True):
            ax.set_title(title, fontsize=9)
    axes[0].set_ylabel(f"{sample.sequence} #{sample.index}", fontsize=8)
    axes[3].set_xlabel(f"{100 * within:.0f}% within 10%", fontsize=8)
    axes[1].set_xlabel(f"0 (dark) .. {vmax:.1f} m (yellow)", fontsize=8)


def plot_scale_over_frames(ax: Axes, result: FolderValidation) -> None:
    """Draw a folder's per-frame scale (sensor depth / eq. 5 depth) over the frame index into ``ax``: the evenly
    spaced frames as a thin line with dots, the run of consecutive frames as a thick line, 1 (the right metric scale)
    and the median of the evenly spaced frames as horizontal lines. Frames without a scale are gaps in the lines."""
    spread, window = result.spread, result.window
    if spread.indices:
        ax.plot(spread.indices, spread.scales, "o-", ms=3, lw=0.8, color="tab:blue",
                label=f"evenly spaced (gap {spread.stability.gap_frames:.0f} frames)")
    if window.indices:
        ax.plot(window.indices, window.scales, "-", lw=2.0, color="tab:orange", label="consecutive frames")
    ax.axhline(1.0, color="black", lw=0.8, ls=":", label="1 (right scale)")
    if np.isfinite(spread.stability.median):
        ax.axhline(spread.stability.median, color="tab:blue", lw=0.8, ls="--",
                   label=f"median {spread.stability.median:.3f}")
    ax.set_xlabel("frame index")
    ax.set_ylabel("scale: sensor / eq. 5 depth")
    ax.set_title(result.name, fontsize=10)
    ax.legend(fontsize=7, loc="best")

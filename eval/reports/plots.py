"""Plots of the judge (the only module of ``eval`` that imports matplotlib).

Plot functions draw into axes the caller passes in and return them; the ``save_*`` wrappers build a
:class:`matplotlib.figure.Figure` (no pyplot, no global state, works headless) and write it to a file.

- :func:`plot_trajectory_top`: estimated vs ground-truth trajectory seen from above (two world axes);
- :func:`plot_trajectory_axes`: x, y, z over time;
- :func:`plot_error_over_time`: a per-pose error (ATE) over time;
- :func:`plot_depth_error_map`: a key-frame's depth error like the paper's Fig. 3/4: blue where the estimate is
  within 10 % of the ground truth (correct), red shades for wrong estimates (darker = larger error, saturating at
  50 %), grey where the ground truth is valid but there is no estimate, black where there is no ground truth.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from eval.errors import EvalError
from slamcommon.depth_metrics import CORRECT_THRESHOLD, correct_depth_mask, relative_depth_error, valid_depth

GT_STYLE = {"color": "0.25", "linestyle": "--", "linewidth": 1.2, "label": "ground truth"}
EST_STYLE = {"color": "tab:blue", "linewidth": 1.2, "label": "estimate"}
CORRECT_RGB = (0.12, 0.35, 0.95)
MISSING_RGB = (0.55, 0.55, 0.55)
NO_GT_RGB = (0.0, 0.0, 0.0)
_AXES = {"x": 0, "y": 1, "z": 2}


def plot_trajectory_top(ax: Axes, gt_positions: np.ndarray, est_positions: np.ndarray, plane: str = "xy") -> Axes:
    """Both trajectories projected on ``plane`` (two of x, y, z, e.g. "xy" or "xz"), equal axis scale, metres."""
    a, b = (_AXES[c] for c in plane)
    gt, est = np.asarray(gt_positions), np.asarray(est_positions)
    ax.plot(gt[:, a], gt[:, b], **GT_STYLE)
    ax.plot(est[:, a], est[:, b], **EST_STYLE)
    ax.plot(gt[:1, a], gt[:1, b], "o", color="0.25", markersize=4)
    ax.plot(est[:1, a], est[:1, b], "o", color="tab:blue", markersize=4)
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("trajectory (top view)")
    return ax


def plot_trajectory_axes(
    axes: Sequence[Axes], timestamps: np.ndarray, gt_positions: np.ndarray, est_positions: np.ndarray
) -> Sequence[Axes]:
    """x, y and z [m] over time [s] (relative to the first timestamp), one axis each (3 axes)."""
    t = np.asarray(timestamps) - float(timestamps[0])
    for k, ax in enumerate(axes[:3]):
        ax.plot(t, np.asarray(gt_positions)[:, k], **GT_STYLE)
        ax.plot(t, np.asarray(est_positions)[:, k], **EST_STYLE)
        ax.set_ylabel(f"{'xyz'[k]} [m]")
    axes[2].set_xlabel("time [s]")
    axes[0].legend(loc="best", fontsize="small")
    return axes


def plot_error_over_time(
    ax: Axes, timestamps: np.ndarray, errors: np.ndarray, label: str = "ATE", unit: str = "m"
) -> Axes:
    """A per-pose error over time with its RMSE as a horizontal line."""
    t = np.asarray(timestamps) - float(timestamps[0])
    e = np.asarray(errors)
    ax.plot(t, e, color="tab:red", linewidth=1.0, label=label)
    if e.size:
        rmse = float(np.sqrt(np.mean(e * e)))
        ax.axhline(rmse, color="k", linewidth=0.8, linestyle=":", label=f"RMSE {rmse:.4f} {unit}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{label} [{unit}]")
    ax.set_ylim(bottom=0)
    ax.legend(loc="best", fontsize="small")
    return ax


def depth_error_image(
    depth_est: np.ndarray, depth_gt: np.ndarray, threshold: float = CORRECT_THRESHOLD, saturate: float = 0.5
) -> np.ndarray:
    """(H, W, 3) float RGB in 0..1 coding each pixel (see the module docstring for the colours)."""
    gt_ok = valid_depth(depth_gt)
    rel = relative_depth_error(depth_est, depth_gt)
    correct = correct_depth_mask(depth_est, depth_gt, threshold)
    wrong = np.isfinite(rel) & ~correct
    img = np.zeros((*gt_ok.shape, 3))
    img[gt_ok] = MISSING_RGB
    strength = np.clip((np.nan_to_num(rel) - threshold) / max(saturate - threshold, 1e-9), 0.0, 1.0)
    red = np.stack([0.95 - 0.45 * strength, 0.55 * (1 - strength), 0.45 * (1 - strength)], axis=-1)
    img[wrong] = red[wrong]
    img[correct] = CORRECT_RGB
    img[~gt_ok] = NO_GT_RGB
    return img


def plot_depth_error_map(
    ax: Axes, depth_est: np.ndarray, depth_gt: np.ndarray, threshold: float = CORRECT_THRESHOLD, title: str = ""
) -> Axes:
    """The coded error image of one key-frame; the title gives the share of correct and estimated pixels."""
    gt_ok = valid_depth(depth_gt)
    n_gt = max(int(gt_ok.sum()), 1)
    correct = 100.0 * int(correct_depth_mask(depth_est, depth_gt, threshold).sum()) / n_gt
    dense = 100.0 * int((gt_ok & valid_depth(depth_est)).sum()) / n_gt
    ax.imshow(depth_error_image(depth_est, depth_gt, threshold), interpolation="nearest")
    ax.set_title(f"{title}{' ' if title else ''}{correct:.1f}% correct, {dense:.1f}% dense", fontsize="small")
    ax.set_axis_off()
    return ax


def plot_depth_map(ax: Axes, depth: np.ndarray, vmax: float | None = None, title: str = "") -> Axes:
    """A depth map in metres (0 / NaN shown black)."""
    d = np.where(valid_depth(depth), depth, np.nan)
    cmap = colormaps["viridis"].with_extremes(bad="black")
    ax.imshow(d, cmap=cmap, vmin=0.0, vmax=vmax, interpolation="nearest")
    ax.set_title(title, fontsize="small")
    ax.set_axis_off()
    return ax


def depth_legend_handles(threshold: float = CORRECT_THRESHOLD) -> list[Patch]:
    """Legend patches for :func:`depth_error_image`'s colours."""
    return [
        Patch(color=CORRECT_RGB, label=f"correct (< {100 * threshold:.0f} %)"),
        Patch(color=(0.95, 0.55, 0.45), label="wrong (darker = larger)"),
        Patch(color=MISSING_RGB, label="no estimate"),
        Patch(color=NO_GT_RGB, label="no ground truth"),
    ]


# ---------------------------------------------------------------------------------------------- figure wrappers
def save_trajectory_figure(
    path: str | Path,
    timestamps: np.ndarray,
    gt_positions: np.ndarray,
    est_positions: np.ndarray,
    errors: np.ndarray | None = None,
    title: str = "",
    plane: str = "xy",
    dpi: int = 120,
    labels: tuple[str, str] | None = None,
) -> Path:
    """Top view, x/y/z over time and (if given) the ATE per pose over time, in one figure written to ``path``.
    ``labels``: legend names of the two trajectories instead of "ground truth" and "estimate"."""
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    grid = fig.add_gridspec(4, 2)
    top = plot_trajectory_top(fig.add_subplot(grid[:3, 0]), gt_positions, est_positions, plane)
    axes = [fig.add_subplot(grid[k, 1]) for k in range(3)]
    plot_trajectory_axes(axes, timestamps, gt_positions, est_positions)
    if labels is not None:
        for ax in (top, axes[0]):
            for line, label in zip(ax.lines[:2], labels, strict=True):
                line.set_label(label)
            ax.legend(loc="best", fontsize="small")
    if errors is not None:
        plot_error_over_time(fig.add_subplot(grid[3, :]), timestamps, errors)
    if title:
        fig.suptitle(title)
    return _save(fig, path, dpi)


def save_depth_error_figure(
    path: str | Path,
    depth_est: Sequence[np.ndarray],
    depth_gt: Sequence[np.ndarray],
    titles: Sequence[str] | None = None,
    threshold: float = CORRECT_THRESHOLD,
    dpi: int = 120,
) -> Path:
    """One row per key-frame: ground-truth depth, estimated depth, coded error map (like the paper's Fig. 4)."""
    n = len(depth_est)
    fig = Figure(figsize=(10, 2.7 * max(n, 1) + 0.6), layout="constrained")
    axes = fig.subplots(max(n, 1), 3, squeeze=False)
    for k in range(n):
        vmax = (
            float(np.nanmax(np.where(valid_depth(depth_gt[k]), depth_gt[k], np.nan)))
            if valid_depth(depth_gt[k]).any()
            else None
        )
        name = titles[k] if titles else f"key-frame {k}"
        plot_depth_map(axes[k, 0], depth_gt[k], vmax, f"{name}: ground truth")
        plot_depth_map(axes[k, 1], depth_est[k], vmax, "estimate")
        plot_depth_error_map(axes[k, 2], depth_est[k], depth_gt[k], threshold)
    fig.legend(handles=depth_legend_handles(threshold), loc="outside lower center", ncols=4, fontsize="small")
    return _save(fig, path, dpi)


def save_depth_error_row_figure(
    path: str | Path,
    depth_est: Sequence[np.ndarray],
    depth_gt: Sequence[np.ndarray],
    titles: Sequence[str],
    title: str = "",
    threshold: float = CORRECT_THRESHOLD,
    dpi: int = 110,
) -> Path:
    """One coded depth error map per column (e.g. one key-frame per ablation variant, like the paper's Fig. 3 B)."""
    n = len(depth_est)
    fig = Figure(figsize=(4.0 * max(n, 1), 3.6), layout="constrained")
    axes = fig.subplots(1, max(n, 1), squeeze=False)[0]
    for ax, est, gt, name in zip(axes, depth_est, depth_gt, titles, strict=True):
        plot_depth_error_map(ax, est, gt, threshold, title=f"{name}:")
    if title:
        fig.suptitle(title)
    fig.legend(handles=depth_legend_handles(threshold), loc="outside lower center", ncols=4, fontsize="small")
    return _save(fig, path, dpi)


def save_sweep_figure(
    points: pd.DataFrame, path: str | Path, methods: Sequence[str], axes_titles: dict[str, str], dpi: int = 110
) -> Path:
    """ATE and correct depth (a pair of rows) against each difficulty axis (columns, at most ``per_row`` axes to a
    pair of rows), one line per method.

    ``points``: one row per run with columns axis, x, method, ate_rmse, depth_percent_correct; ``axes_titles``:
    axis name -> x-axis label, in column order.
    """
    names = list(axes_titles)
    per_row = 4
    cols, bands = min(len(names), per_row), max(1, -(-len(names) // per_row))
    fig = Figure(figsize=(4.2 * cols, 6.0 * bands), layout="constrained")
    grid = fig.subplots(2 * bands, cols, squeeze=False)
    for i, axis in enumerate(names):
        band, col = divmod(i, per_row)
        sub = points[points["axis"] == axis]
        for row, (metric, label) in enumerate((("ate_rmse", "ATE RMSE [m]"),
                                               ("depth_percent_correct", "correct depth [%]"))):  # fmt: skip
            ax = grid[2 * band + row, col]
            for k, method in enumerate(methods):  # one colour per method in every panel
                line = sub[sub["method"] == method].groupby("x")[metric].mean().sort_index()
                if line.notna().any():
                    ax.plot(line.index, line.to_numpy(), marker="o", label=method, color=f"C{k % 10}")
            ax.set_xlabel(axes_titles[axis])
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
            if axis == "focal":
                ax.axvline(1.0, color="0.5", linestyle=":", linewidth=1)
        grid[2 * band, col].set_title(axes_titles[axis], fontsize="medium")
    for i in range(len(names), 2 * bands * cols // 2):  # empty panels of the last band
        band, col = divmod(i, per_row)
        grid[2 * band, col].set_visible(False)
        grid[2 * band + 1, col].set_visible(False)
    legend: dict[str, Any] = {}  # every method drawn in any panel (some have no ATE, e.g. REMODE)
    for ax in grid.ravel():
        for handle, name in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(name, handle)
    labels = [m for m in methods if m in legend]
    handles = [legend[m] for m in labels]
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 6), fontsize="small")
    return _save(fig, path, dpi)


def save_accuracy_scatter(
    points: pd.DataFrame, path: str | Path, methods: Sequence[str], ate_target: float | None = None, dpi: int = 110
) -> Path:
    """ATE / path length (%) against key-frame correct depth (%), one point per run, one colour per method, and a
    dashed line at ``ate_target``. ``points``: columns sequence, method, ate_percent_length, depth_percent_correct."""
    fig = Figure(figsize=(6.4, 4.6), layout="constrained")
    ax = fig.subplots()
    for k, method in enumerate(methods):
        sub = points[points["method"] == method].dropna(subset=["ate_percent_length", "depth_percent_correct"])
        if not sub.empty:
            ax.scatter(sub["depth_percent_correct"], sub["ate_percent_length"], color=f"C{k % 10}", label=method)
    if ate_target is not None:
        ax.axhline(ate_target, color="0.4", linestyle="--", linewidth=1, label=f"target {ate_target:g} %")
    ax.set_xlabel("key-frame correct depth [%]")
    ax.set_ylabel("ATE / path length [%]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return _save(fig, path, dpi)


def plot_runs_strip(ax: Axes, frame: pd.DataFrame, metric: str, methods: Sequence[str],
                    sequences: Sequence[str]) -> Axes:
    """Every run's ``metric`` as a dot, one column group per method and a colour per sequence, with each cell's
    median as a short black bar: the spread over runs that a table's single number hides. ``frame``: the long frame
    (``sequence, method, metric, value``)."""
    sub = frame[frame["metric"] == metric]
    cmap = colormaps["tab10"]
    width = 0.8 / max(len(sequences), 1)
    for i, method in enumerate(methods):
        for j, seq in enumerate(sequences):
            values = sub[(sub["method"] == method) & (sub["sequence"] == seq)]["value"].dropna().to_numpy()
            if not values.size:
                continue
            x = i - 0.4 + (j + 0.5) * width
            jitter = np.linspace(-0.25, 0.25, values.size) * width if values.size > 1 else np.zeros(1)
            ax.scatter(x + jitter, values, s=10, color=cmap(j % 10), label=seq if i == 0 else None, zorder=3)
            ax.hlines(np.median(values), x - 0.4 * width, x + 0.4 * width, color="k", linewidth=1.2, zorder=4)
    ax.set_xticks(range(len(methods)), list(methods), rotation=30, ha="right")
    ax.set_ylabel(metric)
    ax.grid(axis="y", alpha=0.3)
    return ax


def save_runs_figure(frame: pd.DataFrame, path: str | Path, methods: Sequence[str], sequences: Sequence[str],
                     metrics: Sequence[tuple[str, str]], title: str = "", dpi: int = 110) -> Path | None:
    """One :func:`plot_runs_strip` panel per ``(metric, label)`` with a value; None when no panel has one."""
    shown = [(m, label) for m, label in metrics if (frame["metric"] == m).any()]
    if not shown:
        return None
    fig = Figure(figsize=(max(6.0, 0.9 * len(methods) + 2), 3.2 * len(shown)))
    axes = fig.subplots(len(shown), 1, squeeze=False)[:, 0]
    for ax, (metric, label) in zip(axes, shown, strict=True):
        plot_runs_strip(ax, frame, metric, methods, sequences)
        ax.set_ylabel(label)
    axes[0].legend(fontsize=6, ncol=min(len(sequences), 5), loc="upper left", bbox_to_anchor=(0, 1.25))
    if title:
        fig.suptitle(title, fontsize=9, y=1.0)
    fig.tight_layout()
    return _save(fig, path, dpi)


def save_transfer_figure(ranks: pd.DataFrame, path: str | Path, domains: Sequence[str], metrics: Sequence[Any],
                         dpi: int = 110) -> Path | None:
    """One bump chart per metric with ranks: each method's rank (1 = best, on top) in every domain, a line per
    method, so a method that moves between the simulated and the real domains stands out. ``ranks``: domain, metric,
    method, rank (:func:`eval.reports.transfer.rank_methods`); ``metrics``: objects with ``name`` and ``label``."""
    shown = [m for m in metrics if (ranks["metric"] == m.name).any()]
    if not shown or not domains:
        return None
    fig = Figure(figsize=(max(4.0, 1.6 * len(domains) + 2.5) * min(len(shown), 2) / 1.4, 3.4 * ((len(shown) + 1) // 2)))
    axes = fig.subplots((len(shown) + 1) // 2, min(len(shown), 2), squeeze=False).ravel()
    cmap = colormaps["tab10"]
    methods = sorted(ranks["method"].unique())
    for ax, metric in zip(axes, shown, strict=False):
        sub = ranks[ranks["metric"] == metric.name]
        for i, method in enumerate(methods):
            row = sub[sub["method"] == method].set_index("domain")["rank"].reindex(domains)
            if row.notna().any():
                ax.plot(range(len(domains)), row.to_numpy(), "o-", color=cmap(i % 10), label=method)
        ax.set_xticks(range(len(domains)), list(domains), rotation=20, ha="right", fontsize=7)
        n = int(sub["rank"].max()) if len(sub) else 1
        ax.set_ylim(n + 0.5, 0.5)
        ax.set_yticks(range(1, n + 1))
        ax.set_ylabel("rank (1 = best)")
        ax.set_title(metric.label, fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    handles = {}  # every method of any panel (REMODE has depth only), once
    for ax in axes[: len(shown)]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    axes[0].legend(list(handles.values()), list(handles), fontsize=6, loc="lower left")
    fig.tight_layout()
    return _save(fig, path, dpi)


def check_figure_path(path: str | Path) -> Path:
    """``path`` when matplotlib can write a figure of its suffix, else :class:`~eval.errors.EvalError` naming the
    suffixes it can (so that a command refuses a bad file name before it computes the figure)."""
    path = Path(path)
    formats = Figure().canvas.get_supported_filetypes()
    if path.suffix.lstrip(".").lower() not in formats:
        raise EvalError(f"cannot save a figure as {str(path)!r}: valid suffixes: "
                        f"{', '.join('.' + f for f in sorted(formats))}")  # fmt: skip
    return path


def _save(fig: Figure, path: str | Path, dpi: int) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path

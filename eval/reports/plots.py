"""Plots of the judge (the only module of ``eval`` that imports matplotlib).

Plot functions draw into axes the caller passes in and return them; the ``save_*`` wrappers build a
:class:`matplotlib.figure.Figure` (no pyplot, no global state, works headless) and write it to a file.

- :func:`plot_trajectory_top`: estimated vs ground-truth trajectory seen from above (two world axes);
- :func:`plot_trajectory_axes`: x, y, z over time;
- :func:`plot_error_over_time`: a per-pose error (ATE) over time;
- :func:`plot_depth_error_map`: a key-frame's depth error like the paper's Fig. 3/4: blue where the estimate is
  within 10 % of the ground truth (correct), red shades for wrong estimates (darker = larger error, saturating at
  50 %), grey where the ground truth is valid but there is no estimate, black where there is no ground truth;
- for a paper, over every method of a suite: :func:`plot_methods_top` (every method's trajectory aligned to the
  ground truth in one top view), :func:`plot_ate_bands` (ATE over time, the median over seeds and a band from their
  min to their max), :func:`plot_relative_error_boxes` (relative error at several distances as boxplots, as
  rpg_trajectory_evaluation draws them), :func:`plot_method_strip` (a figure per method, e.g. speed and memory).

Every method is drawn in its own colour and marker (:func:`eval.reports.style.method_style`, the same in every
figure); a method without a value in a panel is named there as ``n/a`` with the reason; every axis states its unit.
A failed run (:func:`eval.metrics.results.failure_of`: never initialised, or tracked less than
:data:`eval.metrics.results.MIN_TRACKED_SHARE` of its frames) is never drawn at its value: it is the failure mark at
the foot of its column with its tracked share (``X 22 %``), and counts in no median or line.
A figure is written in the format its file name says (``.png``, ``.pdf``, ``.svg``; :func:`save_figure`): a PDF
comes with a PNG twin (same name, ``.png``) for the Markdown and the HTML report, which cannot show a PDF inline;
PDF and SVG files carry no creation date, so the same figure gives the same bytes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib import colormaps, rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.metrics.catalogue import ATE_PERCENT_LENGTH, DEPTH_PERCENT_CORRECT, TRACKED_SHARE
from eval.metrics.results import FAILURE_MARK, failure_of, share_text
from eval.reports.style import GROUND_TRUTH_STYLE, MethodStyle, method_style
from slamcommon.depth_metrics import CORRECT_THRESHOLD, correct_depth_mask, relative_depth_error, valid_depth

GT_STYLE = {"color": GROUND_TRUTH_STYLE.color, "linestyle": GROUND_TRUTH_STYLE.linestyle, "linewidth": 1.2,
            "label": "ground truth"}
EST_STYLE = {"color": "tab:blue", "linewidth": 1.2, "label": "estimate"}
CORRECT_RGB = (0.12, 0.35, 0.95)
MISSING_RGB = (0.55, 0.55, 0.55)
NO_GT_RGB = (0.0, 0.0, 0.0)
_AXES = {"x": 0, "y": 1, "z": 2}


def plot_trajectory_top(ax: Axes, gt_positions: np.ndarray, est_positions: np.ndarray, plane: str = "xy",
                        style: MethodStyle | None = None) -> Axes:
    """Both trajectories projected on ``plane`` (two of x, y, z, e.g. "xy" or "xz"), equal axis scale, metres;
    ``style``: the estimate's method's look (default: a plain blue)."""
    a, b = (_AXES[c] for c in plane)
    gt, est = np.asarray(gt_positions), np.asarray(est_positions)
    est_style = EST_STYLE if style is None else {**EST_STYLE, "color": style.color}
    ax.plot(gt[:, a], gt[:, b], **GT_STYLE)
    ax.plot(est[:, a], est[:, b], **est_style)
    ax.plot(gt[:1, a], gt[:1, b], "o", color=GT_STYLE["color"], markersize=4)
    ax.plot(est[:1, a], est[:1, b], "o", color=est_style["color"], markersize=4)
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("trajectory (top view)")
    return ax


def plot_trajectory_axes(
    axes: Sequence[Axes], timestamps: np.ndarray, gt_positions: np.ndarray, est_positions: np.ndarray,
    style: MethodStyle | None = None,
) -> Sequence[Axes]:
    """x, y and z [m] over time [s] (relative to the first timestamp), one axis each (3 axes); ``style``: the
    estimate's method's look."""
    t = np.asarray(timestamps) - float(timestamps[0])
    est_style = EST_STYLE if style is None else {**EST_STYLE, "color": style.color}
    for k, ax in enumerate(axes[:3]):
        ax.plot(t, np.asarray(gt_positions)[:, k], **GT_STYLE)
        ax.plot(t, np.asarray(est_positions)[:, k], **est_style)
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
    style: MethodStyle | None = None,
) -> Path:
    """Top view, x/y/z over time and (if given) the ATE per pose over time, in one figure written to ``path``.
    ``labels``: legend names of the two trajectories instead of "ground truth" and "estimate"; ``style``: the
    estimate's method's look (:func:`eval.reports.style.method_style`)."""
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    grid = fig.add_gridspec(4, 2)
    top = plot_trajectory_top(fig.add_subplot(grid[:3, 0]), gt_positions, est_positions, plane, style)
    axes = [fig.add_subplot(grid[k, 1]) for k in range(3)]
    plot_trajectory_axes(axes, timestamps, gt_positions, est_positions, style)
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

    ``points``: one row per run with columns axis, x, method, the keys of the catalogue's sweep-figure metrics (ATE
    RMSE, correct depth) and of the tracked share; ``axes_titles``: axis name -> x-axis label, in column order. Each
    line is the median over the runs at an x that did not fail (:func:`eval.metrics.results.failure_of` of their
    tracked share); an x
    where at least half of a method's runs failed has no point: the failure mark with the median share of its
    failed runs at the foot of the panel (:func:`draw_failures`).
    """
    share = TRACKED_SHARE.key
    if share in points.columns:
        failed = np.array([failure_of({share: v}) is not None
                           for v in points[share].to_numpy(dtype=float)], dtype=bool)  # fmt: skip
    else:
        failed = np.zeros(len(points), dtype=bool)
    points = points.assign(_failed=failed)
    names = list(axes_titles)
    per_row = 4
    cols, bands = min(len(names), per_row), max(1, -(-len(names) // per_row))
    fig = Figure(figsize=(4.2 * cols, 6.0 * bands), layout="constrained")
    grid = fig.subplots(2 * bands, cols, squeeze=False)
    for i, axis in enumerate(names):
        band, col = divmod(i, per_row)
        sub = points[points["axis"] == axis]
        for row, (label, metric) in enumerate(catalogue.blocks(catalogue.SWEEP_FIGURE)):
            ax = grid[2 * band + row, col]
            for method in methods:  # each method's own colour and marker (eval.reports.style)
                own = sub[sub["method"] == method]
                lost = own.groupby("x")["_failed"].agg(lambda f: 2 * int(f.sum()) >= len(f) and bool(f.any()))
                look = method_style(method)
                line = own[~own["_failed"]].groupby("x")[metric].median()
                line = line[~line.index.isin(lost[lost].index)].sort_index()
                if line.notna().any():
                    ax.plot(line.index, line.to_numpy(), marker=look.marker, label=method, color=look.color)
                if lost.any() and own[metric].notna().any():
                    at = [x for x in lost[lost].index]
                    draw_failures(ax, at, [float(own[own["_failed"] & (own["x"] == x)][share].median())
                                           for x in at], look.color)  # fmt: skip
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
    """ATE / path length (%) against key-frame correct depth (%), one point per run in its method's colour and
    marker, each labelled with its sequence (the name up to any ``@camera``), and a dashed line at ``ate_target``.
    ``points``: columns sequence, method and the keys of :data:`~eval.metrics.catalogue.ATE_PERCENT_LENGTH` and
    :data:`~eval.metrics.catalogue.DEPTH_PERCENT_CORRECT`."""
    x, y = DEPTH_PERCENT_CORRECT.key, ATE_PERCENT_LENGTH.key
    fig = Figure(figsize=(7.2, 5.2), layout="constrained")
    ax = fig.subplots()
    for method in methods:
        sub = points[points["method"] == method].dropna(subset=[y, x])
        if sub.empty:
            continue
        look = method_style(method)
        ax.scatter(sub[x], sub[y], color=look.color, marker=look.marker, label=method, zorder=3)
        for row in sub.to_dict("records"):
            ax.annotate(str(row["sequence"]).split("@")[0], (row[x], row[y]),
                        xytext=(4, 3), textcoords="offset points", fontsize=6, color=look.color)  # fmt: skip
    if ate_target is not None:
        ax.axhline(ate_target, color="0.4", linestyle="--", linewidth=1, label=f"target {ate_target:g} %")
    ax.set_xlabel("key-frame correct depth [%]")
    ax.set_ylabel("ATE / path length [%]")
    ax.grid(True, alpha=0.3)
    fig.legend(fontsize="small", loc="outside right upper")
    return _save(fig, path, dpi)


def draw_failures(ax: Axes, xs: Sequence[float], shares: Sequence[float], color: Any) -> None:
    """Failed runs at data x ``xs``: the failure mark at the foot of the panel (axes-fraction y), each with its
    tracked share, in ``color``: a failure is never drawn at a value."""
    for x, share in zip(xs, shares, strict=True):
        ax.text(x, 0.02, f"{FAILURE_MARK}\n{share_text(share)}", transform=ax.get_xaxis_transform(), ha="center",
                va="bottom", fontsize=6, color=color, fontweight="bold", zorder=5)  # fmt: skip


def draw_not_available(ax: Axes, x: float, reason: str) -> None:
    """Write ``n/a`` and its ``reason`` upright in the column at ``x`` of ``ax`` (data x, axes-fraction y): a method
    with no value in a panel says why instead of leaving a blank."""
    ax.text(x, 0.5, f"n/a: {reason}", transform=ax.get_xaxis_transform(), rotation=90, ha="center", va="center",
            fontsize=7, color="0.35", wrap=True)  # fmt: skip


def plot_runs_strip(ax: Axes, frame: pd.DataFrame, metric: str, methods: Sequence[str], sequences: Sequence[str],
                    missing: Mapping[str, str] | None = None) -> Axes:
    """Every run's ``metric`` as a dot, one column group per method (its name in its colour) and a colour per
    sequence, with each cell's median as a short black bar: the spread over runs that a table's single number
    hides. ``frame``: the long frame (``sequence, method, metric, value``); ``missing``: method -> why it has no
    value (written in its column as ``n/a``). A failed run (with a ``run`` column: its tracked-share and pose-pair
    rows, :func:`eval.metrics.results.failure_of`) is the failure mark with its share at the foot of
    its place (:func:`draw_failures`), not a dot; a cell's bar is the median of its runs that did not fail, none
    when at least half failed."""
    from eval.reports.tables import failed_runs

    failed = failed_runs(frame) if "run" in frame.columns else set()
    shares = ({(str(r.sequence), str(r.method), str(r.run)): r.value for r in
               frame[frame["metric"] == TRACKED_SHARE.key].itertuples()} if failed else {})  # fmt: skip
    sub = frame[frame["metric"] == metric]
    cmap = colormaps["tab10"]
    width = 0.8 / max(len(sequences), 1)
    labelled: set[str] = set()
    for i, method in enumerate(methods):
        drawn = False
        for j, seq in enumerate(sequences):
            cell = sub[(sub["method"] == method) & (sub["sequence"] == seq)].dropna(subset=["value"])
            if cell.empty:
                continue
            drawn = True
            x = i - 0.4 + (j + 0.5) * width
            bad = (np.array([(str(seq), str(method), str(r)) in failed for r in cell["run"]], dtype=bool)
                   if failed else np.zeros(len(cell), dtype=bool))  # fmt: skip
            jitter = np.linspace(-0.25, 0.25, len(cell)) * width if len(cell) > 1 else np.zeros(1)
            values = cell["value"].to_numpy(dtype=float)
            if (~bad).any():
                ax.scatter(x + jitter[~bad], values[~bad], s=10, color=cmap(j % 10),
                           label=None if seq in labelled else seq, zorder=3)  # fmt: skip
                labelled.add(seq)
            if bad.any():
                runs = cell["run"].to_numpy()[bad]
                draw_failures(ax, list(x + jitter[bad]),
                              [float(shares.get((str(seq), str(method), str(r)), np.nan)) for r in runs],
                              cmap(j % 10))  # fmt: skip
            if (~bad).any() and 2 * int(bad.sum()) < len(cell):
                ax.hlines(np.median(values[~bad]), x - 0.4 * width, x + 0.4 * width, color="k", linewidth=1.2,
                          zorder=4)  # fmt: skip
        if not drawn:
            draw_not_available(ax, i, (missing or {}).get(method, "no value"))
    ax.set_xticks(range(len(methods)), list(methods), rotation=30, ha="right")
    for tick, method in zip(ax.get_xticklabels(), methods, strict=True):
        tick.set_color(method_style(method).color)
    ax.set_xlim(-0.6, len(methods) - 0.4)
    ax.set_ylabel(metric)
    ax.grid(axis="y", alpha=0.3)
    return ax


def save_runs_figure(frame: pd.DataFrame, path: str | Path, methods: Sequence[str], sequences: Sequence[str],
                     metrics: Sequence[tuple[str, str]], title: str = "", dpi: int = 110,
                     missing: Mapping[str, Mapping[str, str]] | None = None) -> Path | None:
    """One :func:`plot_runs_strip` panel per ``(metric, label)`` with a value; None when no panel has one.
    ``missing``: metric -> method -> why the method has no value (its column says ``n/a`` and why)."""
    shown = [(m, label) for m, label in metrics if (frame["metric"] == m).any()]
    if not shown:
        return None
    fig = Figure(figsize=(max(6.0, 0.9 * len(methods) + 2), 3.2 * len(shown) + 0.8), layout="constrained")
    axes = fig.subplots(len(shown), 1, squeeze=False)[:, 0]
    for ax, (metric, label) in zip(axes, shown, strict=True):
        plot_runs_strip(ax, frame, metric, methods, sequences, (missing or {}).get(metric))
        ax.set_ylabel(label)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, fontsize=6, ncols=min(len(labels), 5), loc="outside lower center")
    from eval.reports.tables import failed_runs

    if "run" in frame.columns and failed_runs(frame):
        title = (f"{title}\n" if title else "") + (f"{FAILURE_MARK} and a share: a failed run (never initialised, or "
                                                  "tracked too little), drawn at no value")  # fmt: skip
    if title:
        fig.suptitle(title, fontsize=9)
    return _save(fig, path, dpi)


def save_transfer_figure(ranks: pd.DataFrame, path: str | Path, domains: Sequence[str], metrics: Sequence[Any],
                         dpi: int = 110) -> Path | None:
    """One bump chart per metric with ranks: each method's rank (1 = best, on top) in every domain, a line per
    method, so a method that moves between the simulated and the real domains stands out. ``ranks``: domain, metric,
    method, rank (:func:`eval.reports.transfer.rank_methods`); ``metrics``: objects with ``name`` and ``label``."""
    shown = [m for m in metrics if (ranks["metric"] == m.name).any()]
    if not shown or not domains:
        return None
    fig = Figure(figsize=(max(4.0, 1.6 * len(domains) + 2.5) * min(len(shown), 2) / 1.4,
                          3.4 * ((len(shown) + 1) // 2) + 0.8), layout="constrained")  # fmt: skip
    axes = fig.subplots((len(shown) + 1) // 2, min(len(shown), 2), squeeze=False).ravel()
    methods = sorted(ranks["method"].unique())
    for ax, metric in zip(axes, shown, strict=False):
        sub = ranks[ranks["metric"] == metric.name]
        for method in methods:
            row = sub[sub["method"] == method].set_index("domain")["rank"].reindex(domains)
            if row.notna().any():
                look = method_style(method)
                ax.plot(range(len(domains)), row.to_numpy(), linestyle="-", marker=look.marker, color=look.color,
                        label=method)  # fmt: skip
        ax.set_xticks(range(len(domains)), list(domains), rotation=20, ha="right", fontsize=7)
        n = int(sub["rank"].max()) if len(sub) else 1
        ax.set_ylim(n + 0.5, 0.5)
        ax.set_yticks(range(1, n + 1))
        ax.set_ylabel("rank (1 = best)")
        ax.set_title(metric.label, fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    handles = {}  # every method of any panel (REMODE has depth only), once, below the panels: it covers no data
    for ax in axes[: len(shown)]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    fig.legend(list(handles.values()), list(handles), fontsize=7, loc="outside lower center",
               ncols=min(len(handles), 6))  # fmt: skip
    return _save(fig, path, dpi)


# ----------------------------------------------------------------------------------------- every method at once
def plot_methods_top(ax: Axes, gt_positions: np.ndarray, tracks: Mapping[str, np.ndarray], plane: str = "xy",
                     labels: Mapping[str, str] | None = None) -> Axes:
    """The ground truth and every method's trajectory (``tracks``: method -> (M, 3) positions, aligned to the ground
    truth, metres) projected on ``plane``, each in its method's colour, a marker at its start; equal axis scale.
    ``labels``: legend text per method (default: its name)."""
    a, b = (_AXES[c] for c in plane)
    gt = np.asarray(gt_positions)
    ax.plot(gt[:, a], gt[:, b], **GT_STYLE)
    for method, positions in tracks.items():
        p, look = np.asarray(positions), method_style(method)
        ax.plot(p[:, a], p[:, b], color=look.color, linestyle=look.linestyle, linewidth=1.0,
                label=(labels or {}).get(method, method))  # fmt: skip
        ax.plot(p[:1, a], p[:1, b], linestyle="none", marker=look.marker, color=look.color, markersize=5)
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    return ax


def plot_ate_bands(ax: Axes, times: np.ndarray, bands: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                   runs: Mapping[str, int] | None = None) -> Axes:
    """ATE over time per method: ``bands``: method -> (median, min, max) over its runs (seeds) at ``times`` (s from
    the sequence's start; NaN where a run has no pose), metres. The median is a line in the method's colour, the
    runs' range a band around it; ``runs``: how many runs each band spans (in the legend)."""
    t = np.asarray(times, dtype=np.float64)
    for method, (median, lo, hi) in bands.items():
        look = method_style(method)
        n = (runs or {}).get(method)
        ax.plot(t, median, color=look.color, linestyle=look.linestyle, linewidth=1.0,
                label=method + (f" ({n} runs)" if n and n > 1 else ""))  # fmt: skip
        if n is None or n > 1:
            ax.fill_between(t, lo, hi, color=look.color, alpha=0.2, linewidth=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("ATE [m]")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    return ax


def plot_relative_error_boxes(ax: Axes, distances: Sequence[str], errors: Mapping[str, Sequence[np.ndarray]],
                              ylabel: str) -> Axes:
    """Relative error at several distances as grouped boxplots (rpg_trajectory_evaluation's figure): one group per
    distance (``distances``: the tick labels, e.g. ``1.3 m``), one box per method in its colour, over the pairs of
    all its runs (``errors``: method -> one array per distance; an empty array draws no box). Whiskers at 1.5 IQR,
    no outlier markers (thousands of pairs); ``ylabel`` states the unit."""
    methods = [m for m, per in errors.items() if any(np.asarray(e).size for e in per)]
    width = 0.8 / max(len(methods), 1)
    for k, method in enumerate(methods):
        look = method_style(method)
        data = [np.asarray(e, dtype=np.float64) for e in errors[method]]
        where = [i for i, e in enumerate(data) if e.size]
        positions = [i - 0.4 + (k + 0.5) * width for i in where]
        boxes = ax.boxplot([data[i] for i in where], positions=positions, widths=0.85 * width, patch_artist=True,
                           showfliers=False, manage_ticks=False)  # fmt: skip
        for box in boxes["boxes"]:
            box.set(facecolor=look.color, alpha=0.55, edgecolor=look.color)
        for part in ("whiskers", "caps"):
            for line in boxes[part]:
                line.set(color=look.color)
        for line in boxes["medians"]:
            line.set(color="black", linewidth=1.0)
        ax.plot([], [], linestyle="none", marker="s", color=look.color, label=method)  # its legend entry
    ax.set_xticks(range(len(distances)), list(distances))
    ax.set_xlim(-0.6, len(distances) - 0.4)
    ax.set_xlabel("distance travelled [m]")
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    ax.grid(axis="y", alpha=0.3)
    return ax


def plot_method_strip(ax: Axes, values: Mapping[str, np.ndarray], methods: Sequence[str], ylabel: str,
                      missing: Mapping[str, str] | None = None) -> Axes:
    """One column per method (``methods`` in order): each run's value (``values``: method -> (K,)) a dot in the
    method's colour and marker, the median a black bar; a method without a value says ``n/a`` and why (``missing``).
    ``ylabel`` states the unit."""
    for i, method in enumerate(methods):
        v = np.asarray(values.get(method, []), dtype=np.float64)
        v = v[np.isfinite(v)]
        if not v.size:
            draw_not_available(ax, i, (missing or {}).get(method, "no value"))
            continue
        look = method_style(method)
        jitter = np.linspace(-0.15, 0.15, v.size) if v.size > 1 else np.zeros(1)
        ax.scatter(i + jitter, v, s=14, color=look.color, marker=look.marker, zorder=3)
        ax.hlines(np.median(v), i - 0.25, i + 0.25, color="k", linewidth=1.2, zorder=4)
    ax.set_xticks(range(len(methods)), list(methods), rotation=30, ha="right")
    for tick, method in zip(ax.get_xticklabels(), methods, strict=True):
        tick.set_color(method_style(method).color)
    ax.set_xlim(-0.6, len(methods) - 0.4)
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    ax.grid(axis="y", alpha=0.3)
    return ax


def _legend_with_missing(fig: Figure, ax: Axes, missing: Mapping[str, str]) -> None:
    """The figure's legend (right of the panels, covering no data): ``ax``'s entries, then one ``n/a`` entry per
    method without a value, with the reason (``missing``: method -> why)."""
    handles, names = ax.get_legend_handles_labels()
    for method, why in missing.items():
        handles.append(Line2D([], [], linestyle="none", marker=method_style(method).marker, color="0.6"))
        names.append(f"{method}: n/a ({why})")
    fig.legend(handles, names, loc="outside right upper", fontsize="small")


def save_sequence_figure(path: str | Path, title: str, gt_positions: np.ndarray, tracks: Mapping[str, np.ndarray],
                         times: np.ndarray, bands: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                         runs: Mapping[str, int], missing: Mapping[str, str], labels: Mapping[str, str] | None = None,
                         plane: str = "xy", dpi: int = 110) -> Path:
    """One sequence, every method: the top view of the trajectories aligned to the ground truth
    (:func:`plot_methods_top`) beside the ATE over time with a band across seeds (:func:`plot_ate_bands`); methods
    without a trajectory listed in the legend as ``n/a`` with the reason (``missing``)."""
    fig = Figure(figsize=(11.0, 4.6), layout="constrained")
    top, ate = fig.subplots(1, 2, width_ratios=(1.0, 1.3))
    plot_methods_top(top, gt_positions, tracks, plane, labels)
    top.set_title("trajectories aligned to the ground truth (top view)", fontsize="small")
    plot_ate_bands(ate, times, bands, runs)
    ate.set_title("ATE over time: median over runs, band from min to max", fontsize="small")
    _legend_with_missing(fig, top, missing)
    fig.suptitle(title, fontsize="medium")
    return _save(fig, path, dpi)


def save_relative_error_figure(path: str | Path, title: str, distances: Sequence[str],
                               translation: Mapping[str, Sequence[np.ndarray]],
                               rotation: Mapping[str, Sequence[np.ndarray]], missing: Mapping[str, str],
                               dpi: int = 110) -> Path:
    """One sequence, every method: the relative translation error [m] and rotation error [deg] at each distance as
    boxplots (:func:`plot_relative_error_boxes`), as rpg_trajectory_evaluation draws them; methods without a
    trajectory listed in the legend as ``n/a`` with the reason."""
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    plot_relative_error_boxes(left, distances, translation, "relative translation error [m]")
    plot_relative_error_boxes(right, distances, rotation, "relative rotation error [deg]")
    _legend_with_missing(fig, left, missing)
    fig.suptitle(title, fontsize="medium")
    return _save(fig, path, dpi)


def save_resources_figure(path: str | Path, methods: Sequence[str], fps: Mapping[str, np.ndarray],
                          memory: Mapping[str, np.ndarray], missing: Mapping[str, str], title: str = "",
                          dpi: int = 110) -> Path:
    """Speed and memory per method, as VSLAM-LAB plots them: frames per second end to end and peak resident memory
    (MiB), one dot per run (:func:`plot_method_strip`)."""
    fig = Figure(figsize=(max(6.0, 0.8 * len(methods) + 3), 3.6), layout="constrained")
    left, right = fig.subplots(1, 2)
    plot_method_strip(left, fps, methods, "frames per second, end to end [1/s]", missing)
    plot_method_strip(right, memory, methods, "peak resident memory [MiB]", missing)
    if title:
        fig.suptitle(title, fontsize="medium")
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


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` in the format of ``path``'s suffix (module docstring: a PDF gets a PNG twin; PDF and SVG carry no
    creation date); returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix.lower()
    metadata = {"CreationDate": None} if suffix == ".pdf" else {"Date": None} if suffix == ".svg" else None
    with rc_context({"svg.hashsalt": "cnnslam"}):  # an SVG's element ids from a fixed salt, not at random
        fig.savefig(path, dpi=dpi, metadata=metadata)
    if suffix == ".pdf":
        fig.savefig(path.with_suffix(".png"), dpi=dpi)
    return path


_save = save_figure

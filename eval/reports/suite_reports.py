"""What each suite leaves under ``results/``: tables (Markdown, CSV, LaTeX), plots, and the long-form CSV of all its
runs (``<suite>_long.csv``: sequence, method, metric, value, plus run metadata: seed, frames, agent entry point and
keyword arguments, git revision, wall time).

- ``table1``: ``table1.{md,csv,tex}`` shaped like the paper's Table 1 (ATE block, percentage-of-correct-depth block,
  Avg. row); the Markdown quotes the paper's number beside each of ours, ``ours (paper)``;
- ``rotation``: ``rotation.{md,csv,tex}``: tracked share, rotation error, correct depth per sequence and method;
- ``ablation``: ``ablation.{md,csv,tex}`` and ``ablation.png`` (one key-frame's depth error per variant, Fig. 3);
- ``sweep``: ``sweep.png`` (ATE and correct depth against each difficulty axis) and ``sweep.{md,csv}``;
- ``depth_quality``: ``depth_quality.{md,csv,tex}`` (ATE / path length, scale error, correct depth, rotation error),
  the issue's targets per sequence for CNN-SLAM, and ``depth_quality.png`` (ATE / length against correct depth);
- ``quick``: ``quick.md`` and ``quick_runs.json`` (the run records the gate compares, ``cnnslam regress``).

Every cell is the median of the cell's runs (seeds) with their range, ``median [min, max]``
(:mod:`eval.reports.tables`); every suite also writes ``<suite>_stats.csv`` (per sequence, method and metric: runs,
median, quartiles, min, max) and ``<suite>_runs.png`` (every run as a dot, per method and sequence). Every Markdown
file starts with how it was made (command, frames, seeds, revision) and the failure rule in one line
(:data:`eval.metrics.results.FAILURE_RULE`: a run that never initialised or tracked less than
:data:`eval.metrics.results.MIN_TRACKED_SHARE` of its frames is a failure, shown ``X (22 %)`` in every table, plot
and average, never as a figure), and ends with the state of the runs: the failure rate per method (runs that crashed
or timed out, and runs that failed by the rule), methods skipped (and why), runs that failed (and their errors).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from eval.metrics import catalogue
from eval.metrics.catalogue import (
    ATE_PERCENT_LENGTH,
    ATE_RMSE,
    DEPTH_PERCENT_CORRECT,
    FRAMES,
    TRACKED_SHARE,
)
from eval.metrics.results import MIN_TRACKED_SHARE, RunRecord, failure_of, failure_text
from eval.metrics.runs import suite_records_json
from eval.reports.inputs import SuiteRun
from eval.reports.paper_table1 import PAPER_NAMES, covers_paper_sequences, paper_name, paper_value  # noqa: F401
from eval.reports.plots import save_accuracy_scatter, save_depth_error_row_figure, save_sweep_figure
from eval.reports.report_parts import (
    header_markdown,
    long_frame,
    markdown_image,
    suite_table,
    with_relative_errors,
    write_suite_report,
    write_tables,
)
from eval.reports.style import DEFAULT_FIGURE_FORMAT
from eval.reports.tables import (
    AVG_LABEL,
    TABLE1_BLOCKS,
    Spread,
    avg_coverage,
    cell_text,
    table_to_markdown,
    without_failures,
)
from sim_envs.driver import match_timestamp

# Each table's (title, metric) column blocks, in order: the catalogue's places (eval.metrics.catalogue)
ROTATION_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.ROTATION)
SIM3_BLOCK: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.SIM3)
# The global model (Sec. 3.5) of the agents that hand one back (eval.metrics.map_metrics)
MAP_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.MAP)
QUICK_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.QUICK)
SWEEP_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.SWEEP)
DEPTH_QUALITY_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.DEPTH_QUALITY)
# The SLAM issue's targets on the office and living sequences: absolute-scale ATE (SE(3) alignment) at most 2 % of
# the path length, scale error at most 5 %, key-frame correct depth above the raw CNN's.
# A run that tracked less than this share of its frames is lost: a failure (the one rule,
# eval.metrics.results.failure_of; the threshold and its source: eval.metrics.results.MIN_TRACKED_SHARE)
TARGET_ATE_PERCENT_LENGTH = 2.0
TARGET_SCALE_ERROR_PERCENT = 5.0


# ----------------------------------------------------------------------------------------------------- table1
def ours_beside_paper(ours: pd.DataFrame, metric_block: str, metric: str, digits: int,
                      spread: Spread | None = None) -> str:
    """One block of our Table 1 as Markdown, each cell ``ours (paper)`` where the paper has the number; with
    ``spread`` (:func:`eval.reports.tables.spread_of`), ours is ``median [min, max]``, with a partial run's coverage.
    The paper's Avg. is quoted only beside an Avg. over all nine of its sequences: an average over fewer is another
    figure."""
    all_nine = covers_paper_sequences(label for label in ours.index if label != AVG_LABEL)
    block = ours[metric_block] if metric_block in ours.columns.get_level_values(0) else pd.DataFrame(index=ours.index)
    header = ["sequence", *block.columns]
    lines = ["| " + " | ".join(header) + " |", "|---|" + "---:|" * len(block.columns)]
    for label, row in block.iterrows():
        cells = []
        for method, value in row.items():
            text = cell_text(value, label, (metric_block, method), spread, digits)
            fewer = label == AVG_LABEL and spread is not None and avg_coverage(spread, method) is not None
            quoted = math.nan if fewer else paper_value(label, str(method), metric, all_nine)
            if not math.isnan(quoted):
                text += f" ({quoted:.{digits}f})"
            cells.append(text)
        name = str(label) if label == AVG_LABEL else f"{label} ({paper_name(label, 'ours only')})"
        lines.append("| " + " | ".join([name, *cells]) + " |")
    return "\n".join(lines) + "\n"


def report_table1(run: SuiteRun, results_dir: str | Path, command: str,
                  figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``table1.{md,csv,tex}`` and ``table1_long.csv``."""
    results_dir = Path(results_dir)
    table, spread = suite_table(run, TABLE1_BLOCKS)
    sim3, sim3_spread = suite_table(run, SIM3_BLOCK)
    paths = write_tables(table, results_dir / "table1", "CNN-SLAM Table 1 analogue (ours).", spread=spread,
                         blocks=TABLE1_BLOCKS, run=run)  # fmt: skip
    ate_title, ate_metric = TABLE1_BLOCKS[0]
    depth_title, depth_metric = TABLE1_BLOCKS[1]
    text = [
        header_markdown(run, "Table 1 analogue: absolute trajectory error and percentage of correct depth", command),
        "Each cell: **ours, median [min, max] of the runs (the paper's Table 1)**. Our sequences are simulated "
        "analogues of the paper's "
        "(ICL-NUIM office/living room, TUM fr3 sequences), not the same images: compare shapes (which method is "
        "best, by how much), not values. `oracle` is the ground truth fed through the same pipeline (a sanity "
        "row: 0 m, 100 %). `-`: no value (REMODE has no trajectory of its own; a skipped method; a run that "
        "crashed). `X (22 %)`: a failure (never initialised, or tracked less than "
        f"{round(100 * MIN_TRACKED_SHARE)} % of its frames), no figure. The Avg. row is shown only where a method "
        "has every sequence, each run covering its whole sequence (a run that scored part of it says so in its "
        "cell, `(10/60 frames)`); a failed sequence is left out of its method's Avg., which says how many it covers, "
        "`(7/9)`; the paper's Avg. is quoted only beside ours over its nine sequences.\n",
        f"## {ate_title}\n",
        ours_beside_paper(table, ate_title, ate_metric, 3, spread),
        f"## {depth_title}\n",
        "A pixel is correct when its depth is within 10 % of the ground truth; the share is over all pixels of the "
        "key-frames with valid ground truth (a sparse method is penalised for the pixels it has no depth for).\n",
        ours_beside_paper(table, depth_title, depth_metric, 3, spread),
        "## Scale-aligned ATE, Sim(3) [m]\n",
        "The paper's ATE (above) aligns with SE(3): no scale correction, so a monocular method pays for a wrong "
        "scale. Monocular SLAM papers report ATE after Sim(3) alignment (`evo_ape -as`); both are here.\n",
        table_to_markdown(sim3, spread=sim3_spread),
        *_map_section(run),
        "## Ours alone (as in table1.csv / table1.tex)\n",
        table_to_markdown(table, spread=spread),
    ]
    return write_suite_report(run, results_dir, "table1", text, paths,
                              blocks=(*TABLE1_BLOCKS, *SIM3_BLOCK, *MAP_BLOCKS), figure_format=figure_format,
                              paper=True)  # fmt: skip


def _map_section(run: SuiteRun) -> list[str]:
    """The global model's figures (Sec. 3.5, :mod:`eval.metrics.map_metrics`) for the methods that hand back a model;
    empty when none does."""
    table, spread = suite_table(run, MAP_BLOCKS)
    table = table.dropna(axis=1, how="all")
    if table.empty or table.shape[1] == 0:
        return []
    spread = Spread(spread.lo[table.columns], spread.hi[table.columns], spread.partial, spread.failures)
    return [
        "## Global model (Sec. 3.5, Fig. 1c)\n",
        "The key-frames fused live into the agent's surfel model, moved onto the ground truth with the run's ATE "
        "alignment, against the scene's surfaces (2 cm samples; `eval/metrics/map_metrics.py`). Accuracy: median "
        "distance of the model's points to the surfaces; completeness: share of the surfaces a key-frame saw that "
        "have a model point within 5 cm; label accuracy: share of the labelled model points whose fused label is the "
        "surface's. Methods that build no model are left out.\n",
        table_to_markdown(table, spread=spread),
    ]


# --------------------------------------------------------------------------------------------------- rotation
def report_rotation(run: SuiteRun, results_dir: str | Path, command: str,
                    figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``rotation.{md,csv,tex}`` and ``rotation_long.csv``."""
    results_dir = Path(results_dir)
    table, spread = suite_table(run, ROTATION_BLOCKS)
    paths = write_tables(table, results_dir / "rotation", "Pure-rotation stress sequences.", spread=spread,
                         blocks=ROTATION_BLOCKS, run=run)  # fmt: skip
    text = [
        header_markdown(run, "Rotation stress: tracking and depth under pure rotation", command),
        "Sequences `rot_<axes>_<deg/s>`: the camera turns about a fixed optical centre (like TUM fr1/rpy), so a "
        "monocular method gets no parallax to triangulate from. Tracked share: frames the method reported as "
        "tracked. Rotation error: RMSE of the angle between estimated and true orientation (degrees) after the "
        "orientation-only alignment (the rotation that best aligns the orientations; positions play no part, so a "
        "near-static position cloud cannot decide it). RPE rotation: RMSE of the relative rotation error over 1 s, "
        "no alignment at all. Correct depth as in Table 1.\n",
        table_to_markdown(table, spread=spread),
    ]
    return write_suite_report(run, results_dir, "rotation", text, paths, blocks=ROTATION_BLOCKS,
                              figure_format=figure_format)  # fmt: skip


# --------------------------------------------------------------------------------------------------- ablation
def report_ablation(run: SuiteRun, results_dir: str | Path, command: str,
                    figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``ablation.{md,csv,tex}``, ``ablation.png`` (when there are key-frames) and ``ablation_long.csv``."""
    results_dir = Path(results_dir)
    table, spread = suite_table(run, TABLE1_BLOCKS)
    paths = write_tables(table, results_dir / "ablation", "Ablation of the CNN depth (Fig. 3).", spread=spread,
                         blocks=TABLE1_BLOCKS, run=run)  # fmt: skip
    figure = save_ablation_figure(run, results_dir / f"ablation.{figure_format}")
    text = [
        header_markdown(run, "Ablation (the paper's Fig. 3): raw CNN depth, focal-length adjustment, refinement",
                        command),  # fmt: skip
        "`raw-CNN`: the network's depth as predicted; `focal-adjusted`: with the focal-length adjustment of eq. 5 "
        "(the test camera's focal length differs from the training camera's); `adjusted+refined`: the full system, "
        "the adjusted depth refined by small-baseline stereo (eq. 10-11).\n",
        table_to_markdown(table, spread=spread),
        markdown_image(figure, "one key-frame's depth error per variant", results_dir) if figure else "",
    ]
    return write_suite_report(run, results_dir, "ablation", text, [*paths, *([figure] if figure else [])],
                              blocks=TABLE1_BLOCKS, figure_format=figure_format)  # fmt: skip



def _keyframes_of(run: SuiteRun, record: RunRecord) -> dict[str, np.ndarray] | None:
    path = run.out_root / str(record.run) / "keyframes.npz"
    if not path.is_file():
        return None
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    return arrays if "depth" in arrays and arrays["depth"].shape[0] else None


def save_ablation_figure(run: SuiteRun, path: Path) -> Path | None:
    """For the first sequence where every variant has key-frames: the key-frame of each variant nearest to the
    middle of the run, its depth error map (blue correct, red wrong, grey missing) against the ground truth."""
    by_sequence: dict[str, dict[str, RunRecord]] = {}
    for record in run.records:
        by_sequence.setdefault(record.sequence, {})[record.method] = record
    methods = list(run.suite.methods)
    for ref in run.suite.sequences:
        found = by_sequence.get(ref.name, {})
        keyframes = {m: _keyframes_of(run, found[m]) for m in methods if m in found}
        if len(keyframes) != len(methods) or any(v is None for v in keyframes.values()):
            continue
        estimates, truths, titles = [], [], []
        source = ref.make_source()
        try:
            for method in methods:
                kf = keyframes[method]
                stamps = kf["timestamps"]
                frames = int(found[method].metrics.get(FRAMES.key, len(source)))
                middle = float(source.timestamps[min(frames // 2, len(source) - 1)])
                k = int(np.argmin(np.abs(stamps - middle)))  # the key-frame shown: the one nearest the middle
                i = match_timestamp(source.timestamps, float(stamps[k]))
                if i is None:
                    return None
                estimates.append(kf["depth"][k])
                truths.append(source.frame(i).depth)
                titles.append(f"{method}, t={stamps[k]:.2f} s")
        finally:
            source.close()
        return save_depth_error_row_figure(
            path, estimates, truths, titles, title=f"{ref.name}: depth error of one key-frame per variant"
        )
    return None


# ------------------------------------------------------------------------------------------------------ sweep
SWEEP_TABLE_METRICS: tuple[str, ...] = tuple(key for _, key in catalogue.blocks(catalogue.SWEEP_FIGURE))
_SWEEP_COLUMNS: tuple[str, ...] = (*SWEEP_TABLE_METRICS, TRACKED_SHARE.key)  # a sweep point's figures


def sweep_points(run: SuiteRun) -> pd.DataFrame:
    """One row per finished sweep run: axis, x (the axis value; for the rotation axis the measured rotation
    share), method, the sweep figure's metrics (:data:`SWEEP_TABLE_METRICS`), the tracked share (columns named by
    their keys) and ``failure`` (why the run is a
    failure, :func:`eval.metrics.results.failure_of`, e.g. ``tracked 22 % < 90 %``; empty when it is not: its figures
    count in no median, table or line)."""
    rows = []
    for record in run.records:
        meta = record.metadata
        axis = meta.get("axis")
        if axis is None:
            continue
        x = meta.get("rotation_share") if axis == "rotation" else meta.get("axis_value")
        metrics = record.metrics
        rows.append(
            {
                "axis": axis,
                "x": math.nan if x is None else float(x),
                "setting": meta.get("axis_value"),
                "sequence": record.sequence,
                "method": record.method,
                **{key: metrics.get(key, math.nan) for key in _SWEEP_COLUMNS},
                "failure": failure_of(metrics) or "",
            }
        )
    columns = ["axis", "x", "setting", "sequence", "method", *_SWEEP_COLUMNS, "failure"]
    return pd.DataFrame(rows, columns=columns)


def report_sweep(run: SuiteRun, results_dir: str | Path, command: str,
                 figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``sweep.png``, ``sweep.md``, ``sweep.csv`` (one row per point) and ``sweep_long.csv``."""
    results_dir = Path(results_dir)
    points = sweep_points(run)
    csv = results_dir / "sweep.csv"
    csv.parent.mkdir(parents=True, exist_ok=True)
    points.to_csv(csv, index=False, float_format="%.6g")
    figure = save_sweep_figure(points, results_dir / f"sweep.{figure_format}", list(run.suite.methods),
                               run.suite.axis_titles)
    text = [
        header_markdown(run, "Difficulty sweep: one axis at a time", command),
        "Axes: texture density of the room (share of textured surfaces); share of rotation in the motion (the "
        "hand-held trajectory with an extra pan at 0-60 deg/s; x = measured share of image motion due to "
        "rotation, for a scene 2 m away); focal length of the test camera over the training camera's (NYU) at the "
        "same resolution (1 = no mismatch; the base sequence's ICL camera is 0.93); these three through the "
        "default camera (kinect). Camera axes: one effect of the camera alone, on the clean camera, at strengths "
        "where 1 is the kinect preset's value (`sim_envs.sensor.camera_effects.SINGLE_EFFECTS`): noise (x ICL-NUIM's), "
        "motion blur (exposure x half a frame interval, global shutter), auto-exposure (exposure jitter x 1 %), "
        "rolling shutter (readout in frame intervals; kinect 0.05, hard 0.5) and lens distortion (x TUM fr1's, "
        "undistorted and cropped to what the lens saw before the agent sees it).\n",
        markdown_image(figure, "ATE and correct depth against each axis", results_dir),
    ]
    for axis, title in run.suite.axis_titles.items():
        sub = points[points["axis"] == axis]
        if sub.empty:
            continue
        text.append(f"### {title}\n\n" + sweep_markdown(sub))
    return write_suite_report(run, results_dir, "sweep", text, [csv, figure],
                              blocks=SWEEP_BLOCKS, figure_format=figure_format)


def sweep_cells(points: pd.DataFrame) -> dict[tuple[Any, Any, str, str], str]:
    """(setting, x, method, metric) -> the cell of one axis's sweep table (:func:`sweep_points` rows of one axis):
    ``X (22 %)`` when at least half of its runs fail (:func:`eval.metrics.results.failure_of`; the median tracked
    share of the failed runs), else the median over the runs that did not fail, with ``k/n failed`` and the tracked
    share where below 100 %; ``-`` without a value."""
    out: dict[tuple[Any, Any, str, str], str] = {}
    for (setting, x, method), cell in points.groupby(["setting", "x", "method"], sort=True, dropna=False):
        shares = cell[TRACKED_SHARE.key].to_numpy(dtype=float)
        failed = np.array([failure_of({TRACKED_SHARE.key: v}) is not None for v in shares])
        n, k = len(cell), int(failed.sum())
        for metric in SWEEP_TABLE_METRICS:
            if k and 2 * k >= n:
                out[(setting, x, method, metric)] = failure_text(float(np.median(shares[failed])))
                continue
            values = cell[metric].to_numpy(dtype=float)[~failed]
            values = values[np.isfinite(values)]
            if not values.size:
                out[(setting, x, method, metric)] = "-"
                continue
            kept = shares[~failed]
            share = float(np.median(kept[np.isfinite(kept)])) if np.isfinite(kept).any() else math.nan
            notes = ([f"{math.floor(round(100 * share, 6))} %"] if share < 1.0 else []) + (
                [f"{k}/{n} failed"] if k else [])  # fmt: skip
            out[(setting, x, method, metric)] = f"{np.median(values):.3f}" + (f" ({', '.join(notes)})" if notes
                                                                                else "")  # fmt: skip
    return out


def sweep_markdown(points: pd.DataFrame) -> str:
    """One axis's sweep table: rows (setting, x), columns (metric, method) of :data:`SWEEP_TABLE_METRICS`, cells of
    :func:`sweep_cells`."""
    cells = sweep_cells(points)
    methods = list(dict.fromkeys(points["method"]))
    header = ["setting", "x", *(f"{metric}: {method}" for metric in SWEEP_TABLE_METRICS for method in methods)]
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for setting, x in sorted({(s, v) for s, v, _, _ in cells}, key=lambda k: (k[0], k[1])):
        row = [cells.get((setting, x, method, metric), "-") for metric in SWEEP_TABLE_METRICS for method in methods]
        lines.append("| " + " | ".join([f"{setting:g}", f"{x:.3f}", *row]) + " |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------- depth quality
def target_checks(table: pd.DataFrame, method: str = "CNN-SLAM", reference: str = "raw-CNN") -> pd.DataFrame:
    """Per sequence of a :data:`DEPTH_QUALITY_BLOCKS` table, whether ``method`` meets each target: ``ate`` (ATE /
    length <= :data:`TARGET_ATE_PERCENT_LENGTH`), ``scale`` (scale error <= :data:`TARGET_SCALE_ERROR_PERCENT`),
    ``depth`` (correct depth above ``reference``'s); NaN-valued figures fail. Index: the sequences (no Avg.)."""
    rows = table.drop(index=AVG_LABEL, errors="ignore")

    def column(block: int, who: str) -> pd.Series:
        key = (DEPTH_QUALITY_BLOCKS[block][0], who)
        return rows[key] if key in rows.columns else pd.Series(np.nan, index=rows.index)

    return pd.DataFrame({
        "ate": column(0, method) <= TARGET_ATE_PERCENT_LENGTH,
        "scale": column(1, method) <= TARGET_SCALE_ERROR_PERCENT,
        "depth": column(2, method) > column(2, reference),
    })  # fmt: skip


def report_depth_quality(run: SuiteRun, results_dir: str | Path, command: str,
                         figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``depth_quality.{md,csv,tex}``, ``depth_quality.png`` and ``depth_quality_long.csv``."""
    results_dir = Path(results_dir)
    frame = with_relative_errors(long_frame(run))
    table, spread = suite_table(run, DEPTH_QUALITY_BLOCKS, frame)
    paths = write_tables(table, results_dir / "depth_quality", "CNN-SLAM and the accuracy of key-frame depth.",
                         spread=spread, blocks=DEPTH_QUALITY_BLOCKS, run=run)  # fmt: skip
    scored = without_failures(frame)  # a failed run is no point of the scatter
    points = (scored[scored["metric"].isin([ATE_PERCENT_LENGTH.key, DEPTH_PERCENT_CORRECT.key])]
              .pivot_table(index=["sequence", "method"], columns="metric", values="value").reset_index())  # fmt: skip
    figure = save_accuracy_scatter(points, results_dir / f"depth_quality.{figure_format}", list(run.suite.methods),
                                   TARGET_ATE_PERCENT_LENGTH)  # fmt: skip
    checks = target_checks(table)
    lines = [f"| sequence | ATE / length <= {TARGET_ATE_PERCENT_LENGTH:g} % | scale error <= "
             f"{TARGET_SCALE_ERROR_PERCENT:g} % | correct depth above raw-CNN's |",
             "|---|:---:|:---:|:---:|"]
    for seq, row in checks.iterrows():
        lines.append(f"| {seq} | " + " | ".join("yes" if ok else "no" for ok in row) + " |")
    met = {name: int(checks[name].sum()) for name in checks.columns}
    text = [
        header_markdown(run, "CNN-SLAM and the accuracy of key-frame depth (full-length sequences)", command),
        "Whole sequences, single-threaded. ATE: RMSE after SE(3) alignment, no scale correction, "
        "over the ground-truth path length. Scale error: |1/s - 1| for the Sim(3) alignment's scale s. Correct depth "
        "as in Table 1. `CNN-SLAM` and `raw-CNN` run the shipped network; `dev-depth-N` run CNN-SLAM on ground-truth "
        "depth degraded like a CNN's (holes filled, small objects closed, 4 px edge blur, 2 % per-frame scale "
        "jitter, 1 % pixel noise) with N % low-frequency multiplicative error, in the network's place: they receive "
        "ground truth and are references for how accurate key-frame depth must be, not competitors.\n",
        table_to_markdown(table, spread=spread),
        f"## Targets, CNN-SLAM\n\nMet on {met['ate']} / {met['scale']} / {met['depth']} of {len(checks)} sequences "
        "(ATE / scale / depth).\n",
        "\n".join(lines) + "\n",
        markdown_image(figure, "ATE / length against correct depth, each run labelled with its sequence", results_dir),
    ]
    return write_suite_report(run, results_dir, "depth_quality", text, [*paths, figure], blocks=DEPTH_QUALITY_BLOCKS,
                              figure_format=figure_format)  # fmt: skip


# ------------------------------------------------------------------------------------------------------ quick
def report_quick(run: SuiteRun, results_dir: str | Path, command: str,
                 figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``quick.md``, ``quick_runs.json`` (the gate's run file) and ``quick_long.csv``."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    runs_json = results_dir / "quick_runs.json"
    runs_json.write_text(suite_records_json(run.records))
    table, spread = suite_table(run, QUICK_BLOCKS)
    text = [
        header_markdown(run, "Quick suite (the CI regression baseline)", command),
        "Compared metric by metric with `results/baselines/quick.json` by `cnnslam bench quick` and by "
        "`tests/eval/test_quick_regression.py`; after an intended change: `cnnslam bench quick --update-baseline`.\n",
        table_to_markdown(table, spread=spread),
    ]
    return write_suite_report(run, results_dir, "quick", text, [runs_json], blocks=QUICK_BLOCKS,
                              figure_format=figure_format)  # fmt: skip


def report_generic(run: SuiteRun, results_dir: str | Path, command: str,
                   figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """``<suite>.{md,csv,tex}`` with the Table-1 blocks and tracked share, and ``<suite>_long.csv``; for sequences
    with a second reference in the dataset list, a section scoring every run against it too."""
    results_dir = Path(results_dir)
    table, spread = suite_table(run, QUICK_BLOCKS)
    paths = write_tables(table, results_dir / run.suite.name, f"Suite {run.suite.name}.", spread=spread,
                         blocks=QUICK_BLOCKS, run=run)  # fmt: skip
    text = [header_markdown(run, f"Suite {run.suite.name}", command), table_to_markdown(table, spread=spread)]
    second = second_reference_markdown(run)
    return write_suite_report(run, results_dir, run.suite.name, [*text, *([second] if second else [])], paths,
                              blocks=QUICK_BLOCKS, figure_format=figure_format)  # fmt: skip


SECOND_REFERENCE_METRICS: tuple[tuple[str, str, float], ...] = tuple(  # (metric, heading, factor)
    (s.key, s.label_at(catalogue.SECOND_REFERENCE), s.factor_at(catalogue.SECOND_REFERENCE))
    for s in catalogue.shown_at(catalogue.SECOND_REFERENCE))  # fmt: skip
GROUND_TRUTH_ROW = "(the folder's ground truth)"


def second_reference_markdown(run: SuiteRun, references: dict[str, Path] | None = None) -> str:
    """Every finished run of a sequence that has a second reference (``references``: sequence name -> TUM file;
    default: the dataset list's ``reference`` entries, :meth:`eval.reports.inputs.Suite.second_references`)
    scored against it as against ground truth (SE(3) alignment, TUM association), beside the folder's own ground
    truth scored against it: how far the two references disagree is the floor below which no error can be read.
    Cells: median [min, max] over runs. Empty when no sequence of the suite has one."""
    from eval.errors import EvalError, SuiteError
    from eval.metrics.trajectory import PoseTrajectory
    from eval.metrics.trajectory_metrics import evaluate_trajectory
    from slamcommon.formats import read_tum_trajectory

    if references is None:
        try:
            references = dict(run.suite.second_references())
        except SuiteError:
            return ""
    names = [s.name for s in run.suite.sequences if s.name in references]
    if not names:
        return ""

    def trajectory(path: Path) -> PoseTrajectory:
        stamps, T = read_tum_trajectory(path)
        return PoseTrajectory(stamps, T)

    lines = ["## Against a second reference", "",
             "Each run scored against the sequence's second reference (its dataset-list `reference`, e.g. the "
             "structure-from-motion trajectory of `cnnslam reference`) as against ground truth; the first row scores "
             "the folder's own ground truth against it: the two references' disagreement, below which no error can "
             "be read. Median [min, max] over runs.", ""]  # fmt: skip
    heads = [h for _, h, _ in SECOND_REFERENCE_METRICS]
    for name in names:
        path = Path(references[name])
        shown = path.resolve().relative_to(Path.cwd()) if path.resolve().is_relative_to(Path.cwd()) else path
        lines += [f"**{name}** against `{shown}`:", ""]
        try:
            reference = trajectory(path)
        except (OSError, EvalError, ValueError) as exc:
            lines += [f"(not scored: {exc})", ""]
            continue
        rows: dict[str, list[dict[str, float]]] = {}
        problems = []
        for record in run.records:
            if record.sequence != name:
                continue
            folder = run.outcomes[str(record.run)].folder
            own_trajectory = ATE_RMSE.key in record.metrics  # REMODE: LSD-BS's poses, not its own
            try:
                if GROUND_TRUTH_ROW not in rows:
                    rows[GROUND_TRUTH_ROW] = [evaluate_trajectory(reference, trajectory(folder / "groundtruth.tum"))
                                              .flat_metrics()]  # fmt: skip
                if not own_trajectory:
                    continue
                flat = evaluate_trajectory(reference, trajectory(folder / "trajectory.tum")).flat_metrics()
            except (OSError, EvalError, ValueError) as exc:
                problems.append(f"{record.method} ({record.run}): {exc}")
                continue
            rows.setdefault(record.method, []).append(flat)
        lines += ["| method | runs | " + " | ".join(heads) + " |", "|---|---:|" + "---:|" * len(heads)]
        for method, flats in rows.items():
            cells = []
            for metric, _, factor in SECOND_REFERENCE_METRICS:
                v = np.array([f.get(metric, math.nan) for f in flats], dtype=float) * factor
                v = v[np.isfinite(v)]
                if v.size == 0:
                    cells.append("-")
                    continue
                lo, hi = v.min(), v.max()
                cells.append(f"{np.median(v):.3f}" + ("" if lo == hi else f" [{lo:.3f}, {hi:.3f}]"))
            runs = "-" if method == GROUND_TRUTH_ROW else str(len(flats))
            lines.append(f"| {method} | {runs} | " + " | ".join(cells) + " |")
        lines += [*(f"- not scored: {p}" for p in problems), ""]
    return "\n".join(lines)


REPORTS = {  # a suite's report layout (eval.bench.suites.REPORT_LAYOUTS) -> its writer
    "generic": report_generic,
    "table1": report_table1,
    "rotation": report_rotation,
    "ablation": report_ablation,
    "sweep": report_sweep,
    "quick": report_quick,
    "depth_quality": report_depth_quality,
}


def write_report(run: SuiteRun, results_dir: str | Path, command: str,
                 figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """The suite's outputs in ``results_dir`` (see the module docstring), figures in ``figure_format`` (png, pdf,
    svg); returns the files written."""
    return REPORTS[run.suite.report](run, results_dir, command, figure_format)

"""The figures of a suite's report that a paper takes, over every method at once, written in the suite's figure
format (``--figure-format png|pdf|svg``; :data:`eval.reports.style.FIGURE_FORMATS`) under
``<results>/<suite>_figures/``:

- ``<sequence>_trajectories.<fmt>``: every method's trajectory aligned to the ground truth in one top view (each
  method's median run by ATE) beside the ATE over time, the median over its runs with a band from their min to their
  max (as evo users ask for: one colour per method, several methods on one plot, a band across runs);
- ``<sequence>_relative_error.<fmt>``: relative translation [m] and rotation [deg] error at 10-50 % of the path as
  boxplots over every pair of every run, one box per method (rpg_trajectory_evaluation's figure);

and ``<results>/<suite>_resources.<fmt>``: frames per second end to end and peak memory per method, one dot per run
(VSLAM-LAB's figure). A method without a trajectory (REMODE), skipped here or whose runs failed is named in the
legend as ``n/a`` with the reason. Failed runs (:func:`eval.metrics.results.failure_of`: never initialised, or
tracked less than :data:`eval.metrics.results.MIN_TRACKED_SHARE` of their frames) are drawn in no trajectory, band
or box; a method whose runs on a sequence failed in at least half is named in the legend as ``n/a: X (22 %)``.
Colours and markers: :mod:`eval.reports.style`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from eval.metrics.catalogue import ATE_RMSE, FPS_END_TO_END, PEAK_RSS_MIB, TRACKED_SHARE
from eval.metrics.results import failure_of, failure_text
from eval.reports.inputs import SuiteRun
from eval.reports.plots import save_relative_error_figure, save_resources_figure, save_sequence_figure
from eval.reports.run_data import RunTrack, ate_bands, median_track, missing_reasons
from eval.reports.style import DEFAULT_FIGURE_FORMAT


@dataclass(frozen=True)
class ReportFigure:
    """A figure a report shows: its ``path`` and a ``caption`` saying what it holds."""

    path: Path
    caption: str


def file_slug(name: str) -> str:
    """``name`` made safe for a file name (``office0@kinect`` -> ``office0_kinect``)."""
    return re.sub(r"[^A-Za-z0-9_.+-]", "_", name).strip("_") or "_"


def figures_dir(results_dir: str | Path, suite: str) -> Path:
    """Where a suite's per-sequence figures go: ``<results>/<suite>_figures``."""
    return Path(results_dir) / f"{suite}_figures"


def sequence_figures(run: SuiteRun, tracks: dict[str, dict[str, list[RunTrack]]], results_dir: str | Path,
                     figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[ReportFigure]:
    """For each sequence of the suite with a trajectory to show: its trajectories-and-ATE figure and its
    relative-error boxplots (module docstring), from ``tracks`` (:func:`eval.reports.run_data.suite_tracks`)."""
    out: list[ReportFigure] = []
    folder = figures_dir(results_dir, run.suite.name)
    for ref in run.suite.sequences:
        by_method = {m: tracks[ref.name][m] for m in run.suite.methods if m in tracks.get(ref.name, {})}
        by_method, failed = without_failed_tracks(run, ref.name, by_method)
        if not by_method:
            continue
        missing = {m: why for m, why in missing_reasons(run, ATE_RMSE.key, sequence=ref.name).items()
                   if m not in by_method}  # fmt: skip
        missing.update(failed)
        longest = max((t for ts in by_method.values() for t in ts), key=lambda t: t.stamps.size)
        stamps = longest.stamps
        shown = {m: median_track(ts) for m, ts in by_method.items()}
        labels = {m: m + (f" (seed {t.seed}, median of {len(by_method[m])})" if len(by_method[m]) > 1 else "")
                  for m, t in shown.items()}  # fmt: skip
        bands = {m: ate_bands(ts, stamps) for m, ts in by_method.items()}
        alignment = ", ".join(sorted({t.alignment for ts in by_method.values() for t in ts}))
        slug = file_slug(ref.name)
        path = save_sequence_figure(folder / f"{slug}_trajectories.{figure_format}",
                                    f"{ref.name}: every method aligned to the ground truth ({alignment})",
                                    longest.gt, {m: t.est for m, t in shown.items()}, stamps - stamps[0], bands,
                                    {m: len(ts) for m, ts in by_method.items()}, missing, labels)  # fmt: skip
        out.append(ReportFigure(path, f"{ref.name}: trajectories (top view, each method's median run by ATE) and "
                                      "ATE over time (median over runs, band: min to max)"))  # fmt: skip
        shares = longest.relative
        distances = [f"{r.distance_m:g} m\n({r.share} %)" for r in shares]
        translation = {m: [np.concatenate([t.relative[k].translation for t in ts]) for k in range(len(shares))]
                       for m, ts in by_method.items()}  # fmt: skip
        rotation = {m: [np.concatenate([t.relative[k].rotation_deg for t in ts]) for k in range(len(shares))]
                    for m, ts in by_method.items()}  # fmt: skip
        if any(e.size for per in translation.values() for e in per):
            path = save_relative_error_figure(folder / f"{slug}_relative_error.{figure_format}",
                                              f"{ref.name}: relative error at 10-50 % of the path ({alignment})",
                                              distances, translation, rotation, missing)  # fmt: skip
            out.append(ReportFigure(path, f"{ref.name}: relative translation and rotation error at several "
                                          "distances, every pair of every run (boxes: quartiles, whiskers: 1.5 IQR)"))
    return out


def without_failed_tracks(run: SuiteRun, sequence: str, by_method: dict[str, list[RunTrack]]
                          ) -> tuple[dict[str, list[RunTrack]], dict[str, str]]:
    """``by_method`` (method -> its tracks on ``sequence``) less the failed runs' tracks
    (:func:`eval.metrics.results.failure_of` of their records), and method -> ``X (22 %): ...`` for the methods whose
    runs on ``sequence`` failed in at least half (their tracks all left out)."""
    kept: dict[str, list[RunTrack]] = {}
    failed: dict[str, str] = {}
    for method, tracks in by_method.items():
        records = [r for r in run.records if r.sequence == sequence and r.method == method]
        lost = [r for r in records if failure_of(r.metrics) is not None]
        if lost and 2 * len(lost) >= len(records):
            share = float(np.median([r.metrics.get(TRACKED_SHARE.key, 0.0) for r in lost]))
            failed[method] = (f"{failure_text(share if np.isfinite(share) else 0.0)}: a failure (never initialised, "
                              "or tracked too little)")  # fmt: skip
            continue
        keys = {str(r.run) for r in lost}
        if ts := [t for t in tracks if t.key not in keys]:
            kept[method] = ts
    return kept, failed


def resources_figure(run: SuiteRun, results_dir: str | Path,
                     figure_format: str = DEFAULT_FIGURE_FORMAT) -> ReportFigure | None:
    """``<suite>_resources.<fmt>``: frames per second end to end and peak memory per method, one dot per run; None
    when no run recorded either."""
    methods = [m for m in run.suite.methods if any(r.method == m for r in run.records)]
    fps = {m: np.array([r.resources.get(FPS_END_TO_END.key, np.nan) for r in run.records if r.method == m])
           for m in methods}  # fmt: skip
    memory = {m: np.array([r.resources.get(PEAK_RSS_MIB.key, np.nan) for r in run.records if r.method == m])
              for m in methods}  # fmt: skip
    if not any(np.isfinite(v).any() for v in (*fps.values(), *memory.values())):
        return None
    missing = missing_reasons(run, PEAK_RSS_MIB.key, methods)
    path = save_resources_figure(Path(results_dir) / f"{run.suite.name}_resources.{figure_format}", methods, fps,
                                 memory, missing, f"{run.suite.name}: speed and memory, every run")  # fmt: skip
    return ReportFigure(path, "speed and memory per method: frames per second end to end and peak resident memory, "
                              "one dot per run (bar: median)")

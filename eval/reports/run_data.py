"""What the reports read from a suite's run folders besides the run records: each finished run's trajectory aligned
to its ground truth, its ATE per pose and its relative errors (from the folder's ``trajectory.tum`` and
``groundtruth.tum``, scored as the run's record scores them: :func:`eval.metrics.runs.run_trajectory_metrics`), and why
a method has no value for a metric (:func:`missing_reasons`).

The per-sequence figures of a suite (:mod:`eval.reports.paper_figures`) and its HTML report
(:mod:`eval.reports.html_report`) read the runs once through :func:`suite_tracks`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from eval.errors import EvalError
from eval.metrics.runs import GROUP_ABSENT, metric_group, run_trajectory_metrics
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import RelativeErrors
from eval.reports.inputs import RunSpec, SuiteRun


@dataclass(frozen=True, eq=False)
class RunTrack:
    """One finished run's trajectory as scored: ``key``, ``method``, ``seed``; ``stamps`` (M,) seconds of its scored
    poses; ``gt`` and ``est`` (M, 3) positions in metres, the estimate aligned to the ground truth with the run's
    alignment; ``ate`` (M,) metres per pose; ``rmse`` their RMSE, metres; ``relative``: its relative errors at several
    distances (:func:`eval.metrics.trajectory_metrics.relative_errors`); ``alignment``: the alignment used."""

    key: str
    method: str
    seed: int
    stamps: np.ndarray
    gt: np.ndarray
    est: np.ndarray
    ate: np.ndarray
    rmse: float
    relative: tuple[RelativeErrors, ...]
    alignment: str


def run_track(folder: str | Path, spec: RunSpec) -> RunTrack | None:
    """The run in ``folder`` scored from its TUM files (:class:`RunTrack`); None when the folder lacks them or holds
    fewer than two poses."""
    folder = Path(folder)
    gt_path, est_path = folder / "groundtruth.tum", folder / "trajectory.tum"
    if not (gt_path.is_file() and est_path.is_file()):
        return None
    try:
        gt, est = PoseTrajectory.from_tum_file(gt_path), PoseTrajectory.from_tum_file(est_path)
        m = run_trajectory_metrics(gt.timestamps, gt.T_world_cam, est.T_world_cam, spec.alignment)
    except EvalError:
        return None
    return RunTrack(spec.key, spec.method.name, spec.seed, np.asarray(m.gt.timestamps), m.gt.positions,
                    m.est_aligned.positions, m.ate_errors, m.ate.rmse, m.relative, m.alignment.used)  # fmt: skip


def suite_tracks(run: SuiteRun) -> dict[str, dict[str, list[RunTrack]]]:
    """sequence -> method -> the tracks of its finished runs (plan order), for the methods with a trajectory of their
    own (metric group ``trajectory``)."""
    out: dict[str, dict[str, list[RunTrack]]] = {}
    for spec in run.specs:
        outcome = run.outcomes.get(spec.key)
        if outcome is None or outcome.status in ("failed", "not_run") or "trajectory" not in spec.method.metrics:
            continue
        track = run_track(outcome.folder, spec)
        if track is not None:
            out.setdefault(spec.sequence.name, {}).setdefault(spec.method.name, []).append(track)
    return out


def median_track(tracks: Sequence[RunTrack]) -> RunTrack:
    """The run whose ATE RMSE is the median of ``tracks`` (the lower of the two middle ones for an even count): the
    one a figure shows for its method."""
    order = sorted(tracks, key=lambda t: (math.inf if math.isnan(t.rmse) else t.rmse, t.seed))
    return order[(len(order) - 1) // 2]


def ate_bands(tracks: Sequence[RunTrack], stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(median, min, max) over ``tracks`` of the ATE per pose (metres) at ``stamps`` (s; a run without a pose at a
    stamp, e.g. an external trajectory with frames missing, leaves it out there; NaN where no run has one)."""
    stamps = np.asarray(stamps, dtype=np.float64)
    grid = np.full((len(tracks), stamps.size), np.nan)
    for k, track in enumerate(tracks):
        where = np.searchsorted(stamps, track.stamps)
        ok = (where < stamps.size) & (stamps[np.minimum(where, stamps.size - 1)] == track.stamps)
        grid[k, where[ok]] = track.ate[ok]
    with np.errstate(all="ignore"):
        have = np.isfinite(grid).any(axis=0)
        median = np.full(stamps.size, np.nan)
        lo, hi = median.copy(), median.copy()
        median[have] = np.nanmedian(grid[:, have], axis=0)
        lo[have] = np.nanmin(grid[:, have], axis=0)
        hi[have] = np.nanmax(grid[:, have], axis=0)
    return median, lo, hi


def missing_reasons(run: SuiteRun, metric: str, methods: Sequence[str] | None = None,
                    sequence: str | None = None) -> dict[str, str]:
    """method -> why it has no finite value of ``metric`` in ``run`` (on ``sequence``, or on any), for each of
    ``methods`` (default: the suite's) that has none: skipped here (and why), a metric group it does not report
    (``no trajectory of its own``: REMODE runs on LSD-BS's poses), every run failed, not run (``--report-only``),
    or its runs gave no value (NaN). Methods with a value are left out."""
    names = list(run.suite.methods) if methods is None else list(methods)
    table = {m.name: m for m in run.methods}
    group = metric_group(metric)
    out: dict[str, str] = {}
    for name in names:
        values = [r.metrics.get(metric, r.resources.get(metric, math.nan)) for r in run.records
                  if r.method == name and (sequence is None or r.sequence == sequence)]  # fmt: skip
        if any(isinstance(v, int | float) and math.isfinite(v) for v in values):
            continue
        specs = [s for s in run.specs if s.method.name == name and (sequence is None or s.sequence.name == sequence)]
        statuses = {run.outcomes[s.key].status for s in specs if s.key in run.outcomes}
        if name in run.skipped_methods:
            out[name] = "skipped: " + " ".join(run.skipped_methods[name].split())[:160]
        elif name in table and group is not None and not table[name].keeps(metric):
            out[name] = GROUP_ABSENT.get(group, f"no {group} figures")
        elif not specs:
            out[name] = "not in this selection"
        elif statuses == {"failed"}:
            out[name] = "every run failed"
        elif statuses <= {"not_run", "failed"}:
            out[name] = "not run (--report-only and no finished run)"
        else:
            out[name] = "no value on its runs"
    return out

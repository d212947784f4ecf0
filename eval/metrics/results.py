"""One run's evaluation as a typed record, and many runs gathered in a pandas frame in long form.

A run record (:class:`RunRecord`: what :func:`evaluate_episode` returns, :func:`save_run` writes and
:func:`load_run` reads; frozen, changed with :meth:`RunRecord.replace`, as evo's ``core.result.Result`` is one
object, not a dict edited in place) is written as the JSON object::

    {"schema": "cnnslam-run/1", "sequence": str, "method": str, "agent": str, "uses_ground_truth": bool,
     "alignment": {...}, "association": {...}, "rpe": {"delta": float, "unit": str}, "warnings": [str, ...],
     "metrics": {name: float, ...},           # flat scalar metrics (names below)
     "keyframes": [{"timestamp": s, "percent_correct": ..., ...}, ...],
     "metadata": {name: scalar, ...},         # run settings (seed, config...), free-form scalars
     "ground_truth_used": [str, ...],         # only external methods: what their method.toml declares
     "sensor": str}                           # only suite runs: the method's sensor (mono, rgbd...)

``alignment`` (:meth:`eval.metrics.trajectory_metrics.TrajectoryMetrics.describe_alignment`): ``requested``, ``used``
(what was done:
``se3``, ``sim3``, ``origin``, ``none`` or ``rotation_only``), ``title`` (the same in words), ``scale``,
``degenerate``, ``fallback``, ``warning``, the fits behind the SE(3) and Sim(3) ATE under ``se3`` and ``sim3``, and
the orientation-only alignment's definition under ``orientation``. ``alignment``, ``association``, ``rpe``,
``warnings`` and the trajectory part of ``metrics`` have the same names and meaning in ``cnnslam eval --json``
(:mod:`eval.commands.cli_eval`).

Metric names (all values numbers): the catalogue, :mod:`eval.metrics.catalogue`, gives each its name, unit, direction
and range; the trajectory figures are defined in :mod:`eval.metrics.trajectory_metrics`, the key-frame depth figures
(pooled over key-frames, the Table-1 figure, and their mean over key-frames) and the label figures here
(:func:`evaluate_episode`), the step times in :func:`_timing_metrics`.

What a run used (:attr:`RunRecord.resources`, :data:`RESOURCE_FIGURES`): wall time, frames per second end to end and
of the agent's step, peak resident memory. They are measured, not computed: the same run gives other values, so they
live in the run folder's ``timing.json`` beside ``metrics.json`` (whose bytes the same run always reproduces), and
:func:`load_run` reads them into the record from there; :meth:`RunRecord.to_json` leaves them out.

Long form (:func:`runs_frame`): one row per (run, metric or resource figure) with columns ``sequence, method, metric,
value`` plus ``run`` (the run's index or file), ``agent``, ``uses_ground_truth``, ``alignment``, ``alignment_used``,
``association`` and one column per metadata key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pandas as pd

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.metrics.association import AssociationRule
from eval.metrics.catalogue import (
    ATE_PAIRS,
    DEPTH_ABS_REL,
    DEPTH_DELTA_1_25,
    DEPTH_DENSITY,
    DEPTH_KEYFRAMES,
    DEPTH_PERCENT_CORRECT,
    DEPTH_PERCENT_CORRECT_MEAN,
    DEPTH_RMSE,
    FPS,
    FPS_END_TO_END,
    FRAMES,
    STEP_MS_MAX,
    STEP_MS_MEAN,
    STEP_MS_MEDIAN,
    TRACKED_SHARE,
    WALL_S,
)
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import RpeUnit, evaluate_trajectory
from sim_envs.frames import NUM_CLASSES
from slamcommon.alignment import AlignmentMethod
from slamcommon.depth_metrics import (
    CORRECT_THRESHOLD,
    DepthMetrics,
    aggregate_depth_metrics,
    depth_metrics,
)
from slamcommon.semantic_metrics import confusion_matrix, metrics_from_confusion
from slamcommon.strict_json import json_ready

RUN_SCHEMA = "cnnslam-run/1"
LONG_COLUMNS = ["sequence", "method", "metric", "value"]
TIMING_FILE = "timing.json"  # a run folder's measured figures, beside its metrics.json
# A run's resource figures (RunRecord.resources; the names of timing.json; the catalogue's resource specs): the wall
# time of the whole run (frames rendered or read, the agent, scoring, plots), frames per second end to end (frames /
# wall time) and of the agent's step alone (1 / mean step time), the peak resident memory of the process that ran it
# (a system run in a process of its own, ORB-SLAM3, is not in it), and an external system's own run time
RESOURCE_FIGURES: tuple[str, ...] = catalogue.keys(resource=True)


class ResultsError(EvalError):
    """A run record or results file that cannot be read."""


@dataclass(frozen=True)
class RunRecord:
    """One scored run (the module docstring gives the JSON form and the metric names).

    ``metrics``: flat scalar metrics, NaN where a figure has no value; ``alignment`` / ``association`` / ``rpe``:
    how the trajectory was scored (:mod:`eval.metrics.trajectory_metrics`); ``keyframes``: per key-frame depth rows;
    ``metadata``: the run's settings; ``ground_truth_used`` and ``sensor``: written only when set. ``run``: the run's
    key in its suite (:attr:`eval.bench.run.RunSpec.key`), set when a suite reads the record back; never written to
    ``metrics.json``. ``resources``: what the run used (:data:`RESOURCE_FIGURES`: wall time, frames per second, peak
    memory), read from the run's ``timing.json`` by :func:`load_run`; never written to ``metrics.json`` (measured
    figures differ from run to run; the record's bytes do not). Frozen: derive a changed record with :meth:`replace`.
    """

    sequence: str
    method: str
    agent: str
    metrics: Mapping[str, float]
    uses_ground_truth: bool = False
    alignment: Mapping[str, Any] = field(default_factory=dict)
    association: Mapping[str, Any] = field(default_factory=dict)
    rpe: Mapping[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    keyframes: tuple[Mapping[str, Any], ...] = ()
    metadata: Mapping[str, Any] = field(default_factory=dict)
    ground_truth_used: tuple[str, ...] | None = None
    sensor: str | None = None
    run: str | None = None
    resources: Mapping[str, float] = field(default_factory=dict)
    schema: str = RUN_SCHEMA

    def replace(self, **changes: Any) -> RunRecord:
        """A copy with ``changes`` (field name -> new value)."""
        return dataclasses.replace(self, **changes)

    def with_warning(self, warning: str) -> RunRecord:
        """A copy with ``warning`` appended to :attr:`warnings`."""
        return self.replace(warnings=(*self.warnings, warning))

    def to_json(self, include_run: bool = False) -> dict[str, Any]:
        """The JSON object of ``metrics.json`` (key order fixed: the same run gives the same bytes); with
        ``include_run`` the suite's run key last (a suite's run file, :func:`eval.bench.runner.suite_records_json`)."""
        out: dict[str, Any] = {
            "schema": self.schema,
            "sequence": self.sequence,
            "method": self.method,
            "agent": self.agent,
            "uses_ground_truth": self.uses_ground_truth,
            "alignment": dict(self.alignment),
            "association": dict(self.association),
            "rpe": dict(self.rpe),
            "warnings": list(self.warnings),
            "metrics": dict(self.metrics),
            "keyframes": [dict(k) for k in self.keyframes],
            "metadata": dict(self.metadata),
        }
        if self.ground_truth_used is not None:
            out["ground_truth_used"] = list(self.ground_truth_used)
        if self.sensor is not None:
            out["sensor"] = self.sensor
        if include_run and self.run is not None:
            out["run"] = self.run
        return out

    @classmethod
    def from_json(cls, data: Any, source: str = "<data>") -> RunRecord:
        """A record from its JSON object (``metrics.json``, or an element of a suite's run file); null metrics
        become NaN. Raises :class:`ResultsError` naming ``source`` and what is missing."""
        if not isinstance(data, Mapping) or not isinstance(data.get("metrics"), Mapping):
            raise ResultsError(f"{source}: a run record is a JSON object with a 'metrics' object")
        if "sequence" not in data or not (data.get("method") or data.get("agent")):
            raise ResultsError(f"{source}: a run record needs 'sequence' and 'method' (or 'agent')")
        method = str(data.get("method") or data.get("agent"))
        used = data.get("ground_truth_used")
        try:
            metrics = {str(k): math.nan if v is None else float(v) for k, v in data["metrics"].items()}
        except (TypeError, ValueError) as exc:
            raise ResultsError(f"{source}: every metric of a run record is a number or null ({exc})") from exc
        return cls(
            sequence=str(data["sequence"]),
            method=method,
            agent=str(data.get("agent") or method),
            metrics=metrics,
            uses_ground_truth=bool(data.get("uses_ground_truth", False)),
            alignment=dict(data.get("alignment") or {}),
            association=dict(data.get("association") or {}),
            rpe=dict(data.get("rpe") or {}),
            warnings=tuple(str(w) for w in data.get("warnings") or ()),
            keyframes=tuple(dict(k) for k in data.get("keyframes") or ()),
            metadata=dict(data.get("metadata") or {}),
            ground_truth_used=None if used is None else tuple(str(u) for u in used),
            sensor=None if data.get("sensor") is None else str(data["sensor"]),
            run=None if data.get("run") is None else str(data["run"]),
            schema=str(data.get("schema", RUN_SCHEMA)),
        )


# ------------------------------------------------------------------------------------------------- failures
MIN_TRACKED_SHARE: float = 0.9
"""The least share (0..1) of its frames a run must track not to be a failure: a run tracking less was lost for a
significant part of its sequence. Source: the convention of the SLAM papers whose tables we compare with, which print
"X" instead of a figure where tracking was "lost at some point or a significant portion of the sequence is not
processed by the system" (Mur-Artal, Montiel, Tardós, "ORB-SLAM: a Versatile and Accurate Monocular SLAM System",
IEEE T-RO 31(5) 2015, Table III; DROID-SLAM's TUM RGB-D table, Teed and Deng, NeurIPS 2021, marks failed methods the
same way). Those papers give no number; we read "a significant portion" as more than one frame in ten, so 0.9, fixed
here and not from where our own methods fall. The TUM RGB-D benchmark's ATE (Sturm et al., IROS 2012) is computed over
the poses a run returns, so a figure of a run that lost a tenth of its sequence or more is no figure for the sequence.
"""
FAILURE_MARK = "X"  # the mark every table, plot and report shows for a failure, with its tracked share: "X (22 %)"
FAILURE_RULE = (
    f"A run is a failure ({FAILURE_MARK}, with its tracked share) when it never initialises (0 % of its frames "
    f"tracked, or no pose scored) or tracks less than {round(100 * MIN_TRACKED_SHARE)} % of its frames (the 'X' "
    "of ORB-SLAM's tables: tracking lost for a significant portion of the sequence); a cell over seeds is a "
    "failure when at least half of its runs fail, otherwise the median over the runs that did not fail ('k/n "
    "failed'); an average covers the sequences that are not failures and says how many ('(7/9)'); a share below "
    "100 % is shown next to its figure."
)  # the one line every report states


def share_text(share: float) -> str:
    """A tracked share (0..1) as whole percent rounded down, so a share below a threshold never prints as it
    ("0.896" -> "89 %"); "?" when not finite."""
    if share is None or not math.isfinite(share):
        return "?"
    return f"{math.floor(round(100.0 * float(share), 6)):d} %"


def failure_text(share: float) -> str:
    """What a table shows for a failure in place of its figure: the mark and its tracked share, ``"X (22 %)"``."""
    return f"{FAILURE_MARK} ({share_text(share)})"


def failure_of(metrics: Mapping[str, float]) -> str | None:
    """Whether a run's record is a failure, and why: ``"never initialised"`` when it tracked none of its frames
    (tracked share, :data:`~eval.metrics.catalogue.TRACKED_SHARE`, 0) or scored no pose (pose pairs,
    :data:`~eval.metrics.catalogue.ATE_PAIRS`, 0, e.g. an SfM run registering none of its images),
    ``"tracked 22 % < 90 %"`` when its tracked share is below :data:`MIN_TRACKED_SHARE`; None for a run that is not
    a failure, or whose record has neither figure (a method scored without a trajectory)."""
    share = metrics.get(TRACKED_SHARE.key)
    pairs = metrics.get(ATE_PAIRS.key)
    share_known = share is not None and math.isfinite(float(share))
    if (share_known and float(share) <= 0.0) or (pairs is not None and math.isfinite(float(pairs))
                                                 and float(pairs) <= 0.0):  # fmt: skip
        return "never initialised"
    if share_known and float(share) < MIN_TRACKED_SHARE:
        return f"tracked {share_text(float(share))} < {share_text(MIN_TRACKED_SHARE)}"
    return None


def is_failure(metrics: Mapping[str, float]) -> bool:
    """True when :func:`failure_of` finds the run a failure."""
    return failure_of(metrics) is not None


def resources_of(timing: Mapping[str, Any], frames: float | None = None) -> dict[str, float]:
    """A run's :data:`RESOURCE_FIGURES` from its ``timing.json`` content (those it has, as floats); a record from
    before the end-to-end frame rate was written gets it as ``frames`` / wall time where both are known."""
    out = {k: float(timing[k]) for k in RESOURCE_FIGURES if isinstance(timing.get(k), int | float)
           and not isinstance(timing.get(k), bool)}  # fmt: skip
    wall = out.get(WALL_S.key)
    if FPS_END_TO_END.key not in out and frames is not None and wall and math.isfinite(frames) and wall > 0:
        out[FPS_END_TO_END.key] = float(frames) / wall
    return out


def coverage(metrics: Mapping[str, float]) -> tuple[int, int] | None:
    """How much of its sequence a run's trajectory covers, from its metrics: ``(poses scored, frames)`` (the ATE's
    pose pairs and the sequence's frames the run was given) when the run scored fewer poses than its frames (an
    external system's trajectory with frames missing); None for a whole run or one without trajectory metrics. A
    partial run's figures are over the poses it has, not its sequence: tables say so."""
    pairs, frames = metrics.get(ATE_PAIRS.key), metrics.get(FRAMES.key)
    if pairs is None or frames is None or not (math.isfinite(pairs) and math.isfinite(frames)) or pairs >= frames:
        return None
    return int(pairs), int(frames)


# ------------------------------------------------------------------------------------------------- one episode
def evaluate_episode(
    result: Any,
    *,
    alignment: str | AlignmentMethod = AlignmentMethod.SE3,
    rpe_delta: float = 1.0,
    rpe_unit: str | RpeUnit = RpeUnit.SECONDS,
    depth_threshold: float = CORRECT_THRESHOLD,
    method: str | None = None,
    metadata: Mapping[str, Any] | None = None,
    seconds: dict[str, float] | None = None,
) -> RunRecord:
    """Score a driver's episode result (duck-typed on the fields of ``sim_envs.driver.EpisodeResult``).

    Uses ``sequence``, ``agent``, ``timestamps`` (N,), ``T_world_cam_est`` (N, 4, 4), ``T_world_cam_gt``
    (N, 4, 4), ``tracked`` (N,), ``keyframes`` (list of ``KeyframeDepth``), ``keyframe_gt`` (list of ``Frame``, the
    ground truth at each key-frame), ``step_seconds`` (N,), ``uses_ground_truth`` and ``extras``. Estimated and
    ground-truth poses are paired by index (rule ``"index"``). A key-frame is matched to the ground-truth frame with
    its timestamp; one that cannot be scored is skipped with a warning, never losing the rest.
    ``method``: the name shown in tables (default: the agent string). ``seconds``: when given, the wall seconds of
    the trajectory metrics and of the key-frame (depth and label) metrics are added to it (``trajectory_metrics``,
    ``keyframe_metrics``), for the run's profile.
    """
    t_start = time.perf_counter()
    timestamps = np.asarray(result.timestamps, dtype=np.float64)
    gt = PoseTrajectory(timestamps, result.T_world_cam_gt)
    est = PoseTrajectory(timestamps, result.T_world_cam_est)
    traj = evaluate_trajectory(
        gt,
        est,
        alignment=alignment,
        association=AssociationRule.INDEX,
        rpe_delta=rpe_delta,
        rpe_unit=rpe_unit,
        tracked=np.asarray(result.tracked, dtype=bool),
    )
    warnings = list(traj.warnings)
    metrics: dict[str, float] = traj.flat_metrics()
    metrics[FRAMES.key] = float(len(timestamps))
    metrics.update(_timing_metrics(np.asarray(getattr(result, "step_seconds", []), dtype=np.float64)))
    t_keyframes = time.perf_counter()
    per_kf, kf_rows, conf = _score_keyframes(result.keyframes, result.keyframe_gt, depth_threshold, warnings)
    pooled = aggregate_depth_metrics(per_kf, "pooled")
    mean = aggregate_depth_metrics(per_kf, "mean")
    metrics.update(
        {
            DEPTH_PERCENT_CORRECT.key: pooled.percent_correct,
            DEPTH_PERCENT_CORRECT_MEAN.key: mean.percent_correct,
            DEPTH_DENSITY.key: pooled.density,
            DEPTH_ABS_REL.key: pooled.abs_rel,
            DEPTH_RMSE.key: pooled.rmse,
            DEPTH_DELTA_1_25.key: pooled.delta_1_25,
            DEPTH_KEYFRAMES.key: float(len(per_kf)),
        }
    )
    if conf is not None:
        sem = metrics_from_confusion(conf)
        metrics.update({f"semantic_{k}": float(v) for k, v in sem.to_dict().items() if k != "n_pixels"})
    if seconds is not None:
        t_end = time.perf_counter()
        seconds["trajectory_metrics"] = seconds.get("trajectory_metrics", 0.0) + t_keyframes - t_start
        seconds["keyframe_metrics"] = seconds.get("keyframe_metrics", 0.0) + t_end - t_keyframes
    agent = str(result.agent)
    return RunRecord(
        sequence=str(result.sequence),
        method=method or agent,
        agent=agent,
        metrics=metrics,
        uses_ground_truth=bool(getattr(result, "uses_ground_truth", False)),
        alignment=traj.describe_alignment(),
        association=traj.association.describe(),
        rpe=traj.describe_rpe(),
        warnings=tuple(warnings),
        keyframes=tuple(kf_rows),
        metadata=dict(metadata or {}),
    )


def _timing_metrics(step_seconds: np.ndarray) -> dict[str, float]:
    s = step_seconds[np.isfinite(step_seconds)]
    if s.size == 0:
        return {}
    return {
        STEP_MS_MEAN.key: 1000.0 * float(s.mean()),
        STEP_MS_MEDIAN.key: 1000.0 * float(np.median(s)),
        STEP_MS_MAX.key: 1000.0 * float(s.max()),
        FPS.key: float(1.0 / s.mean()) if s.mean() > 0 else math.nan,
    }


def _score_keyframes(keyframes, keyframe_gt, threshold: float, warnings: list[str]):
    """Per key-frame depth metrics, JSON rows, and the summed semantic confusion (None if no labels to score)."""
    from sim_envs.driver import match_timestamp

    gt_frames = list(keyframe_gt)
    gt_stamps = np.array([float(f.timestamp) for f in gt_frames])
    per_kf: list[DepthMetrics] = []
    rows: list[dict[str, Any]] = []
    conf = None
    for k, kf in enumerate(keyframes):
        t = float(kf.timestamp)
        near = match_timestamp(gt_stamps, t)  # the world's tolerance, as the episode paired them
        if near is None:
            warnings.append(f"key-frame {k} at t={t:.6f} s has no ground-truth frame; skipped")
            continue
        frame = gt_frames[near]
        depth_est = np.asarray(kf.depth, dtype=np.float32)
        depth_gt = np.asarray(frame.depth, dtype=np.float32)
        if depth_est.shape != depth_gt.shape:
            if depth_est.ndim != 2:
                warnings.append(f"key-frame {k}: depth of shape {depth_est.shape} is not (H, W); skipped")
                continue
            warnings.append(
                f"key-frame {k}: depth {depth_est.shape} resized (nearest) to the ground truth's {depth_gt.shape}"
            )
            depth_est = cv2.resize(depth_est, depth_gt.shape[::-1], interpolation=cv2.INTER_NEAREST)
        m = depth_metrics(depth_est, depth_gt, threshold)
        per_kf.append(m)
        rows.append({"timestamp": t, **m.to_dict()})
        labels = getattr(kf, "labels", None)
        if labels is not None and frame.labels is not None:
            pred = np.asarray(labels)
            pred = pred if pred.ndim == 2 else np.argmax(pred, axis=2)
            if pred.shape != frame.labels.shape:
                pred = cv2.resize(pred.astype(np.uint8), frame.labels.shape[::-1], interpolation=cv2.INTER_NEAREST)
            c = confusion_matrix(pred, frame.labels, NUM_CLASSES)
            conf = c if conf is None else conf + c
    return per_kf, rows, conf


# ------------------------------------------------------------------------------------------------------ files
def save_run(record: RunRecord, path: str | Path) -> Path:
    """Write a run record as strict JSON (NaN -> null)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(json_ready(record.to_json()), indent=2, allow_nan=False) + "\n")
    return path


def load_run(path: str | Path) -> RunRecord:
    """Read a run record; null metrics come back as NaN. A ``metrics.json`` with a ``timing.json`` beside it (a run
    folder) gets its :attr:`RunRecord.resources` from there (:func:`resources_of`)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ResultsError(f"{path}: not a readable JSON run record: {exc}") from exc
    record = RunRecord.from_json(data, str(path))
    timing_path = path.with_name(TIMING_FILE)
    if path.name != TIMING_FILE and timing_path.is_file():
        try:
            timing = json.loads(timing_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ResultsError(f"{timing_path}: not readable JSON: {exc}") from exc
        record = record.replace(resources=resources_of(timing, record.metrics.get(FRAMES.key)))
    return record


# ------------------------------------------------------------------------------------------------------- tables
def runs_frame(records: Iterable[RunRecord], run_ids: Iterable[str] | None = None) -> pd.DataFrame:
    """Many run records in long form: one row per (run, metric); see the module docstring for the columns.
    ``run_ids``: the ``run`` column (default: each record's :attr:`RunRecord.run`, else its position)."""
    rows = []
    ids = list(run_ids) if run_ids is not None else None
    for n, rec in enumerate(records):
        base = {
            "sequence": rec.sequence,
            "method": rec.method,
            "run": ids[n] if ids is not None else (rec.run if rec.run is not None else str(n)),
            "agent": rec.agent,
            "uses_ground_truth": rec.uses_ground_truth,
            "alignment": rec.alignment.get("requested"),
            "alignment_used": rec.alignment.get("used"),
            "association": rec.association.get("rule"),
        }
        meta = {k: v for k, v in rec.metadata.items() if isinstance(v, str | int | float | bool)}
        for metric, value in {**rec.metrics, **rec.resources}.items():
            rows.append({**base, **meta, "metric": metric, "value": math.nan if value is None else float(value)})
    if not rows:  # no run scored (all failed): the same columns, a numeric value column
        return pd.DataFrame({c: pd.Series(dtype=float if c == "value" else object) for c in [*LONG_COLUMNS, "run"]})
    frame = pd.DataFrame(rows)
    first = [*LONG_COLUMNS, "run"]
    return frame[first + [c for c in frame.columns if c not in first]]


def load_runs(paths: Iterable[str | Path]) -> pd.DataFrame:
    """Read run-record JSON files (files, or folders searched for ``*.json``) into one long frame."""
    files: list[Path] = []
    for p in map(Path, paths):
        files += sorted(p.rglob("*.json")) if p.is_dir() else [p]
    return runs_frame([load_run(f) for f in files], run_ids=[str(f) for f in files])

"""The validation of the depth network on the TEST sequences (which it never saw): depth accuracy with and without
the focal-length adjustment (CNN-SLAM eq. 5; the paper's Fig. 3 (a) vs (b)) and semantic accuracy.

Frames are taken evenly spaced from each sequence (``frames_per_sequence``); the network sees each frame's RGB only,
the ground truth (depth, labels) scores it. Metrics (:mod:`slamcommon.depth_metrics`,
:mod:`slamcommon.semantic_metrics`, the judge's) are pooled over pixels per sequence, per camera group (ICL-NUIM
analogues, TUM fr3 analogues) and overall.

A development tool of the network, like its training: it reads the simulator's ground truth, which the SLAM stages
never see.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from cnnslam.depth.depth_prediction import focal_length_adjustment
from cnnslam.depthnet.metrics import gradient_pixel_scale, log_depth_slope
from cnnslam.depthnet.predict import DepthNetPredictor
from cnnslam.errors import CnnSlamError
from cnnslam.track.tracking import to_gray
from sim_envs.sequences import TABLE1_SEQUENCES
from slamcommon.depth_metrics import DepthMetrics, aggregate_depth_metrics, depth_metrics
from slamcommon.semantic_metrics import SemanticMetrics, confusion_matrix, metrics_from_confusion

# The test sequences of CNN-SLAM's Table 1 (ICL-NUIM office 0-2 / living 0-2 analogues, ICL intrinsics; TUM fr3
# analogues, fr3 intrinsics), as registered in sim_envs.sequences.
VALIDATION_SEQUENCES: tuple[str, ...] = TABLE1_SEQUENCES
# Targets of the issue ("Done means"), checked on the focal-adjusted depth and the labels over all frames.
TARGETS: dict[str, tuple[str, float]] = {
    "abs_rel": ("<=", 0.20),
    "percent_correct": (">=", 30.0),  # the paper's correct depth, % of valid ground-truth pixels
    "pixel_accuracy": (">=", 0.75),
}


@dataclass(frozen=True)
class SampleFrame:
    """One frame kept for the figure: rgb (H, W, 3) uint8; depth_pred (adjusted), depth_gt (H, W) float32 metres;
    labels_pred, labels_gt (H, W) uint8."""

    sequence: str
    index: int
    rgb: np.ndarray
    depth_pred: np.ndarray
    depth_gt: np.ndarray
    labels_pred: np.ndarray
    labels_gt: np.ndarray


@dataclass(frozen=True)
class SequenceResult:
    """Scores of one sequence (or a group of them). f_cur, f_tr: pixels at the network's resolution."""

    name: str
    camera: str
    f_cur: float
    f_tr: float
    frames: int
    raw: DepthMetrics
    adjusted: DepthMetrics
    semantic: SemanticMetrics


@dataclass(frozen=True)
class ValidationReport:
    """Per-sequence, per-group ("icl", "tum") and overall results; ``samples`` for the figure."""

    sequences: tuple[SequenceResult, ...]
    groups: dict[str, SequenceResult]
    overall: SequenceResult
    frames_per_sequence: int
    samples: tuple[SampleFrame, ...] = field(default=(), repr=False)
    camera_effects: str = "clean"  # the world's camera the frames were seen through

    def targets_met(self) -> dict[str, bool]:
        """Each target of :data:`TARGETS` on the overall adjusted depth / labels."""
        values = {
            "abs_rel": self.overall.adjusted.abs_rel,
            "percent_correct": self.overall.adjusted.percent_correct,
            "pixel_accuracy": self.overall.semantic.pixel_accuracy,
        }
        out = {}
        for key, (op, bound) in TARGETS.items():
            out[key] = bool(values[key] <= bound) if op == "<=" else bool(values[key] >= bound)
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable figures (samples left out)."""

        def one(r: SequenceResult) -> dict[str, Any]:
            d = asdict(r)
            d["focal_ratio"] = r.f_cur / r.f_tr
            d["semantic"]["iou"] = list(r.semantic.iou)
            return d

        return {
            "frames_per_sequence": self.frames_per_sequence,
            "camera_effects": self.camera_effects,
            "overall": one(self.overall),
            "groups": {k: one(v) for k, v in self.groups.items()},
            "sequences": [one(r) for r in self.sequences],
            "targets": {k: {"op": op, "value": v} for k, (op, v) in TARGETS.items()},
            "targets_met": self.targets_met(),
        }


@dataclass
class _Tally:
    """Per-frame depth metrics (pooled at the end) and the summed (C, C+1) label confusion of some frames."""

    num_classes: int
    raw: list[DepthMetrics] = field(default_factory=list)
    adjusted: list[DepthMetrics] = field(default_factory=list)
    confusion: np.ndarray | None = None
    frames: int = 0

    def __post_init__(self) -> None:
        if self.confusion is None:
            self.confusion = np.zeros((self.num_classes, self.num_classes + 1), np.int64)

    def add(self, other: _Tally) -> None:
        self.raw += other.raw
        self.adjusted += other.adjusted
        self.confusion = self.confusion + other.confusion
        self.frames += other.frames

    def result(self, name: str, camera: str, f_cur: float, f_tr: float) -> SequenceResult:
        return SequenceResult(
            name, camera, f_cur, f_tr, self.frames, aggregate_depth_metrics(self.raw, "pooled"),
            aggregate_depth_metrics(self.adjusted, "pooled"), metrics_from_confusion(self.confusion),
        )


def camera_group(camera: str) -> str:
    """"icl" for the ICL-NUIM camera, "tum" for TUM cameras, the name itself otherwise."""
    return "tum" if camera.startswith("tum") else camera


def frame_indices(n_frames: int, k: int) -> list[int]:
    """``k`` frame indices evenly spaced over ``n_frames`` (first and last included)."""
    return sorted({int(i) for i in np.linspace(0, n_frames - 1, min(k, n_frames)).round()})


def validate_sequences(
    predictor: DepthNetPredictor,
    names: Sequence[str] = VALIDATION_SEQUENCES,
    frames_per_sequence: int = 40,
    sample_every: int = 0,
    progress: Callable[[Iterable[Any], int], Iterator[Any]] | None = None,
    camera_effects: str = "clean",
) -> ValidationReport:
    """Score ``predictor`` on ``frames_per_sequence`` frames of each registered sequence in ``names``, seen
    through the world's camera ``camera_effects`` (a :mod:`sim_envs.sensor.camera_effects` preset; "clean": the
    renderer's
    bytes).

    sample_every: keep one sample frame (the middle one) of every ``sample_every``-th sequence for the figure
    (0 = none). progress: wraps the iterator over (sequence, frame index) jobs, e.g. a tqdm bar.
    """
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    num_classes = predictor.model.config.num_classes
    jobs = []
    sources = {}
    for name in names:
        spec = get_sequence(name)
        sources[name] = SimulatedSequence(with_camera(spec, camera_effects) if camera_effects != "clean" else spec)
        jobs.extend((name, i) for i in frame_indices(spec.n_frames, frames_per_sequence))
    tallies: dict[str, _Tally] = {name: _Tally(num_classes) for name in names}
    focal: dict[str, float] = {}
    samples: list[SampleFrame] = []
    wrap = progress or (lambda it, total: it)
    sample_names = set(names[:: sample_every]) if sample_every > 0 else set()
    try:
        for name, i in wrap(iter(jobs), len(jobs)):
            src = sources[name]
            frame = src.frame(i)
            raw = predictor.predict_raw(frame.rgb)
            f_cur = predictor.current_focal(src.intrinsics.as_array(), frame.rgb.shape[:2])
            focal[name] = f_cur
            adjusted = focal_length_adjustment(raw.depth, f_cur, predictor.train_focal)
            labels = raw.labels
            t = tallies[name]
            t.raw.append(depth_metrics(raw.depth, frame.depth))
            t.adjusted.append(depth_metrics(adjusted, frame.depth))
            t.confusion = t.confusion + confusion_matrix(labels, frame.labels, num_classes)
            t.frames += 1
            mid = frame_indices(len(src), frames_per_sequence)
            if name in sample_names and i == mid[len(mid) // 2]:
                samples.append(SampleFrame(name, i, frame.rgb, adjusted, frame.depth, labels, frame.labels))
    finally:
        for src in sources.values():
            src.close()

    f_tr = predictor.train_focal
    per_seq = []
    groups: dict[str, _Tally] = {}
    group_focal: dict[str, list[float]] = {}
    overall = _Tally(num_classes)
    for name in names:
        camera = get_sequence(name).camera
        per_seq.append(tallies[name].result(name, camera, focal[name], f_tr))
        g = camera_group(camera)
        groups.setdefault(g, _Tally(num_classes)).add(tallies[name])
        group_focal.setdefault(g, []).append(focal[name])
        overall.add(tallies[name])
    group_results = {
        g: t.result(g, g, float(np.mean(group_focal[g])), f_tr) for g, t in groups.items()
    }
    all_f = float(np.mean([focal[n] for n in names]))
    return ValidationReport(
        tuple(per_seq), group_results, overall.result("all", "mixed", all_f, f_tr), frames_per_sequence,
        tuple(samples), camera_effects,
    )


@dataclass(frozen=True)
class ScaleStability:
    """The per-frame scale s_t (sensor depth / eq. 5 CNN depth, median over a frame's valid pixels) of a series of
    frames, summarised (:func:`scale_stability`).

    frames: frames with a finite, positive scale; median, iqr (25 %, 75 %), range_5_95 (5 %, 95 % quantiles),
    cv (coefficient of variation: std / mean, population std) over those frames. pairs: neighbouring entries of the
    series both with a scale; change_median_pct, change_p95_pct: median and 95th percentile over those pairs of
    100 |ln(s_t / s_{t-1})| (about the % change for small changes). gap_frames, gap_s: median frame-index and
    timestamp difference of those pairs (the time the change spans; nan without pairs or times)."""

    frames: int
    median: float
    iqr: tuple[float, float]
    range_5_95: tuple[float, float]
    cv: float
    pairs: int
    change_median_pct: float
    change_p95_pct: float
    gap_frames: float
    gap_s: float = float("nan")


def scale_stability(scales: Sequence[float], indices: Sequence[int] | None = None,
                    times: Sequence[float] | None = None) -> ScaleStability:
    """Level, spread and frame-to-frame change of a per-frame scale series (:class:`ScaleStability`).

    scales: one entry per frame in frame order; nan (or any non-finite or non-positive value) marks a frame without
    a scale (no valid pixels). Such a frame is left out of the level statistics, and a change is only taken between
    two neighbouring entries that both have a scale: a hole breaks the series, it is never bridged. indices, times:
    each entry's frame index and timestamp [s] (default: 0, 1, 2, ...; no times), for the gap the changes span.
    An empty series (or one without any scale) gives 0 frames, 0 pairs and nan figures.
    """
    s = np.asarray(scales, dtype=np.float64).reshape(-1)
    idx = np.arange(s.size, dtype=np.float64) if indices is None else np.asarray(indices, dtype=np.float64)
    if idx.shape != s.shape:
        raise ValueError(f"indices must have one entry per scale ({s.size}), got {idx.size}")
    ts = None if times is None else np.asarray(times, dtype=np.float64)
    if ts is not None and ts.shape != s.shape:
        raise ValueError(f"times must have one entry per scale ({s.size}), got {ts.size}")
    ok = np.isfinite(s) & (s > 0)
    nan = float("nan")
    v = s[ok]
    if v.size:
        median = float(np.median(v))
        q = np.quantile(v, [0.25, 0.75, 0.05, 0.95])
        cv = float(np.std(v) / np.mean(v))
    else:
        median, q, cv = nan, np.full(4, nan), nan
    both = ok[1:] & ok[:-1]
    change = 100.0 * np.abs(np.log(s[1:][both] / s[:-1][both])) if both.any() else np.empty(0)
    gap = np.diff(idx)[both]
    gap_s = np.diff(ts)[both] if ts is not None else np.empty(0)
    return ScaleStability(
        frames=int(v.size), median=median, iqr=(float(q[0]), float(q[1])), range_5_95=(float(q[2]), float(q[3])),
        cv=cv, pairs=int(change.size),
        change_median_pct=float(np.median(change)) if change.size else nan,
        change_p95_pct=float(np.quantile(change, 0.95)) if change.size else nan,
        gap_frames=float(np.median(gap)) if gap.size else nan,
        gap_s=float(np.median(gap_s)) if gap_s.size else nan,
    )


@dataclass(frozen=True)
class ScaleSeries:
    """A per-frame scale series: frame indices, timestamps [s] and scales (nan: no scale in that frame), with its
    :class:`ScaleStability`."""

    indices: tuple[int, ...]
    times: tuple[float, ...]
    scales: tuple[float, ...]
    stability: ScaleStability

    @classmethod
    def of(cls, indices: Sequence[int], times: Sequence[float], scales: Sequence[float]) -> ScaleSeries:
        """The series and its statistics (:func:`scale_stability`)."""
        return cls(tuple(int(i) for i in indices), tuple(float(t) for t in times), tuple(float(x) for x in scales),
                   scale_stability(scales, indices, times))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: nan becomes null."""
        d = asdict(self)
        return _nan_to_none(d)


def _nan_to_none(x: Any) -> Any:
    if isinstance(x, float) and not np.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_nan_to_none(v) for v in x]
    return x


_NO_SERIES = ScaleSeries((), (), (), scale_stability([]))


@dataclass(frozen=True)
class FolderValidation:
    """The network on a real RGB-D folder's frames: depth metrics raw and after eq. 5 (pooled over pixels), and the
    scale of the adjusted depth: per frame ``median(gt / pred)`` over the valid pixels, summarised over the frames
    by its median and quartiles (1 = the right metric scale). gradient_scale_*: the same over each frame's 20 % of
    pixels with the strongest image gradient (:func:`~cnnslam.depthnet.metrics.gradient_pixel_scale`); slope_*: each
    frame's log-depth slope (:func:`~cnnslam.depthnet.metrics.log_depth_slope`, 1 = the right depth range, below 1
    compressed). All on the adjusted depth. f_cur, f_tr: pixels at the network's resolution. spread: the scale
    series of the evenly spaced frames (its frame-to-frame change spans their gap); window: the same over a run of
    consecutive frames in the middle of the folder (change per frame). Its JSON (:meth:`to_dict`) adds
    ``focal_ratio`` = f_cur / f_tr and ``depth_scale_error`` = |scale median - 1|."""

    name: str
    frames: int
    f_cur: float
    f_tr: float
    raw: DepthMetrics
    adjusted: DepthMetrics
    scale_median: float
    scale_quartiles: tuple[float, float]
    gradient_scale_median: float = float("nan")
    gradient_scale_quartiles: tuple[float, float] = (float("nan"), float("nan"))
    slope_median: float = float("nan")
    slope_quartiles: tuple[float, float] = (float("nan"), float("nan"))
    spread: ScaleSeries = _NO_SERIES
    window: ScaleSeries = _NO_SERIES

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["focal_ratio"] = self.f_cur / self.f_tr
        d["depth_scale_error"] = abs(self.scale_median - 1.0)  # the network's depth scale off the sensor's
        d["spread"], d["window"] = self.spread.to_dict(), self.window.to_dict()
        return d


def validate_folder(
    predictor: DepthNetPredictor,
    source: Any,
    frames: int = 100,
    progress: Callable[[Iterable[Any], int], Iterator[Any]] | None = None,
    window: int = 0,
) -> FolderValidation:
    """Score ``predictor`` on ``frames`` evenly spaced frames of ``source`` (a frame source of a real RGB-D folder,
    :func:`sim_envs.folders.datasets.load_rgbd_folder`: frames with ``rgb`` and metric ``depth``, 0 = no measurement).
    window: also the scale of ``window`` consecutive frames centred on the folder's middle (all frames when it has
    fewer; 0 = none), for the change from one frame to the next; they only feed ``FolderValidation.window``.

    Real data is test data: nothing here feeds back into the network or the SLAM. Where the depth camera is not
    registered to the colour camera (7-Scenes), depth edges are a few pixels off the image's, which inflates the
    errors there; the figures are an upper bound of the network's error on those frames.
    """
    if window < 0:
        raise CnnSlamError(f"window must be >= 0 consecutive frames (0 = none), got {window}")
    n = len(source)
    idx = frame_indices(n, frames)
    start = max(0, (n - window) // 2)
    win = list(range(start, min(n, start + window))) if window else []
    raw_frames: list[DepthMetrics] = []
    adj_frames: list[DepthMetrics] = []
    scales, gradient_scales, slopes = [], [], []
    series: dict[str, tuple[list[int], list[float], list[float]]] = {"spread": ([], [], []), "window": ([], [], [])}
    f_cur = predictor.current_focal(source.intrinsics.as_array(), (source.intrinsics.height, source.intrinsics.width))
    wrap = progress or (lambda it, total: it)
    jobs = [("spread", i) for i in idx] + [("window", i) for i in win]
    for part, i in wrap(iter(jobs), len(jobs)):
        frame = source.frame(i)
        indices, times, values = series[part]
        indices.append(i)
        times.append(float(frame.timestamp))
        if frame.depth is None:
            values.append(float("nan"))
            continue
        raw = predictor.predict_raw(frame.rgb)
        adjusted = focal_length_adjustment(raw.depth, f_cur, predictor.train_focal)
        valid = (frame.depth > 0) & (adjusted > 0)
        scale = float(np.median(frame.depth[valid] / adjusted[valid])) if valid.sum() >= 100 else float("nan")
        values.append(scale)
        if part == "window":
            continue
        raw_frames.append(depth_metrics(raw.depth, frame.depth))
        adj_frames.append(depth_metrics(adjusted, frame.depth))
        if np.isfinite(scale):
            scales.append(scale)
            gradient_scales.append(gradient_pixel_scale(to_gray(frame.rgb), adjusted, frame.depth))
            slopes.append(log_depth_slope(adjusted, frame.depth))
    s, gs, sl = (_median_quartiles(v) for v in (scales, gradient_scales, slopes))
    return FolderValidation(
        name=str(getattr(source, "name", "folder")), frames=len(scales), f_cur=f_cur, f_tr=predictor.train_focal,
        raw=aggregate_depth_metrics(raw_frames, "pooled"), adjusted=aggregate_depth_metrics(adj_frames, "pooled"),
        scale_median=s[0], scale_quartiles=s[1],
        gradient_scale_median=gs[0], gradient_scale_quartiles=gs[1], slope_median=sl[0], slope_quartiles=sl[1],
        spread=ScaleSeries.of(*series["spread"]), window=ScaleSeries.of(*series["window"]),
    )


def _median_quartiles(values: Sequence[float]) -> tuple[float, tuple[float, float]]:
    """Median and (25 %, 75 %) quantiles of the finite values; nan without any."""
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=np.float64)
    if v.size == 0:
        return float("nan"), (float("nan"), float("nan"))
    return float(np.median(v)), (float(np.quantile(v, 0.25)), float(np.quantile(v, 0.75)))


def folder_validation_markdown(results: Sequence[FolderValidation], simulated: dict[str, Any] | None = None) -> str:
    """``results/depthnet_real.md``: one row per folder, beside the simulated test sequences' overall figures
    (``simulated``: the ``overall`` block of ``results/depthnet.json``)."""
    lines = [
        "# Depth network on real frames\n",
        "The shipped network (trained on rendered rooms only; real data is test data) on evenly spaced frames of real "
        "RGB-D folders at 320x240, scored against the sensor's depth. Raw = the network's output, eq. 5 = after the "
        "focal-length adjustment. Scale = per frame median(sensor depth / eq. 5 depth), median [quartiles] over the "
        "frames: 1 is the right metric scale; at high-gradient pixels: the same over each frame's 20 % of pixels "
        "with the strongest image gradient, those direct tracking weighs most. Depth slope = per frame the "
        "least-squares slope of log(eq. 5 depth) on log(sensor depth), median [quartiles]: 1 is the right depth "
        "range, below 1 the network compresses it (near surfaces too far, far ones too near). "
        "7-Scenes folders are read as their colour camera (525 px), their "
        "depth registered to it from the depth camera (585 px) by the Kinect's 2.6 cm baseline "
        "(`docs/benchmarks.md`); the registration is not exact at depth edges. Made by "
        "`cnnslam train validate-folder`.\n",
        "| data | frames | f_cur/f_tr | AbsRel raw | AbsRel eq. 5 | RMSE eq. 5 [m] | δ<1.25 eq. 5 [%] | "
        "within 10 % raw [%] | within 10 % eq. 5 [%] | scale (sensor / eq. 5) | scale at high-gradient pixels | "
        "depth slope |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r.name} (real) | {r.frames} | {r.f_cur / r.f_tr:.3f} | {r.raw.abs_rel:.3f} | {r.adjusted.abs_rel:.3f} "
            f"| {r.adjusted.rmse:.3f} | {r.adjusted.delta_1_25:.1f} | {r.raw.percent_correct:.1f} | "
            f"{r.adjusted.percent_correct:.1f} | {_mq(r.scale_median, r.scale_quartiles)} | "
            f"{_mq(r.gradient_scale_median, r.gradient_scale_quartiles)} | {_mq(r.slope_median, r.slope_quartiles)} |"
        )
    if simulated:
        raw, adj = simulated.get("raw", {}), simulated.get("adjusted", {})
        lines.append(
            f"| simulated test sequences (all, `results/depthnet.md`) | {simulated.get('frames', '-')} | "
            f"{simulated.get('focal_ratio', float('nan')):.3f} | {raw.get('abs_rel', float('nan')):.3f} | "
            f"{adj.get('abs_rel', float('nan')):.3f} | {adj.get('rmse', float('nan')):.3f} | "
            f"{adj.get('delta_1_25', float('nan')):.1f} | {raw.get('percent_correct', float('nan')):.1f} | "
            f"{adj.get('percent_correct', float('nan')):.1f} | - | - | - |"
        )
    lines += ["", *scale_stability_markdown(results)]
    return "\n".join(lines) + "\n"


def scale_stability_markdown(results: Sequence[FolderValidation], figure: str = "depthnet_real_scale.png"
                             ) -> list[str]:
    """The section on the scale over time: per folder the level, spread and frame-to-frame change of the per-frame
    scale, over the evenly spaced frames and over the run of consecutive frames."""
    lines = [
        "## The network's scale over time\n",
        "Per frame s = median(sensor depth / eq. 5 depth) over its valid pixels. Level and spread over the frames: "
        "median, quartiles, 5-95 % range, coefficient of variation (std / mean). Frame-to-frame change: median and "
        "95th percentile of 100 |ln(s_t / s_t-1)| (about % for small changes) over neighbouring frames, spanning "
        "the gap given (frames, seconds): \"evenly spaced\" = the frames of the table above, \"consecutive\" = a "
        "run of consecutive frames in the middle of the folder (the change from one frame to the next). A frame "
        "without a scale breaks the series; no change is taken across it.\n",
        "| data | frames | median | quartiles | 5-95 % | CV [%] | gap [frames / s] | change median [%] | "
        "change p95 [%] |",
        "|---|---:|---:|---|---|---:|---|---:|---:|",
    ]
    for r in results:
        for what, ser in (("evenly spaced", r.spread), ("consecutive", r.window)):
            st = ser.stability
            if not ser.indices:
                continue
            lines.append(
                f"| {r.name} ({what}, frames {ser.indices[0]}-{ser.indices[-1]}) | {st.frames} | {st.median:.3f} | "
                f"{st.iqr[0]:.3f}-{st.iqr[1]:.3f} | {st.range_5_95[0]:.3f}-{st.range_5_95[1]:.3f} | "
                f"{100 * st.cv:.1f} | {st.gap_frames:.0f} / {st.gap_s:.3f} | {st.change_median_pct:.2f} | "
                f"{st.change_p95_pct:.2f} |"
            )
    lines += ["", f"![scale over frames]({figure})", ""]
    return lines


def _mq(median: float, quartiles: tuple[float, float]) -> str:
    return f"{median:.3f} [{quartiles[0]:.3f}, {quartiles[1]:.3f}]"

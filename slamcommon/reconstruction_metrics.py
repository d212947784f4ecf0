"""Reconstruction and semantic-fusion metrics of a global 3D model against the simulator's ground-truth surfaces.

Inputs are plain arrays (the judge never imports ``cnnslam``): the model as points (N, 3) with optional labels, the
ground truth as labelled surface samples (M, 3) with outward normals (``sim_envs.scenes.surface_sampling``), all in the
ground-truth world frame and in metres. The caller aligns the model first (``slamcommon.alignment``).

Reconstruction (as in the multi-view-stereo benchmarks, e.g. Middlebury / DTU "accuracy" and "completeness"):

- accuracy: for every model point the distance to the ground-truth surface; its mean, median and the share within
  ``threshold`` (5 cm by default). The distance to the nearest sample is refined with that sample's normal:
  d = sqrt((n . e)^2 + max(0, |e_t| - s / sqrt(2))^2) with e the offset to the sample, e_t its tangential part and s
  the sample spacing, i.e. the exact point-to-plane distance while the point lies over the sample's cell and the
  Euclidean excess beyond it. This removes the sampling bias (up to s / sqrt(2)) of a plain nearest-sample distance.
- completeness: for every ground-truth sample the distance to the nearest model point; mean, median, share within
  ``threshold``. Only surfaces the camera saw should count: :func:`visible_in_views` keeps the samples that at least
  one ground-truth view sees (in its image, in front of it, and within a tolerance of that view's ground-truth depth
  at the sample's pixel, i.e. not occluded). Ours: the views are the ground-truth frames of the agent's key-frames,
  because the model is built from key-frames only, so a surface no key-frame saw cannot be asked of it.

Semantic label fusion (CNN-SLAM Sec. 3.5 / 4.3, made quantitative): the ground-truth label of a 3D point is the
label of the nearest ground-truth sample, if that sample is within ``max_distance`` (else the point is on no known
surface and is not scored). Frame-wise CNN labels are scored at the 3D points of their key-frame pixels
(back-projected with the key-frame's estimated depth and pose); the fused model is scored at exactly the same points
with the label of the nearest model point (within ``max_distance``), so both are measured on the same surfaces with
the same ground truth. The accuracy of the model's own elements (one vote per element) is reported beside.

On the fused measurements themselves (:func:`measurement_label_metrics`, ours): the fusion is replayed with, in
place of the CNN's class probabilities, each measurement's ground-truth label (one-hot) and whether its frame-wise
label was right, so that every model element holds the weight of the measurements fused into it per ground-truth
class. Each measurement is then scored twice against its own ground-truth label: with its frame-wise label, and
with the fused label of the element it went into. No nearest-neighbour search and no depth error enters: these are
exactly the same surfaces. The share a single best label per element could reach (``purity``) bounds the fused
accuracy; elements whose measurements disagree in ground truth (``mixed``: data association joined different
surfaces) are reported apart from ``pure`` ones, where the label fusion alone is at work.
Accuracies are shares 0..1; ``gain_points`` is (fused - frame-wise) x 100, in percentage points.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from slamcommon.errors import MetricError
from slamcommon.fused import fma
from slamcommon.labels import NO_LABEL, NUM_CLASSES
from slamcommon.semantic_metrics import confusion_matrix, metrics_from_confusion

DEFAULT_THRESHOLD: float = 0.05  # m; issue 7: share within 5 cm
DEFAULT_LABEL_DISTANCE: float = 0.10  # m; ours: a point farther than this from every ground-truth sample is on no
# known surface and gets no ground-truth label
VISIBILITY_ABS_TOLERANCE: float = 0.03  # m; ours: a sample is seen when |z - D_gt(u)| < 3 cm + 2 % of z (the render
VISIBILITY_REL_TOLERANCE: float = 0.02  # meshes deviate from the analytic surfaces by < 5 % of small radii)


class ReconstructionMetricsError(MetricError):
    """Inputs of the reconstruction metrics that cannot be scored (shapes, empty sets)."""


@dataclass(frozen=True)
class ReconstructionMetrics:
    """Accuracy (model -> ground truth) and completeness (ground truth -> model).

    Distances in metres, ``*_within`` shares 0..1 of points closer than ``threshold`` metres; NaN where a set is
    empty. n_model, n_gt: the points scored on each side.
    """

    accuracy_mean: float
    accuracy_median: float
    accuracy_within: float
    completeness_mean: float
    completeness_median: float
    completeness_within: float
    threshold: float
    n_model: int
    n_gt: int

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


@dataclass(frozen=True)
class LabelFusionMetrics:
    """Semantic accuracy of the fused model beside the frame-wise CNN labels on the same surfaces.

    fused_accuracy, framewise_accuracy: shares 0..1 over the same ``n_points`` frame-wise 3D points (those with a
    ground-truth label and a model point within ``max_distance``); gain_points: (fused - frame-wise) x 100;
    fused_mean_iou, framewise_mean_iou: mean IoU over the 4 classes on those points; model_accuracy: share of model
    elements (with a label and a ground-truth label) whose label is right, over ``n_model`` elements; coverage: share
    of the frame-wise points with a ground-truth label that the model covers.
    """

    fused_accuracy: float
    framewise_accuracy: float
    gain_points: float
    fused_mean_iou: float
    framewise_mean_iou: float
    model_accuracy: float
    n_points: int
    n_model: int
    coverage: float
    max_distance: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


@dataclass(frozen=True)
class MeasurementLabelMetrics:
    """Fused vs frame-wise label accuracy over the measurements fused into a model (module docstring).

    Shares 0..1 of the measurement weight with a ground-truth label (``mass``, in the fusion's weight units):
    fused_accuracy, framewise_accuracy, gain_points = (fused - frame-wise) x 100; purity: what the best single
    label per element would score (the ceiling of any per-element label); pure_share: the weight in elements whose
    measurements all share one ground-truth label, with the fused and frame-wise accuracy there and in the rest
    (``mixed_*``, NaN when empty); n_elements: elements holding labelled measurements.
    """

    fused_accuracy: float
    framewise_accuracy: float
    gain_points: float
    purity: float
    pure_share: float
    pure_fused_accuracy: float
    pure_framewise_accuracy: float
    mixed_fused_accuracy: float
    mixed_framewise_accuracy: float
    n_elements: int
    mass: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _points(name: str, points: np.ndarray, allow_empty: bool = True) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ReconstructionMetricsError(f"{name} must be (N, 3) metres, got shape {p.shape}")
    if not np.isfinite(p).all():
        raise ReconstructionMetricsError(f"{name} holds NaN or inf")
    if not allow_empty and p.shape[0] == 0:
        raise ReconstructionMetricsError(f"{name} is empty")
    return p


def _share(d: np.ndarray, threshold: float) -> float:
    return float(np.mean(d < threshold)) if d.size else math.nan


def _mean(d: np.ndarray) -> float:
    return float(np.mean(d)) if d.size else math.nan


def _median(d: np.ndarray) -> float:
    return float(np.median(d)) if d.size else math.nan


def nearest_tree(points: np.ndarray) -> cKDTree:
    """A ``cKDTree`` of ``points`` (N, 3) for exact nearest-neighbour queries, built by sliding-midpoint splits
    (``balanced_tree=False``) without shrinking each node's box to its points (``compact_nodes=False``): on surface
    samples and a dense model about half the build time and half the query time of the default median splits (a
    whole-room model of 195 000 points against 832 000 samples: 1.75 -> 0.89 s); the answers are the same exact
    nearest neighbours."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def distance_to_surface(points: np.ndarray, samples: np.ndarray, normals: np.ndarray | None = None,
                        spacing: float | None = None, tree: cKDTree | None = None,
                        nearest: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Distance (N,) float64 metres from each of ``points`` (N, 3) to the surface sampled by ``samples`` (M, 3),
    and the index (N,) int64 of the nearest sample.

    With ``normals`` (M, 3) and ``spacing`` the nearest-sample distance is refined as in the module docstring
    (point-to-plane over the sample's cell); without them it is the plain Euclidean distance to the nearest sample.
    ``tree``: a prebuilt ``cKDTree(samples)`` to reuse; ``nearest``: ``cKDTree(samples).query(points, k=1)`` already
    made (distances, indices), to reuse.
    """
    p = _points("points", points)
    s = _points("samples", samples, allow_empty=False)
    if p.shape[0] == 0:
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    if nearest is None:
        tree = nearest_tree(s) if tree is None else tree
        nearest = tree.query(p, k=1)
    d, idx = nearest
    idx = np.asarray(idx, dtype=np.int64)
    if normals is None or spacing is None:
        return np.asarray(d, dtype=np.float64), idx
    n = np.asarray(normals, dtype=np.float64)
    if n.shape != s.shape:
        raise ReconstructionMetricsError(f"normals {n.shape} must match the samples {s.shape}")
    if not spacing > 0:
        raise ReconstructionMetricsError(f"spacing must be positive metres, got {spacing!r}")
    e = p - s[idx]
    ni = n[idx]
    normal_part = np.einsum("ij,ij->i", e, ni)
    tangential = np.linalg.norm(e - normal_part[:, None] * ni, axis=1)
    excess = np.clip(tangential - spacing / math.sqrt(2.0), 0.0, None)
    return np.sqrt(normal_part**2 + excess**2), idx


def reconstruction_metrics(model_points: np.ndarray, gt_points: np.ndarray, gt_normals: np.ndarray | None = None,
                           gt_spacing: float | None = None, threshold: float = DEFAULT_THRESHOLD,
                           seen: np.ndarray | None = None,
                           nearest: tuple[np.ndarray, np.ndarray] | None = None) -> ReconstructionMetrics:
    """Accuracy and completeness of a model (N, 3) against ground-truth samples (M, 3) (module docstring).

    gt_normals (M, 3) and gt_spacing (m) enable the point-to-surface refinement of the accuracy distances. ``seen``
    (M,) bool: the samples that count for completeness, the surfaces the views saw (:func:`visible_in_views`); the
    accuracy is still measured against every sample (a model point on a surface no view saw in full is not an
    error). ``n_gt`` counts the samples scored for completeness. ``nearest``: the model points' nearest samples
    already found (``cKDTree(gt_points).query(model_points, k=1)``), to reuse.
    """
    model = _points("model_points", model_points)
    all_gt = _points("gt_points", gt_points, allow_empty=False)
    if not (math.isfinite(threshold) and threshold > 0):
        raise ReconstructionMetricsError(f"threshold must be positive metres, got {threshold!r}")
    acc, _ = distance_to_surface(model, all_gt, gt_normals, gt_spacing, nearest=nearest)
    gt = all_gt
    if seen is not None:
        seen = np.asarray(seen)
        if seen.shape != (all_gt.shape[0],) or seen.dtype != bool:
            raise ReconstructionMetricsError(f"seen must be a bool mask of the {all_gt.shape[0]} ground-truth samples, "
                                             f"got {seen.dtype} {seen.shape}")
        if not seen.any():
            raise ReconstructionMetricsError("no ground-truth sample was seen: nothing to score completeness on")
        gt = all_gt[seen]
    if model.shape[0]:
        comp, _ = nearest_tree(model).query(gt, k=1)
        comp = np.asarray(comp, dtype=np.float64)
    else:
        comp = np.full(gt.shape[0], np.inf)
    return ReconstructionMetrics(
        accuracy_mean=_mean(acc), accuracy_median=_median(acc), accuracy_within=_share(acc, threshold),
        completeness_mean=_mean(comp) if model.shape[0] else math.inf,
        completeness_median=_median(comp) if model.shape[0] else math.inf,
        completeness_within=_share(comp, threshold), threshold=float(threshold), n_model=int(model.shape[0]),
        n_gt=int(gt.shape[0]),
    )


def visible_in_views(points: np.ndarray, T_world_cam: np.ndarray, depths: np.ndarray | list[np.ndarray],
                     intrinsics: np.ndarray, abs_tolerance: float = VISIBILITY_ABS_TOLERANCE,
                     rel_tolerance: float = VISIBILITY_REL_TOLERANCE) -> np.ndarray:
    """Which ground-truth points (N, 3) at least one view sees: (N,) bool.

    T_world_cam: (K, 4, 4) ground-truth camera-to-world poses (OpenCV axes); depths: K ground-truth depth maps
    (H, W) metres (0 = no surface); intrinsics: [fx, fy, cx, cy] pixels. A point is seen by a view when it projects
    inside the image (nearest pixel), in front of the camera, onto a pixel with depth, and its camera z is within
    ``abs_tolerance + rel_tolerance * z`` of that depth (not occluded).
    """
    p = _points("points", points)
    poses = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    if len(depths) != poses.shape[0]:
        raise ReconstructionMetricsError(f"{poses.shape[0]} poses but {len(depths)} depth maps")
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    seen = np.zeros(p.shape[0], dtype=bool)
    for T, depth in zip(poses, depths, strict=True):
        d = np.ascontiguousarray(depth, dtype=np.float32)
        if d.ndim != 2:
            raise ReconstructionMetricsError(f"depth maps must be (H, W), got {d.shape}")
        _mark_seen(p, np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]), d, fx, fy, cx, cy,
                   float(abs_tolerance), float(rel_tolerance), seen)
    return seen


@njit(cache=True, nogil=True)
def _mark_seen(p, R, t, d, fx, fy, cx, cy, abs_tolerance, rel_tolerance, seen):  # pragma: no cover - compiled
    """Set ``seen`` for the points not yet seen that the view (R, t: camera-to-world; d: its float32 depth map) sees.

    One pass in the operations and order of the numpy formulation (camera coordinates (p - t) @ R as BLAS sums
    them, fused; then z > 1e-6, u = rint(fx x / z + cx), v likewise, inside [0, W - 1] x [0, H - 1], depth > 0 and
    |z - depth| < abs + rel z), so the same points (tests: against that formulation)."""
    h, w = d.shape
    for i in range(p.shape[0]):
        if seen[i]:
            continue
        a0, a1, a2 = p[i, 0] - t[0], p[i, 1] - t[1], p[i, 2] - t[2]
        z = fma(a2, R[2, 2], fma(a1, R[1, 2], a0 * R[0, 2]))
        if not z > 1e-6:
            continue
        x = fma(a2, R[2, 0], fma(a1, R[1, 0], a0 * R[0, 0]))
        y = fma(a2, R[2, 1], fma(a1, R[1, 1], a0 * R[0, 1]))
        u = np.rint(fx * x / z + cx)
        v = np.rint(fy * y / z + cy)
        if not (u >= 0 and u <= w - 1 and v >= 0 and v <= h - 1):
            continue
        dz = d[int(v), int(u)]
        if dz > 0 and abs(z - dz) < abs_tolerance + rel_tolerance * z:
            seen[i] = True


def nearest_labels(points: np.ndarray, gt_points: np.ndarray, gt_labels: np.ndarray,
                   max_distance: float = DEFAULT_LABEL_DISTANCE,
                   tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The label (N,) uint8 of the nearest ground-truth sample of each point ((N, 3) metres), ``NO_LABEL`` (255)
    where that sample is farther than ``max_distance``; and the distances (N,) float64 metres."""
    p = _points("points", points)
    gt = _points("gt_points", gt_points, allow_empty=False)
    labels = np.asarray(gt_labels)
    if labels.shape != (gt.shape[0],):
        raise ReconstructionMetricsError(f"gt_labels must be ({gt.shape[0]},), got {labels.shape}")
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.uint8), np.zeros(0)
    tree = nearest_tree(gt) if tree is None else tree
    d, idx = tree.query(p, k=1)
    out = np.where(d <= max_distance, labels[idx], NO_LABEL).astype(np.uint8)
    return out, np.asarray(d, dtype=np.float64)


def _accuracy_and_iou(pred: np.ndarray, gt: np.ndarray) -> tuple[float, float]:
    if gt.size == 0:
        return math.nan, math.nan
    m = metrics_from_confusion(confusion_matrix(pred.reshape(1, -1), gt.reshape(1, -1), NUM_CLASSES))
    return m.pixel_accuracy, m.mean_iou


def label_fusion_metrics(model_points: np.ndarray, model_labels: np.ndarray, frame_points: np.ndarray,
                         frame_labels: np.ndarray, gt_points: np.ndarray, gt_labels: np.ndarray,
                         max_distance: float = DEFAULT_LABEL_DISTANCE) -> LabelFusionMetrics:
    """Fused vs frame-wise semantic accuracy on the same surfaces (module docstring).

    model_points (N, 3), model_labels (N,) uint8 (``NO_LABEL`` = element without a label); frame_points (F, 3) the
    back-projected key-frame pixels, frame_labels (F,) their frame-wise CNN labels; gt_points (M, 3), gt_labels (M,)
    ground-truth samples. All metres in the ground-truth world frame.
    """
    model = _points("model_points", model_points)
    frames = _points("frame_points", frame_points)
    m_labels = np.asarray(model_labels).reshape(-1)
    f_labels = np.asarray(frame_labels).reshape(-1)
    if m_labels.shape[0] != model.shape[0] or f_labels.shape[0] != frames.shape[0]:
        raise ReconstructionMetricsError(
            f"labels must have one entry per point: model {m_labels.shape[0]} vs {model.shape[0]}, frame-wise "
            f"{f_labels.shape[0]} vs {frames.shape[0]}")
    if not (math.isfinite(max_distance) and max_distance > 0):
        raise ReconstructionMetricsError(f"max_distance must be positive metres, got {max_distance!r}")
    gt_tree = nearest_tree(_points("gt_points", gt_points, allow_empty=False))
    gt_of_frames, _ = nearest_labels(frames, gt_points, gt_labels, max_distance, gt_tree)
    labelled = m_labels != NO_LABEL
    fused = np.full(frames.shape[0], NO_LABEL, dtype=np.uint8)
    if labelled.any() and frames.shape[0]:
        d, idx = nearest_tree(model[labelled]).query(frames, k=1)
        near = d <= max_distance
        fused[near] = m_labels[labelled][idx[near]]
    with_gt = gt_of_frames != NO_LABEL
    scored = with_gt & (fused != NO_LABEL)
    fused_acc, fused_iou = _accuracy_and_iou(fused[scored], gt_of_frames[scored])
    frame_acc, frame_iou = _accuracy_and_iou(f_labels[scored].astype(np.int64), gt_of_frames[scored])
    gt_of_model, _ = nearest_labels(model, gt_points, gt_labels, max_distance, gt_tree)
    model_scored = labelled & (gt_of_model != NO_LABEL)
    model_acc = float(np.mean(m_labels[model_scored] == gt_of_model[model_scored])) if model_scored.any() else math.nan
    n_gt = int(with_gt.sum())
    return LabelFusionMetrics(
        fused_accuracy=fused_acc, framewise_accuracy=frame_acc, gain_points=(fused_acc - frame_acc) * 100.0,
        fused_mean_iou=fused_iou, framewise_mean_iou=frame_iou, model_accuracy=model_acc,
        n_points=int(scored.sum()), n_model=int(model_scored.sum()),
        coverage=float(scored.sum() / n_gt) if n_gt else math.nan, max_distance=float(max_distance),
    )


def image_label_accuracy(fused_maps: list[np.ndarray], framewise_maps: list[np.ndarray],
                         gt_maps: list[np.ndarray]) -> tuple[float, float, int]:
    """Fused vs frame-wise label accuracy in image space: (fused share, frame-wise share, pixels).

    Each list holds one (H, W) label map per key-frame: the fused model's labels rendered into the key-frame
    (``NO_LABEL`` where the model does not cover the pixel), the frame-wise CNN labels, and the ground-truth labels.
    Pixels count where the ground truth has a label and the fused map covers them; both are scored there.
    """
    if not len(fused_maps) == len(framewise_maps) == len(gt_maps):
        raise ReconstructionMetricsError(
            f"need as many fused ({len(fused_maps)}), frame-wise ({len(framewise_maps)}) and ground-truth "
            f"({len(gt_maps)}) label maps")
    right_fused = right_frame = total = 0
    for fused, frame, gt in zip(fused_maps, framewise_maps, gt_maps, strict=True):
        fused, frame, gt = np.asarray(fused), np.asarray(frame), np.asarray(gt)
        if not fused.shape == frame.shape == gt.shape or gt.ndim != 2:
            raise ReconstructionMetricsError(
                f"label maps must share one (H, W) shape, got {fused.shape}, {frame.shape}, {gt.shape}")
        keep = (gt != NO_LABEL) & (fused != NO_LABEL)
        right_fused += int(np.count_nonzero(fused[keep] == gt[keep]))
        right_frame += int(np.count_nonzero(frame[keep] == gt[keep]))
        total += int(np.count_nonzero(keep))
    if total == 0:
        return math.nan, math.nan, 0
    return right_fused / total, right_frame / total, total


def measurement_label_metrics(fused_labels: np.ndarray, gt_evidence: np.ndarray,
                              framewise_right: np.ndarray) -> MeasurementLabelMetrics:
    """Fused vs frame-wise accuracy on the fused measurements themselves (module docstring).

    fused_labels (N,): each element's fused label (``NO_LABEL`` = none, scored wrong); gt_evidence (N, C) >= 0: the
    weight of the measurements fused into each element, per ground-truth class; framewise_right (N,) >= 0: the part
    of that weight whose frame-wise label equalled its ground truth (at most the row sum of ``gt_evidence``).
    """
    labels = np.asarray(fused_labels).reshape(-1).astype(np.int64)
    E = np.asarray(gt_evidence, dtype=np.float64)
    right = np.asarray(framewise_right, dtype=np.float64).reshape(-1)
    if E.ndim != 2 or not labels.shape[0] == E.shape[0] == right.shape[0]:
        raise ReconstructionMetricsError(
            f"need one fused label, one evidence row (N, C) and one frame-wise weight per element, got "
            f"{labels.shape}, {E.shape}, {right.shape}")
    if not (np.isfinite(E).all() and np.isfinite(right).all()) or (E < 0).any() or (right < 0).any():
        raise ReconstructionMetricsError("label evidence and frame-wise weights must be finite and >= 0")
    row = E.sum(axis=1)
    if (right > row * (1 + 1e-5) + 1e-9).any():
        raise ReconstructionMetricsError("framewise_right exceeds an element's labelled weight (row of gt_evidence)")
    total = float(row.sum())
    if total <= 0:
        nan = math.nan
        return MeasurementLabelMetrics(nan, nan, nan, nan, nan, nan, nan, nan, nan, 0, 0.0)
    has = (labels >= 0) & (labels < E.shape[1])
    fused_right = np.zeros_like(row)
    fused_right[has] = E[np.flatnonzero(has), labels[has]]
    pure = E.max(axis=1) >= row * (1 - 1e-6)

    def share(num: np.ndarray, sel: np.ndarray) -> float:
        den = float(row[sel].sum())
        return float(num[sel].sum()) / den if den > 0 else math.nan

    every = np.ones(row.shape, bool)
    fused, frame = share(fused_right, every), share(right, every)
    return MeasurementLabelMetrics(
        fused_accuracy=fused, framewise_accuracy=frame, gain_points=(fused - frame) * 100.0,
        purity=float(E.max(axis=1).sum()) / total, pure_share=float(row[pure].sum()) / total,
        pure_fused_accuracy=share(fused_right, pure), pure_framewise_accuracy=share(right, pure),
        mixed_fused_accuracy=share(fused_right, ~pure), mixed_framewise_accuracy=share(right, ~pure),
        n_elements=int(np.count_nonzero(row > 0)), mass=total)

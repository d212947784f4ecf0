"""CNN-SLAM as a system: the frame thread and the key-frame thread of the paper (Sec. 4, Fig. 2).

One frame per call (:meth:`CnnSlam.process`), trajectory and key-frames at the end (:meth:`CnnSlam.finish`).

The two threads
---------------
- Frame thread (the caller's thread, i.e. the agent's ``step``): builds the frame's image pyramid, tracks it
  against the active key-frame (eq. 1-4, :mod:`cnnslam.track.tracking`), refines the active key-frame's depth with it
  (eq. 10-11, :mod:`cnnslam.keyframe.refinement`), and decides whether the frame becomes a new key-frame (LSD-SLAM's
  score).
- Key-frame thread (``cnnslam-keyframe``, a daemon thread): initialises new key-frames (CNN depth on that frame,
  eq. 5; uncertainty, eq. 6; fusion with the previous key-frame, eq. 7-9; or propagation without a CNN) and
  maintains the pose graph (edges by direct alignment to key-frames with a similar view, loop edges, global
  optimisation at each new key-frame), and fuses every frozen key-frame into the global model with its class
  probabilities (Sec. 3.5, :mod:`cnnslam.model.global_model`; ``global_model.enabled``).

Hand-over (who pushes, reads and clears what)
---------------------------------------------
- At a key-frame switch the frame thread PUSHES an initialisation job (the frame's image and pyramid, timestamp,
  the previous key-frame, the tracked T_prev_new and its Hessian, and the frame's ground truth only when an agent
  with ``uses_ground_truth`` gave it) and WAITS for its result: the only time the frame thread waits for the other
  thread. From the switch on, the previous key-frame's maps are never written again (frozen); the key-frame thread
  READS them for eq. 6-9 and for later alignments.
- The key-frame thread PUBLISHES the new :class:`~cnnslam.keyframe.keyframes.Keyframe` through the job's future and
appends
  it to the key-frame list (under a lock); the frame thread makes it the active key-frame and then PUSHES a pose-
  graph job for it, which runs while the frame thread goes on tracking. The pose-graph work is split into small
  jobs (add the key-frame, one alignment per candidate, one optimisation), and initialisation jobs jump the queue,
  so a key-frame switch waits for at most one small job. After the pose-graph job the frame thread PUSHES a fusion
  job for the key-frame it just left (frozen): the model is the key-frame thread's alone; :meth:`finish` fuses the
  last key-frame and re-places every key-frame's surfels at its final pose.
- The pose-graph job WRITES optimised ``T_world_kf`` of every key-frame (atomic attribute swaps); the frame thread
  READS ``T_world_kf`` of its active key-frame to report T_world_cur = T_world_kf T_kf_cur, so reported poses move
  with the graph. Refinement WRITES the active key-frame's ``maps`` (atomic swaps of an immutable record).
- Errors raised in the key-frame thread are re-raised in the frame thread at its next call; :meth:`finish` waits
  for the queue to drain (CLEARS it) and stops the thread.

With ``SystemConfig.threads = False`` every job runs in the caller's thread at the point where it would be pushed,
in the same order: the deterministic mode (same inputs, same bytes). With threads, tracking and refinement of a frame
are identical, but the moment at which a pose-graph optimisation lands (and so the reported world poses and the
candidate key-frames of later alignments) depends on timing.

Tracking loss and recovery
--------------------------
A frame is first tracked from the constant-velocity prediction and, when that fails (or ``motion_model =
"last_pose"``), from the previous frame's pose and from the last tracked pose. If all fail, it is re-tracked against
up to ``recovery_candidates`` other key-frames nearest to the predicted pose (LSD-SLAM re-localises the same way);
success makes that key-frame active again (its depth is refined further). If all fail the frame is reported lost
(``tracked = 0``) with the motion-model prediction as its pose, and the velocity is zeroed: later lost frames hold
that pose rather than extrapolate it. Lost frames neither refine depth nor create key-frames.

The first key-frame is the first frame, at the world origin (T_world_kf = identity).
"""

from __future__ import annotations

import itertools
import queue
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from cnnslam.config import CnnSlamConfig
from cnnslam.depth.depth_prediction import GroundTruthHint, predict_keyframe_depth
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import orthonormalize, se3_inverse
from cnnslam.graph.pose_graph import PoseGraph, PoseGraphEdge, align_keyframes, field_of_view, neighbour_candidates
from cnnslam.keyframe.keyframes import (
    Keyframe,
    KeyframeInit,
    KeyframeMaps,
    WorkingSetBuilder,
    init_cnn_keyframe,
    init_first_keyframe_without_cnn,
    keyframe_score,
    needs_new_keyframe,
    propagate_keyframe,
)
from cnnslam.keyframe.refinement import refine_keyframe, stereo_observation
from cnnslam.model.global_model import GlobalModel
from cnnslam.track.tracking import (
    ImagePyramid,
    TrackingResult,
    affine_brightness,
    build_image_pyramid,
    build_tracking_reference,
    gradient_masks,
    to_gray,
    track_frame,
)
from slamcommon.agent_keys import FRAMES, TRACKED_SHARE


@dataclass(frozen=True)
class FrameResult:
    """What the system answers for one frame.

    T_world_cam: (4, 4) float64 current estimate (T_world_kf T_kf_cur); tracked: False when lost; keyframe: index
    of the key-frame the frame was tracked against (the new one on a switch: its frame IS that key-frame);
    new_keyframe: this frame became a key-frame; good_share, usage: tracking quality (LSD-SLAM); score: key-frame
    score; recovered: tracked only after switching to another key-frame; seconds: wall time per stage.
    """

    T_world_cam: np.ndarray
    tracked: bool
    keyframe: int
    new_keyframe: bool
    good_share: float
    usage: float
    score: float
    recovered: bool
    seconds: dict[str, float]


@dataclass(frozen=True)
class KeyframeOutput:
    """A key-frame as the system finally holds it.

    depth: (H, W) float32 metres refined (0 = none); variance: (H, W) float32 m^2 (inf = none); T_world_kf: (4, 4)
    float64 pose-graph-optimised pose; labels: (H, W) uint8 CNN labels (the argmax of its class probabilities) or
    None without a CNN; label_probs: (H, W, C) float16 CNN class probabilities while the key-frame holds them, i.e.
    with the global model off (with it on, the model holds the fused distributions and the key-frame its labels);
    cnn_depth: (H, W) float32 the CNN depth it was initialised with (None without a CNN); rgb: (H, W, 3) uint8 its
    image. The arrays are read-only views of the system's final arrays, not copies.
    """

    index: int
    timestamp: float
    rgb: np.ndarray
    depth: np.ndarray
    variance: np.ndarray
    T_world_kf: np.ndarray
    labels: np.ndarray | None
    label_probs: np.ndarray | None
    cnn_depth: np.ndarray | None
    parent: int | None


class SlamObserver(Protocol):
    """What the system tells an observer while it runs (LSD-SLAM's ``Output3DWrapper``): a viewer, a logger, a map
    server. Every method is optional (the system calls the ones an observer has); an error raised by one ends the
    run like an error of the system.

    - ``frame(timestamp, T_world_cam, tracked)``: frame thread, after each frame (the pose as answered);
    - ``keyframe_fused(index, T_world_kf, model)``: key-frame thread, after a key-frame was fused into the global
      model (Sec. 3.5); ``model`` is the live :class:`~cnnslam.model.global_model.GlobalModel`: read it there (e.g.
      ``model.snapshot()``), do not keep it for later;
    - ``finished(result)``: at the end, with the :class:`SlamResult`.
    """

    def frame(self, timestamp: float, T_world_cam: np.ndarray, tracked: bool) -> None: ...

    def keyframe_fused(self, index: int, T_world_kf: np.ndarray, model: GlobalModel) -> None: ...

    def finished(self, result: SlamResult) -> None: ...


def _notify(observers: tuple[Any, ...], event: str, *args: Any) -> None:
    for observer in observers:
        callback = getattr(observer, event, None)
        if callback is not None:
            callback(*args)


@dataclass(frozen=True)
class SlamResult:
    """Everything at the end of a sequence.

    timestamps: (N,) float64 s; T_world_cam: (N, 4, 4) float64 final trajectory (each frame re-expressed through
    its key-frame's optimised pose: T_world_kf T_kf_cur); T_world_cam_online: (N, 4, 4) the poses answered frame by
    frame; tracked: (N,) bool; keyframes: list of :class:`KeyframeOutput`; edges: (i, j, kind) of the pose graph;
    stats: JSON-serialisable diagnostics (counts, timings); model: the global model fused live by the key-frame
    thread (:class:`~cnnslam.model.global_model.GlobalModel`, ``global_model.enabled``).
    """

    timestamps: np.ndarray
    T_world_cam: np.ndarray
    T_world_cam_online: np.ndarray
    tracked: np.ndarray
    keyframes: list[KeyframeOutput]
    edges: list[tuple[int, int, str]]
    stats: dict[str, Any] = field(default_factory=dict)
    model: GlobalModel | None = None  # the global model (Sec. 3.5), re-placed at the final poses; None if disabled


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (its data shared, not copied)."""
    view = array.view()
    view.flags.writeable = False
    return view


class _KeyframeWorker:
    """The key-frame thread: a priority queue of jobs (0 = key-frame initialisation, 1 = pose graph), FIFO within a
    priority. With ``threaded=False`` jobs run at once in the caller's thread."""

    def __init__(self, threaded: bool) -> None:
        self.threaded = threaded
        self._queue: queue.PriorityQueue = queue.PriorityQueue()
        self._seq = itertools.count()
        self.error: BaseException | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._thread = threading.Thread(target=self._loop, name="cnnslam-keyframe", daemon=True)
            self._thread.start()

    def submit(self, priority: int, fn: Any, *args: Any) -> Future:
        fut: Future = Future()
        if not self.threaded:
            try:
                fut.set_result(fn(*args))
            except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
                fut.set_exception(exc)
            return fut
        self._queue.put((priority, next(self._seq), (fn, args, fut)))
        return fut

    def _loop(self) -> None:
        while True:
            _, _, item = self._queue.get()
            try:
                if item is None:
                    return
                fn, args, fut = item
                try:
                    fut.set_result(fn(*args))
                except BaseException as exc:  # noqa: BLE001 - re-raised in the frame thread
                    self.error = exc
                    fut.set_exception(exc)
            finally:
                self._queue.task_done()

    def drain(self) -> None:
        """Wait until every queued job has run."""
        if self.threaded:
            self._queue.join()

    def close(self) -> None:
        if self._thread is not None and self._thread.is_alive():
            self._queue.put((99, next(self._seq), None))
            self._thread.join()
        self._thread = None


class CnnSlam:
    """The CNN-SLAM system (see the module docstring for the threads and their hand-over).

    config: :class:`CnnSlamConfig`; intrinsics: [fx, fy, cx, cy] pixels; image_size: (H, W), divisible by
    2^(pyramid_levels - 1); predictor: the depth network (``predict_raw``, ``train_focal``) when
    ``config.depth.source == "cnn"``, else unused; observers: :class:`SlamObserver`-like objects told of every
    frame, every fused key-frame and the end.
    """

    def __init__(self, config: CnnSlamConfig, intrinsics: np.ndarray, image_size: tuple[int, int],
                 predictor: Any = None, observers: tuple[Any, ...] | list[Any] = ()) -> None:
        self.config = config
        self.observers = tuple(observers)  # SlamObserver-like objects
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        if not (np.isfinite(self.intrinsics).all() and self.intrinsics[0] > 0 and self.intrinsics[1] > 0):
            raise CnnSlamError(f"intrinsics must be finite [fx, fy, cx, cy] with fx, fy > 0, got {intrinsics!r}")
        self.image_size = (int(image_size[0]), int(image_size[1]))
        step = 1 << (config.tracking.pyramid_levels - 1)
        if self.image_size[0] % step or self.image_size[1] % step:
            raise CnnSlamError(f"image size {self.image_size} must be divisible by {step} "
                               f"(tracking.pyramid_levels = {config.tracking.pyramid_levels})")
        if config.depth.uses_cnn and predictor is None:
            raise CnnSlamError("depth.source = 'cnn' needs a depth predictor")
        self.predictor = predictor
        self._rng = np.random.default_rng(config.system.seed)
        self._fov = field_of_view(self.intrinsics, self.image_size)
        self._builder = WorkingSetBuilder(self.intrinsics, config.tracking)
        self._worker = _KeyframeWorker(config.system.threads)
        self._graph = PoseGraph()  # owned by the key-frame thread
        self._keyframes: list[Keyframe] = []  # appended by the key-frame thread, read by both (under the lock)
        # depth.prediction_scale_alignment's state, key-frame thread only: each key-frame's log scale and the CNN's
        # log scale at every key-frame, in the first key-frame's units
        self._kf_log_scale: dict[int, float] = {}
        self._cnn_log_scales: list[float] = []
        self._kf_lock = threading.Lock()
        self._graph_futures: list[Future] = []
        # the global model (Sec. 3.5), key-frame thread only: each key-frame is fused once, when it is frozen
        self._model = GlobalModel(config.global_model) if config.global_model.enabled else None
        self._fused: set[int] = set()
        # frame-thread state
        self._active: Keyframe | None = None
        self._prev: tuple[Keyframe, np.ndarray] | None = None  # (key-frame, T_kf_prev) of the last frame
        self._last_good: tuple[Keyframe, np.ndarray] | None = None  # (key-frame, T_kf) of the last tracked frame
        self._velocity = np.eye(4)  # T_prev_cur of the last tracked motion
        # the last tracked frame's affine brightness (log gain, offset) against its key-frame, and that key-frame
        self._affine: tuple[Keyframe | None, tuple[float, float]] = (None, (0.0, 0.0))
        self._frames: list[tuple[float, Keyframe, np.ndarray, bool]] = []  # (timestamp, kf, T_kf_cur, tracked)
        self._online: list[np.ndarray] = []
        self._counters = {"lost": 0, "recovered": 0, "refined_pixels": 0, "observed_pixels": 0,
                          "alignments": 0, "edges_rejected": 0, "optimisations": 0}
        self._seconds = {"tracking": 0.0, "refinement": 0.0, "keyframe_wait": 0.0, "pyramid": 0.0,
                         "keyframe_init": 0.0, "pose_graph": 0.0, "prediction": 0.0, "fusion": 0.0,
                         "tracking_cpu": 0.0}  # the frame thread's CPU seconds in tracking (time.thread_time)
        self._finished = False

    # ------------------------------------------------------------------------------------------------ frame thread

    def process(self, rgb: np.ndarray, timestamp: float, ground_truth: GroundTruthHint | None = None) -> FrameResult:
        """Track one frame (and refine, and maybe switch key-frames). rgb: (H, W, 3) uint8; timestamp: seconds.

        ground_truth: only from agents with ``uses_ground_truth`` (the development predictor, LSD-BS); it is handed
        to the key-frame initialisation of this frame if the frame becomes a key-frame, and used for nothing else.
        """
        if self._finished:
            raise CnnSlamError("process() after finish(); make a new CnnSlam for a new sequence")
        self._raise_worker_error()
        rgb = np.asarray(rgb)
        if rgb.shape[:2] != self.image_size:
            raise CnnSlamError(f"frame of size {rgb.shape[:2]} but the system was made for {self.image_size}")
        t0 = time.perf_counter()
        pyramid = build_image_pyramid(to_gray(rgb), self.intrinsics, self.config.tracking.pyramid_levels)
        seconds = {"pyramid": time.perf_counter() - t0}
        self._seconds["pyramid"] += seconds["pyramid"]
        if self._active is None:
            return self._start(rgb, pyramid, float(timestamp), ground_truth, seconds)

        t0, c0 = time.perf_counter(), time.thread_time()
        active = self._active
        assert self._prev is not None
        T_world_prev = self._prev[0].T_world_kf @ self._prev[1]
        T_world_pred = self._predicted_world_pose()
        result, keyframe, recovered = self._track(pyramid, active, T_world_pred)
        seconds["tracking"] = time.perf_counter() - t0
        self._seconds["tracking"] += seconds["tracking"]
        self._seconds["tracking_cpu"] += time.thread_time() - c0
        if result is None or keyframe is None:  # lost: report the prediction, then hold it (no extrapolation)
            self._counters["lost"] += 1
            T_kf_cur = orthonormalize(se3_inverse(active.T_world_kf) @ T_world_pred)
            self._record(float(timestamp), active, T_kf_cur, False)
            self._prev = (active, T_kf_cur)
            self._velocity = np.eye(4)
            return FrameResult(active.T_world_kf @ T_kf_cur, False, active.index, False, 0.0, 0.0, 0.0, False,
                               seconds)
        if recovered:
            self._counters["recovered"] += 1
            self._active = keyframe
        T_kf_cur = result.T_kf_cur
        T_world_cur = keyframe.T_world_kf @ T_kf_cur
        self._velocity = orthonormalize(se3_inverse(T_world_prev) @ T_world_cur)
        keyframe.frames_tracked += 1
        self._last_good = (keyframe, T_kf_cur)
        self._affine = (keyframe, result.affine)

        if self.config.refinement.enabled:
            t0 = time.perf_counter()
            self._refine(keyframe, pyramid, T_kf_cur, result)
            seconds["refinement"] = time.perf_counter() - t0
            self._seconds["refinement"] += seconds["refinement"]

        score = keyframe_score(T_kf_cur[:3, 3], keyframe.mean_inverse_depth, result.usage, self.config.keyframes)
        new_kf = needs_new_keyframe(score, keyframe.frames_tracked, self.config.keyframes)
        if new_kf:
            t0 = time.perf_counter()
            fut = self._worker.submit(0, self._make_keyframe, rgb, pyramid, float(timestamp), ground_truth,
                                      keyframe, T_kf_cur)
            new = fut.result()  # the frame thread's only wait
            seconds["keyframe_wait"] = time.perf_counter() - t0
            self._seconds["keyframe_wait"] += seconds["keyframe_wait"]
            self._graph_futures.append(self._worker.submit(1, self._update_graph, new, keyframe, T_kf_cur,
                                                           result.hessian))
            if self._model is not None:  # the previous key-frame is frozen from now on: fuse it
                self._graph_futures.append(self._worker.submit(1, self._fuse_keyframe, keyframe))
            self._active = new
            self._release_working_sets()
            keyframe, T_kf_cur = new, np.eye(4)
            self._last_good = (new, T_kf_cur)
        self._record(float(timestamp), keyframe, T_kf_cur, True)
        self._prev = (keyframe, T_kf_cur)
        return FrameResult(keyframe.T_world_kf @ T_kf_cur, True, keyframe.index, new_kf, result.good_share,
                           result.usage, score, recovered, seconds)

    def _start(self, rgb: np.ndarray, pyramid: ImagePyramid, timestamp: float, ground_truth: GroundTruthHint | None,
               seconds: dict[str, float]) -> FrameResult:
        t0 = time.perf_counter()
        first = self._worker.submit(0, self._make_keyframe, rgb, pyramid, timestamp, ground_truth, None, None).result()
        seconds["keyframe_wait"] = time.perf_counter() - t0
        self._seconds["keyframe_wait"] += seconds["keyframe_wait"]
        self._graph_futures.append(self._worker.submit(1, self._update_graph, first, None, None, None))
        self._active = first
        self._record(timestamp, first, np.eye(4), True)
        self._prev = self._last_good = (first, np.eye(4))
        return FrameResult(first.T_world_kf.copy(), True, first.index, True, 1.0, 1.0, 0.0, False, seconds)

    def _predicted_world_pose(self) -> np.ndarray:
        assert self._prev is not None
        kf, T_kf_prev = self._prev
        T_world_prev = kf.T_world_kf @ T_kf_prev
        if self.config.tracking.motion_model == "constant_velocity":
            return T_world_prev @ self._velocity
        return T_world_prev

    def _track(self, pyramid: ImagePyramid, active: Keyframe, T_world_pred: np.ndarray,
               ) -> tuple[TrackingResult | None, Keyframe | None, bool]:
        """Track against the active key-frame from the prediction, then from the last pose, then recover."""
        cfg = self.config.tracking
        assert self._prev is not None
        kf_prev, T_kfprev_prev = self._prev
        T_world_prev = kf_prev.T_world_kf @ T_kfprev_prev
        starts = [T_world_pred]
        if not np.allclose(T_world_pred, T_world_prev):
            starts.append(T_world_prev)
        if self._last_good is not None:
            T_world_good = self._last_good[0].T_world_kf @ self._last_good[1]
            if not any(np.allclose(T_world_good, T) for T in starts):
                starts.append(T_world_good)
        # LSD-SLAM's initialisation phase (no CNN): only divergence counts as lost
        lenient = (not self.config.depth.uses_cnn) and len(self._keyframes) <= cfg.initialization_keyframes
        best: TrackingResult | None = None
        # a frame's brightness is close to the last one's: start from its affine brightness against the same key-frame
        affine = self._affine[1] if self._affine[0] is active else (0.0, 0.0)
        for T_world_start in starts:
            res = track_frame(active.reference, pyramid, se3_inverse(active.T_world_kf) @ T_world_start, cfg,
                              affine_init=affine)
            if res.tracked or (lenient and not res.diverged):
                best = res
                break
        if best is not None:
            return best, active, False
        for cand in self._recovery_candidates(active, T_world_pred):
            for T_world_start in starts:
                res = track_frame(cand.reference, pyramid, se3_inverse(cand.T_world_kf) @ T_world_start, cfg)
                if res.tracked:
                    return res, cand, True
        return None, None, False

    def _recovery_candidates(self, active: Keyframe, T_world_pred: np.ndarray) -> list[Keyframe]:
        n = self.config.tracking.recovery_candidates
        if n == 0:
            return []
        with self._kf_lock:
            others = [k for k in self._keyframes if k is not active]
        pos = T_world_pred[:3, 3]
        view = T_world_pred[:3, 2]
        scored = []
        for k in others:
            dist = float(np.linalg.norm(k.T_world_kf[:3, 3] - pos) * k.mean_inverse_depth)
            angle = float(np.arccos(np.clip(k.T_world_kf[:3, 2] @ view, -1.0, 1.0)))
            scored.append((dist + angle, k.index, k))
        scored.sort(key=lambda s: (s[0], s[1]))
        return [k for _, _, k in scored[:n]]

    def _refine(self, keyframe: Keyframe, pyramid: ImagePyramid, T_kf_cur: np.ndarray, result: TrackingResult) -> None:
        """Eq. 10-11 on the active key-frame with this frame, then publish the new maps (one atomic swap)."""
        cfg = self.config
        maps = keyframe.maps
        image = pyramid.images[0]
        if result.affine != (0.0, 0.0):  # the frame in the key-frame's brightness, as tracking compared it
            image = affine_brightness(image, *result.affine)
        obs = stereo_observation(
            keyframe.pyramid.images[0], keyframe.pyramid.grad_x[0], keyframe.pyramid.grad_y[0], maps.depth,
            maps.variance, image, T_kf_cur, self.intrinsics, cfg.refinement,
            tracking_residual=2.0 * result.mean_energy,
        )
        keep = cfg.depth.uses_cnn or cfg.refinement.density == "dense"
        depth, variance, stats = refine_keyframe(maps.depth, maps.variance, obs, cfg.refinement,
                                                 keep_without_observation=keep)
        self._counters["observed_pixels"] += stats.observed
        self._counters["refined_pixels"] += stats.fused + stats.created
        reference = build_tracking_reference(keyframe.pyramid, depth, variance, cfg.tracking, keyframe.gradient_masks)
        count = maps.stereo_count
        if stats.fused_mask is not None and stats.fused_mask.any():
            count = np.zeros(depth.shape, np.uint16) if count is None else count.copy()
            count[stats.fused_mask & (count < np.iinfo(np.uint16).max)] += 1
        keyframe.set_maps(KeyframeMaps(depth, variance, reference, stereo_count=count))

    def _release_working_sets(self) -> None:
        """Keep the tracking working sets (pyramid, masks, tracking points) of the active key-frame and the
        ``system.working_keyframes`` newest others; the older ones drop theirs, to be made again (same bytes) when
        recovery or an alignment uses them. Frame thread, at a key-frame switch."""
        keep = self.config.system.working_keyframes
        with self._kf_lock:
            old = self._keyframes[: max(0, len(self._keyframes) - 1 - keep)]
        for k in old:
            if k is not self._active and k.working_set_held:
                k.release_working_set()

    def _record(self, timestamp: float, keyframe: Keyframe, T_kf_cur: np.ndarray, tracked: bool) -> None:
        self._frames.append((timestamp, keyframe, np.array(T_kf_cur), tracked))
        self._online.append(keyframe.T_world_kf @ T_kf_cur)
        if self.observers:
            _notify(self.observers, "frame", timestamp, self._online[-1].copy(), tracked)

    def _raise_worker_error(self) -> None:
        if self._worker.error is not None:
            err = self._worker.error
            raise CnnSlamError(f"the key-frame thread failed: {type(err).__name__}: {err}") from err

    # --------------------------------------------------------------------------------------------- key-frame thread

    def _make_keyframe(self, rgb: np.ndarray, pyramid: ImagePyramid, timestamp: float,
                       ground_truth: GroundTruthHint | None, parent: Keyframe | None,
                       T_parent_new: np.ndarray | None) -> Keyframe:
        """Initialise a key-frame from its frame: CNN depth (eq. 5), eq. 6-9 against the parent; or, without a
        CNN, the first key-frame's configured initial depth / the parent's propagated depth."""
        t0 = time.perf_counter()
        cfg = self.config
        label_probs = cnn_depth = None
        if cfg.depth.uses_cnn:
            tp = time.perf_counter()
            pred = predict_keyframe_depth(self.predictor, rgb, self.intrinsics, cfg.depth.focal_adjustment,
                                          ground_truth)
            self._seconds["prediction"] += time.perf_counter() - tp
            label_probs, cnn_depth = pred.label_probs, pred.depth
            if parent is None:
                init = init_cnn_keyframe(pred.depth, self.intrinsics, cfg.depth)
            else:
                parent_maps = parent.maps
                init = init_cnn_keyframe(pred.depth, self.intrinsics, cfg.depth, parent_maps.depth,
                                         parent_maps.variance, T_parent_new,
                                         self._kf_log_scale.get(parent.index, 0.0), self._cnn_log_scales,
                                         parent_maps.stereo_count)
            self._cnn_log_scales.append(init.cnn_log_scale)
        elif parent is None:
            mask = None
            if cfg.refinement.density == "semi_dense":
                gx, gy = pyramid.grad_x[0], pyramid.grad_y[0]
                mask = np.sqrt(gx * gx + gy * gy) >= cfg.refinement.min_gradient_create
            gt_depth = None if ground_truth is None else ground_truth.measured_depth  # LSD-BS: the sensor's depth
            init = init_first_keyframe_without_cnn(self.image_size, cfg.depth, self._rng, mask, gt_depth,
                                                   perturb_last_bits_of_ground_truth=cfg.system.seed > 0)
        else:
            parent_maps = parent.maps
            init = propagate_keyframe(parent_maps.depth, parent_maps.variance, self.intrinsics,
                                      se3_inverse(T_parent_new), cfg.depth)
        keyframe = self._publish(init, rgb, pyramid, timestamp, label_probs, cnn_depth, parent, T_parent_new)
        self._kf_log_scale[keyframe.index] = init.log_scale
        self._seconds["keyframe_init"] += time.perf_counter() - t0
        return keyframe

    def _publish(self, init: KeyframeInit, rgb: np.ndarray, pyramid: ImagePyramid, timestamp: float,
                 label_probs: np.ndarray | None, cnn_depth: np.ndarray | None, parent: Keyframe | None,
                 T_parent_new: np.ndarray | None) -> Keyframe:
        masks = gradient_masks(pyramid, self.config.tracking.min_gradient)
        reference = build_tracking_reference(pyramid, init.depth, init.variance, self.config.tracking, masks)
        T_world_kf = np.eye(4) if parent is None else orthonormalize(parent.T_world_kf @ T_parent_new)
        with self._kf_lock:
            keyframe = Keyframe(len(self._keyframes), timestamp, rgb, pyramid,
                                KeyframeMaps(init.depth, init.variance, reference), T_world_kf, label_probs,
                                cnn_depth, None if parent is None else parent.index, masks, self._builder)
            self._keyframes.append(keyframe)
        return keyframe

    def _fuse_keyframe(self, keyframe: Keyframe) -> None:
        """Sec. 3.5: fuse a frozen key-frame (its refined depth and variance, its image and CNN class probabilities)
        into the global model at its current pose; the model re-places it when the pose graph has moved it
        (:meth:`finish`). Key-frame thread; each key-frame once (a key-frame made active again by recovery keeps
        what it had when it was first frozen)."""
        if self._model is None or keyframe.index in self._fused:
            return
        t0 = time.perf_counter()
        maps = keyframe.maps
        labels = None if keyframe.label_probs is None else keyframe.label_probs.astype(np.float32)
        self._model.integrate(maps.depth, keyframe.T_world_kf, self.intrinsics, keyframe.rgb, labels,
                              maps.variance, anchor=keyframe.index)
        cfg = self.config.global_model
        if cfg.unstable_confidence > 0:  # Keller's removal of unstable points
            self._model.prune(cfg.unstable_confidence, cfg.unstable_age)
        self._fused.add(keyframe.index)
        if not self.config.system.keep_label_probabilities:  # the model holds the distributions now
            keyframe.keep_labels_only()  # 1.8 -> 1.2 MB per key-frame
        self._seconds["fusion"] += time.perf_counter() - t0
        if self.observers:
            _notify(self.observers, "keyframe_fused", keyframe.index, keyframe.T_world_kf.copy(), self._model)

    def _update_graph(self, keyframe: Keyframe, parent: Keyframe | None, T_parent_new: np.ndarray | None,
                      hessian: np.ndarray | None) -> None:
        """Add the key-frame and its sequential edge to the pose graph, then queue one alignment job per candidate
        neighbour and an optimisation job (small jobs, so that a key-frame initialisation never waits long)."""
        t0 = time.perf_counter()
        cfg = self.config
        graph = self._graph
        graph.add_keyframe(keyframe.index, keyframe.T_world_kf)
        if parent is None:
            return
        graph.add_edge(PoseGraphEdge(parent.index, keyframe.index, T_parent_new, hessian, "sequential"))
        if cfg.pose_graph.enabled:
            with self._kf_lock:
                older = [k for k in self._keyframes if k.index < keyframe.index and k.index != parent.index]
            others = {k.index: (graph.poses[k.index], k.mean_inverse_depth) for k in older}
            candidates = neighbour_candidates(graph.poses[keyframe.index], keyframe.mean_inverse_depth, others,
                                              self._fov, cfg.pose_graph)
            self._seconds["pose_graph"] += time.perf_counter() - t0
            for idx in candidates:
                self._worker.submit(1, self._align_candidate, keyframe, idx)
            self._worker.submit(1, self._optimise_graph)
        else:
            self._seconds["pose_graph"] += time.perf_counter() - t0

    def _align_candidate(self, keyframe: Keyframe, idx: int) -> None:
        """Direct alignment of a new key-frame with candidate ``idx``; an edge when both directions agree."""
        t0 = time.perf_counter()
        cfg = self.config
        graph = self._graph
        cand = self._keyframes[idx]
        cand_reference = cand.reference
        kind = "loop" if keyframe.index - idx >= cfg.pose_graph.loop_min_index_gap else "neighbour"
        self._counters["alignments"] += 1
        res = align_keyframes(
            idx, cand_reference, cand.pyramid, 1.0 / cand_reference.mean_inverse_depth,
            keyframe.index, keyframe.reference, keyframe.pyramid,
            se3_inverse(graph.poses[idx]) @ graph.poses[keyframe.index], cfg.tracking, cfg.pose_graph, kind,
        )
        if res.edge is None:
            self._counters["edges_rejected"] += 1
        else:
            graph.add_edge(res.edge)
        self._seconds["pose_graph"] += time.perf_counter() - t0

    def _optimise_graph(self) -> None:
        """Global optimisation; the optimised poses are written to the key-frames (atomic swaps)."""
        t0 = time.perf_counter()
        result = self._graph.optimise(self.config.pose_graph)
        self._counters["optimisations"] += 1
        self._graph.set_poses(result.poses)
        with self._kf_lock:
            for k in self._keyframes:
                if k.index in result.poses:
                    k.T_world_kf = result.poses[k.index].copy()
        self._seconds["pose_graph"] += time.perf_counter() - t0

    # ------------------------------------------------------------------------------------------------------ end

    @property
    def keyframes(self) -> list[Keyframe]:
        """The key-frames so far (a copy of the list; the objects are live)."""
        with self._kf_lock:
            return list(self._keyframes)

    def finish(self) -> SlamResult:
        """Wait for the key-frame thread, stop it, and return the trajectory and the key-frames."""
        if not self._finished:
            self._worker.drain()
            self._worker.close()
            self._finished = True
        self._raise_worker_error()
        for fut in self._graph_futures:
            fut.result()
        all_keyframes = self.keyframes  # final: the key-frame thread has stopped
        if self._model is not None:  # the last key-frames, then every key-frame at its final pose-graph pose
            for k in all_keyframes:
                self._fuse_keyframe(k)
        # the maps are final now: the working sets are no longer needed (released before the model's re-placement,
        # the largest transient of a long episode)
        for k in all_keyframes:
            k.release_working_set()
        if self._model is not None:
            self._model.update_poses({k.index: k.T_world_kf for k in all_keyframes})
        n = len(self._frames)
        stamps = np.array([f[0] for f in self._frames], dtype=np.float64)
        final = np.stack([f[1].T_world_kf @ f[2] for f in self._frames]) if n else np.zeros((0, 4, 4))
        online = np.stack(self._online) if n else np.zeros((0, 4, 4))
        tracked = np.array([f[3] for f in self._frames], dtype=bool)
        # the outputs are read-only views of the final maps, not copies (a long sequence's key-frames would
        # otherwise be held twice at the end)
        keyframes = [
            KeyframeOutput(
                index=k.index, timestamp=k.timestamp, rgb=_read_only(k.rgb), depth=_read_only(k.maps.depth),
                variance=_read_only(k.maps.variance),
                T_world_kf=k.T_world_kf.copy(),
                labels=None if (labels := k.labels) is None else _read_only(labels),
                label_probs=None if k.label_probs is None else _read_only(k.label_probs),
                cnn_depth=None if k.cnn_depth is None else _read_only(k.cnn_depth), parent=k.parent,
            )
            for k in all_keyframes
        ]
        edges = [(e.i, e.j, e.kind) for e in self._graph.edges]
        stats: dict[str, Any] = {
            FRAMES: n,
            TRACKED_SHARE: float(tracked.mean()) if n else 0.0,
            "keyframes": len(keyframes),
            "edges": len(edges),
            "loop_edges": sum(1 for e in edges if e[2] == "loop"),
            "neighbour_edges": sum(1 for e in edges if e[2] == "neighbour"),
            **self._counters,
            "seconds": dict(self._seconds),
            "threads": self.config.system.threads,
        }
        if self._model is not None:
            stats["model_surfels"] = len(self._model)
        result = SlamResult(stamps, final, online, tracked, keyframes, edges, stats, self._model)
        _notify(self.observers, "finished", result)
        return result

    def close(self) -> None:
        """Stop the key-frame thread without collecting results (idempotent)."""
        self._worker.close()
        self._finished = True

    def __del__(self) -> None:
        worker = getattr(self, "_worker", None)
        if worker is not None and worker._thread is not None:
            worker.close()

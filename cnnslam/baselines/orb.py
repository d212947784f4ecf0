"""ORB-SLAM (Mur-Artal et al. 2015, the paper's [20]) as a baseline agent: feature-based monocular SLAM with OpenCV.

``"cnnslam.baselines.orb:OrbSlamAgent"``; keyword arguments (all optional)::

    OrbSlamAgent(config={"n_features": 1000, ...},   # OrbConfig field overrides (cnnslam.baselines.orb_config)
                 seed=0)                              # RANSAC's draws (0: unseeded order; same seed, same bytes)

What it does per frame (one thread; ORB-SLAM's local mapping runs synchronously after each new key-frame):

- ORB features distributed over a grid (:mod:`~cnnslam.baselines.orb_features`).
- Not initialised: matches against a reference frame in a window around each keypoint's last match; when an
  essential matrix or homography with enough parallax explains them, the first two key-frames and their points are
  created (:mod:`~cnnslam.baselines.orb_init`), refined by bundle adjustment, and the map is scaled so that the
  first key-frame's median depth is 1: the map has NO absolute scale. The world frame is the first key-frame's
  camera. With too little parallax (a pure rotation) it never initialises, as ORB-SLAM on TUM fr1/rpy (CNN-SLAM
  Sec. 4.2). Until then every frame reports the identity pose with ``tracked = 0``.
- Tracking: the constant-velocity prediction projects the last frame's points (ORB: TrackWithMotionModel), or
  descriptor matches against the reference key-frame (TrackReferenceKeyFrame); motion-only bundle adjustment;
  then the local map (points of the key-frames sharing points with the frame and their covisible key-frames) is
  projected and matched and the pose optimised again (TrackLocalMap). Tracked with at least 30 inliers.
- Key-frames when the frame tracks fewer than 90 % of the reference key-frame's points (ORB, monocular) and at least
  ``keyframe_min_frames`` frames passed since the last one (ours: ORB waits for an idle local mapping), then local
  mapping (:mod:`~cnnslam.baselines.orb_mapping`): point culling, triangulation with covisible key-frames, fusion of
  duplicates, local bundle adjustment (:func:`~cnnslam.baselines.orb_ba.bundle_adjust`), key-frame culling.
- Lost: ``tracked = 0`` and the last tracked pose. It re-localises against the key-frames that share most
  descriptors with the frame (PnP RANSAC, ``cv2.solvePnPRansac``, then the local map); a map of at most 5
  key-frames is reset instead and initialisation starts again from scratch: the new map has its own world frame and
  scale (ORB-SLAM does the same), counted in ``extras["resets"]``.

``finish()`` returns every remaining key-frame with a SPARSE depth map: 0 everywhere except at the keypoints that
observe a map point, where it is that point's depth in the key-frame's camera (map units, nearest point per pixel),
as the paper scores ORB-SLAM's key-frames. No loop closing and no pose-graph optimisation (ORB-SLAM's third
thread); no bag-of-words vocabulary (descriptor votes instead).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np

from cnnslam.baselines.base import BaselineAgent
from cnnslam.baselines.orb_ba import optimize_pose
from cnnslam.baselines.orb_config import OrbConfig
from cnnslam.baselines.orb_features import (
    Features,
    extract_features,
    level_inv_sigma,
    make_orb,
    match_descriptors,
    match_in_windows,
    to_gray,
)
from cnnslam.baselines.orb_init import initialize_two_view, ransac_order
from cnnslam.baselines.orb_map import KeyFrame, SparseMap
from cnnslam.baselines.orb_mapping import (
    cull_keyframes,
    cull_recent_points,
    local_bundle_adjustment,
    median_depth,
    search_in_neighbours,
    triangulate_new_points,
    visible_points,
)
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import intrinsics_matrix, orthonormalize, se3_inverse
from slamcommon.config import configure

TrackingState = Literal["not_initialized", "ok", "lost"]
LOCAL_MAP_MAX_KEYFRAMES: int = 80  # ORB UpdateLocalKeyFrames: at most 80 local key-frames
MIN_POSE_INLIERS: int = 10  # ORB: a pose optimisation with fewer inliers is a failure
REF_RATIO_TWO_KEYFRAMES: float = 0.4  # ORB NeedNewKeyFrame: thRefRatio with only one key-frame (monocular: 0.9 else)
WIDE_VIEW_RADIUS: float = 1.6  # ORB RadiusByViewingCos: 4.0 / 2.5 when the view is not frontal (cos <= 0.998)


@dataclass(frozen=True)
class OrbFrameResult:
    """What the system answers for one frame.

    T_world_cam: (4, 4) float64 camera-to-world in the map's frame and units (identity before initialisation, the
    last tracked pose when lost); tracked: True when tracking succeeded; state: after this frame; n_inliers: pose
    inliers; new_keyframe: this frame became a key-frame; seconds: wall time of the frame.
    """

    T_world_cam: np.ndarray
    tracked: bool
    state: TrackingState
    n_inliers: int
    new_keyframe: bool
    seconds: float


@dataclass
class _Frame:
    index: int
    timestamp: float
    features: Features
    T_cam_world: np.ndarray | None = None
    point_ids: np.ndarray | None = None  # (N,) matched map point per keypoint (-1 none)


class OrbSlam:
    """The ORB-SLAM system; see the module docstring. intrinsics: [fx, fy, cx, cy] pixels; image_size: (H, W)."""

    def __init__(self, intrinsics: np.ndarray, image_size: tuple[int, int], config: OrbConfig | None = None,
                 seed: int = 0) -> None:
        self.config = config or OrbConfig()
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        if not (np.isfinite(self.intrinsics).all() and self.intrinsics[0] > 0 and self.intrinsics[1] > 0):
            raise CnnSlamError(f"intrinsics must be finite [fx, fy, cx, cy] with fx, fy > 0, got {intrinsics!r}")
        self.K = intrinsics_matrix(self.intrinsics)
        self.image_size = (int(image_size[0]), int(image_size[1]))
        # seed 0: the matches in their own order (the bytes of an unseeded run); s > 0: RANSAC's inputs permuted
        self._rng = np.random.default_rng(seed) if seed else None
        self._orb = make_orb(self.config)
        self.map = SparseMap(self.config.scale_factor, self.config.n_levels)
        self.state: TrackingState = "not_initialized"
        self._n = 0
        self._init_ref: _Frame | None = None
        self._init_prev_uv: np.ndarray | None = None
        self._last: _Frame | None = None
        self._velocity: np.ndarray | None = None  # T_cur_last of the last tracked motion (camera frames)
        self._ref_kf: KeyFrame | None = None
        self._last_kf_frame = -1
        self._last_reloc_frame = -(10**9)
        self._anchor_id = 0
        self._recent_points: list[int] = []
        self._last_T_world_cam = np.eye(4)
        self._db: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # relocalisation descriptors (kf, kp, desc)
        self.frame_refs: list[tuple[KeyFrame, np.ndarray] | None] = []  # per frame: (ref key-frame, T_cam_ref)
        self.counters = {"resets": 0, "relocalisations": 0, "lost_frames": 0, "keyframes_created": 0,
                         "keyframes_culled": 0, "init_attempts": 0, "fused": 0, "ba_outliers": 0}
        self.init_frame: int | None = None
        self.last_init_failure = ""
        self.seconds = {"features": 0.0, "tracking": 0.0, "mapping": 0.0, "initialisation": 0.0}

    # ---------------------------------------------------------------------------------------------------- per frame

    def process(self, rgb: np.ndarray, timestamp: float) -> OrbFrameResult:
        """Process one (H, W, 3) uint8 frame taken at ``timestamp`` seconds."""
        t_start = time.perf_counter()
        if np.asarray(rgb).shape[:2] != self.image_size:
            raise CnnSlamError(f"frame of size {np.asarray(rgb).shape[:2]} but the system was made for "
                               f"{self.image_size}")
        t0 = time.perf_counter()
        frame = _Frame(self._n, float(timestamp), extract_features(to_gray(rgb), self._orb, self.config))
        self.seconds["features"] += time.perf_counter() - t0
        self._n += 1
        new_kf = False
        if self.state == "not_initialized":
            t0 = time.perf_counter()
            tracked = self._initialise(frame)
            self.seconds["initialisation"] += time.perf_counter() - t0
        else:
            tracked, new_kf = self._track(frame)
        if tracked:
            assert frame.T_cam_world is not None
            self._last_T_world_cam = se3_inverse(frame.T_cam_world)
            assert self._ref_kf is not None
            self.frame_refs.append((self._ref_kf, frame.T_cam_world @ self._ref_kf.T_world_cam))
        else:
            self.frame_refs.append(None)
        n_inl = 0 if frame.point_ids is None else int((frame.point_ids >= 0).sum())
        return OrbFrameResult(self._last_T_world_cam.copy(), tracked, self.state, n_inl, new_kf,
                              time.perf_counter() - t_start)

    # ---------------------------------------------------------------------------------------------- initialisation

    def _initialise(self, frame: _Frame) -> bool:
        cfg = self.config
        if self._init_ref is None or len(self._init_ref.features) < cfg.init_min_matches:
            self._set_init_reference(frame)
            return False
        ref = self._init_ref
        assert self._init_prev_uv is not None
        pairs = match_in_windows(self._init_prev_uv, ref.features.descriptors, frame.features.uv,
                                 frame.features.descriptors, cfg.init_window_px, cfg.th_low, cfg.ratio_init)
        if len(pairs) < cfg.init_min_matches:
            self.last_init_failure = f"{len(pairs)} matches with the reference frame < {cfg.init_min_matches}"
            self._set_init_reference(frame)
            return False
        self._init_prev_uv[pairs[:, 0]] = frame.features.uv[pairs[:, 1]]
        self.counters["init_attempts"] += 1
        res = initialize_two_view(ref.features.uv[pairs[:, 0]], frame.features.uv[pairs[:, 1]], self.K, cfg,
                                  self._rng, level_inv_sigma(ref.features.octave[pairs[:, 0]], cfg.scale_factor),
                                  level_inv_sigma(frame.features.octave[pairs[:, 1]], cfg.scale_factor))
        if not res.success:
            self.last_init_failure = res.reason
            return False
        m = self.map
        kf0 = m.new_keyframe(ref.index, ref.timestamp, np.eye(4), ref.features)
        kf1 = m.new_keyframe(frame.index, frame.timestamp, res.T_cur_ref, frame.features)
        used = pairs[res.match_index]
        m.add_points(res.points_ref, kf0, used[:, 0], kf1, used[:, 1])
        self._anchor_id = kf0.id
        local_bundle_adjustment(m, kf1, self.intrinsics, cfg, anchor_id=kf0.id)
        depth = median_depth(m, kf0)
        n_pts = int((~m.bad[kf1.tracked_points()]).sum())
        if not np.isfinite(depth) or depth <= 0 or n_pts < cfg.init_min_points:
            self.last_init_failure = f"{n_pts} points after the initial bundle adjustment < {cfg.init_min_points}"
            self._reset_map()
            self._set_init_reference(frame)
            return False
        s = 1.0 / depth  # ORB: median depth of the first key-frame = 1
        kf1.T_cam_world[:3, 3] *= s
        m.positions *= s
        m.update_points(m.good_point_ids())
        self.state = "ok"
        self.init_frame = frame.index
        self.last_init_failure = ""
        self._ref_kf = kf1
        self._last_kf_frame = frame.index
        self._velocity = None
        frame.T_cam_world = kf1.T_cam_world.copy()
        frame.point_ids = kf1.point_ids.copy()
        self._last = frame
        self._recent_points = list(m.good_point_ids())
        self._init_ref = None
        self._db = None
        return True

    def _set_init_reference(self, frame: _Frame) -> None:
        self._init_ref = frame
        self._init_prev_uv = frame.features.uv.copy()

    def _reset_map(self) -> None:
        self.map = SparseMap(self.config.scale_factor, self.config.n_levels)
        self.state = "not_initialized"
        self._init_ref = None
        self._last = None
        self._velocity = None
        self._ref_kf = None
        self._recent_points = []
        self._db = None

    # ----------------------------------------------------------------------------------------------------- tracking

    def _track(self, frame: _Frame) -> tuple[bool, bool]:
        cfg = self.config
        t0 = time.perf_counter()
        ok = False
        was_lost = self.state == "lost"
        if self.state == "ok":
            ok = self._track_motion_model(frame) if self._velocity is not None else False
            if not ok:
                ok = self._track_reference_keyframe(frame)
        else:
            ok = self._relocalise(frame)
            if ok:
                self.counters["relocalisations"] += 1
                self._last_reloc_frame = frame.index
        if ok:
            ok = self._track_local_map(frame)
        self.seconds["tracking"] += time.perf_counter() - t0
        if not ok:
            self.counters["lost_frames"] += 1
            self.state = "lost"
            frame.point_ids = None
            if len(self.map.good_keyframes()) <= cfg.reset_if_lost_with_keyframes:
                self.counters["resets"] += 1
                self._reset_map()
                self._set_init_reference(frame)
            return False, False
        self.state = "ok"
        assert self._last is not None and self._last.T_cam_world is not None and frame.T_cam_world is not None
        self._velocity = None if was_lost else frame.T_cam_world @ se3_inverse(self._last.T_cam_world)
        self._last = frame
        new_kf = False
        if self._need_keyframe(frame):
            t1 = time.perf_counter()
            self._create_keyframe(frame)
            self.seconds["mapping"] += time.perf_counter() - t1
            new_kf = True
        return True, new_kf

    def _pose_from_matches(self, frame: _Frame, T_init: np.ndarray, kp: np.ndarray, pids: np.ndarray) -> bool:
        """Motion-only bundle adjustment from ``T_init`` with keypoints ``kp`` matched to points ``pids``; on
        success sets the frame's pose and inlier matches."""
        f = frame.features
        T, inl = optimize_pose(T_init, self.map.positions[pids], f.uv[kp], level_inv_sigma(f.octave[kp],
                               self.config.scale_factor), self.intrinsics, self.config.pose_rounds,
                               self.config.pose_iterations)
        if inl.sum() < MIN_POSE_INLIERS:
            return False
        frame.T_cam_world = orthonormalize(T)
        frame.point_ids = np.full(len(f), -1, np.int64)
        frame.point_ids[kp[inl]] = pids[inl]
        return True

    def _track_motion_model(self, frame: _Frame) -> bool:
        cfg = self.config
        last = self._last
        assert last is not None and last.T_cam_world is not None and last.point_ids is not None
        assert self._velocity is not None
        T_pred = self._velocity @ last.T_cam_world
        pids = np.unique(last.point_ids[last.point_ids >= 0])
        pids = pids[~self.map.bad[pids]]
        vis = visible_points(self.map, pids, T_pred, self.intrinsics, self.image_size)
        f = frame.features
        for factor in (1.0, 2.0):  # ORB: a second search with twice the radius when too few matches
            radius = factor * cfg.motion_radius_px * cfg.scale_factor ** vis.octave
            pairs = match_in_windows(vis.uv, self.map.descriptors[vis.ids], f.uv, f.descriptors, radius,
                                     cfg.th_high, cfg.ratio_projection)
            if len(pairs) >= cfg.min_motion_matches:
                break
        if len(pairs) < cfg.min_motion_matches:
            return False
        return self._pose_from_matches(frame, T_pred, pairs[:, 1], vis.ids[pairs[:, 0]])

    def _track_reference_keyframe(self, frame: _Frame) -> bool:
        cfg = self.config
        kf = self._ref_kf
        last = self._last
        assert kf is not None and last is not None and last.T_cam_world is not None
        kps = np.flatnonzero(kf.point_ids >= 0)
        kps = kps[~self.map.bad[kf.point_ids[kps]]]
        pairs = match_descriptors(frame.features.descriptors, kf.features.descriptors[kps], cfg.th_low, 0.7)
        if len(pairs) < cfg.min_reference_matches:
            return False
        return self._pose_from_matches(frame, last.T_cam_world, pairs[:, 0], kf.point_ids[kps[pairs[:, 1]]])

    def _local_keyframes(self, frame: _Frame) -> list[KeyFrame]:
        """ORB UpdateLocalKeyFrames: key-frames observing the frame's points, then their best covisible ones; the
        one sharing most points becomes the reference key-frame."""
        m = self.map
        assert frame.point_ids is not None
        counts: dict[int, int] = {}
        for pid in frame.point_ids[frame.point_ids >= 0]:
            for k in m.observations[pid]:
                counts[k] = counts.get(k, 0) + 1
        first = [m.keyframes[k] for _, k in sorted((-c, k) for k, c in counts.items()) if not m.keyframes[k].bad]
        if not first:
            return []
        self._ref_kf = first[0]
        local = {k.id: k for k in first[:LOCAL_MAP_MAX_KEYFRAMES]}
        for kf in first:
            if len(local) >= LOCAL_MAP_MAX_KEYFRAMES:
                break
            for nb in m.best_covisible(kf, 10):
                local.setdefault(nb.id, nb)
        return list(local.values())

    def _track_local_map(self, frame: _Frame) -> bool:
        cfg = self.config
        m = self.map
        assert frame.T_cam_world is not None and frame.point_ids is not None
        local = self._local_keyframes(frame)
        pts = m.points_of(local)
        already = frame.point_ids[frame.point_ids >= 0]
        vis = visible_points(m, pts, frame.T_cam_world, self.intrinsics, self.image_size)
        m.n_visible[vis.ids] += 1
        todo = ~np.isin(vis.ids, already)
        f = frame.features
        if todo.any():
            radius = (cfg.local_radius_px * np.where(vis.view_cos[todo] > 0.998, 1.0, WIDE_VIEW_RADIUS)
                      * cfg.scale_factor ** vis.octave[todo])
            free = frame.point_ids < 0
            pairs = match_in_windows(vis.uv[todo], m.descriptors[vis.ids[todo]], f.uv, f.descriptors, radius,
                                     cfg.th_high, cfg.ratio_projection, candidates_b=free)
            frame.point_ids[pairs[:, 1]] = vis.ids[todo][pairs[:, 0]]
        kp = np.flatnonzero(frame.point_ids >= 0)
        pids = frame.point_ids[kp]
        if not self._pose_from_matches(frame, frame.T_cam_world, kp, pids):
            return False
        inl = frame.point_ids[frame.point_ids >= 0]
        m.n_found[inl] += 1
        needed = cfg.min_tracked_inliers
        if frame.index < self._last_reloc_frame + cfg.keyframe_max_frames:
            needed = cfg.min_relocalised_inliers
        return len(inl) >= needed

    # ------------------------------------------------------------------------------------------------ relocalisation

    def _relocalisation_db(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._db is None:
            kf_ids, kps, descs = [], [], []
            for kf in self.map.good_keyframes():
                idx = np.flatnonzero(kf.point_ids >= 0)
                idx = idx[~self.map.bad[kf.point_ids[idx]]]
                kf_ids.append(np.full(idx.size, kf.id, np.int64))
                kps.append(idx)
                descs.append(kf.features.descriptors[idx])
            self._db = (np.concatenate(kf_ids), np.concatenate(kps), np.concatenate(descs))
        return self._db

    def _relocalise(self, frame: _Frame) -> bool:
        """Descriptor votes pick candidate key-frames; PnP RANSAC and motion-only BA against each (ORB-SLAM's
        Relocalization with its bag-of-words candidates replaced by the votes)."""
        cfg = self.config
        kf_ids, _, descs = self._relocalisation_db()
        f = frame.features
        if len(f) == 0 or len(descs) == 0:
            return False
        matches = cv2.BFMatcher(cv2.NORM_HAMMING).match(f.descriptors, descs)
        close = [mt.trainIdx for mt in matches if mt.distance <= cfg.th_low]
        if not close:
            return False
        votes = np.bincount(kf_ids[np.asarray(close)])
        candidates = np.argsort(-votes, kind="stable")[: cfg.relocalisation_candidates]
        for kf_id in candidates:
            if votes[kf_id] < cfg.min_reference_matches:
                break
            kf = self.map.keyframes[int(kf_id)]
            kps = np.flatnonzero(kf.point_ids >= 0)
            kps = kps[~self.map.bad[kf.point_ids[kps]]]
            pairs = match_descriptors(f.descriptors, kf.features.descriptors[kps], cfg.th_low, 0.75)
            if len(pairs) < cfg.min_reference_matches:
                continue
            order = ransac_order(len(pairs), self._rng)
            pairs = pairs[order]
            pids = kf.point_ids[kps[pairs[:, 1]]]
            obj = self.map.positions[pids]
            img = f.uv[pairs[:, 0]]
            ok, rvec, tvec, inliers = cv2.solvePnPRansac(
                obj, img, self.K, None, iterationsCount=cfg.pnp_iterations,
                reprojectionError=cfg.pnp_reprojection_px, confidence=0.99, flags=cv2.SOLVEPNP_EPNP)
            if not ok or inliers is None or len(inliers) < MIN_POSE_INLIERS:
                continue
            T = np.eye(4)
            T[:3, :3] = cv2.Rodrigues(rvec)[0]
            T[:3, 3] = tvec.reshape(3)
            inl = inliers.reshape(-1)
            if self._pose_from_matches(frame, T, pairs[inl, 0], pids[inl]):
                self._ref_kf = kf
                return True
        return False

    # ---------------------------------------------------------------------------------------------------- key-frames

    def _need_keyframe(self, frame: _Frame) -> bool:
        """ORB NeedNewKeyFrame (monocular) with our minimum gap (see OrbConfig.keyframe_min_frames)."""
        cfg = self.config
        m = self.map
        kf = self._ref_kf
        assert kf is not None and frame.point_ids is not None
        n_kfs = len(m.good_keyframes())
        if frame.index < self._last_reloc_frame + cfg.keyframe_max_frames and n_kfs > cfg.keyframe_max_frames:
            return False
        min_obs = 3 if n_kfs > 2 else 2
        ref_pts = kf.tracked_points()
        ref_pts = ref_pts[~m.bad[ref_pts]]
        n_ref = sum(1 for p in ref_pts if len(m.observations[p]) >= min_obs)
        inliers = int((frame.point_ids >= 0).sum())
        ratio = REF_RATIO_TWO_KEYFRAMES if n_kfs < 2 else cfg.keyframe_ref_ratio
        since = frame.index - self._last_kf_frame
        c1 = since >= cfg.keyframe_max_frames or since >= cfg.keyframe_min_frames
        c2 = inliers < ratio * n_ref and inliers > cfg.min_reference_matches
        return bool(c1 and c2)

    def _create_keyframe(self, frame: _Frame) -> None:
        cfg = self.config
        m = self.map
        assert frame.T_cam_world is not None and frame.point_ids is not None
        kf = m.new_keyframe(frame.index, frame.timestamp, frame.T_cam_world, frame.features)
        for kp in np.flatnonzero(frame.point_ids >= 0):
            pid = int(frame.point_ids[kp])
            if not m.bad[pid]:
                m.add_observation(pid, kf, int(kp))
        m.update_points(m.points_of([kf]))
        self.counters["keyframes_created"] += 1
        self._recent_points = cull_recent_points(m, self._recent_points, kf.id, cfg)
        new = triangulate_new_points(m, kf, self.intrinsics, cfg)
        self._recent_points.extend(int(p) for p in new)
        self.counters["fused"] += search_in_neighbours(m, kf, self.intrinsics, self.image_size, cfg)
        stats = local_bundle_adjustment(m, kf, self.intrinsics, cfg, anchor_id=self._anchor_id)
        self.counters["ba_outliers"] += stats.n_outliers
        self.counters["keyframes_culled"] += cull_keyframes(m, kf, cfg, protected={self._anchor_id, kf.id})
        self._ref_kf = kf
        self._last_kf_frame = frame.index
        self._db = None
        frame.T_cam_world = kf.T_cam_world.copy()
        frame.point_ids = np.where(kf.point_ids >= 0, kf.point_ids, -1)
        frame.point_ids[frame.point_ids >= 0] = np.where(m.bad[frame.point_ids[frame.point_ids >= 0]], -1,
                                                         frame.point_ids[frame.point_ids >= 0])

    # ---------------------------------------------------------------------------------------------------- output

    def keyframe_depth(self, kf: KeyFrame) -> np.ndarray:
        """(H, W) float32 sparse depth of a key-frame: at the (rounded) pixel of each keypoint observing a good map
        point, that point's camera depth (map units; the nearest where several fall on one pixel); 0 elsewhere."""
        h, w = self.image_size
        depth = np.zeros((h, w), np.float32)
        kps = np.flatnonzero(kf.point_ids >= 0)
        kps = kps[~self.map.bad[kf.point_ids[kps]]]
        if kps.size == 0:
            return depth
        X = self.map.positions[kf.point_ids[kps]]
        z = X @ kf.T_cam_world[2, :3] + kf.T_cam_world[2, 3]
        uv = np.rint(kf.features.uv[kps]).astype(np.int64)
        ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        z, uv = z[ok], uv[ok]
        order = np.argsort(-z, kind="stable")  # far first, so that the nearest is written last
        depth[uv[order, 1], uv[order, 0]] = z[order].astype(np.float32)
        return depth

    def final_trajectory(self, online: np.ndarray) -> np.ndarray:
        """(N, 4, 4) camera-to-world poses with each tracked frame re-expressed through its reference key-frame's
        final pose (ORB-SLAM's saved trajectory); frames without a living reference keep ``online``'s pose."""
        out = np.array(online, dtype=np.float64)
        for i, ref in enumerate(self.frame_refs):
            if ref is None:
                continue
            kf, T_cam_ref = ref
            if not kf.bad and self.map.keyframes.get(kf.id) is kf:
                out[i] = se3_inverse(T_cam_ref @ kf.T_cam_world)
        return out


class OrbSlamAgent(BaselineAgent):
    """ORB-SLAM as a ``sim_envs`` agent (see the module docstring for what it does and the arguments)."""

    uses_ground_truth = False
    name = "orb_slam"

    def __init__(self, config: OrbConfig | dict[str, Any] | None = None, seed: int = 0) -> None:
        super().__init__()
        self.config = configure(OrbConfig(), config)
        self.seed = int(seed)
        self.system: OrbSlam | None = None
        self._seconds: list[float] = []

    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        self.system = OrbSlam(intrinsics, image_size, self.config, self.seed)
        self._seconds = []

    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        assert self.system is not None  # the base calls _track after _start only
        out = self.system.process(observation["rgb"], timestamp)
        self._seconds.append(out.seconds)
        return out.T_world_cam, out.tracked

    def _finish(self) -> Any:
        """An ``AgentOutput``: every key-frame with its sparse map-point depth (map units) and final pose."""
        from sim_envs.agent import AgentOutput, KeyframeDepth

        assert self.system is not None
        sys_ = self.system
        keyframes = [
            KeyframeDepth(timestamp=kf.timestamp, depth=sys_.keyframe_depth(kf), T_world_cam=kf.T_world_cam)
            for kf in sys_.map.good_keyframes()
        ]
        n = len(self._tracked)
        secs = np.asarray(self._seconds)
        extras: dict[str, Any] = {
            **self.episode_extras(),
            "keyframes": len(keyframes),
            "landmarks": int((~sys_.map.bad).sum()),  # the good points of its own map
            "init_frame": sys_.init_frame,
            "last_init_failure": sys_.last_init_failure,
            "state": sys_.state,
            **sys_.counters,
            "seconds": dict(sys_.seconds),
            "mean_step_seconds": float(secs.mean()) if n else 0.0,
            "fps": float(n / secs.sum()) if n and secs.sum() > 0 else 0.0,
            "config": self.config.to_dict(),
            "seed": self.seed,
        }
        return AgentOutput(keyframes=keyframes, extras=extras)

    def final_trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """(timestamps (N,), T_world_cam (N, 4, 4)): every tracked frame through its reference key-frame's final
        pose (after the episode; the online answers are what the driver recorded)."""
        if self.system is None or not self._started:
            raise CnnSlamError("final_trajectory() before reset()")
        online = np.stack(self._poses) if self._poses else np.zeros((0, 4, 4))
        return np.asarray(self._timestamps), self.system.final_trajectory(online)

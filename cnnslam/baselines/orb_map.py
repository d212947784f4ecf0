"""The sparse map of the ORB-SLAM baseline: key-frames and map points with their observations (ORB-SLAM's ``Map``,
``KeyFrame``, ``MapPoint``).

A key-frame holds its ORB features, its extrinsics ``T_cam_world`` (world -> camera, ORB-SLAM's Tcw; the project's
``T_world_cam`` is its inverse) and, per keypoint, the id of the map point it observes (-1 = none). A map point holds
its world position (map units: the monocular map has no absolute scale), a representative descriptor (the
observation descriptor with the least median distance to the others, ORB-SLAM's ComputeDistinctiveDescriptors), its
mean viewing direction and the distance range over which ORB can detect it (ORB-SLAM's scale invariance region),
its observations ``{key-frame id: keypoint index}`` and the counters of map-point culling (frames in which it was
predicted visible / actually found). Points and key-frames are never deleted, only flagged bad.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from itertools import chain

import numpy as np
from numba import njit

from cnnslam.baselines.orb_features import Features, popcount64
from cnnslam.geometry import se3_inverse


@dataclass
class KeyFrame:
    """A key-frame. features: its ORB features (N of them); point_ids: (N,) int64 map point per keypoint (-1 none);
    T_cam_world: (4, 4) float64 world -> camera (written by bundle adjustment)."""

    id: int
    frame_index: int
    timestamp: float
    T_cam_world: np.ndarray
    features: Features
    point_ids: np.ndarray
    bad: bool = False

    @property
    def T_world_cam(self) -> np.ndarray:
        """(4, 4) camera -> world."""
        return se3_inverse(self.T_cam_world)

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates."""
        return -self.T_cam_world[:3, :3].T @ self.T_cam_world[:3, 3]

    def tracked_points(self) -> np.ndarray:
        """Ids of the (not necessarily good) map points it observes."""
        return self.point_ids[self.point_ids >= 0]


@njit(cache=True, nogil=True)
def _point_summaries(counts, slot, keyframe, octave, words, centers, X, first_kf, levels,
                     descriptors):  # pragma: no cover - compiled
    """Per point (its observations in consecutive rows): the mean unit viewing ray (normalised), the far end of
    its scale-invariance range (distance from the reference key-frame, the creating one if it still observes the
    point, else the first, times the scale of the observing level) and the row of its representative descriptor
    (least median Hamming distance to the point's others; the first for 2 or fewer)."""
    P = counts.shape[0]
    normals = np.zeros((P, 3))
    max_distance = np.zeros(P)
    best = np.zeros(P, np.int64)
    start = 0
    for p in range(P):
        n = counts[p]
        mx, my, mz = 0.0, 0.0, 0.0
        ref, found = start, False
        for r in range(start, start + n):
            c = slot[r]
            rx, ry, rz = X[p, 0] - centers[c, 0], X[p, 1] - centers[c, 1], X[p, 2] - centers[c, 2]
            norm = max(math.sqrt(rx * rx + ry * ry + rz * rz), 1e-12)
            mx += rx / norm
            my += ry / norm
            mz += rz / norm
            if not found and keyframe[r] == first_kf[p]:
                ref, found = r, True
        norm = max(math.sqrt(mx * mx + my * my + mz * mz), 1e-12)
        normals[p, 0], normals[p, 1], normals[p, 2] = mx / norm, my / norm, mz / norm
        c = slot[ref]
        dx, dy, dz = X[p, 0] - centers[c, 0], X[p, 1] - centers[c, 1], X[p, 2] - centers[c, 2]
        max_distance[p] = math.sqrt(dx * dx + dy * dy + dz * dz) * levels[octave[ref]]
        best[p] = start
        if descriptors and n > 2:
            d = np.empty(n)
            best_median = np.inf
            for i in range(n):
                for j in range(n):
                    h = 0
                    for w in range(4):
                        h += popcount64(words[start + i, w] ^ words[start + j, w])
                    d[j] = h
                d.sort()
                median = d[n // 2] if n % 2 else (d[n // 2 - 1] + d[n // 2]) / 2.0
                if median < best_median:
                    best_median = median
                    best[p] = start + i
        start += n
    return normals, max_distance, best


@dataclass(frozen=True)
class FlatObservations:
    """Observations of some map points, flattened (:meth:`SparseMap.flat_observations`).

    counts: (P,) observations of each point; keyframe, keypoint, octave: (O,) int64 of each observation, the
    points' observations one after another; uv: (O, 2) the observing keypoints' pixels; descriptors: (O, 32) uint8
    of the observing keypoints, or None; keyframe_ids: the sorted distinct key-frames, slot: (O,) each
    observation's index into them.
    """

    counts: np.ndarray
    keyframe: np.ndarray
    keypoint: np.ndarray
    octave: np.ndarray
    uv: np.ndarray
    descriptors: np.ndarray | None
    keyframe_ids: np.ndarray
    slot: np.ndarray


class _KeypointStore:
    """The keypoints of every key-frame in creation order, in arrays grown by doubling: key-frame ``k``'s keypoint
    ``i`` is row ``start[k] + i`` of ``octave`` (int64), ``uv`` ((.., 2) float64 pixels) and ``descriptors`` ((.., 32)
    uint8). The views it hands out cover only the filled rows."""

    def __init__(self) -> None:
        self._start = np.zeros(16, np.int64)
        self._octave = np.zeros(1024, np.int64)
        self._uv = np.zeros((1024, 2))
        self._descriptors = np.zeros((1024, 32), np.uint8)
        self._n_keyframes = 0
        self._rows = 0

    def append(self, features: Features) -> None:
        """Add the next key-frame's keypoints (key-frame ids are consecutive from 0)."""
        n = len(features)
        if self._n_keyframes == self._start.shape[0]:
            self._start = np.concatenate([self._start, np.zeros_like(self._start)])
        if self._rows + n > self._octave.shape[0]:
            grow = max(self._octave.shape[0], n)
            self._octave = np.concatenate([self._octave, np.zeros(grow, np.int64)])
            self._uv = np.concatenate([self._uv, np.zeros((grow, 2))])
            self._descriptors = np.concatenate([self._descriptors, np.zeros((grow, 32), np.uint8)])
        self._start[self._n_keyframes] = self._rows
        self._octave[self._rows:self._rows + n] = features.octave
        self._uv[self._rows:self._rows + n] = features.uv
        self._descriptors[self._rows:self._rows + n] = features.descriptors
        self._n_keyframes += 1
        self._rows += n

    @property
    def start(self) -> np.ndarray:
        """(K,) int64 first row of each key-frame."""
        return self._start[:self._n_keyframes]

    @property
    def octave(self) -> np.ndarray:
        """(R,) int64 pyramid level of every stored keypoint."""
        return self._octave[:self._rows]

    @property
    def uv(self) -> np.ndarray:
        """(R, 2) float64 pixel of every stored keypoint."""
        return self._uv[:self._rows]

    @property
    def descriptors(self) -> np.ndarray:
        """(R, 32) uint8 descriptor of every stored keypoint."""
        return self._descriptors[:self._rows]


@dataclass
class SparseMap:
    """Key-frames and map points (see the module docstring). Point attributes are arrays indexed by point id."""

    scale_factor: float
    n_levels: int
    keyframes: dict[int, KeyFrame] = field(default_factory=dict)
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    descriptors: np.ndarray = field(default_factory=lambda: np.zeros((0, 32), np.uint8))
    normals: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    max_distance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    min_distance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bad: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    first_kf: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    n_visible: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    n_found: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    observations: list[dict[int, int]] = field(default_factory=list)
    next_kf_id: int = 0
    # the covisibility graph, kept up to date by every change of an observation (ORB-SLAM's connection weights):
    # {key-frame id: {other key-frame id: number of good points both observe}}; bad points observe nothing
    _shared: dict[int, dict[int, int]] = field(default_factory=dict, repr=False)
    # best_covisible's ranking per key-frame, dropped when one of its counts changes
    _ranked: dict[int, list[tuple[int, int]]] = field(default_factory=dict, repr=False)
    # every key-frame's keypoints one after another (key-frame k's from row _kp_store.start[k]): their octaves,
    # pixels and descriptors, so that flat_observations gathers by row instead of looping over key-frames
    _kp_store: _KeypointStore = field(default_factory=_KeypointStore, repr=False)

    # ----------------------------------------------------------------------------------------------- key-frames

    def new_keyframe(self, frame_index: int, timestamp: float, T_cam_world: np.ndarray, features: Features) -> KeyFrame:
        """Create and register a key-frame without observations."""
        kf = KeyFrame(self.next_kf_id, int(frame_index), float(timestamp), np.array(T_cam_world, dtype=np.float64),
                      features, np.full(len(features), -1, dtype=np.int64))
        self.keyframes[kf.id] = kf
        self._kp_store.append(features)
        self.next_kf_id += 1
        return kf

    def good_keyframes(self) -> list[KeyFrame]:
        """Key-frames not flagged bad, by id."""
        return [kf for _, kf in sorted(self.keyframes.items()) if not kf.bad]

    def covisibility(self, kf: KeyFrame) -> dict[int, int]:
        """Other good key-frames sharing good map points with ``kf``: {key-frame id: shared point count}."""
        shared = self._shared.get(kf.id, {})
        return {k: c for k, c in shared.items() if c > 0 and not self.keyframes[k].bad}

    def _share(self, a: int, others: Iterable[int], delta: int) -> None:
        """Add ``delta`` to the shared-point count of key-frame ``a`` with each of ``others`` (both ways)."""
        row = self._shared.setdefault(a, {})
        for b in others:
            if b == a:
                continue
            row[b] = row.get(b, 0) + delta
            col = self._shared.setdefault(b, {})
            col[a] = col.get(a, 0) + delta
            self._ranked.pop(b, None)
        self._ranked.pop(a, None)

    def best_covisible(self, kf: KeyFrame, n: int, min_shared: int = 1) -> list[KeyFrame]:
        """Up to ``n`` key-frames sharing most points with ``kf`` (at least ``min_shared``), most shared first."""
        ranked = self._ranked.get(kf.id)
        if ranked is None:  # by shared count, then id; dropped when a count of kf's changes
            ranked = [(c, k) for k, c in sorted(self.covisibility(kf).items(), key=lambda kc: (-kc[1], kc[0]))]
            self._ranked[kf.id] = ranked
        if min_shared > 1:
            return [self.keyframes[k] for c, k in ranked if c >= min_shared][:n]
        return [self.keyframes[k] for _, k in ranked[:n]]

    def set_keyframe_bad(self, kf: KeyFrame) -> None:
        """Flag a key-frame bad and drop its observations (points left with fewer than 2 become bad)."""
        for kp in np.flatnonzero(kf.point_ids >= 0):
            self.erase_observation(int(kf.point_ids[kp]), kf)
        kf.bad = True

    # ----------------------------------------------------------------------------------------------- map points

    @property
    def n_points(self) -> int:
        """Number of point ids ever created."""
        return int(self.positions.shape[0])

    def good_point_ids(self) -> np.ndarray:
        """Ids of points not flagged bad."""
        return np.flatnonzero(~self.bad)

    def add_points(self, positions: np.ndarray, kf_a: KeyFrame, kp_a: np.ndarray, kf_b: KeyFrame,
                   kp_b: np.ndarray) -> np.ndarray:
        """New points at ``positions`` ((M, 3) world) observed by keypoints ``kp_a`` of ``kf_a`` and ``kp_b`` of
        ``kf_b`` ((M,) int). Returns their ids (M,) int64. ``kf_a`` is their reference key-frame."""
        m = len(positions)
        ids = np.arange(self.n_points, self.n_points + m, dtype=np.int64)
        self.positions = np.concatenate([self.positions, np.asarray(positions, dtype=np.float64).reshape(m, 3)])
        self.descriptors = np.concatenate([self.descriptors, kf_a.features.descriptors[kp_a]])
        self.normals = np.concatenate([self.normals, np.zeros((m, 3))])
        self.max_distance = np.concatenate([self.max_distance, np.zeros(m)])
        self.min_distance = np.concatenate([self.min_distance, np.zeros(m)])
        self.bad = np.concatenate([self.bad, np.zeros(m, bool)])
        self.first_kf = np.concatenate([self.first_kf, np.full(m, kf_a.id, np.int64)])
        self.n_visible = np.concatenate([self.n_visible, np.ones(m, np.int64)])
        self.n_found = np.concatenate([self.n_found, np.ones(m, np.int64)])
        for pid, a, b in zip(ids, kp_a, kp_b, strict=True):
            self.observations.append({kf_a.id: int(a), kf_b.id: int(b)})
            kf_a.point_ids[a] = pid
            kf_b.point_ids[b] = pid
        if m:
            self._share(kf_a.id, (kf_b.id,), m)
        self.update_points(ids)
        return ids

    def add_observation(self, pid: int, kf: KeyFrame, kp: int) -> None:
        """Record that keypoint ``kp`` of ``kf`` observes point ``pid`` (replacing what that keypoint observed)."""
        old = int(kf.point_ids[kp])
        if old == pid:
            return
        if old >= 0:
            self.erase_observation(old, kf)
        if kf.id in self.observations[pid]:  # the point already had another keypoint in this key-frame
            kf.point_ids[self.observations[pid][kf.id]] = -1
        else:
            self._share(kf.id, self.observations[pid], 1)
        self.observations[pid][kf.id] = int(kp)
        kf.point_ids[kp] = pid

    def erase_observation(self, pid: int, kf: KeyFrame) -> None:
        """Remove ``kf``'s observation of ``pid``; a point left with fewer than 2 observations becomes bad."""
        kp = self.observations[pid].pop(kf.id, None)
        if kp is not None:
            self._share(kf.id, self.observations[pid], -1)
            if kf.point_ids[kp] == pid:
                kf.point_ids[kp] = -1
        if len(self.observations[pid]) < 2:
            self.set_point_bad(pid)

    def set_point_bad(self, pid: int) -> None:
        """Flag a point bad and detach it from every key-frame."""
        observers = list(self.observations[pid])
        for i, kf_id in enumerate(observers):
            self._share(kf_id, observers[i + 1:], -1)
        for kf_id, kp in list(self.observations[pid].items()):
            kf = self.keyframes[kf_id]
            if kf.point_ids[kp] == pid:
                kf.point_ids[kp] = -1
        self.observations[pid] = {}
        self.bad[pid] = True

    def replace_point(self, old: int, new: int) -> None:
        """Fuse duplicate ``old`` into ``new`` (ORB-SLAM's MapPoint::Replace): ``old``'s observations move to ``new``
        where that key-frame does not already observe ``new``; ``old`` becomes bad. Call :meth:`update_points` on
        ``new`` afterwards."""
        if old == new or self.bad[old] or self.bad[new]:
            return
        observers = list(self.observations[old])
        for i, kf_id in enumerate(observers):
            self._share(kf_id, observers[i + 1:], -1)
        for kf_id, kp in list(self.observations[old].items()):
            kf = self.keyframes[kf_id]
            if kf_id in self.observations[new]:
                kf.point_ids[kp] = -1
            else:
                self._share(kf_id, self.observations[new], 1)
                self.observations[new][kf_id] = kp
                kf.point_ids[kp] = new
        self.n_visible[new] += self.n_visible[old]
        self.n_found[new] += self.n_found[old]
        self.observations[old] = {}
        self.bad[old] = True

    def flat_observations(self, ids: np.ndarray, descriptors: bool = False) -> FlatObservations:
        """Every observation of points ``ids`` (in that order, each point's in its dict order) as flat arrays."""
        observations = self.observations
        obs = [observations[pid] for pid in np.asarray(ids, dtype=np.int64).tolist()]
        counts = np.fromiter(map(len, obs), np.int64, len(obs))
        total = int(counts.sum())
        flat_kf = np.fromiter(chain.from_iterable(obs), np.int64, total)  # the dicts' keys, in dict order
        flat_kp = np.fromiter(chain.from_iterable(map(dict.values, obs)), np.int64, total)
        present = np.zeros(self.next_kf_id, bool)  # key-frame ids are 0 .. next_kf_id - 1
        present[flat_kf] = True
        kf_ids = np.flatnonzero(present)
        slot = (np.cumsum(present) - 1)[flat_kf]
        rows = self._kp_store.start[flat_kf] + flat_kp  # np.take: ~8x numpy's fancy indexing of rows of 2-D arrays
        flat_octave = np.take(self._kp_store.octave, rows)
        flat_uv = np.take(self._kp_store.uv, rows, axis=0)
        flat_desc = np.take(self._kp_store.descriptors, rows, axis=0) if descriptors else None
        return FlatObservations(counts, flat_kf, flat_kp, flat_octave, flat_uv, flat_desc, kf_ids, slot)

    def update_points(self, ids: np.ndarray, descriptors: bool = True) -> None:
        """Recompute the viewing direction, distance range and (``descriptors=True``) representative descriptor of
        points ``ids`` from their observations (one numba pass, :func:`_point_summaries`)."""
        ids = np.unique(np.asarray(ids, dtype=np.int64))
        ids = ids[~self.bad[ids]]
        if ids.size == 0:
            return
        levels = self.scale_factor ** np.arange(self.n_levels)
        flat = self.flat_observations(ids, descriptors=descriptors)
        centers = np.stack([self.keyframes[int(k)].center for k in flat.keyframe_ids])
        words = (np.zeros((0, 4), np.uint64) if flat.descriptors is None
                 else flat.descriptors.view(np.uint64).reshape(-1, 4))
        normals, max_distance, best = _point_summaries(
            flat.counts, flat.slot, flat.keyframe, flat.octave, words, centers,
            self.positions[ids], self.first_kf[ids], levels, flat.descriptors is not None)
        self.normals[ids] = normals
        self.max_distance[ids] = max_distance
        self.min_distance[ids] = max_distance / levels[-1]
        if flat.descriptors is not None:
            self.descriptors[ids] = flat.descriptors[best]

    def predict_octave(self, ids: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """ORB-SLAM's PredictScale: the pyramid level at which points ``ids`` seen from ``distance`` (map units)
        should be detected, (M,) int64 in [0, n_levels)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            level = np.ceil(np.log(self.max_distance[ids] / distance) / np.log(self.scale_factor))
        return np.clip(np.nan_to_num(level, nan=0.0), 0, self.n_levels - 1).astype(np.int64)

    def points_of(self, keyframes: list[KeyFrame]) -> np.ndarray:
        """Sorted ids of the good points observed by any of ``keyframes``."""
        if not keyframes:
            return np.zeros(0, np.int64)
        ids = np.unique(np.concatenate([kf.tracked_points() for kf in keyframes]))
        return ids[~self.bad[ids]]

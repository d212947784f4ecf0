"""Local mapping of the ORB-SLAM baseline (ORB-SLAM's ``LocalMapping``), run synchronously after each new key-frame:
map-point culling, triangulation of new points with covisible key-frames, fusion of duplicates, local bundle
adjustment, and key-frame culling. Also the frustum test shared with tracking (``MapPoint``/``Frame::isInFrustum``).

Pixels (u, v) at full resolution; extrinsics ``T_cam_world`` (world -> camera); map units (no absolute scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnnslam.baselines.orb_ba import bundle_adjust, project
from cnnslam.baselines.orb_config import CHI2_1DOF, CHI2_2DOF, OrbConfig
from cnnslam.baselines.orb_features import level_inv_sigma, match_descriptors, match_in_windows
from cnnslam.baselines.orb_init import triangulate
from cnnslam.baselines.orb_map import KeyFrame, SparseMap
from cnnslam.geometry import hat

MIN_VIEW_COS: float = 0.5  # ORB isInFrustum: viewing angle to the point's mean direction below 60 deg
DISTANCE_MARGIN: tuple[float, float] = (0.8, 1.2)  # ORB isInFrustum: slack on the scale invariance region
EPIPOLE_EXCLUSION_PX: float = 5.0  # ORB: matches within 10 px (x scale) of the epipole at 640x480; ours at 320x240


@dataclass(frozen=True)
class Visible:
    """Points of the map that a camera should see (ORB-SLAM's isInFrustum).

    ids: (M,) int64 point ids; uv: (M, 2) predicted pixels; octave: (M,) int64 predicted pyramid level;
    view_cos: (M,) cosine between the viewing ray and the point's mean viewing direction.
    """

    ids: np.ndarray
    uv: np.ndarray
    octave: np.ndarray
    view_cos: np.ndarray


def visible_points(m: SparseMap, ids: np.ndarray, T_cam_world: np.ndarray, intrinsics: np.ndarray,
                   image_size: tuple[int, int]) -> Visible:
    """Points of ``ids`` in front of the camera, projecting inside the image, within their distance range and
    seen at less than 60 deg from their mean viewing direction."""
    ids = np.asarray(ids, dtype=np.int64)
    ids = ids[~m.bad[ids]]
    uv, z = project(T_cam_world, m.positions[ids], intrinsics)
    h, w = image_size
    center = -T_cam_world[:3, :3].T @ T_cam_world[:3, 3]
    ray = m.positions[ids] - center
    dist = np.linalg.norm(ray, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        view_cos = np.einsum("ij,ij->i", ray, m.normals[ids]) / dist
    ok = (z > 0) & np.isfinite(uv).all(axis=1)
    ok &= (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    ok &= (dist >= DISTANCE_MARGIN[0] * m.min_distance[ids]) & (dist <= DISTANCE_MARGIN[1] * m.max_distance[ids])
    ok &= np.nan_to_num(view_cos, nan=-1.0) >= MIN_VIEW_COS
    ids, uv, dist, view_cos = ids[ok], uv[ok], dist[ok], view_cos[ok]
    return Visible(ids, uv, m.predict_octave(ids, dist), view_cos)


def median_depth(m: SparseMap, kf: KeyFrame) -> float:
    """Median camera depth of the good points ``kf`` observes (map units); NaN when it has none."""
    ids = kf.tracked_points()
    ids = ids[~m.bad[ids]]
    if ids.size == 0:
        return float("nan")
    z = m.positions[ids] @ kf.T_cam_world[2, :3] + kf.T_cam_world[2, 3]
    return float(np.median(z))


# ------------------------------------------------------------------------------------------------ new points


def triangulate_new_points(m: SparseMap, kf: KeyFrame, intrinsics: np.ndarray, config: OrbConfig) -> np.ndarray:
    """ORB-SLAM's CreateNewMapPoints: match the unmatched keypoints of ``kf`` with those of its best covisible
    key-frames (descriptor ratio test and epipolar constraint), triangulate, and keep points with parallax, in front
    of both cameras, reprojecting within chi2(2 dof) in both and with consistent scale. Returns the new ids."""
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    Kinv = np.linalg.inv(K)
    new_ids: list[np.ndarray] = []
    scales = config.scale_factor ** np.arange(config.n_levels)
    ratio_factor = config.scale_consistency * config.scale_factor
    for nb in m.best_covisible(kf, config.triangulation_neighbours):
        baseline = float(np.linalg.norm(kf.center - nb.center))
        depth_nb = median_depth(m, nb)
        if not np.isfinite(depth_nb) or baseline / depth_nb < config.min_baseline_ratio:
            continue
        free_a = np.flatnonzero(kf.point_ids < 0)
        free_b = np.flatnonzero(nb.point_ids < 0)
        if free_a.size == 0 or free_b.size == 0:
            continue
        fa, fb = kf.features, nb.features
        pairs = match_descriptors(fa.descriptors[free_a], fb.descriptors[free_b], config.th_low,
                                  config.ratio_triangulation)
        if len(pairs) == 0:
            continue
        ia, ib = free_a[pairs[:, 0]], free_b[pairs[:, 1]]
        # epipolar constraint x_a^T F x_b = 0 with F = K^-T [t]x R K^-1 for T_a_b = T_a_world T_world_b
        T_ab = kf.T_cam_world @ nb.T_world_cam
        F = Kinv.T @ hat(T_ab[:3, 3]) @ T_ab[:3, :3] @ Kinv
        xb = np.c_[fb.uv[ib], np.ones(len(ib))]
        xa = np.c_[fa.uv[ia], np.ones(len(ia))]
        lines = xb @ F.T
        dist2 = np.einsum("ij,ij->i", lines, xa) ** 2 / np.maximum(lines[:, 0] ** 2 + lines[:, 1] ** 2, 1e-12)
        sig2_a = scales[fa.octave[ia]] ** 2
        ok = dist2 < CHI2_1DOF * sig2_a
        # not next to the epipole (the image of kf's centre in nb), where depth is ill-conditioned
        e_b = K @ (nb.T_cam_world[:3, :3] @ kf.center + nb.T_cam_world[:3, 3])
        if abs(e_b[2]) > 1e-12:
            near = np.linalg.norm(fb.uv[ib] - e_b[:2] / e_b[2], axis=1) < EPIPOLE_EXCLUSION_PX * scales[fb.octave[ib]]
            ok &= ~near
        ia, ib = ia[ok], ib[ok]
        if ia.size == 0:
            continue
        na = (fa.uv[ia] - [cx, cy]) / [fx, fy]
        nbn = (fb.uv[ib] - [cx, cy]) / [fx, fy]
        X = triangulate(kf.T_cam_world, nb.T_cam_world, na, nbn)
        good = np.isfinite(X).all(axis=1)
        X = np.where(good[:, None], X, 0.0)
        ra, rb = X - kf.center, X - nb.center
        da, db = np.linalg.norm(ra, axis=1), np.linalg.norm(rb, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_par = np.einsum("ij,ij->i", ra, rb) / (da * db)
        good &= (np.nan_to_num(cos_par, nan=1.0) < config.max_cos_parallax) & (cos_par > 0)
        uv_a, z_a = project(kf.T_cam_world, X, intrinsics)
        uv_b, z_b = project(nb.T_cam_world, X, intrinsics)
        good &= (z_a > 0) & (z_b > 0)
        err_a = np.nan_to_num(((uv_a - fa.uv[ia]) ** 2).sum(1), nan=np.inf)
        err_b = np.nan_to_num(((uv_b - fb.uv[ib]) ** 2).sum(1), nan=np.inf)
        good &= (err_a < CHI2_2DOF * sig2_a[ok]) & (err_b < CHI2_2DOF * scales[fb.octave[ib]] ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio_dist = da / db
        ratio_octave = scales[fa.octave[ia]] / scales[fb.octave[ib]]
        good &= (ratio_dist * ratio_factor >= ratio_octave) & (ratio_dist <= ratio_octave * ratio_factor)
        if good.any():
            new_ids.append(m.add_points(X[good], kf, ia[good], nb, ib[good]))
    return np.concatenate(new_ids) if new_ids else np.zeros(0, np.int64)


# ------------------------------------------------------------------------------------------------ duplicates


def fuse_into(m: SparseMap, target: KeyFrame, ids: np.ndarray, intrinsics: np.ndarray, image_size: tuple[int, int],
              config: OrbConfig) -> int:
    """ORB-SLAM's ORBmatcher::Fuse: project points ``ids`` into ``target``; a point matching a keypoint (within
    the fuse radius at its predicted level, Hamming <= TH_LOW, reprojection chi2 < 5.991) either becomes an
    observation of that keypoint or, if the keypoint already observes another point, the two are fused (the one
    with more observations survives). Returns the number of fused or added observations."""
    ids = np.asarray(ids, dtype=np.int64)
    ids = ids[~m.bad[ids]]
    ids = np.array([p for p in ids if target.id not in m.observations[p]], dtype=np.int64)
    if ids.size == 0:
        return 0
    vis = visible_points(m, ids, target.T_cam_world, intrinsics, image_size)
    if vis.ids.size == 0:
        return 0
    f = target.features
    radius = config.fuse_radius_px * config.scale_factor ** vis.octave
    pairs = match_in_windows(vis.uv, m.descriptors[vis.ids], f.uv, f.descriptors, radius, config.th_low, 1.0)
    done = 0
    touched: list[int] = []
    for i, j in pairs:
        pid = int(vis.ids[i])
        err2 = float(((vis.uv[i] - f.uv[j]) ** 2).sum()) * level_inv_sigma(f.octave[j], config.scale_factor) ** 2
        if err2 > CHI2_2DOF or m.bad[pid]:
            continue
        other = int(target.point_ids[j])
        if other >= 0 and not m.bad[other]:
            if other == pid:
                continue
            if len(m.observations[other]) > len(m.observations[pid]):
                m.replace_point(pid, other)
                touched.append(other)
            else:
                m.replace_point(other, pid)
                touched.append(pid)
        else:
            m.add_observation(pid, target, int(j))
            touched.append(pid)
        done += 1
    m.update_points(np.array(touched, dtype=np.int64))
    return done


def search_in_neighbours(m: SparseMap, kf: KeyFrame, intrinsics: np.ndarray, image_size: tuple[int, int],
                         config: OrbConfig) -> int:
    """ORB-SLAM's SearchInNeighbors: fuse ``kf``'s points into its covisible key-frames and theirs into ``kf``."""
    neighbours = m.best_covisible(kf, config.triangulation_neighbours)
    own = kf.tracked_points()
    fused = 0
    for nb in neighbours:
        fused += fuse_into(m, nb, own[~m.bad[own]], intrinsics, image_size, config)
    theirs = m.points_of(neighbours)
    fused += fuse_into(m, kf, theirs, intrinsics, image_size, config)
    m.update_points(m.points_of([kf]))
    return fused


# ------------------------------------------------------------------------------------------------ culling


def cull_recent_points(m: SparseMap, recent: list[int], current_kf_id: int, config: OrbConfig) -> list[int]:
    """ORB-SLAM's MapPointCulling on recently created points; returns the ones still on probation."""
    keep: list[int] = []
    for pid in recent:
        if m.bad[pid]:
            continue
        age = current_kf_id - int(m.first_kf[pid])
        if m.n_found[pid] < config.min_found_ratio * m.n_visible[pid]:
            m.set_point_bad(pid)
        elif age >= 2 and len(m.observations[pid]) <= 2:
            m.set_point_bad(pid)
        elif age < 3:
            keep.append(pid)
    return keep


def cull_keyframes(m: SparseMap, kf: KeyFrame, config: OrbConfig, protected: set[int]) -> int:
    """ORB-SLAM's KeyFrameCulling: a covisible key-frame of ``kf`` (not in ``protected``) is removed when at least
    ``redundant_share`` of its points are seen by ``redundant_observers`` other key-frames at the same or a finer
    scale. Returns the number removed."""
    removed = 0
    candidates = [o for o in m.best_covisible(kf, 10**6) if o.id not in protected and not o.bad]
    if not candidates:
        return 0
    # the observations of every candidate's points, flattened once; a key-frame culled below has its rows masked
    # (set_keyframe_bad erases exactly its observations), points it leaves bad drop out through m.bad
    union = np.unique(np.concatenate([o.tracked_points() for o in candidates]))
    flat = m.flat_observations(union)
    start = np.cumsum(flat.counts) - flat.counts
    live = np.ones(len(flat.keyframe), dtype=bool)
    for other in candidates:
        if other.bad:
            continue
        kps = np.flatnonzero(other.point_ids >= 0)
        kps = kps[~m.bad[other.point_ids[kps]]]
        if kps.size == 0:
            continue
        idx = np.searchsorted(union, other.point_ids[kps])
        counts = flat.counts[idx]
        owner = np.repeat(np.arange(kps.size), counts)  # the point (index into kps) of each observation
        rows = start[idx][owner] + np.arange(owner.size) - np.repeat(np.cumsum(counts) - counts, counts)
        finer = live[rows] & (flat.keyframe[rows] != other.id) & (
            flat.octave[rows] <= other.features.octave[kps][owner] + 1)
        seen = np.bincount(owner[finer], minlength=kps.size)
        redundant = int((seen >= config.redundant_observers).sum())
        if redundant > config.redundant_share * kps.size:
            m.set_keyframe_bad(other)
            live &= flat.keyframe != other.id
            removed += 1
    return removed


# ------------------------------------------------------------------------------------------------ bundle adjustment


@dataclass(frozen=True)
class LocalBAStats:
    """What one local bundle adjustment did: key-frames optimised / fixed, points, observations, outliers removed,
    robust cost before and after."""

    n_local: int
    n_fixed: int
    n_points: int
    n_observations: int
    n_outliers: int
    cost_initial: float
    cost_final: float


def local_bundle_adjustment(m: SparseMap, kf: KeyFrame, intrinsics: np.ndarray, config: OrbConfig,
                            anchor_id: int) -> LocalBAStats:
    """ORB-SLAM's LocalBundleAdjustment around ``kf``: ``kf`` and its best covisible key-frames are optimised with
    all points they see; other key-frames seeing those points are held fixed, and so is ``anchor_id`` (the map's
    first key-frame: the gauge). Two rounds; observations with chi2 > 5.991 or behind a camera after the first are
    left out of the second, and erased from the map after it."""
    local = [kf] + m.best_covisible(kf, config.local_ba_keyframes - 1)
    local_ids = {k.id for k in local}
    pts = m.points_of(local)
    flat = m.flat_observations(pts)
    owner = np.repeat(np.arange(len(pts)), flat.counts)  # index into pts of each observation
    bad_ids = [k for k in flat.keyframe_ids if m.keyframes[int(k)].bad]
    outside = ~np.isin(flat.keyframe, list(local_ids)) & ~np.isin(flat.keyframe, bad_ids)
    ids, counts = np.unique(flat.keyframe[outside], return_counts=True)
    fixed_ids = [int(k) for _, k in sorted(zip(-counts, ids, strict=True))[: config.local_ba_fixed_keyframes]]
    cams = local + [m.keyframes[k] for k in fixed_ids]
    fixed = np.array([k.id == anchor_id for k in local] + [True] * len(fixed_ids))
    if not fixed.any():  # no gauge: hold the oldest key-frame
        fixed[int(np.argmin([k.id for k in cams]))] = True
    cam_ids = np.array([k.id for k in cams])
    used = np.isin(flat.keyframe, cam_ids)
    if not used.any():
        return LocalBAStats(len(local), len(fixed_ids), len(pts), 0, 0, 0.0, 0.0)
    okf_a, oct_a = flat.keyframe[used], flat.octave[used]
    order = np.argsort(cam_ids)
    oc_a = order[np.searchsorted(cam_ids[order], okf_a)]
    op_a = owner[used]
    ouv_a = flat.uv[used]
    osig_a = level_inv_sigma(oct_a, config.scale_factor)
    T0 = np.stack([k.T_cam_world for k in cams])
    X0 = m.positions[pts]
    first = bundle_adjust(T0, fixed, X0, oc_a, op_a, ouv_a, osig_a, intrinsics, iterations=config.local_ba_rounds[0])
    inl = _inlier_observations(first.T_cam_world, first.points, oc_a, op_a, first.chi2)
    second = bundle_adjust(first.T_cam_world, fixed, first.points, oc_a[inl], op_a[inl], ouv_a[inl], osig_a[inl],
                           intrinsics, iterations=config.local_ba_rounds[1])
    for i, k in enumerate(cams):
        if not fixed[i]:
            k.T_cam_world = second.T_cam_world[i]
    m.positions[pts] = second.points
    # classify every observation with the final estimate; erase the outliers
    _, J = _chi2_all(second.T_cam_world, second.points, oc_a, op_a, ouv_a, osig_a, intrinsics)
    bad_obs = np.flatnonzero(J)
    for o in bad_obs:
        pid = int(pts[op_a[o]])
        if not m.bad[pid]:
            m.erase_observation(pid, m.keyframes[int(okf_a[o])])
    m.update_points(pts[~m.bad[pts]], descriptors=False)
    m.update_points(pts[op_a[bad_obs]])  # their observations changed
    return LocalBAStats(len(local), len(fixed_ids), len(pts), len(oc_a), len(bad_obs), first.cost_initial,
                        second.cost_final)


def _inlier_observations(T: np.ndarray, X: np.ndarray, oc: np.ndarray, op: np.ndarray, chi2: np.ndarray) -> np.ndarray:
    z = np.einsum("oj,oj->o", T[oc, 2, :3], X[op]) + T[oc, 2, 3]
    return (chi2 <= CHI2_2DOF) & (z > 0)


def _chi2_all(T: np.ndarray, X: np.ndarray, oc: np.ndarray, op: np.ndarray, uv: np.ndarray, inv_sigma: np.ndarray,
              intrinsics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """chi2 (O,) of every observation and the outlier mask (chi2 > 5.991 or behind the camera)."""
    p = np.einsum("oij,oj->oi", T[oc, :3, :3], X[op]) + T[oc, :3, 3]
    fx, fy, cx, cy = np.asarray(intrinsics, dtype=np.float64).reshape(4)
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = np.stack([fx * p[:, 0] / p[:, 2] + cx, fy * p[:, 1] / p[:, 2] + cy], axis=1)
    chi2 = np.nan_to_num((((proj - uv) * inv_sigma[:, None]) ** 2).sum(1), nan=np.inf)
    return chi2, (chi2 > CHI2_2DOF) | (p[:, 2] <= 0)

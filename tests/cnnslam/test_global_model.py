"""Known answers of the global model: noise averaging, label fusion, re-placement, the memory bound, pruning."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import pixel_rays
from cnnslam.model.global_model import NO_LABEL, GlobalModel, GlobalModelConfig, radial_confidence, voxel_keys

K = np.array([60.0, 60.0, 39.5, 29.5])  # a small 80 x 60 camera keeps these tests fast
SIZE = (60, 80)
PLANE_Z = 2.0


def pose(t=(0.0, 0.0, 0.0), rotvec_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


def plane_depth(T_world_cam: np.ndarray, z: float = PLANE_Z) -> np.ndarray:
    """Planar depth (H, W) of the world plane Z = z seen from a camera (0 where the ray misses it)."""
    rays = pixel_rays(SIZE, K)
    d = rays @ T_world_cam[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - T_world_cam[2, 3]) / d[..., 2]
    return np.where(np.isfinite(t) & (t > 0), t, 0.0).astype(np.float32)


def plane_distance(model: GlobalModel) -> np.ndarray:
    return np.abs(model.snapshot().positions[:, 2].astype(np.float64) - PLANE_Z)


def test_two_noisy_views_of_a_plane_average_the_noise():
    rng = np.random.default_rng(0)
    sigma = 0.01
    variance = np.full(SIZE, sigma**2, np.float32)
    cfg = GlobalModelConfig(normal_smoothing_px=2.0)
    T_a, T_b = pose(), pose((0.03, 0.0, 0.0))
    single = GlobalModel(cfg)
    single.integrate(plane_depth(T_a) + rng.normal(0, sigma, SIZE).astype(np.float32), T_a, K, variance=variance)
    err_single = plane_distance(single)
    fused = GlobalModel(cfg)
    fused.integrate(plane_depth(T_a) + rng.normal(0, sigma, SIZE).astype(np.float32), T_a, K, variance=variance)
    stats = fused.integrate(plane_depth(T_b) + rng.normal(0, sigma, SIZE).astype(np.float32), T_b, K,
                            variance=variance)
    assert stats.associated > 0.7 * stats.measurements  # the second view merged into the first one's surfels
    twice = fused.snapshot().observations >= 2
    assert twice.mean() > 0.6
    rms_single = float(np.sqrt(np.mean(err_single**2)))
    rms_twice = float(np.sqrt(np.mean(plane_distance(fused)[twice] ** 2)))
    # one noisy measurement per surfel: about sigma; two averaged: about sigma / sqrt(2)
    assert 0.7 * sigma < rms_single < 1.2 * sigma
    assert rms_twice < 0.85 * rms_single


def test_label_fusion_of_noisy_label_maps_beats_a_single_frame():
    rng = np.random.default_rng(1)
    n_views, p_correct = 7, 0.55  # known confusion: right with 0.55, else one of the 3 other classes uniformly

    def true_class(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return (x > 0).astype(np.int64) + 2 * (y > 0).astype(np.int64)  # four quadrants of the plane

    rays = pixel_rays(SIZE, K)
    models = {1: GlobalModel(), n_views: GlobalModel()}
    frame_right = frame_total = 0
    for v in range(n_views):
        T = pose((0.02 * np.cos(v), 0.02 * np.sin(v), 0.0), (0.3 * v, -0.2 * v, 0.0))
        depth = plane_depth(T)
        world = (rays * depth[..., None]) @ T[:3, :3].T + T[:3, 3]
        truth = true_class(world[..., 0], world[..., 1])
        wrong = rng.random(SIZE) > p_correct
        shift = rng.integers(1, 4, SIZE)
        labels = np.where(wrong, (truth + shift) % 4, truth).astype(np.uint8)
        frame_right += int((labels == truth).sum())
        frame_total += truth.size
        for n, model in models.items():
            if v < n:
                model.integrate(depth, T, K, label_probs=labels, anchor=v)
    accuracy = {}
    for n, model in models.items():
        cloud = model.snapshot()
        inner = (np.abs(cloud.positions[:, 0]) > 0.05) & (np.abs(cloud.positions[:, 1]) > 0.05)
        truth = true_class(cloud.positions[inner, 0], cloud.positions[inner, 1])
        accuracy[n] = float(np.mean(cloud.labels[inner] == truth))
        assert np.allclose(cloud.label_probs.sum(axis=1), 1.0, atol=1e-5)
        evidence = model.label_evidence()  # one-hot maps: the summed alpha of the pixels per class
        assert np.allclose(evidence / evidence.sum(axis=1, keepdims=True), cloud.label_probs, atol=1e-6)
    frame_wise = frame_right / frame_total
    assert frame_wise == pytest.approx(p_correct, abs=0.02)
    assert accuracy[1] < 0.65  # one frame: about as noisy as its label map
    # seven frames: the plurality of 7 votes (right with 0.55, each wrong class 0.15) is right with about 0.82
    assert accuracy[n_views] > 0.75
    assert accuracy[n_views] > accuracy[1] + 0.15


def test_associate_finds_the_surfel_each_pixel_was_fused_into_without_changing_the_model():
    T_a, T_b = pose(), pose((0.05, 0.0, 0.0))
    model = GlobalModel()
    model.integrate(plane_depth(T_a), T_a, K, label_probs=np.full(SIZE, 2, np.uint8))
    before = model.snapshot()
    index = model.associate(plane_depth(T_b), T_b, K)
    assert index.shape == SIZE and index.dtype == np.int64
    found = index >= 0
    assert found.mean() > 0.8  # the second view sees the same plane, shifted by 5 cm
    # each found pixel's surfel lies on the pixel's ray, within the surfel spacing
    rays = pixel_rays(SIZE, K)
    world = (rays * plane_depth(T_b)[..., None]) @ T_b[:3, :3].T + T_b[:3, 3]
    gap = np.linalg.norm(before.positions[index[found]] - world[found], axis=1)
    assert np.median(gap) < 0.02
    assert np.array_equal(model.labels()[index[found]], np.full(int(found.sum()), 2, np.uint8))
    after = model.snapshot()
    assert len(after) == len(before) and np.array_equal(after.positions, before.positions)
    # a plane 1 m behind the model is another surface: nothing to associate
    assert (model.associate(plane_depth(T_b, PLANE_Z + 1.0), T_b, K) < 0).all()
    with pytest.raises(CnnSlamError, match="variance must be"):
        model.associate(plane_depth(T_b), T_b, K, variance=np.ones((3, 3)))


def test_replacing_a_keyframe_moves_its_surfels_with_it():
    exact = np.full(SIZE, 0.005**2, np.float32)  # 5 mm sigma: a 10 cm misplacement does not associate
    T0, T1 = pose(), pose((0.4, 0.0, 0.0), (0.0, 8.0, 0.0))
    T1_wrong = T1.copy()
    T1_wrong[2, 3] += 0.10  # the tracker placed key-frame 1 10 cm too far forward
    model = GlobalModel()
    model.integrate(plane_depth(T0), T0, K, variance=exact, anchor=0)
    model.integrate(plane_depth(T1), T1_wrong, K, variance=exact, anchor=1)
    before = plane_distance(model)
    assert (before > 0.09).mean() > 0.3  # key-frame 1's surfels float 10 cm off the plane
    n_before = len(model)
    stats = model.update_poses({0: T0, 1: T1, 7: pose()})  # 7 was never fused: ignored
    assert stats.keyframes_moved == 1 and stats.surfels_moved > 0
    assert stats.max_displacement == pytest.approx(0.10, abs=1e-5)
    assert np.all(plane_distance(model) < 1e-3)
    assert stats.surfels_merged > 0 and len(model) == n_before - stats.surfels_merged  # duplicates merged
    assert np.allclose(model.keyframe_poses[1], T1)
    # fusing at the right poses in the first place merges more (projective association is finer than the voxel
    # hash), but the re-placed model is within the same bound: at most one surfel per voxel key
    direct = GlobalModel()
    direct.integrate(plane_depth(T0), T0, K, variance=exact, anchor=0)
    direct.integrate(plane_depth(T1), T1, K, variance=exact, anchor=1)
    assert len(direct) < len(model) < 2 * len(direct)
    # a tiny move waits until it adds up
    nudge = T1.copy()
    nudge[0, 3] += 1e-6
    assert model.update_poses({1: nudge}).keyframes_moved == 0
    with pytest.raises(CnnSlamError, match="already fused"):
        model.integrate(plane_depth(T1), T0, K, anchor=1)


def test_the_model_stays_bounded_over_many_noisy_frames():
    rng = np.random.default_rng(2)
    model = GlobalModel(GlobalModelConfig(voxel_size=0.03))
    sizes = []
    for _ in range(240):
        T = pose(rng.normal(0, 0.05, 3), rng.normal(0, 2.0, 3))
        depth = plane_depth(T) * np.exp(rng.normal(0, 0.02, SIZE)).astype(np.float32)  # 2 % depth noise
        model.integrate(depth, T, K)
        sizes.append(len(model))
    # after a while nothing new is seen: the noise merges into existing surfels (association or voxel hash)
    assert sizes[-1] < 1.1 * sizes[119]
    # at most one surfel per voxel key: the plane patch seen (under 2.8 x 2.2 m) within the noise band (+-3 sigma
    # of 4 cm, i.e. 9 voxels) bounds the count
    assert len(model) < 2.8 * 2.2 / 0.03**2 * 9
    cloud = model.snapshot()
    assert np.abs(cloud.positions[:, 2] - PLANE_Z).max() < 0.3
    assert len(np.unique(voxel_keys(cloud.positions, cloud.normals, 0.03))) > 0.8 * len(model)


def test_prune_removes_what_was_seen_once():
    model = GlobalModel()
    T = pose()
    for _ in range(3):
        model.integrate(plane_depth(T), T, K)
    blob = plane_depth(T)
    blob[20:30, 30:40] = 1.0  # a one-off object 1 m in front of the plane
    model.integrate(blob, T, K)
    n = len(model)
    removed = model.prune(min_confidence=1.0, min_age=0)
    near = model.snapshot().positions[:, 2] < 1.5
    assert removed > 0 and len(model) == n - removed and not near.any()
    with pytest.raises(CnnSlamError, match="prune"):
        model.prune(-1.0)


def test_surfels_seen_through_are_removed_and_kept_when_switched_off():
    T = pose()
    blob = plane_depth(T)
    blob[20:30, 30:40] = 1.0  # an outlier 1 m in front of the plane, in one frame only
    for max_misses, left in ((2, 0), (0, 1)):
        model = GlobalModel(GlobalModelConfig(max_misses=max_misses))
        model.integrate(plane_depth(T), T, K)
        model.integrate(blob, T, K)
        removed = 0
        for k in range(3):  # later frames see the plane through where the blob was
            removed += model.integrate(plane_depth(pose((0.01 * k, 0.0, 0.0))), pose((0.01 * k, 0.0, 0.0)), K).removed
        near = model.snapshot().positions[:, 2] < 1.5
        assert near.any() == bool(left)
        assert (removed > 0) == (max_misses > 0)
        assert np.abs(model.snapshot().positions[~near, 2] - PLANE_Z).max() < 1e-3  # the plane stays


def test_render_gives_the_fused_surface_and_snapshots_are_consistent():
    model = GlobalModel()
    T = pose((0.0, 0.0, 0.0), (0.0, 10.0, 0.0))
    depth = plane_depth(T)
    probs = np.zeros((*SIZE, 4), np.float32)
    probs[..., 2] = 0.7
    probs[..., 0] = 0.3
    model.integrate(depth, T, K, rgb=np.full((*SIZE, 3), 200, np.uint8), label_probs=probs)
    view = model.render(T, K, SIZE)
    hit = view.index >= 0
    assert hit[2:-2, 2:-2].mean() > 0.98  # the 2-pixel border has no normal, so it is not fused
    assert np.allclose(view.depth[hit], depth[hit], rtol=1e-3)
    assert np.allclose(view.vertices[hit][:, 2], view.depth[hit])
    cloud = model.snapshot()
    assert (cloud.labels == 2).all() and np.allclose(cloud.label_probs[:, 2], 0.7, atol=1e-5)
    assert (cloud.colours == 200).all() and (cloud.anchors == -1).all()
    assert np.allclose(np.linalg.norm(cloud.normals, axis=1), 1.0, atol=1e-5)
    assert (cloud.normals[:, 2] < -0.9).all()  # facing the camera that saw them
    bare = GlobalModel()
    bare.integrate(depth, T, K)
    assert (bare.snapshot().labels == NO_LABEL).all()
    assert radial_confidence(SIZE, K)[30, 40] == pytest.approx(1.0, abs=0.01)


def test_bad_inputs_are_rejected_with_the_value_named():
    model = GlobalModel()
    with pytest.raises(CnnSlamError, match=r"\(H, W\)"):
        model.integrate(np.zeros((2, 3, 4)), np.eye(4), K)
    with pytest.raises(CnnSlamError, match="T_world_cam"):
        model.integrate(np.ones(SIZE), np.full((4, 4), np.nan), K)
    with pytest.raises(CnnSlamError, match="label probabilities"):
        model.integrate(np.ones(SIZE), np.eye(4), K, label_probs=np.ones((*SIZE, 3)))
    with pytest.raises(CnnSlamError, match="voxel_size"):
        GlobalModelConfig(voxel_size=0.0)
    with pytest.raises(CnnSlamError, match="label_weighting"):
        GlobalModelConfig(label_weighting="votes")  # type: ignore[arg-type]


def test_association_on_the_measurement_grid_equals_the_full_splat():
    """associate_kernel(grid=2) visits only the even rows and columns, where stride-2 measurements lie: the same
    targets and misses as the full splat; measurements off that grid fall back to the full splat."""
    from cnnslam.model.surfel_kernels import associate_kernel

    rng = np.random.default_rng(3)
    h, w = 60, 80
    n = 4000
    pos = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.2, 1.2, n), rng.uniform(1.5, 2.5, n)])
    nrm = np.tile([0.0, 0.0, -1.0], (n, 1)) + rng.normal(0, 0.1, (n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    radius = rng.uniform(0.01, 0.06, n).astype(np.float32)
    conf = rng.uniform(0.1, 1.0, n).astype(np.float32)
    weight = rng.uniform(0.5, 2.0, n).astype(np.float32)
    depth = rng.uniform(1.5, 2.5, (h, w)).astype(np.float32)
    R, t = np.eye(3), np.zeros(3)

    def run(vs, us, grid):
        z = depth[vs, us].astype(np.float64)
        rays = np.column_stack([(us - K[2]) / K[0], (vs - K[3]) / K[1], np.ones(vs.size)])
        x_cam = rays * z[:, None]
        n_cam = np.tile([0.0, 0.0, -1.0], (vs.size, 1))
        return associate_kernel(pos.astype(np.float32), radius, nrm.astype(np.float32), conf, weight,
                                R.astype(np.float32), t.astype(np.float32), R, K[0], K[1], K[2], K[3], 3.0,
                                np.float32(0.01), depth, vs, us, x_cam, n_cam, z, np.full(vs.size, 1e-3), True, 0.05,
                                3.0, 0.01, 0.3, 0.5, grid)

    vs, us = (a.ravel().astype(np.int64) for a in np.mgrid[0:h:2, 0:w:2])
    full = run(vs, us, 1)
    assert (full[0] >= 0).sum() > 100 and full[1].size > 100  # a test that associates and misses
    for got, want in zip(run(vs, us, 2), full, strict=True):
        np.testing.assert_array_equal(got, want)
    keep = vs + 1 < h  # rows off the grid: grid=2 would skip their pixels, so the kernel falls back
    odd_vs, odd_us = vs[keep] + 1, us[keep]
    for got, want in zip(run(odd_vs, odd_us, 2), run(odd_vs, odd_us, 1), strict=True):
        np.testing.assert_array_equal(got, want)

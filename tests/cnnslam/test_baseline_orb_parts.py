"""Parts of the ORB-SLAM baseline with known answers: feature distribution, window matching, pose-only and bundle
adjustment on synthetic data, the map's bookkeeping, and the two-view initialisation on a rendered pair."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.baselines.orb_ba import bundle_adjust, huber_cost, huber_weights, optimize_pose, project
from cnnslam.baselines.orb_config import OrbConfig
from cnnslam.baselines.orb_features import (
    Features,
    extract_features,
    grid_select,
    hamming,
    level_inv_sigma,
    make_orb,
    match_descriptors,
    match_in_windows,
    to_gray,
)
from cnnslam.baselines.orb_init import check_rt, initialize_two_view
from cnnslam.baselines.orb_map import SparseMap
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import intrinsics_matrix, relative_pose, rotation_angle_deg, se3_exp, se3_inverse
from slamcommon.errors import ConfigError

INTR = np.array([240.6, 240.0, 159.5, 119.5])  # the ICL preset at 320x240
SIZE = (240, 320)


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(4, 4) T_world_cam with OpenCV axes at ``eye`` looking at ``target`` (world z up)."""
    z = target - eye
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def _synthetic_views(rng: np.random.Generator, n_cams: int = 6, n_points: int = 300):
    """Points in front of a sideways-moving camera; returns (T_cam_world (K, 4, 4), points (P, 3), observations)."""
    points = rng.uniform([-2.0, -1.5, 3.0], [2.0, 1.5, 6.0], (n_points, 3))
    T = np.stack([se3_inverse(se3_exp(np.r_[0.12 * k, 0.02 * k, 0.0, 0.0, 0.02 * k, 0.01 * k]))
                  for k in range(n_cams)])
    oc, op, ouv = [], [], []
    for k in range(n_cams):
        uv, z = project(T[k], points, INTR)
        ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 320) & (uv[:, 1] >= 0) & (uv[:, 1] < 240)
        idx = np.flatnonzero(ok)
        oc.append(np.full(idx.size, k))
        op.append(idx)
        ouv.append(uv[idx])
    return T, points, np.concatenate(oc), np.concatenate(op), np.concatenate(ouv)


# ------------------------------------------------------------------------------------------------ features


def test_grid_select_spreads_keypoints_over_cells() -> None:
    # 200 strong keypoints crowd one corner cell, 15 weak ones lie in 15 other cells: the weak ones must survive
    rng = np.random.default_rng(0)
    crowd = rng.uniform(0, 19, (200, 2))
    spread = np.stack([np.arange(15) * 20.0 + 30.0, np.full(15, 100.0)], axis=1)
    uv = np.r_[crowd, spread]
    response = np.r_[rng.uniform(5.0, 10.0, 200), np.full(15, 1.0)]
    chosen = grid_select(uv, response, (240, 320), 20, 60)
    assert chosen.size == 60
    assert set(range(200, 215)) <= set(chosen.tolist())  # every isolated keypoint is kept
    # a cell keeps its ceil(60 / 192) = 1 strongest; the other 44 slots go to the strongest of the rest
    crowd_kept = chosen[chosen < 200]
    assert crowd_kept.size == 45
    assert response[crowd_kept].min() >= np.sort(response[:200])[-45]


def test_hamming_and_level_sigma() -> None:
    a = np.zeros((1, 32), np.uint8)
    b = np.zeros((1, 32), np.uint8)
    b[0, :3] = [0b1, 0b11, 0xFF]
    assert hamming(a, b).tolist() == [11]
    np.testing.assert_allclose(level_inv_sigma(np.array([0, 1, 2]), 1.2), [1.0, 1 / 1.2, 1 / 1.44])


def test_match_in_windows_picks_nearest_descriptor_inside_the_radius() -> None:
    rng = np.random.default_rng(1)
    desc_b = rng.integers(0, 256, (4, 32), dtype=np.uint8)
    uv_b = np.array([[10.0, 10.0], [12.0, 10.0], [50.0, 50.0], [100.0, 100.0]])
    desc_a = desc_b[[1, 3]].copy()
    desc_a[0, 0] ^= 0b1  # one bit off keypoint 1
    uv_a = np.array([[11.0, 10.0], [60.0, 60.0]])  # the second is far from its twin (keypoint 3)
    pairs = match_in_windows(uv_a, desc_a, uv_b, desc_b, radius=5.0, max_distance=50, ratio=0.9)
    assert pairs.tolist() == [[0, 1]]
    wide = match_in_windows(uv_a, desc_a, uv_b, desc_b, radius=np.array([5.0, 60.0]), max_distance=50, ratio=0.9)
    assert wide.tolist() == [[0, 1], [1, 3]]
    # the ratio test rejects a match whose second-best candidate is nearly as close in descriptor space
    desc_b2 = desc_b.copy()
    desc_b2[0] = desc_a[0]
    desc_b2[0, 1] ^= 0b1
    assert match_in_windows(uv_a[:1], desc_a[:1], uv_b, desc_b2, 5.0, 50, 0.9).size == 0


def test_match_descriptors_is_one_to_one() -> None:
    rng = np.random.default_rng(2)
    base = rng.integers(0, 256, (30, 32), dtype=np.uint8)
    pairs = match_descriptors(base, base[::-1].copy(), max_distance=50, ratio=0.8)
    assert len(pairs) == 30
    assert (pairs[:, 1] == 29 - pairs[:, 0]).all()


# ------------------------------------------------------------------------------------------------ optimisation


def test_optimize_pose_recovers_the_pose_and_flags_outliers() -> None:
    rng = np.random.default_rng(3)
    T_true, points, *_ = _synthetic_views(rng, n_cams=4)
    uv, z = project(T_true[3], points, INTR)
    uv_noisy = uv + rng.normal(0, 0.5, uv.shape)
    outliers = np.zeros(len(points), bool)
    outliers[::10] = True
    uv_noisy[outliers] += 25.0
    T0 = se3_exp(np.r_[0.03, -0.02, 0.02, 0.02, -0.01, 0.015]) @ T_true[3]
    T, inl = optimize_pose(T0, points, uv_noisy, np.ones(len(points)), INTR)
    assert rotation_angle_deg(T @ se3_inverse(T_true[3])) < 0.05
    assert np.linalg.norm(T[:3, 3] - T_true[3][:3, 3]) < 5e-3
    assert not inl[outliers].any()
    assert inl[~outliers].mean() > 0.95


def test_huber_weights_and_cost() -> None:
    d = np.sqrt(5.991)
    np.testing.assert_allclose(huber_weights(np.array([1.0, 4 * 5.991])), [1.0, 0.5])
    assert huber_cost(np.array([1.0])) == pytest.approx(1.0)
    assert huber_cost(np.array([4 * 5.991])) == pytest.approx(2 * d * 2 * d - d**2)


def test_bundle_adjust_recovers_exact_cameras_and_points() -> None:
    rng = np.random.default_rng(4)
    T_true, points, oc, op, uv = _synthetic_views(rng)
    T0 = T_true.copy()
    T0[2:] = se3_exp(rng.normal(0, 0.004, (len(T0) - 2, 6))) @ T_true[2:]
    X0 = points + rng.normal(0, 0.02, points.shape)
    fixed = np.array([True, True] + [False] * (len(T0) - 2))  # two fixed cameras: gauge and scale
    res = bundle_adjust(T0, fixed, X0, oc, op, uv, np.ones(len(oc)), INTR, iterations=10)
    np.testing.assert_array_equal(res.T_cam_world[:2], T0[:2])  # fixed cameras untouched
    np.testing.assert_allclose(res.T_cam_world, T_true, atol=1e-5)
    np.testing.assert_allclose(res.points, points, atol=1e-4)
    assert res.cost_final < 1e-6 * res.cost_initial


def test_bundle_adjust_with_noise_and_outliers_reaches_the_optimum() -> None:
    rng = np.random.default_rng(5)
    T_true, points, oc, op, uv = _synthetic_views(rng)
    uv = uv + rng.normal(0, 0.3, uv.shape)
    uv[::40] += rng.choice([-20.0, 20.0], uv[::40].shape)  # outliers, 20 px off in random directions
    fixed = np.array([True, True] + [False] * (len(T_true) - 2))
    T0 = T_true.copy()
    T0[2:] = se3_exp(rng.normal(0, 0.004, (len(T0) - 2, 6))) @ T_true[2:]
    X0 = points + rng.normal(0, 0.02, points.shape)
    sigma = np.ones(len(oc))
    res = bundle_adjust(T0, fixed, X0, oc, op, uv, sigma, INTR, iterations=15)
    # the optimum, reached from the truth with many more Huber reweightings and iterations
    ref = bundle_adjust(T_true, fixed, points, oc, op, uv, sigma, INTR, iterations=100)
    assert res.cost_final == pytest.approx(ref.cost_final, rel=1e-3)
    for k in range(2, len(T0)):
        start = rotation_angle_deg(T0[k] @ se3_inverse(ref.T_cam_world[k]))
        assert rotation_angle_deg(res.T_cam_world[k] @ se3_inverse(ref.T_cam_world[k])) < min(0.05, 0.5 * start)
        assert np.linalg.norm(res.T_cam_world[k][:3, 3] - ref.T_cam_world[k][:3, 3]) < 2e-3
    flagged = res.chi2 > 5.991
    # (a point seen by two cameras can absorb an outlier, and then its other observation looks wrong)
    inlier = np.ones(len(oc), bool)
    inlier[::40] = False
    assert flagged[::40].mean() > 0.9 and flagged[inlier].mean() < 0.01


def test_bundle_adjust_rejects_inconsistent_shapes() -> None:
    with pytest.raises(CnnSlamError, match="inconsistent shapes"):
        bundle_adjust(np.eye(4)[None], np.array([True, False]), np.zeros((1, 3)), np.zeros(1, int),
                      np.zeros(1, int), np.zeros((1, 2)), np.ones(1), INTR)


# ------------------------------------------------------------------------------------------------ map bookkeeping


def _features(n: int, seed: int) -> Features:
    rng = np.random.default_rng(seed)
    return Features(rng.uniform(0, 300, (n, 2)), np.zeros(n, np.int64),
                    rng.integers(0, 256, (n, 32), dtype=np.uint8), np.ones(n, np.float32))


def test_sparse_map_observations_fusion_and_culling() -> None:
    m = SparseMap(1.2, 8)
    kfs = [m.new_keyframe(i, i / 30, np.eye(4), _features(5, i)) for i in range(3)]
    kfs[1].T_cam_world = se3_inverse(se3_exp(np.r_[0.1, 0, 0, 0, 0, 0]))
    ids = m.add_points(np.array([[0.0, 0.0, 2.0], [0.5, 0.0, 3.0]]), kfs[0], np.array([0, 1]), kfs[1],
                       np.array([2, 3]))
    assert ids.tolist() == [0, 1]
    assert kfs[0].point_ids.tolist() == [0, 1, -1, -1, -1] and kfs[1].point_ids.tolist() == [-1, -1, 0, 1, -1]
    assert m.covisibility(kfs[0]) == {1: 2}
    np.testing.assert_allclose(m.normals[0], [0.0, 0.0, 1.0], atol=0.03)
    assert m.max_distance[0] == pytest.approx(2.0) and m.min_distance[0] == pytest.approx(2.0 / 1.2**7)
    m.add_observation(1, kfs[2], 4)
    assert m.observations[1] == {0: 1, 1: 3, 2: 4}
    m.replace_point(0, 1)  # 0's observations cannot move: kf 0 and kf 1 already see 1
    assert m.bad[0] and kfs[0].point_ids[0] == -1 and kfs[1].point_ids[2] == -1
    m.erase_observation(1, kfs[2])
    m.erase_observation(1, kfs[1])  # one observation left: the point goes bad
    assert m.bad[1] and m.observations[1] == {} and (kfs[0].point_ids < 0).all()
    assert m.good_point_ids().size == 0


def test_update_points_summaries_have_known_answers() -> None:
    # one point at (0, 0, 4) seen by 4 key-frames centred at x = 0, 1, 2, 3, all at level 2, kf 0 the creating
    # one; its descriptors: all zeros (kf 0), one bit set (kf 1), two bits (kf 2), all 256 bits (kf 3)
    m = SparseMap(1.2, 8)
    feats = []
    for bits in ([0] * 32, [1] + [0] * 31, [3] + [0] * 31, [255] * 32):
        f = _features(3, 0)
        desc = f.descriptors.copy()
        desc[1] = np.array(bits, dtype=np.uint8)
        feats.append(Features(f.uv, np.full(3, 2, np.int64), desc, f.response))
    kfs = [m.new_keyframe(i, i / 30, se3_inverse(se3_exp(np.r_[float(i), 0, 0, 0, 0, 0])), feats[i])
           for i in range(4)]
    pid = int(m.add_points(np.array([[0.0, 0.0, 4.0]]), kfs[0], np.array([1]), kfs[1], np.array([1]))[0])
    m.add_observation(pid, kfs[2], 1)
    m.add_observation(pid, kfs[3], 1)
    m.update_points(np.array([pid]))
    rays = np.array([[0.0, 0.0, 4.0]]) - np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])
    mean = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).sum(axis=0)
    np.testing.assert_allclose(m.normals[pid], mean / np.linalg.norm(mean), rtol=1e-12)
    assert m.max_distance[pid] == pytest.approx(4.0 * 1.2**2)  # from kf 0, the creating key-frame, level 2
    assert m.min_distance[pid] == pytest.approx(4.0 * 1.2**2 / 1.2**7)
    # Hamming distances: 0-1: 1, 0-2: 2, 1-2: 1, x-3: 256, 255, 254; medians of each row (4 values, self 0):
    # kf0 (0,1,2,256) 1.5, kf1 (1,0,1,255) 1.0, kf2 (2,1,0,254) 1.5, kf3 (256,255,254,0) 254.5 -> kf 1's
    np.testing.assert_array_equal(m.descriptors[pid], feats[1].descriptors[1])
    m.erase_observation(pid, kfs[0])  # the creating key-frame gone: the first remaining observation is the reference
    m.update_points(np.array([pid]))
    assert m.max_distance[pid] == pytest.approx(np.hypot(1.0, 4.0) * 1.2**2)


def test_flat_observations_gathers_each_observing_keypoint() -> None:
    # 40 key-frames of 30 .. 199 keypoints (the keypoint store grows past its first capacities), random octaves;
    # every flat row must be the observing key-frame's own keypoint, read back from its Features
    rng = np.random.default_rng(5)
    m = SparseMap(1.2, 8)
    kfs = []
    for i in range(40):
        f = _features(int(rng.integers(30, 200)), i)
        kfs.append(m.new_keyframe(i, i / 30, np.eye(4), Features(f.uv, rng.integers(0, 8, len(f)), f.descriptors,
                                                                 f.response)))
    for _ in range(200):  # at most 4 observations a key-frame on average: each keeps free keypoints
        a, b = (kfs[i] for i in rng.choice(40, 2, replace=False))
        fa, fb = np.flatnonzero(a.point_ids < 0), np.flatnonzero(b.point_ids < 0)
        pid = int(m.add_points(rng.normal(0, 1, (1, 3)) + [0, 0, 3], a, fa[:1], b, fb[:1])[0])
        for c in rng.choice(40, 2, replace=False):
            if c not in (a.id, b.id):
                m.add_observation(pid, kfs[c], int(np.flatnonzero(kfs[c].point_ids < 0)[0]))
    ids = rng.permutation(m.good_point_ids())[:150]
    flat = m.flat_observations(ids, descriptors=True)
    rows = [(k, kp) for pid in ids.tolist() for k, kp in m.observations[pid].items()]
    assert flat.counts.tolist() == [len(m.observations[pid]) for pid in ids.tolist()]
    assert flat.keyframe.tolist() == [k for k, _ in rows] and flat.keypoint.tolist() == [kp for _, kp in rows]
    np.testing.assert_array_equal(flat.octave, [kfs[k].features.octave[kp] for k, kp in rows])
    np.testing.assert_array_equal(flat.uv, [kfs[k].features.uv[kp] for k, kp in rows])
    np.testing.assert_array_equal(flat.descriptors, [kfs[k].features.descriptors[kp] for k, kp in rows])
    assert flat.keyframe_ids.tolist() == sorted({k for k, _ in rows})
    np.testing.assert_array_equal(flat.keyframe_ids[flat.slot], flat.keyframe)
    assert flat.octave.dtype == np.int64 and flat.slot.dtype == np.int64 and flat.uv.dtype == np.float64
    assert m.flat_observations(np.zeros(0, np.int64)).counts.size == 0


def test_covisibility_kept_by_every_change_equals_a_recount() -> None:
    # random additions, fusions, erasures, bad points and a bad key-frame; after each, the maintained counts must
    # equal a count from scratch over the key-frames' good points
    rng = np.random.default_rng(3)
    m = SparseMap(1.2, 8)
    kfs = [m.new_keyframe(i, i / 30, np.eye(4), _features(40, i)) for i in range(6)]

    def recount(kf) -> dict[int, int]:
        counts: dict[int, int] = {}
        for pid in kf.tracked_points():
            if m.bad[pid]:
                continue
            for other in m.observations[pid]:
                if other != kf.id:
                    counts[other] = counts.get(other, 0) + 1
        return {k: c for k, c in counts.items() if not m.keyframes[k].bad}

    for step in range(300):
        op = step % 5 if step > 20 else 0
        a, b = (kfs[i] for i in rng.choice(6, 2, replace=False))
        if op == 0:
            fa, fb = np.flatnonzero(a.point_ids < 0), np.flatnonzero(b.point_ids < 0)
            if fa.size and fb.size:
                m.add_points(rng.normal(0, 1, (1, 3)) + [0, 0, 3], a, fa[:1], b, fb[:1])
        elif op == 1:
            good = m.good_point_ids()
            if good.size:
                m.add_observation(int(rng.choice(good)), a, int(rng.integers(0, 40)))
        elif op == 2:
            obs = a.tracked_points()
            if obs.size:
                m.erase_observation(int(rng.choice(obs)), a)
        elif op == 3:
            good = m.good_point_ids()
            if good.size >= 2:
                old, new = rng.choice(good, 2, replace=False)
                m.replace_point(int(old), int(new))
        elif step % 7 == 0:
            good = m.good_point_ids()
            if good.size:
                m.set_point_bad(int(rng.choice(good)))
        if step == 200:
            m.set_keyframe_bad(kfs[5])
        for kf in kfs:
            assert m.covisibility(kf) == recount(kf), step
            ranked = m.best_covisible(kf, 3)
            expected = sorted(recount(kf).items(), key=lambda kc: (-kc[1], kc[0]))[:3]
            assert [k.id for k in ranked] == [k for k, _ in expected]
    assert sum(len(m.covisibility(kf)) for kf in kfs) > 0 and m.bad.sum() > 0 and kfs[5].bad


# ------------------------------------------------------------------------------------------------ initialisation


def test_check_rt_counts_points_in_front_with_parallax() -> None:
    rng = np.random.default_rng(5)
    K = intrinsics_matrix(INTR)
    X = rng.uniform([-1, -1, 3], [1, 1, 5], (80, 3))
    R, t = np.eye(3), np.array([-0.3, 0.0, 0.0])
    uv1 = X[:, :2] / X[:, 2:] * INTR[:2] + INTR[2:]
    X2 = X + t
    uv2 = X2[:, :2] / X2[:, 2:] * INTR[:2] + INTR[2:]
    good = check_rt(R, t, uv1, uv2, K, 4.0)
    assert good.n_good == 80 and good.good.all() and good.parallax_deg > 3.0
    np.testing.assert_allclose(good.points, X, atol=1e-6)
    assert check_rt(R, -t, uv1, uv2, K, 4.0).n_good == 0  # the mirrored motion puts them behind the cameras


@pytest.fixture(scope="module")
def rendered_pair():
    """Two views of the office room, 0.5 m apart sideways, both looking at the same point of interest."""
    from sim_envs.camera import preset
    from sim_envs.render import make_renderer
    from sim_envs.scenes.scenegen import generate_scene

    scene = generate_scene("office", 1)
    rng = np.random.default_rng(0)
    targets = scene.interest_points()
    while True:  # the first free viewpoint at 1.2-1.6 m looking at an interest point at least 1.5 m away
        eye = np.array([*rng.uniform([0, 0], scene.room_size[:2]), rng.uniform(1.2, 1.6)])
        target = targets[rng.integers(len(targets))]
        if scene.free_space(eye[None], margin=0.5)[0] and np.linalg.norm(target - eye) >= 1.5:
            break
    T_a = _look_at(eye, target)
    T_b = _look_at(eye + 0.5 * T_a[:3, 0], target)
    cam = preset("icl")
    with make_renderer(scene, cam) as renderer:
        return cam, renderer.render(T_a).rgb, renderer.render(T_b).rgb, relative_pose(T_b, T_a)


def test_two_view_initialisation_recovers_the_relative_pose(rendered_pair) -> None:
    cam, rgb_a, rgb_b, T_b_a = rendered_pair
    cfg = OrbConfig()
    orb = make_orb(cfg)
    fa, fb = extract_features(to_gray(rgb_a), orb, cfg), extract_features(to_gray(rgb_b), orb, cfg)
    pairs = match_descriptors(fa.descriptors, fb.descriptors, cfg.th_low, 0.8)
    ia, ib = pairs[:, 0], pairs[:, 1]
    sigmas = level_inv_sigma(fa.octave[ia], 1.2), level_inv_sigma(fb.octave[ib], 1.2)
    res = initialize_two_view(fa.uv[ia], fb.uv[ib], cam.K, cfg, None, *sigmas)
    assert res.success, res.reason
    assert res.model == "essential" and res.parallax_deg > 1.0
    assert rotation_angle_deg(res.T_cur_ref @ se3_inverse(T_b_a)) < 1.0
    # other RANSAC draws (the matches permuted, as a seeded run does): measured 6 of 10 seeds within 1 deg, 3 refuse
    # (parallax below 1 deg or ambiguous) and 1 accepts a 7 deg error: the spread a seed shows in the suites
    errors = []
    for seed in range(10):
        other = initialize_two_view(fa.uv[ia], fb.uv[ib], cam.K, cfg, np.random.default_rng(seed), *sigmas)
        errors.append(rotation_angle_deg(other.T_cur_ref @ se3_inverse(T_b_a)) if other.success else np.inf)
    assert sum(e < 1.0 for e in errors) >= 5, errors
    assert len({round(e, 6) for e in errors if np.isfinite(e)}) > 1  # the seeds do draw other samples
    t_true = T_b_a[:3, 3] / np.linalg.norm(T_b_a[:3, 3])
    assert np.degrees(np.arccos(np.clip(res.T_cur_ref[:3, 3] @ t_true, -1, 1))) < 2.0
    assert np.linalg.norm(res.T_cur_ref[:3, 3]) == pytest.approx(1.0)  # no absolute scale
    assert len(res.points_ref) > 150 and (res.points_ref[:, 2] > 0).all()


def test_two_view_initialisation_fails_without_translation(rendered_pair) -> None:
    # a pure rotation of the same image content: a homography explains it with no parallax, nothing is created
    cam, rgb_a, _, _ = rendered_pair
    K = cam.K
    R = se3_exp(np.r_[0, 0, 0, 0.0, np.radians(6.0), 0.0])[:3, :3]
    import cv2

    rgb_rot = cv2.warpPerspective(rgb_a, K @ R @ np.linalg.inv(K), (cam.width, cam.height))
    cfg = OrbConfig()
    orb = make_orb(cfg)
    fa, fb = extract_features(to_gray(rgb_a), orb, cfg), extract_features(to_gray(rgb_rot), orb, cfg)
    pairs = match_descriptors(fa.descriptors, fb.descriptors, cfg.th_low, 0.8)
    assert len(pairs) >= cfg.init_min_matches
    res = initialize_two_view(fa.uv[pairs[:, 0]], fb.uv[pairs[:, 1]], K, cfg, np.random.default_rng(0))
    assert not res.success
    assert len(res.points_ref) == 0 and np.array_equal(res.T_cur_ref, np.eye(4))


def test_orb_config_validation() -> None:
    with pytest.raises(ConfigError, match="unknown config key 'n_feature'; valid keys: n_features"):
        OrbConfig().with_overrides({"n_feature": 10})
    with pytest.raises(CnnSlamError, match="keyframe_ref_ratio"):
        OrbConfig(keyframe_ref_ratio=1.5)
    assert OrbConfig().with_overrides({"n_features": 500}).n_features == 500

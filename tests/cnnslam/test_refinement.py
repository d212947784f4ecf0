"""Tests of frame-wise refinement (CNN-SLAM eq. 10-11) and of the epipolar stereo that observes depth."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.config import RefinementConfig
from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor
from cnnslam.geometry import relative_pose
from cnnslam.keyframe.refinement import (
    OK,
    StereoObservation,
    StereoSettings,
    _search_range,
    _subpixel_match,
    _triangulate,
    fuse_observation_depth,
    fuse_observation_uncertainty,
    refine_keyframe,
    stereo_observation,
)
from cnnslam.track.tracking import build_image_pyramid, to_gray

CFG = RefinementConfig()


def test_eq10_eq11_by_hand() -> None:
    # D_ki = 2.0 (U 0.04), observation D_t = 2.2 (U 0.01): eq. 10 (0.01*2 + 0.04*2.2)/0.05 = 2.16, eq. 11 0.008
    np.testing.assert_allclose(fuse_observation_depth(np.array([2.0]), np.array([0.04]), np.array([2.2]),
                                                      np.array([0.01])), [2.16])
    np.testing.assert_allclose(fuse_observation_uncertainty(np.array([0.04]), np.array([0.01])), [0.008])
    # an infinitely uncertain observation changes nothing
    np.testing.assert_allclose(fuse_observation_uncertainty(np.array([0.04]), np.array([1e30])), [0.04])


def test_refine_keyframe_fuses_creates_and_keeps() -> None:
    d = np.array([[2.0, 3.0, 0.0]], np.float32)
    u = np.array([[0.04, 0.09, np.inf]], np.float32)
    obs = StereoObservation(np.array([[2.2, 0.0, 1.5]], np.float32), np.array([[0.01, np.inf, 0.02]], np.float32),
                            np.array([[OK, 2, OK]], np.int8))
    cfg = RefinementConfig(prior_variance_inflation=1.0)
    new_d, new_u, stats = refine_keyframe(d, u, obs, cfg)
    np.testing.assert_allclose(new_d, [[2.16, 3.0, 1.5]], rtol=1e-6)  # fused, unchanged, created
    np.testing.assert_allclose(new_u, [[0.008, 0.09, 0.02]], rtol=1e-6)
    assert (stats.observed, stats.fused, stats.created) == (2, 1, 1)
    np.testing.assert_array_equal(stats.fused_mask, [[True, False, True]])  # what took this frame's stereo
    np.testing.assert_array_equal(d, [[2.0, 3.0, 0.0]])  # inputs untouched


def _stereo_pair(room, T_world_cur):
    T_world_kf = room.pose((0.0, 0.0, 0.0))
    rgb0, d0 = room.render(T_world_kf)
    rgb1, _ = room.render(T_world_cur)
    pyr = build_image_pyramid(to_gray(rgb0), room.intrinsics, 1)
    return pyr, d0, to_gray(rgb1), relative_pose(T_world_kf, T_world_cur)


def test_stereo_observes_true_depth_analytic(room) -> None:
    pyr, d0, cur, T_kf_cur = _stereo_pair(room, room.pose((0.15, 0.02, 0.03), (0.3, -0.5, 0.0)))
    prior = (d0 * 1.05).astype(np.float32)  # 5 % off, with an uncertainty that covers it
    var = ((0.1 * prior) ** 2).astype(np.float32)
    obs = stereo_observation(pyr.images[0], pyr.grad_x[0], pyr.grad_y[0], prior, var, cur, T_kf_cur, room.intrinsics,
                             CFG)
    ok = obs.status == OK
    assert ok.mean() > 0.4
    rel = np.abs(obs.depth[ok] - d0[ok]) / d0[ok]
    assert np.median(rel) < 0.01
    # the observation variance describes the error: mostly within 3 sigma
    z = np.abs(obs.depth[ok] - d0[ok]) / np.sqrt(obs.variance[ok])
    assert np.mean(z < 3.0) > 0.9
    assert np.all(np.isinf(obs.variance[~ok]))


def test_refinement_reduces_error_of_degraded_depth_on_rendered_frames() -> None:
    """Issue 5: refinement reduces the depth error of a degraded (CNN-like) depth map on rendered frames; pixels
    without a stereo observation (low texture) keep their depth exactly."""
    from sim_envs.sequences import get_sequence
    from sim_envs.sources.simsource import SimulatedSequence

    with SimulatedSequence(get_sequence("office0")) as seq:
        K = seq.intrinsics.as_array()
        key = seq.frame(0)
        others = [seq.frame(i) for i in (6, 12)]
    gt = key.depth
    degraded = DegradedGroundTruthPredictor(train_focal=float(K[:2].mean()), scale=1.05, seed=3).degrade_depth(gt)
    var = ((0.15 * degraded) ** 2).astype(np.float32)
    pyr = build_image_pyramid(to_gray(key.rgb), K, 1)
    depth = degraded
    valid = gt > 0
    err_before = np.mean(np.abs(degraded - gt)[valid] / gt[valid])
    for frame in others:
        obs = stereo_observation(pyr.images[0], pyr.grad_x[0], pyr.grad_y[0], depth, var, to_gray(frame.rgb),
                                 relative_pose(key.T_world_cam, frame.T_world_cam), K, CFG)
        new_depth, var, stats = refine_keyframe(depth, var, obs, CFG)
        untouched = obs.status != OK
        np.testing.assert_array_equal(new_depth[untouched], depth[untouched])
        assert stats.fused > 1000
        depth = new_depth
    err_after = np.mean(np.abs(depth - gt)[valid] / gt[valid])
    correct = lambda d: np.mean(np.abs(d - gt)[valid] < 0.1 * gt[valid])  # noqa: E731
    assert err_after < 0.9 * err_before, (err_before, err_after)
    assert correct(depth) > correct(degraded)


@pytest.mark.parametrize("density", ["dense", "semi_dense"])
def test_density_selects_the_attempted_pixels(room, density: str) -> None:
    pyr, d0, cur, T_kf_cur = _stereo_pair(room, room.pose((0.05, 0.0, 0.0)))
    cfg = RefinementConfig(density=density)
    obs = stereo_observation(pyr.images[0], pyr.grad_x[0], pyr.grad_y[0], d0, ((0.1 * d0) ** 2).astype(np.float32),
                             cur, T_kf_cur, room.intrinsics, cfg)
    grad = np.hypot(pyr.grad_x[0], pyr.grad_y[0])
    skipped = obs.status == 1
    if density == "semi_dense":
        assert np.all(skipped[grad < cfg.min_gradient_create])
    else:
        assert not skipped[5:-5, 5:-5].any()


def test_observation_outliers_is_lsd_chi_square_gate() -> None:
    from cnnslam.keyframe.refinement import observation_outliers

    d_kf = np.array([2.0, 2.0, 2.0])
    u_kf = np.array([0.01, 0.01, 0.01])  # sigma 0.1 m
    d_obs = np.array([2.05, 2.2, 1.5])
    u_obs = np.array([0.01, 0.01, 0.01])  # combined variance 0.02: |diff| up to 0.1414 m passes at factor 1
    assert observation_outliers(d_kf, u_kf, d_obs, u_obs, 1.0).tolist() == [False, True, True]
    assert observation_outliers(d_kf, u_kf, d_obs, u_obs, 0.25).tolist() == [False, False, True]  # 0.25*0.25 > 0.02
    assert not observation_outliers(d_kf, u_kf, d_obs, u_obs, 0.0).any()


def test_refine_keyframe_does_not_fuse_an_inconsistent_observation() -> None:
    from cnnslam.config import RefinementConfig
    from cnnslam.keyframe.refinement import StereoObservation, refine_keyframe

    depth = np.full((2, 2), 2.0, np.float32)
    variance = np.full((2, 2), 0.01, np.float32)
    obs_depth = np.array([[2.05, 3.0], [2.0, 0.0]], np.float32)
    obs_var = np.array([[0.01, 0.01], [np.inf, np.inf]], np.float32)
    obs = StereoObservation(obs_depth, obs_var, np.zeros((2, 2), np.int8))
    d, u, stats = refine_keyframe(depth, variance, obs, RefinementConfig())
    assert stats.fused == 1 and stats.rejected == 1
    assert d[0, 0] == pytest.approx((2.0 + 2.05) / 2, abs=1e-3)  # eq. 10 with equal variances
    assert d[0, 1] == 2.0 and u[0, 1] == pytest.approx(0.01)  # the outlier left the key-frame unchanged
    d0, _, stats0 = refine_keyframe(depth, variance, obs, RefinementConfig(outlier_factor=0.0))
    assert stats0.fused == 2 and d0[0, 1] > 2.4


def test_semi_dense_drops_hypotheses_beyond_the_inverse_depth_variance_limit() -> None:
    """keep_without_observation=False (LSD-SLAM): a hypothesis whose inverse-depth variance U / D^4 exceeds the
    limit is dropped (depth 0, variance inf), observed or not; the others are kept or fused as usual."""
    d = np.array([[2.0, 1.0, 0.0, 0.5]], np.float32)
    u = np.array([[0.04, 0.5, np.inf, 0.001]], np.float32)  # U / D^4: 0.0025, 0.5, -, 0.016
    obs = StereoObservation(np.array([[0.0, 0.0, 4.0, 0.0]], np.float32),
                            np.array([[np.inf, np.inf, 0.32, np.inf]], np.float32),  # created: 0.32 / 256 = 0.00125
                            np.array([[2, 2, OK, 2]], np.int8))
    cfg = RefinementConfig(max_inverse_depth_variance=0.01)
    new_d, new_u, stats = refine_keyframe(d, u, obs, cfg, keep_without_observation=False)
    np.testing.assert_array_equal(new_d, [[2.0, 0.0, 4.0, 0.0]])
    np.testing.assert_array_equal(new_u, np.array([[0.04, np.inf, 0.32, np.inf]], np.float32))
    assert (stats.observed, stats.fused, stats.created, stats.dropped) == (1, 0, 1, 2)
    kept, _, kept_stats = refine_keyframe(d, u, obs, cfg, keep_without_observation=True)
    assert kept_stats.dropped == 0 and kept[0, 1] == 1.0


def test_stereo_settings_name_every_numeric_config_field() -> None:
    cfg = RefinementConfig(border=5.0, subpixel=False, min_depth=0.1)
    s = StereoSettings.from_config(cfg)
    assert s.border == 5.0 and s.subpixel is False and s.max_idepth_create == pytest.approx(10.0)
    for name in s._fields:
        if name != "max_idepth_create":
            assert getattr(s, name) == getattr(cfg, name), name
    with pytest.raises(AttributeError):
        s.border = 3.0  # type: ignore[misc]


def test_search_range_is_prior_plus_minus_sigmas_or_the_whole_range() -> None:
    s = StereoSettings.from_config(RefinementConfig(search_sigmas=2.0, min_depth=0.05))
    prior, lo, hi = _search_range.py_func(np.float32(2.0), np.float32(0.04), s)
    # sigma of the inverse depth = sqrt(0.04) / 2^2 = 0.05 (1/m): 0.5 +- 2 * 0.05
    assert (prior, lo, hi) == pytest.approx((0.5, 0.4, 0.6))
    assert _search_range.py_func(np.float32(0.0), np.float32(1.0), s) == pytest.approx((1.0, 0.0, 20.0))


def test_subpixel_match_moves_to_the_parabola_minimum() -> None:
    # errors 4, 1, 2 at steps -1, 0, +1: the parabola 2 s^2 - s + 1 is lowest at s = 1/4, where it is 0.875
    x, y, err, refined = _subpixel_match.py_func(10.0, 5.0, 1.0, 4.0, 2.0, 1.0, 0.0)
    assert refined and x == pytest.approx(10.25) and y == 5.0 and err == pytest.approx(0.875)
    assert _subpixel_match.py_func(10.0, 5.0, 1.0, 0.5, 0.5, 1.0, 0.0)[3] is False  # opens downwards: unchanged


def test_triangulate_a_sideways_translation() -> None:
    # current camera 0.1 m to the right of the key-frame (T_cur_kf: t = (-0.1, 0, 0)), f = 100, c = 0: a key-frame
    # ray through the centre whose match is 5 px to the left lies at depth 100 * 0.1 / 5 = 2 m
    fx = 100.0
    idepth, alpha = _triangulate.py_func(-5.0, 0.0, -1.0, 0.0, 0.0, 0.0, np.eye(3), np.array([-0.1, 0.0, 0.0]),
                                         1.0 / fx, 1.0 / fx, 0.0, 0.0)
    assert idepth == pytest.approx(0.5) and abs(alpha) == pytest.approx(1.0 / (fx * 0.1))  # 1 / (f * baseline)


def _shifted_texture_pair() -> tuple[np.ndarray, ...]:
    """A key-frame and a current image 2 px apart (exact float32 arithmetic: 3x3 box sums of random integers / 9),
    with the key-frame's gradients."""
    rng = np.random.default_rng(5)
    h, w = 48, 64
    raw = rng.integers(0, 256, (h + 2, w + 6)).astype(np.float32)
    wide = sum(raw[dy:dy + h, dx:dx + w + 4] for dy in range(3) for dx in range(3)) / np.float32(9.0)
    kf, cur = wide[:, 2:w + 2].copy(), wide[:, 4:w + 4].copy()  # the scene moved 2 px to the left
    gx, gy = np.zeros_like(kf), np.zeros_like(kf)
    gx[:, 1:-1] = 0.5 * (kf[:, 2:] - kf[:, :-2])
    gy[1:-1] = 0.5 * (kf[2:] - kf[:-2])
    return kf, cur, gx, gy


def test_stereo_observation_finds_the_disparity_and_its_bytes_are_pinned(pinned_bytes) -> None:
    # f = 50 px, the current camera 8 cm to the right, 2 px of disparity: depth 50 * 0.08 / 2 = 2 m. The sha256 of
    # every observation below pins the stereo's bytes (computed before its kernel was split into named steps) on the
    # CPUs it was recorded on; the same digest on both.
    import hashlib
    from dataclasses import replace

    kf, cur, gx, gy = _shifted_texture_pair()
    depth = np.full(kf.shape, 2.0, np.float32)
    depth[::5, ::3] = 0.0  # some pixels search the whole inverse-depth range
    var = np.full(kf.shape, 0.05, np.float32)
    T_kf_cur = np.eye(4)
    T_kf_cur[0, 3] = 0.08
    digest = hashlib.sha256()
    for density in ("dense", "semi_dense"):
        for subpixel in (True, False):
            cfg = replace(CFG, density=density, subpixel=subpixel)
            obs = stereo_observation(kf, gx, gy, depth, var, cur, T_kf_cur, np.array([50.0, 50.0, 32.0, 24.0]), cfg)
            ok = obs.status == OK
            assert ok.sum() > 1000 and np.median(obs.depth[ok]) == pytest.approx(2.0, abs=1e-3)
            for a in (obs.depth, obs.variance, obs.status):
                digest.update(a.tobytes())
    stereo = "5cabf97d150052899cb4a67f67591dded22db732142faa88c63e32b82382f590"
    assert digest.hexdigest() == pinned_bytes(digest.hexdigest(), {"unrecorded": stereo, "AMD EPYC, avx2": stereo},
                                              "this test's depth and share assertions")  # fmt: skip

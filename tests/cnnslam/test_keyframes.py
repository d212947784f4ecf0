"""Tests of key-frame selection and of CNN-SLAM eq. 6-9 (uncertainty, propagation and fusion)."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.config import DepthConfig, KeyframeConfig
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import relative_pose, se3_exp
from cnnslam.keyframe.keyframes import (
    fuse_keyframe_depth,
    fuse_keyframe_uncertainty,
    init_cnn_keyframe,
    init_first_keyframe_without_cnn,
    initial_uncertainty,
    keyframe_score,
    needs_new_keyframe,
    propagate_keyframe,
    propagated_uncertainty,
    scale_anchor,
    stereo_pixels,
)

K = np.array([240.6, 240.0, 159.5, 119.5])
PAPER = DepthConfig(prediction_scale_alignment=0.0)  # eq. 6-9 as the paper writes them (no scale alignment)


def aligned(gain: float, reference: str = "map", pixels: str = "all", **kwargs) -> DepthConfig:
    """Prediction scale alignment with ``gain`` towards ``reference``, measured on ``pixels``."""
    return DepthConfig(prediction_scale_alignment=gain, prediction_scale_reference=reference,
                       prediction_scale_pixels=pixels, **kwargs)


def test_eq6_squared_difference() -> None:
    np.testing.assert_allclose(initial_uncertainty(np.array([2.0, 3.0]), np.array([2.5, 2.0])), [0.25, 1.0])


def test_eq7_propagated_uncertainty() -> None:
    # U~ = D_kj(v) / D_ki(u) * U_kj(v) + sigma_p^2 = 3 / 2 * 0.04 + 0.01
    np.testing.assert_allclose(propagated_uncertainty(np.array([3.0]), np.array([2.0]), np.array([0.04]), 0.01),
                               [0.07])


def test_eq8_eq9_fusion_by_hand() -> None:
    # D_ki = 2 with U_ki = 0.3, propagated D_kj = 2.4 with U~ = 0.1:
    # eq. 8: (0.1 * 2 + 0.3 * 2.4) / 0.4 = 2.3; eq. 9: 0.1 * 0.3 / 0.4 = 0.075
    np.testing.assert_allclose(fuse_keyframe_depth(np.array([2.0]), np.array([0.3]), np.array([2.4]),
                                                   np.array([0.1])), [2.3])
    np.testing.assert_allclose(fuse_keyframe_uncertainty(np.array([0.3]), np.array([0.1])), [0.075])
    # equal uncertainties: the mean, and half the uncertainty
    np.testing.assert_allclose(fuse_keyframe_depth(np.array([1.0]), np.array([0.2]), np.array([3.0]),
                                                   np.array([0.2])), [2.0])
    np.testing.assert_allclose(fuse_keyframe_uncertainty(np.array([0.2]), np.array([0.2])), [0.1])


def test_keyframe_score_is_lsd_slams() -> None:
    cfg = KeyframeConfig()
    # (4 * 0.1 * 0.5)^2 + (3 * (1 - 0.8))^2 = 0.04 + 0.36
    assert keyframe_score(np.array([0.1, 0.0, 0.0]), 0.5, 0.8, cfg) == pytest.approx(0.4)
    assert not needs_new_keyframe(0.4, 10, cfg)
    assert needs_new_keyframe(1.2, 10, cfg)
    assert not needs_new_keyframe(1.2, 2, cfg)  # too few frames on the key-frame (LSD MIN_NUM_MAPPED)


def test_first_keyframe_prior() -> None:
    cfg = DepthConfig()
    d = np.full((6, 8), 2.0, np.float32)
    init = init_cnn_keyframe(d, K, cfg)
    np.testing.assert_allclose(init.variance, (cfg.first_keyframe_relative_sigma * 2.0) ** 2, rtol=1e-6)
    assert init.matched_share == 0.0
    with pytest.raises(CnnSlamError, match="positive"):
        init_cnn_keyframe(np.zeros((6, 8), np.float32), K, cfg)


def test_the_alignment_half_way_to_the_running_median_on_stereo_pixels() -> None:
    """Off by default (the paper, chosen at whole length); its reference and pixels default to the running median on
    the stereo pixels, as they were when it was on."""
    assert DepthConfig().prediction_scale_alignment == 0.0
    cfg = DepthConfig(prediction_scale_alignment=0.5)
    assert (cfg.prediction_scale_reference, cfg.prediction_scale_pixels) == ("running_median", "stereo")
    # no stereo yet (a neighbour without counts): nothing is measured, the CNN keeps its depth
    d_cnn = np.full((240, 320), 2.97, np.float32)
    init = init_cnn_keyframe(d_cnn, K, cfg, np.full(d_cnn.shape, 2.7, np.float32),
                             np.full(d_cnn.shape, 0.01, np.float32), np.eye(4))
    assert init.prediction_scale == 1.0


def test_cnn_keyframe_fusion_with_a_neighbour() -> None:
    """A new key-frame 0.3 m in front of its neighbour looking at a wall: the neighbour's refined depth (exact) is
    fused with a CNN depth 10 % too far, per eq. 6-9 pixel by pixel."""
    cfg = DepthConfig(propagation_noise_variance=0.0025)
    T_world_j = np.eye(4)
    T_world_i = se3_exp(np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]))
    T_j_i = relative_pose(T_world_j, T_world_i)
    d_j = np.full((240, 320), 3.0, np.float32)  # the wall at 3 m from j
    u_j = np.full((240, 320), 0.01, np.float32)
    d_cnn = np.full((240, 320), 2.7 * 1.1, np.float32)  # truth from i: 2.7 m
    init = init_cnn_keyframe(d_cnn, K, cfg, d_j, u_j, T_j_i)
    centre = (slice(100, 140), slice(140, 180))
    u_new = (2.97 - 2.7) ** 2  # eq. 6 against the neighbour's depth seen from i
    u_prop = 3.0 / 2.97 * 0.01 + 0.0025  # eq. 7 with D_kj(v) = 3.0 and D_ki(u) = 2.97
    expected_d = (u_prop * 2.97 + u_new * 2.7) / (u_prop + u_new)  # eq. 8
    expected_u = u_prop * u_new / (u_prop + u_new)  # eq. 9
    np.testing.assert_allclose(init.depth[centre], expected_d, rtol=1e-4)
    np.testing.assert_allclose(init.variance[centre], expected_u, rtol=1e-4)
    assert init.matched_share > 0.95
    # pixels where the neighbour has no depth keep the CNN depth with the unmatched prior
    d_j_holed = d_j.copy()
    d_j_holed[:, :160] = 0.0
    holed = init_cnn_keyframe(d_cnn, K, cfg, d_j_holed, u_j, T_j_i)
    np.testing.assert_allclose(holed.depth[100:140, :100], 2.97, rtol=1e-6)
    np.testing.assert_allclose(holed.variance[100:140, :100], (cfg.unmatched_relative_sigma * 2.97) ** 2, rtol=1e-5)
    np.testing.assert_allclose(holed.depth[100:140, 220:], expected_d, rtol=1e-4)
    assert 0.3 < holed.matched_share < 0.7


def test_scale_anchoring_rescales_the_carried_over_map_towards_the_cnn() -> None:
    """The same wall as above: the CNN says 2.97 m where the map (neighbour seen from i) says 2.7 m."""
    T_j_i = relative_pose(np.eye(4), se3_exp(np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0])))
    d_j = np.full((240, 320), 3.0, np.float32)
    u_j = np.full((240, 320), 0.01, np.float32)
    d_cnn = np.full((240, 320), 2.97, np.float32)
    valid = np.ones(d_cnn.shape, bool)
    assert scale_anchor(d_cnn, np.full(d_cnn.shape, 2.7), valid, 1.0) == pytest.approx(1.1)
    assert scale_anchor(d_cnn, np.full(d_cnn.shape, 2.7), valid, 0.5) == pytest.approx(1.1**0.5)
    assert scale_anchor(d_cnn, np.full(d_cnn.shape, 2.7), valid, 0.0) == 1.0
    assert scale_anchor(d_cnn, np.full(d_cnn.shape, 2.7), np.zeros_like(valid), 1.0) == 1.0  # nothing seen by both
    centre = (slice(100, 140), slice(140, 180))
    paper = init_cnn_keyframe(d_cnn, K, PAPER, d_j, u_j, T_j_i)
    assert paper.anchor_scale == 1.0
    full = init_cnn_keyframe(d_cnn, K, aligned(0.0, scale_anchoring=1.0), d_j, u_j, T_j_i)
    assert full.anchor_scale == pytest.approx(1.1, rel=1e-4)
    # the map scaled by 1.1 agrees with the CNN: eq. 8 returns the common depth, eq. 9 a smaller variance
    np.testing.assert_allclose(full.depth[centre], 2.97, rtol=1e-4)
    assert np.all(full.variance[centre] < paper.variance[centre])
    half = init_cnn_keyframe(d_cnn, K, aligned(0.0, scale_anchoring=0.5), d_j, u_j, T_j_i)
    assert np.all((paper.depth[centre] < half.depth[centre]) & (half.depth[centre] < 2.97))
    with pytest.raises(CnnSlamError, match="scale_anchoring"):
        DepthConfig(scale_anchoring=1.5).validate()


def test_prediction_scale_alignment_rescales_the_cnn_towards_the_map() -> None:
    """The same wall: the map says 2.7 m where the CNN says 2.97 m (10 % deeper); the CNN moves, the map stays."""
    T_j_i = relative_pose(np.eye(4), se3_exp(np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0])))
    d_j = np.full((240, 320), 3.0, np.float32)
    u_j = np.full((240, 320), 0.01, np.float32)
    d_cnn = np.full((240, 320), 2.97, np.float32)
    centre = (slice(100, 140), slice(140, 180))
    paper = init_cnn_keyframe(d_cnn, K, PAPER, d_j, u_j, T_j_i)
    assert paper.prediction_scale == 1.0
    full = init_cnn_keyframe(d_cnn, K, aligned(1.0), d_j, u_j, T_j_i)
    assert full.prediction_scale == pytest.approx(1 / 1.1, rel=1e-4) and full.anchor_scale == 1.0
    np.testing.assert_allclose(full.depth, 2.7, rtol=1e-4)  # the map's scale
    half = init_cnn_keyframe(d_cnn, K, aligned(0.5), d_j, u_j, T_j_i)
    assert half.prediction_scale == pytest.approx(1.1**-0.5, rel=1e-4)
    assert np.all((2.7 < half.depth[centre]) & (half.depth[centre] < 2.97))
    first = init_cnn_keyframe(d_cnn, K, aligned(1.0))  # no neighbour: the CNN's
    assert first.prediction_scale == 1.0 and np.all(first.depth == d_cnn)
    with pytest.raises(CnnSlamError, match="prediction_scale_alignment"):
        DepthConfig(prediction_scale_alignment=-0.1).validate()


def test_prediction_scale_alignment_towards_the_running_median_of_the_cnn() -> None:
    """The map (the neighbour, at log scale 0) says 2.7 m, the CNN 2.97 m: the CNN's log scale is log 1.1. With
    earlier CNN scales log 1.1 and log 1.1 the median is log 1.1: the new key-frame keeps the CNN's depth; with
    0 and 0 the median is 0: it takes the map's."""
    T_j_i = relative_pose(np.eye(4), se3_exp(np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0])))
    d_j = np.full((240, 320), 3.0, np.float32)
    u_j = np.full((240, 320), 0.01, np.float32)
    d_cnn = np.full((240, 320), 2.97, np.float32)
    cfg = aligned(1.0, "running_median")
    r = np.log(1.1)
    follows = init_cnn_keyframe(d_cnn, K, cfg, d_j, u_j, T_j_i, 0.0, [r, r])
    assert follows.prediction_scale == pytest.approx(1.0) and follows.cnn_log_scale == pytest.approx(r, abs=1e-4)
    assert follows.log_scale == pytest.approx(r, abs=1e-4)  # this key-frame now sits at the CNN's scale
    holds = init_cnn_keyframe(d_cnn, K, cfg, d_j, u_j, T_j_i, 0.0, [0.0, 0.0])
    assert holds.prediction_scale == pytest.approx(1 / 1.1, rel=1e-4) and holds.log_scale == pytest.approx(0.0)
    np.testing.assert_allclose(holds.depth, 2.7, rtol=1e-4)
    # in a neighbour's units: a neighbour at log scale s makes the CNN's log scale s + r
    shifted = init_cnn_keyframe(d_cnn, K, cfg, d_j, u_j, T_j_i, 0.5, [0.5 + r])
    assert shifted.cnn_log_scale == pytest.approx(0.5 + r, abs=1e-4) and shifted.prediction_scale == pytest.approx(1)
    with pytest.raises(CnnSlamError, match="prediction_scale_reference"):
        DepthConfig(prediction_scale_reference="cnn").validate()


def test_prediction_scale_measured_where_the_neighbour_took_stereo() -> None:
    """Left half of the neighbour refined by stereo (the map says 2.7 m there), right half only the propagated CNN (it
    says 2.97 m, like the new CNN): measured on every pixel the CNN seems half right; on the stereo pixels alone its
    10 % error shows."""
    T_j_i = np.eye(4)  # the same view: pixel u of the new key-frame lands on pixel u of the neighbour
    d_j = np.full((240, 320), 2.97, np.float32)
    d_j[:, :160] = 2.7
    u_j = np.full((240, 320), 0.01, np.float32)
    count = np.zeros((240, 320), np.uint16)
    count[:, :160] = 5
    count[:, 150:160] = 2  # too few observations
    d_cnn = np.full((240, 320), 2.97, np.float32)
    mask = stereo_pixels(d_cnn, count, K, T_j_i, 3)
    assert mask[:, :150].all() and not mask[:, 150:].any()
    assert not stereo_pixels(d_cnn, None, K, T_j_i, 3).any()  # no stereo yet: none
    every = aligned(1.0)
    stereo = aligned(1.0, pixels="stereo")
    a = init_cnn_keyframe(d_cnn, K, every, d_j, u_j, T_j_i, neighbour_stereo_count=count)
    b = init_cnn_keyframe(d_cnn, K, stereo, d_j, u_j, T_j_i, neighbour_stereo_count=count)
    assert 1 / 1.1 < a.prediction_scale <= 1.0  # the median over both halves
    assert b.prediction_scale == pytest.approx(1 / 1.1, rel=1e-4)  # the stereo's scale
    with pytest.raises(CnnSlamError, match="prediction_scale_pixels"):
        DepthConfig(prediction_scale_pixels="edges").validate()
    with pytest.raises(CnnSlamError, match="stereo_min_observations"):
        DepthConfig(stereo_min_observations=0).validate()


def test_eq6_floor_keeps_agreeing_pixels_refinable() -> None:
    cfg = PAPER
    d = np.full((240, 320), 2.0, np.float32)
    init = init_cnn_keyframe(d, K, cfg, d, np.full(d.shape, 0.01, np.float32), np.eye(4))
    assert np.all(init.variance > 0)
    np.testing.assert_allclose(init.depth, 2.0, rtol=1e-6)


def test_propagation_without_cnn_forward_warps() -> None:
    cfg = DepthConfig(source="random")
    d_j = np.full((240, 320), 3.0, np.float32)
    u_j = np.full((240, 320), 0.04, np.float32)
    T_new_j = relative_pose(se3_exp(np.array([0.0, 0.0, 0.5, 0, 0, 0])), np.eye(4))  # new camera 0.5 m forward
    init = propagate_keyframe(d_j, u_j, K, T_new_j, cfg)
    has = init.depth > 0
    np.testing.assert_allclose(init.depth[has], 2.5, rtol=1e-6)
    np.testing.assert_allclose(init.variance[has], 3.0 / 2.5 * 0.04 + cfg.propagation_noise_variance, rtol=1e-5)
    assert 0.5 < init.matched_share < 1.0  # moving forward leaves the border empty


def test_first_keyframe_without_cnn_sources() -> None:
    rng = np.random.default_rng(0)
    mask = np.zeros((4, 5), bool)
    mask[1:3, 1:4] = True
    const = init_first_keyframe_without_cnn((4, 5), DepthConfig(source="constant"), rng, mask)
    assert np.all(const.depth[mask] == 1.0) and np.all(const.depth[~mask] == 0)
    rand = init_first_keyframe_without_cnn((4, 5), DepthConfig(source="random"), rng, mask)
    assert np.all((rand.depth[mask] > 1 / 1.5 - 1e-6) & (rand.depth[mask] < 2.0 + 1e-6))
    gt = np.full((4, 5), 2.0, np.float32)
    boot = init_first_keyframe_without_cnn((4, 5), DepthConfig(source="ground_truth_first"), rng, None, gt)
    np.testing.assert_allclose(boot.depth, 2.0)
    np.testing.assert_allclose(boot.variance, 1e-4 * 2.0**4, rtol=1e-5)  # LSD VAR_GT_INIT_INITIAL in depth units
    with pytest.raises(CnnSlamError, match="ground-truth"):
        init_first_keyframe_without_cnn((4, 5), DepthConfig(source="ground_truth_first"), rng)


def test_lsd_bs_seeded_bootstrap_differs_from_the_ground_truth_in_its_last_bits_only() -> None:
    gt = np.random.default_rng(5).uniform(0.5, 6.0, (24, 32)).astype(np.float32)
    gt[0, :4] = 0.0  # no depth stays no depth
    cfg = DepthConfig(source="ground_truth_first")
    plain = init_first_keyframe_without_cnn((24, 32), cfg, np.random.default_rng(1), None, gt)
    np.testing.assert_array_equal(plain.depth, gt)  # seed 0: the sensor's depth as it is
    runs = [init_first_keyframe_without_cnn((24, 32), cfg, np.random.default_rng(s), None, gt,
                                            perturb_last_bits_of_ground_truth=True) for s in (1, 1, 2)]
    np.testing.assert_array_equal(runs[0].depth, runs[1].depth)  # same seed, same bytes
    assert not np.array_equal(runs[0].depth, runs[2].depth)
    has = gt > 0
    assert np.all(runs[0].depth[~has] == 0) and np.all(np.isinf(runs[0].variance[~has]))
    ulps = np.abs(runs[0].depth[has].astype(np.float64) / gt[has] - 1.0) / np.finfo(np.float32).eps
    assert (ulps > 0).mean() > 0.5 and np.median(ulps) < 3.0 and ulps.max() < 20.0  # N(0, 2 ulp): a few ulps


def test_occlusion_test_keeps_the_cnn_where_the_neighbour_saw_another_surface() -> None:
    cfg = PAPER
    d_cnn = np.full((240, 320), 3.0, np.float32)
    d_j = np.full((240, 320), 3.0, np.float32)
    d_j[:, :160] = 1.0  # an occluder in front of the neighbour, on the left half of its view
    u_j = np.full((240, 320), 0.01, np.float32)
    init = init_cnn_keyframe(d_cnn, K, cfg, d_j, u_j, np.eye(4))
    np.testing.assert_allclose(init.depth[:, :150], 3.0)  # not pulled towards the occluder's 1 m
    np.testing.assert_allclose(init.variance[:, :150], (cfg.unmatched_relative_sigma * 3.0) ** 2, rtol=1e-5)
    assert 0.4 < init.matched_share < 0.6

"""Tests of the CNN depth-prediction stage: the focal-length adjustment (CNN-SLAM eq. 5)."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.depth.depth_prediction import JITTER_STD_ULPS, focal_length_adjustment, perturb_last_bits
from cnnslam.errors import CnnSlamError


def test_eq5_known_values() -> None:
    raw = np.array([[1.0, 2.0], [0.0, 4.0]], np.float32)
    out = focal_length_adjustment(raw, f_cur=240.0, f_tr=480.0)
    np.testing.assert_allclose(out, [[0.5, 1.0], [0.0, 2.0]])
    assert out.dtype == np.float32


def test_eq5_icl_vs_nyu_at_320x240() -> None:
    # ICL-NUIM (481.2 + 480) / 2 / 2 = 240.3 px; NYU (518.8579 + 519.4696) / 2 / 2 = 259.582 px at 320x240
    out = focal_length_adjustment(np.full((2, 2), 3.0, np.float32), 240.3, 259.582)
    np.testing.assert_allclose(out, 3.0 * 240.3 / 259.582, rtol=1e-6)


def test_eq5_identity_for_same_camera() -> None:
    raw = np.random.default_rng(0).uniform(0.5, 5, (3, 4)).astype(np.float32)
    np.testing.assert_array_equal(focal_length_adjustment(raw, 259.6, 259.6), raw)


@pytest.mark.parametrize("f_cur,f_tr", [(0.0, 1.0), (1.0, -2.0), (float("nan"), 1.0), (1.0, float("inf"))])
def test_eq5_rejects_bad_focal_lengths(f_cur: float, f_tr: float) -> None:
    with pytest.raises(CnnSlamError):
        focal_length_adjustment(np.ones((2, 2), np.float32), f_cur, f_tr)


# --------------------------------------------------------------------------- predictors and the raw/adjusted switch


class _FixedNet:
    """A stand-in network: returns a fixed depth, trained at focal 480 px."""

    train_focal = 480.0

    def predict_raw(self, rgb: np.ndarray):
        from cnnslam.depth.depth_prediction import DegradedPrediction

        h, w = rgb.shape[:2]
        return DegradedPrediction(np.full((h, w), 2.0, np.float32), np.full((h, w, 4), 0.25, np.float32))


def test_raw_and_adjusted_switch() -> None:
    from cnnslam.depth.depth_prediction import predict_keyframe_depth

    rgb = np.zeros((4, 6, 3), np.uint8)
    k = np.array([240.0, 240.0, 2.5, 1.5])
    adjusted = predict_keyframe_depth(_FixedNet(), rgb, k, focal_adjustment=True)
    raw = predict_keyframe_depth(_FixedNet(), rgb, k, focal_adjustment=False)
    np.testing.assert_allclose(adjusted.depth, 1.0)  # eq. 5: 240 / 480 * 2
    np.testing.assert_allclose(raw.depth, 2.0)
    np.testing.assert_allclose(adjusted.raw_depth, raw.raw_depth)
    assert adjusted.focal_ratio == pytest.approx(0.5) and raw.focal_ratio == 1.0
    assert adjusted.label_probs is not None and adjusted.label_probs.shape == (4, 6, 4)


def test_degraded_predictor_imitates_a_cnn() -> None:
    from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor, GroundTruthHint, predict_keyframe_depth

    gt = np.full((48, 64), 3.0, np.float32)
    gt[20:28, 30:34] = 1.0  # a small near object
    gt[:, 50:] = 2.0  # a depth edge
    gt[0:3, 0:3] = 0.0  # no surface
    labels = np.zeros((48, 64), np.uint8)
    labels[20:28, 30:34] = 3
    k = np.array([50.0, 50.0, 31.5, 23.5])
    pred = DegradedGroundTruthPredictor(train_focal=60.0, scale=1.1, scale_jitter=0.0, lowfreq_noise=0.0,
                                        pixel_noise=0.0, seed=0)
    out = predict_keyframe_depth(pred, np.zeros((48, 64, 3), np.uint8), k, True, GroundTruthHint(gt, labels))
    assert np.all(out.depth > 0)
    np.testing.assert_allclose(out.raw_depth[24, 10] / out.depth[24, 10], 60.0 / 50.0, rtol=1e-5)  # f_tr / f_cur
    np.testing.assert_allclose(out.depth[24, 10], 3.3, rtol=1e-3)  # the wrong global scale, eq. 5 applied
    assert out.depth[24, 32] > 2.0  # the small near object is smoothed away
    assert 2.2 < out.depth[24, 50] < 3.3  # the depth edge is blurred
    assert out.label_probs is not None
    np.testing.assert_allclose(out.label_probs.sum(axis=-1), 1.0, rtol=1e-5)
    assert out.label_probs[24, 10].argmax() == 0
    a = DegradedGroundTruthPredictor(seed=5).degrade_depth(gt)
    b = DegradedGroundTruthPredictor(seed=5).degrade_depth(gt)
    np.testing.assert_array_equal(a, b)  # same seed, same bytes


def test_degraded_predictor_needs_ground_truth() -> None:
    from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor, predict_keyframe_depth
    from cnnslam.predictors import make_predictor

    with pytest.raises(CnnSlamError, match="GroundTruthAidedAgent"):
        predict_keyframe_depth(DegradedGroundTruthPredictor(), np.zeros((4, 4, 3), np.uint8),
                               np.array([4.0, 4.0, 1.5, 1.5]), True)
    with pytest.raises(CnnSlamError, match="valid predictors"):
        make_predictor("oracle")


def test_ground_truth_hint_prefers_the_depth_sensor_for_the_lsd_bs_bootstrap() -> None:
    from cnnslam.depth.depth_prediction import GroundTruthHint

    exact = np.full((4, 5), 2.0, np.float32)
    sensor = np.full((4, 5), 2.03, np.float32)
    assert GroundTruthHint.from_info({"frame_index": 0}) is None
    hint = GroundTruthHint.from_info({"gt_depth": exact})
    assert hint.sensor_depth is None and hint.measured_depth is hint.depth  # a real folder: its depth is the sensor's
    hint = GroundTruthHint.from_info({"gt_depth": exact, "sensor_depth": sensor})
    np.testing.assert_array_equal(hint.measured_depth, sensor)
    np.testing.assert_array_equal(hint.depth, exact)


@pytest.mark.parametrize("shape,dtype", [((12, 16), np.float32), ((12, 16, 4), np.float32), ((7,), np.float64)])
def test_perturb_last_bits_is_numpys_definition_bit_for_bit(shape, dtype):
    """The compiled pass equals (v * (1 + N(0, (2 ulp)^2))).astype(float32) with the same draws, and leaves the
    generator where NumPy's draws would (the next frame's draws stay the same)."""
    values = np.random.default_rng(3).uniform(0.1, 9.0, shape).astype(dtype)
    ours, ref = np.random.default_rng(11), np.random.default_rng(11)
    ulp = float(np.finfo(np.float32).eps)
    for _ in range(3):
        out = perturb_last_bits(values, ours)
        noise = ref.standard_normal(shape) * (JITTER_STD_ULPS * ulp)
        expected = (np.asarray(values, np.float32) * (1.0 + noise)).astype(np.float32)
        assert out.dtype == np.float32 and out.shape == shape
        assert np.array_equal(out, expected)
    assert ours.standard_normal() == ref.standard_normal()
    rel = np.abs(out.astype(np.float64) / np.asarray(values, np.float32) - 1.0)
    assert 0 < rel.max() < 20 * ulp  # the last bits only
    legacy, ref = np.random.RandomState(5), np.random.RandomState(5)  # not a Generator: NumPy's expression
    expected = (np.asarray(values, np.float32) * (1.0 + ref.standard_normal(shape) * (JITTER_STD_ULPS * ulp)))
    assert np.array_equal(perturb_last_bits(values, legacy), expected.astype(np.float32))
    assert perturb_last_bits(np.float32(2.0), np.random.default_rng(1)).shape == ()  # a scalar stays 0-d


def test_focal_at_train_size_known_answer():
    """f_cur brought to the network's resolution: fx, fy scaled by W_tr / W and H_tr / H, then averaged."""
    from cnnslam.depth.depth_prediction import focal_at_train_size
    from cnnslam.errors import CnnSlamError

    # a 640x480 image with fx 520, fy 510 seen by a 160x120 network: (520 / 4 + 510 / 4) / 2 = 128.75
    assert focal_at_train_size([520.0, 510.0, 320.0, 240.0], (480, 640), (160, 120)) == 128.75
    with pytest.raises(CnnSlamError, match="positive focal lengths"):
        focal_at_train_size([0.0, 510.0, 320.0, 240.0], (480, 640), (160, 120))

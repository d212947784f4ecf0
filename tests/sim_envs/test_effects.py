"""Sensor effects: off by default, deterministic with a seeded generator, and doing what they say."""

import numpy as np
import pytest

from sim_envs.errors import SimEnvError
from sim_envs.render.effects import (
    SensorEffects,
    apply_exposure,
    apply_noise,
    apply_sensor_effects,
    average_frames,
    blur_offsets,
    exposure_gain,
)

IMG = np.random.default_rng(0).integers(20, 236, (24, 32, 3), dtype=np.uint8)


def test_everything_is_off_by_default():
    fx = SensorEffects()
    assert not fx.any
    out = apply_sensor_effects(IMG, fx, np.random.default_rng(0))
    np.testing.assert_array_equal(out, IMG)
    assert out is not IMG
    np.testing.assert_array_equal(blur_offsets(fx), [0.0])
    assert exposure_gain(fx, np.random.default_rng(0)) == 1.0


def test_effects_are_deterministic_with_a_seeded_generator():
    fx = SensorEffects(noise_std=3.0, exposure_jitter=0.1)
    a = apply_sensor_effects(IMG, fx, np.random.default_rng(5))
    b = apply_sensor_effects(IMG, fx, np.random.default_rng(5))
    c = apply_sensor_effects(IMG, fx, np.random.default_rng(6))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_noise_has_the_requested_spread():
    big = np.full((200, 200, 3), 128, np.uint8)
    noisy = apply_noise(big, 4.0, np.random.default_rng(0)).astype(float)
    assert noisy.mean() == pytest.approx(128, abs=0.1)
    assert noisy.std() == pytest.approx(4.0, rel=0.05)


def test_exposure_scales_and_clips():
    out = apply_exposure(np.array([[[100, 200, 10]]], np.uint8), 1.5)
    np.testing.assert_array_equal(out, [[[150, 255, 15]]])


def test_average_frames_is_the_rounded_mean():
    a, b = np.zeros((2, 2, 3), np.uint8), np.full((2, 2, 3), 255, np.uint8)
    np.testing.assert_array_equal(average_frames([a, b]), np.full((2, 2, 3), 128))
    np.testing.assert_array_equal(average_frames([IMG]), IMG)
    with pytest.raises(SimEnvError):
        average_frames([])


def test_blur_offsets_span_the_shutter():
    offsets = blur_offsets(SensorEffects(blur_subframes=5, shutter_s=0.02))
    np.testing.assert_allclose(offsets, [-0.02, -0.015, -0.01, -0.005, 0.0])


@pytest.mark.parametrize("kwargs", [{"noise_std": -1}, {"blur_subframes": 0}, {"blur_subframes": 1.5},
                                    {"exposure_jitter": -0.1}, {"shutter_s": float("nan")}])  # fmt: skip
def test_bad_settings_are_rejected(kwargs):
    with pytest.raises(SimEnvError):
        SensorEffects(**kwargs)

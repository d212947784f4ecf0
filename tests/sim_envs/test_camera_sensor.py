"""The camera's physics as functions of explicit parameters: known answers for the sRGB curves, the vignetting
fall-off, the rows' exposure times and the blur's render weights."""

import numpy as np
import pytest

from sim_envs.camera import Intrinsics
from sim_envs.sensor.camera_sensor import (
    decode_render,
    linear_to_srgb,
    row_times,
    row_weights,
    srgb_to_linear,
    vignette,
)


def test_srgb_round_trip_and_decoding_table():
    v = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(v)), v, atol=1e-12)
    assert srgb_to_linear(np.array([0.04045]))[0] == pytest.approx(0.04045 / 12.92)  # the linear toe
    rgb = np.arange(256, dtype=np.uint8).reshape(16, 16)[..., None].repeat(3, axis=2)
    np.testing.assert_allclose(decode_render(rgb), srgb_to_linear(rgb / 255.0), atol=1e-7)


def test_vignette_is_one_at_the_centre_and_corner_at_the_farthest_corner():
    K = Intrinsics(50.0, 50.0, 31.5, 23.5, 64, 48)
    V = vignette(K, 0.6)
    assert V.shape == (48, 64) and V.dtype == np.float32
    assert V.max() == pytest.approx(1.0, abs=1e-3) and V.min() == pytest.approx(0.6, abs=0.01)
    np.testing.assert_array_equal(vignette(K, 1.0), np.ones((48, 64), np.float32))


def test_rows_are_read_top_to_bottom_around_the_timestamp():
    t = row_times(5, 0.04)
    np.testing.assert_allclose(t, [-0.02, -0.01, 0.0, 0.01, 0.02])
    assert not row_times(5, 0.0).any()
    w = row_weights(np.array([-0.02, 0.0, 0.02]), t, 0.0)
    np.testing.assert_allclose(w.sum(axis=0), 1.0, rtol=1e-6)  # each row a mean of the renders
    np.testing.assert_allclose(w[:, 0], [1, 0, 0])
    np.testing.assert_allclose(w[:, 2], [0, 1, 0])
    np.testing.assert_allclose(w[:, 1], [0.5, 0.5, 0])  # between two renders: linear interpolation in time

"""The image pyramid: known answers for the gradients, the halving and the per-level intrinsics."""

import numpy as np
import pytest

import cnnslam.track.tracking as tracking
from cnnslam.errors import CnnSlamError
from cnnslam.track.pyramid import build_image_pyramid, central_gradients, to_gray


def test_central_gradients_of_a_ramp() -> None:
    img = np.add.outer(2.0 * np.arange(5), 3.0 * np.arange(6)).astype(np.float32)  # I = 2 y + 3 x
    gx, gy = central_gradients(img)
    np.testing.assert_array_equal(gx[:, 1:-1], 3.0)
    np.testing.assert_array_equal(gy[1:-1, :], 2.0)
    assert not gx[:, [0, -1]].any() and not gy[[0, -1], :].any()  # 0 on the border


def test_pyramid_halves_images_and_intrinsics() -> None:
    img = np.arange(16 * 8, dtype=np.float32).reshape(8, 16)
    pyr = build_image_pyramid(img, np.array([100.0, 90.0, 7.5, 3.5]), 3)
    assert pyr.levels == 3 and pyr.shape == (8, 16)
    assert [i.shape for i in pyr.images] == [(8, 16), (4, 8), (2, 4)]
    np.testing.assert_allclose(pyr.images[1][0, 0], img[:2, :2].mean())  # 2x2 averaging
    np.testing.assert_allclose(pyr.intrinsics[1][:2], [50.0, 45.0])
    np.testing.assert_array_equal(pyr.stacked[2][..., 1], pyr.grad_x[2])  # views of the interleaved array
    assert np.shares_memory(pyr.images[0], pyr.stacked[0])


def test_pyramid_refuses_sizes_not_divisible_and_gray_needs_uint8_rgb() -> None:
    with pytest.raises(CnnSlamError, match="divisible by 2"):
        build_image_pyramid(np.zeros((6, 10), np.float32), np.array([1.0, 1.0, 0.0, 0.0]), 3)
    with pytest.raises(CnnSlamError, match="uint8 RGB"):
        to_gray(np.zeros((4, 4, 3), np.float32))


def test_tracking_reexports_the_pyramid() -> None:
    assert tracking.build_image_pyramid is build_image_pyramid and tracking.to_gray is to_gray

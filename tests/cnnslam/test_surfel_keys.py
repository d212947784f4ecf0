"""Voxel keys and radial confidence: known answers."""

import numpy as np
import pytest

import cnnslam.model.global_model as global_model
from cnnslam.model.surfel_keys import KEY_BITS, KEY_OFFSET, radial_confidence, voxel_keys


def test_voxel_key_packs_voxel_coordinates_and_normal_direction() -> None:
    p = np.array([[0.05, -0.05, 0.25], [0.05, -0.05, 0.25], [0.06, -0.01, 0.21]])
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.1, 0.2, 0.9]])
    keys = voxel_keys(p, n, 0.1)
    vox = np.array([0, -1, 2]) + KEY_OFFSET
    expected = (vox[0] << (2 * KEY_BITS + 3)) | (vox[1] << (KEY_BITS + 3)) | (vox[2] << 3) | 4  # +z: 2 * 2 + 0
    assert keys[0] == expected and keys[1] == expected + 1  # -z: the other side of a board is another key
    assert keys[2] == keys[0]  # same voxel, normal mostly +z


def test_radial_confidence_is_one_at_the_principal_point_and_exp_minus_half_over_sigma2_at_the_corner() -> None:
    alpha = radial_confidence((5, 7), np.array([10.0, 10.0, 3.0, 2.0]), sigma=0.6)
    assert alpha.dtype == np.float32 and alpha.shape == (5, 7)
    assert alpha[2, 3] == pytest.approx(1.0)
    assert alpha[0, 0] == pytest.approx(np.exp(-1.0 / (2 * 0.36)), rel=1e-6)


def test_global_model_reexports_the_keys() -> None:
    assert global_model.voxel_keys is voxel_keys and global_model.radial_confidence is radial_confidence

"""slamcommon.formats.kitti: KITTI pose files round-trip; a block that is not a rotation is refused by line."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from slamcommon.errors import FormatError
from slamcommon.formats.kitti import read_kitti_poses, write_kitti_poses


def test_kitti_poses_round_trip(tmp_path):
    T = np.tile(np.eye(4), (3, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec([[0, 0, 0], [0.1, 0.2, 0.3], [-0.5, 0.0, 1.0]]).as_matrix()
    T[:, :3, 3] = [[0, 0, 0], [1.5, -2.0, 0.25], [3.0, 1.0, -1.0]]
    got = read_kitti_poses(write_kitti_poses(tmp_path / "k.txt", T))
    np.testing.assert_allclose(got, T, atol=1e-11)


def test_a_scaled_block_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "k.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 2 0 0 0 0 2 0\n")
    with pytest.raises(FormatError, match=r"k\.txt:2: the 3x3 block is not a rotation"):
        read_kitti_poses(path)

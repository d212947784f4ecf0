"""slamcommon.formats.seven_scenes: a 7-Scenes pose file's rotation projected onto SO(3); no pose is all NaN."""

import numpy as np
import pytest

from slamcommon.errors import FormatError
from slamcommon.formats.seven_scenes import SEVEN_SCENES_COLOUR, read_pose_matrix


def test_a_nearly_orthonormal_pose_is_projected_and_keeps_its_translation(tmp_path):
    M = np.eye(4)
    M[:3, :3] += 2e-4 * np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]])
    M[:3, 3] = [0.5, -1.0, 2.0]
    path = tmp_path / "frame-000000.pose.txt"
    np.savetxt(path, M, delimiter="\t")
    T = read_pose_matrix(path)
    np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)
    assert T[:3, 3].tolist() == [0.5, -1.0, 2.0]
    np.savetxt(path, np.full((4, 4), np.inf))
    assert np.isnan(read_pose_matrix(path)).all()
    np.savetxt(path, np.eye(3))
    with pytest.raises(FormatError, match="expected 4 rows of 4 numbers"):
        read_pose_matrix(path)


def test_the_colour_file_name_gives_prefix_and_frame_number():
    match = SEVEN_SCENES_COLOUR.match("frame-000042.color.png")
    assert match is not None and match[1] == "frame-000042" and int(match[2]) == 42
    assert SEVEN_SCENES_COLOUR.match("frame-000042.depth.png") is None

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.metrics.trajectory import (
    PoseTrajectory,
    TrajectoryError,
    distances_along_path,
    path_length,
    relative_pose,
    rotation_share,
    se3_inverse,
    so3_angle,
    transform_poses,
)


def poses(n, seed=0):
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    T[:, :3, 3] = np.random.default_rng(seed).normal(size=(n, 3))
    return T


def test_se3_inverse_and_relative():
    T = poses(10)
    np.testing.assert_allclose(se3_inverse(T) @ T, np.tile(np.eye(4), (10, 1, 1)), atol=1e-12)
    np.testing.assert_allclose(relative_pose(T[0], T[1]), np.linalg.inv(T[0]) @ T[1], atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-4, 0.5, np.pi / 2, np.pi - 1e-7, np.pi])
def test_so3_angle_accurate_over_the_whole_range(angle):
    R = Rotation.from_rotvec(angle * np.array([0.6, 0.0, 0.8])).as_matrix()
    assert so3_angle(R) == pytest.approx(angle, abs=1e-12, rel=1e-9)


def test_transform_poses_moves_the_world_not_the_camera_axes():
    T = poses(5)
    R = Rotation.from_rotvec([0.0, 0.0, np.pi / 2]).as_matrix()
    out = transform_poses(T, R, np.array([1.0, 0.0, 0.0]), 2.0)
    np.testing.assert_allclose(out[:, :3, 3], 2.0 * T[:, :3, 3] @ R.T + [1.0, 0.0, 0.0])
    np.testing.assert_allclose(out[:, :3, :3], R @ T[:, :3, :3])
    assert np.allclose(np.linalg.det(out[:, :3, :3]), 1.0)


def test_path_length():
    p = np.array([[0, 0, 0], [3, 4, 0], [3, 4, 2.0]])
    assert path_length(p) == 7.0
    np.testing.assert_array_equal(distances_along_path(p), [0.0, 5.0, 7.0])
    assert path_length(p[:1]) == 0.0


def test_pose_trajectory_validation_and_read_only():
    T = poses(3)
    traj = PoseTrajectory([0.0, 1.0, 2.0], T)
    assert len(traj) == 3 and traj.positions.shape == (3, 3) and traj.rotations.shape == (3, 3, 3)
    with pytest.raises(ValueError):
        traj.T_world_cam[0, 0, 0] = 5.0
    T[0, 0, 3] = 123.0  # the trajectory holds its own copy
    assert traj.T_world_cam[0, 0, 3] != 123.0
    assert traj.subset(np.array([2, 2])).timestamps.tolist() == [2.0, 2.0]
    with pytest.raises(TrajectoryError, match="pair one to one"):
        PoseTrajectory([0.0, 1.0], T)
    with pytest.raises(TrajectoryError, match=r"\(N, 4, 4\)"):
        PoseTrajectory([0.0], np.eye(3)[None])


def test_files_round_trip_through_the_trajectory(tmp_path):
    traj = PoseTrajectory(np.arange(4) / 10.0, poses(4, seed=2))
    back = PoseTrajectory.from_tum_file(traj.to_tum_file(tmp_path / "t.txt"))
    np.testing.assert_allclose(back.T_world_cam, traj.T_world_cam, atol=2e-9)
    kitti = PoseTrajectory.from_kitti_file(traj.to_kitti_file(tmp_path / "k.txt"))
    np.testing.assert_allclose(kitti.T_world_cam, traj.T_world_cam, atol=1e-11)
    np.testing.assert_allclose(kitti.timestamps, np.arange(4) / 10.0)
    (tmp_path / "bad.txt").write_text("1 2 3\n")
    with pytest.raises(TrajectoryError, match=r"bad\.txt:1: expected 8 columns"):
        PoseTrajectory.from_tum_file(tmp_path / "bad.txt")


def test_rotation_share_known_answers():
    n = 5
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, 0, 3] = 0.1 * np.arange(n)  # translation only
    assert rotation_share(T) == 0.0
    R = np.tile(np.eye(4), (n, 1, 1))
    R[:, :3, :3] = Rotation.from_euler("y", 0.05 * np.arange(n)[:, None]).as_matrix()  # rotation only
    assert rotation_share(R) == pytest.approx(1.0)
    both = R.copy()
    both[:, 0, 3] = 0.1 * np.arange(n)  # 0.05 rad and 0.1 m per step, scene 2 m away: 0.05 / (0.05 + 0.05)
    assert rotation_share(both, depth_m=2.0) == pytest.approx(0.5)
    assert math.isnan(rotation_share(np.tile(np.eye(4), (3, 1, 1))))

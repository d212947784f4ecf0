"""The trajectory record's helpers: frame times, smooth noise, look-at rotations, and their re-export."""

import numpy as np
import pytest

import sim_envs.motion.trajectories as trajectories
from sim_envs.errors import SimEnvError
from sim_envs.motion.trajectory_core import FPS, Trajectory, frame_times, look_at, poses_from, smooth_noise


def test_frame_times_are_i_over_fps_and_need_two_frames() -> None:
    np.testing.assert_array_equal(frame_times(4, 30.0, t0=1.0), 1.0 + np.arange(4) / 30.0)
    with pytest.raises(SimEnvError, match="at least 2 frames"):
        frame_times(1)


def test_periodic_smooth_noise_ends_where_it_starts() -> None:
    times = frame_times(300, FPS)
    noise = smooth_noise(np.random.default_rng(3), times, sigma=2.0, periodic=True)
    assert noise[0] == pytest.approx(noise[-1]) and noise.std() > 0.1


def test_look_at_points_the_optical_axis_at_the_target_with_image_y_down() -> None:
    R = look_at(np.array([0.0, 0.0, 1.0]), np.array([2.0, 0.0, 1.0])).as_matrix()[0]
    np.testing.assert_allclose(R[:, 2], [1.0, 0.0, 0.0], atol=1e-12)  # z forward along +x
    np.testing.assert_allclose(R[:, 1], [0.0, 0.0, -1.0], atol=1e-12)  # y down = world -z


def test_trajectories_reexports_the_record_and_helpers() -> None:
    assert trajectories.Trajectory is Trajectory and trajectories.look_at is look_at
    assert trajectories.poses_from is poses_from and trajectories.FPS == FPS
    assert set(trajectories.__all__) >= {"Trajectory", "look_at", "poses_from", "frame_times", "smooth_noise"}

"""The path-building steps of the trajectory generators: the camera driven through waypoints (open, slowed down,
closed), in a room that is free everywhere or nowhere."""

import numpy as np
import pytest

from sim_envs.motion.trajectory_core import FPS, frame_times
from sim_envs.motion.trajectory_paths import SLOW_DOWNS, Limits, drive, segment_durations


class _Room:
    """A 6 x 6 x 3 m room whose free space is everywhere (or nowhere), looking at its centre."""

    def __init__(self, free: bool = True) -> None:
        self.room_size = np.array([6.0, 6.0, 3.0])
        self.free = free

    def bounds(self) -> np.ndarray:
        return np.array([[0.0, 0.0, 0.0], self.room_size])

    def interest_points(self) -> np.ndarray:
        return np.array([[3.0, 3.0, 1.0]])

    def free_space(self, points: np.ndarray, margin: float = 0.3) -> np.ndarray:
        return np.full(len(np.atleast_2d(points)), self.free)


EYES = np.array([[1.0, 1.0, 1.5], [2.0, 1.2, 1.5], [3.0, 1.0, 1.5], [4.0, 1.3, 1.5]])
TARGETS = np.array([[3.0, 5.0, 1.0], [3.2, 5.0, 1.0], [3.4, 5.0, 1.0], [3.6, 5.0, 1.0]])
LIMITS = Limits(margin=0.3, max_speed=0.6, max_angular_speed_deg=35.0, height_range=(1.0, 1.8))


def test_open_path_starts_at_the_first_waypoint_and_keeps_the_limits() -> None:
    times = frame_times(200, FPS)
    durations = segment_durations(EYES, TARGETS, 0.3, np.radians(17.5))
    traj = drive(_Room(), times, EYES, TARGETS, durations, np.zeros(200), LIMITS, "handheld")
    assert traj is not None and traj.kind == "handheld"
    np.testing.assert_allclose(traj.positions[0], EYES[0])
    assert traj.linear_speeds().max() <= LIMITS.max_speed


def test_open_path_is_slowed_down_until_its_speeds_are_within_the_limits() -> None:
    eyes = np.column_stack([np.arange(10.0), 1.0 + 0.2 * (np.arange(10) % 2), np.full(10, 1.5)])  # 1 m steps
    targets = eyes + [0.0, 5.0, -0.5]
    times = frame_times(300, FPS)  # 10 s; the knots at 1.25 s a segment span 11.25 s at 0.8 m/s
    fast = np.full(9, 1.25)
    assert drive(_Room(), times, eyes, targets, fast, np.zeros(300), LIMITS, "handheld") is None
    traj = drive(_Room(), times, eyes, targets, fast, np.zeros(300), LIMITS, "handheld", slow_downs=SLOW_DOWNS)
    assert traj is not None and 0.4 < traj.linear_speeds().max() <= LIMITS.max_speed


def test_a_walk_too_short_for_the_frames_or_a_blocked_path_gives_none() -> None:
    times = frame_times(600, FPS)  # 20 s, but the segments last 3 x 4 s even at the largest slow-down
    durations = np.full(3, 4.0 / SLOW_DOWNS[-1])
    assert drive(_Room(), times, EYES, TARGETS, durations, np.zeros(600), LIMITS, "handheld",
                 slow_downs=SLOW_DOWNS) is None  # fmt: skip
    times = frame_times(200, FPS)
    assert drive(_Room(free=False), times, EYES, TARGETS, np.full(3, 3.0), np.zeros(200), LIMITS, "handheld") is None


def test_closed_loop_ends_exactly_where_it_started() -> None:
    ring = np.array([[2.0, 2.0, 1.5], [4.0, 2.0, 1.5], [4.0, 4.0, 1.5], [2.0, 4.0, 1.5]])
    closed_eyes = np.vstack([ring, ring[:1]])
    closed_targets = np.vstack([np.full((4, 3), [3.0, 3.0, 1.0]) + [0.0, 0.0, 0.1] * np.arange(4)[:, None],
                                [[3.0, 3.0, 1.0]]])  # fmt: skip
    times = frame_times(900, FPS)
    durations = segment_durations(closed_eyes, closed_targets + [0.5, 0.0, 0.0], 0.3, np.radians(17.5))
    traj = drive(_Room(), times, closed_eyes, closed_targets + [0.5, 0.0, 0.0], durations, np.zeros(900),
                 LIMITS, "loop", lap=times[-1] - times[0])  # fmt: skip
    assert traj is not None
    np.testing.assert_array_equal(traj.T_world_cam[-1], traj.T_world_cam[0])
    np.testing.assert_allclose(traj.positions[0], ring[0])


@pytest.mark.parametrize("height", [0.5, 2.5])
def test_heights_outside_the_range_are_refused(height: float) -> None:
    eyes = EYES.copy()
    eyes[:, 2] = height
    times = frame_times(200, FPS)
    assert drive(_Room(), times, eyes, TARGETS, np.full(3, 3.0), np.zeros(200), LIMITS, "handheld") is None

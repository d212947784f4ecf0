"""Camera motion from recordings: a recorded trajectory replayed in a room (:func:`replay`), resampled whole
(:func:`recorded_motion`), its motion statistics (:class:`MotionStatistics`, :func:`motion_statistics`; TUM fr1/desk's
as :data:`FR1_DESK_MOTION`), and hand-held motion generated to such statistics (:func:`handheld_stats`).

Conventions as :mod:`sim_envs.motion.trajectories`: 30 Hz, ``T_world_cam`` (N, 4, 4) float64, OpenCV camera axes,
world z up, metres. The statistics are measured on a recording's ground-truth motion, never on SLAM results.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sim_envs.errors import SimEnvError
from sim_envs.motion import trajectory_paths as paths
from sim_envs.motion.trajectory_core import (
    FPS,
    MAX_ATTEMPTS,
    SceneLike,
    Trajectory,
    frame_times,
    look_at,
    poses_from,
    smooth_noise,
)


def replay(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    file: str,
    start_s: float = 0.0,
    fps: float = FPS,
    t0: float = 0.0,
    margin: float = 0.3,
    height_range: tuple[float, float] = (1.0, 1.8),
    target_distance: tuple[float, float] = (1.0, 4.0),
) -> Trajectory:
    """A recorded camera motion (a TUM trajectory ``file``: real hand-held motion, e.g. a TUM RGB-D ground truth)
    replayed in this room from ``start_s`` seconds after the recording's first pose.

    The recording is resampled at the frame times (positions linearly, rotations by spherical interpolation:
    motion-capture poses at 100 Hz are dense enough for both) and taken relative to its first resampled pose, in
    that camera's axes; the motion is then started from a camera placed in the room: an optical centre drawn in free
    space at a height within ``height_range`` (m), upright, aimed at an interest point ``target_distance`` (m)
    away. The relative motion is kept exactly (path, speeds, rotations, hand shake); the recorded camera's tilt to
    gravity at its first pose is not (the start is upright). A start is accepted when every optical centre keeps
    ``margin`` m from any surface and stays inside the room; after :data:`MAX_ATTEMPTS` starts
    :class:`SimEnvError`. The file must cover ``start_s + (n_frames - 1) / fps`` seconds.
    """
    from sim_envs.folders.formats import read_tum_trajectory

    stamps, T = read_tum_trajectory(file, duplicate_timestamps="first")
    times = frame_times(n_frames, fps, t0)
    src = stamps[0] + float(start_s) + (times - times[0])
    if start_s < 0:
        raise SimEnvError(f"start_s must be >= 0 seconds into the recording, got {start_s}")
    if src[-1] > stamps[-1]:
        raise SimEnvError(f"{file} covers {stamps[-1] - stamps[0]:.2f} s; {n_frames} frames at {fps:g} fps from "
                          f"{start_s:g} s need {src[-1] - stamps[0]:.2f} s")  # fmt: skip
    recorded = _resampled(stamps, T, src)
    relative = np.linalg.inv(recorded[0]) @ recorded  # T_first_cam: the motion in the first camera's axes
    points = paths.interest(scene)
    lo, hi = paths.room_box(scene)
    for _ in range(MAX_ATTEMPTS):
        eye = paths.random_free_point(scene, rng, height_range, margin)
        if eye is None:
            continue
        target = paths.pick_target(rng, eye, points, target_distance, None, np.pi)
        if target is None:
            continue
        poses = poses_from(eye, look_at(eye, target))[0] @ relative
        centres = poses[:, :3, 3]
        inside = bool(np.all((centres > lo + margin) & (centres < hi - margin)))
        if inside and bool(np.all(scene.free_space(centres, margin=margin))):
            return Trajectory(times, poses, kind="replay")
    raise SimEnvError(paths.gave_up("replay", scene))


def _resampled(stamps: np.ndarray, T: np.ndarray, src: np.ndarray) -> np.ndarray:
    """(len(src), 4, 4) poses of a recording (``stamps`` (M,) s, ``T`` (M, 4, 4)) at the times ``src``: positions
    linearly, rotations by spherical interpolation."""
    from scipy.spatial.transform import Slerp

    positions = np.column_stack([np.interp(src, stamps, T[:, k, 3]) for k in range(3)])
    rotations = Slerp(stamps, Rotation.from_matrix(T[:, :3, :3]))(src)
    return poses_from(positions, rotations)


def recorded_motion(file: str, fps: float = FPS) -> Trajectory:
    """A TUM trajectory ``file`` (e.g. a TUM RGB-D ground truth) resampled at ``fps`` Hz over the whole recording, as
    :func:`replay` resamples it (positions linearly, rotations by spherical interpolation), in its own world frame;
    timestamps from 0."""
    from sim_envs.folders.formats import read_tum_trajectory

    stamps, T = read_tum_trajectory(file, duplicate_timestamps="first")
    n = int(np.floor((stamps[-1] - stamps[0]) * fps + 1e-9)) + 1
    times = frame_times(n, fps)
    return Trajectory(times, _resampled(stamps, T, stamps[0] + times), kind="replay")


JERK_WINDOW: int = 9  # frames of the Savitzky-Golay window (cubic) the jerk is measured with: 0.3 s at 30 Hz (ours)


@dataclass(frozen=True)
class MotionStatistics:
    """How a camera moves, over a trajectory sampled at 30 Hz (:func:`motion_statistics`).

    speed_mean, speed_p90: mean and 90th percentile of the frame-to-frame speed of the optical centre (m/s);
    angular_speed_mean_deg, angular_speed_p90_deg: the same of the frame-to-frame rotation angle over the time step
    (deg/s); jerk_rms: root mean square of the magnitude of the position's third derivative (m/s^3), from a cubic
    Savitzky-Golay filter over :data:`JERK_WINDOW` frames (a plain third difference of motion-capture poses is
    their noise); angular_rate_share: the root mean square angular velocity about the camera's x (tilt), y (pan)
    and z (roll) axes, each over the largest; velocity_share: the same of the optical centre's velocity along the
    camera's x, y, z axes; angular_rate_halftime_s, velocity_halftime_s: per camera axis, the lag (s) at which the
    autocorrelation of that angular velocity / velocity component first falls below 1/2 (how long a motion lasts);
    frames: how many poses."""

    speed_mean: float
    speed_p90: float
    angular_speed_mean_deg: float
    angular_speed_p90_deg: float
    jerk_rms: float
    angular_rate_share: tuple[float, float, float]
    velocity_share: tuple[float, float, float]
    angular_rate_halftime_s: tuple[float, float, float]
    velocity_halftime_s: tuple[float, float, float]
    frames: int

    def as_dict(self) -> dict[str, Any]:
        """The statistics as a dict (field order)."""
        return asdict(self)


def motion_statistics(trajectory: Trajectory) -> MotionStatistics:
    """:class:`MotionStatistics` of a trajectory (at least :data:`JERK_WINDOW` poses; the frame-to-frame figures
    are those of :meth:`Trajectory.linear_speeds` and :meth:`Trajectory.angular_speeds_deg`)."""
    from scipy.signal import savgol_filter

    n = len(trajectory)
    if n < JERK_WINDOW:
        raise SimEnvError(f"motion statistics need at least {JERK_WINDOW} poses, got {n}")
    dt = float(np.median(np.diff(trajectory.timestamps)))
    speed, ang = trajectory.linear_speeds(), trajectory.angular_speeds_deg()
    jerk = savgol_filter(trajectory.positions, JERK_WINDOW, 3, deriv=3, delta=dt, axis=0)
    rots = trajectory.rotations
    rates = (rots[:-1].inv() * rots[1:]).as_rotvec() / np.diff(trajectory.timestamps)[:, None]  # camera axes
    world_vel = np.diff(trajectory.positions, axis=0) / np.diff(trajectory.timestamps)[:, None]
    cam_vel = np.einsum("nji,nj->ni", rots[:-1].as_matrix(), world_vel)  # R^T v: the velocity in camera axes

    def share(v: np.ndarray) -> tuple[float, float, float]:
        rms = np.sqrt(np.mean(v**2, axis=0))
        return tuple(float(x) for x in rms / max(float(rms.max()), 1e-12))  # type: ignore[return-value]

    def halftime(v: np.ndarray) -> tuple[float, float, float]:
        out = []
        for x in (v - v.mean(axis=0)).T:
            ac = np.correlate(x, x, "full")[len(x) - 1 :]
            below = np.flatnonzero(ac < 0.5 * ac[0]) if ac[0] > 0 else np.array([0])
            out.append(float(below[0] * dt) if below.size else float(len(x) * dt))
        return tuple(out)  # type: ignore[return-value]

    return MotionStatistics(
        speed_mean=float(speed.mean()), speed_p90=float(np.percentile(speed, 90)),
        angular_speed_mean_deg=float(ang.mean()), angular_speed_p90_deg=float(np.percentile(ang, 90)),
        jerk_rms=float(np.sqrt(np.mean(np.sum(jerk**2, axis=1)))), angular_rate_share=share(rates),
        velocity_share=share(cam_vel), angular_rate_halftime_s=halftime(rates),
        velocity_halftime_s=halftime(cam_vel), frames=n,
    )  # fmt: skip


# TUM RGB-D fr1/desk's motion: motion_statistics(recorded_motion(".../rgbd_dataset_freiburg1_desk/groundtruth.txt"))
# over the whole ground truth (23.4 s resampled at 30 Hz), rounded; tests/sim_envs/test_trajectories.py recomputes it
# where the folder is. Test data: these targets are measured from its ground-truth motion, never from SLAM results.
FR1_DESK_MOTION = MotionStatistics(
    speed_mean=0.453, speed_p90=0.671, angular_speed_mean_deg=34.8, angular_speed_p90_deg=61.1, jerk_rms=8.33,
    angular_rate_share=(0.65, 1.0, 0.91), velocity_share=(1.0, 0.57, 0.59), angular_rate_halftime_s=(0.07, 0.17, 0.23),
    velocity_halftime_s=(1.9, 0.43, 0.4), frames=702,
)  # fmt: skip
# median of every valid depth pixel of fr1/desk's 573 frames (sim_envs.sensor.camera_calibration.depth_statistics;
# m): how far the scene is, the distance the generator keeps from its focus
FR1_DESK_DEPTH_M: float = 1.02
FR1_DESK_DEPTH_RANGE_M: tuple[float, float] = (0.61, 1.95)  # its 10th and 90th percentiles (the same pixels; m)


# A natural cubic spline through normal draws every s seconds (smooth_noise) has a derivative whose autocorrelation
# falls to 1/2 after about 0.45 s per second of knot spacing (measured on smooth_noise over 100 s, 20 draws per
# spacing, 0.2-4 s); handheld_stats sets its knot spacings from a target's half-times with it.
HALFTIME_PER_KNOT_S: float = 0.45


def _unit_rate_noise(rng: np.random.Generator, times: np.ndarray, halftimes: Sequence[float],
                     shares: Sequence[float]) -> np.ndarray:  # fmt: skip
    """(N, 3) smooth random signals, column k with knots every ``halftimes[k] / HALFTIME_PER_KNOT_S`` seconds, scaled
    so that its derivative's root mean square is ``shares[k]``."""
    cols = []
    for half, share in zip(halftimes, shares, strict=True):
        x = smooth_noise(rng, times, 1.0, knot_spacing=max(float(half) / HALFTIME_PER_KNOT_S, 2.0 / FPS))
        rate = np.diff(x) / np.diff(times)
        cols.append(float(share) * x / max(float(np.sqrt(np.mean(rate**2))), 1e-12))
    return np.column_stack(cols)


def handheld_stats(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    speed: float = FR1_DESK_MOTION.speed_mean,
    angular_speed_deg: float = FR1_DESK_MOTION.angular_speed_mean_deg,
    velocity_share: tuple[float, float, float] = FR1_DESK_MOTION.velocity_share,
    angular_rate_share: tuple[float, float, float] = FR1_DESK_MOTION.angular_rate_share,
    velocity_halftime_s: tuple[float, float, float] = FR1_DESK_MOTION.velocity_halftime_s,
    angular_rate_halftime_s: tuple[float, float, float] = FR1_DESK_MOTION.angular_rate_halftime_s,
    distance: tuple[float, float] = (0.8 * FR1_DESK_DEPTH_M, 1.25 * FR1_DESK_DEPTH_M),
    focus_height: tuple[float, float] = (0.5, 1.2),
    distance_limits: tuple[float, float] = FR1_DESK_DEPTH_RANGE_M,
    height_range: tuple[float, float] = (1.1, 1.9),
    margin: float = 0.3,
) -> Trajectory:
    """A hand-held camera made to given motion statistics (:class:`MotionStatistics`; default TUM fr1/desk's,
    :data:`FR1_DESK_MOTION`): close to scene content, shaking and sweeping over it as a hand does.

    The camera looks at a focus: an interest point ``focus_height`` (m) high (the tops of desks and tables and what
    stands on them), ``distance`` (m) from a start in free space at a height within ``height_range`` (default
    0.8-1.25 x fr1/desk's median depth). Its optical centre moves by smooth random offsets along the start camera's
    x, y, z axes (:func:`smooth_noise`, knot spacings from ``velocity_halftime_s`` through
    :data:`HALFTIME_PER_KNOT_S`, root mean square rates in the ratios ``velocity_share``), scaled so that the mean
    frame-to-frame speed is exactly ``speed`` (m/s); it keeps aiming at the focus, and smooth random rotations about
    its x, y, z axes (knots from ``angular_rate_halftime_s``, rates in the ratios ``angular_rate_share``) are added,
    scaled (by bisection) until the mean frame-to-frame angular speed is ``angular_speed_deg`` (deg/s, within
    0.5 %). A draw is kept when every optical centre keeps ``margin`` m from any surface inside the room, stays
    ``distance_limits`` (m; default fr1/desk's 10th to 90th percentile of depth) from the focus, and
    aiming at the focus alone turns the camera slower than ``angular_speed_deg``; after :data:`MAX_ATTEMPTS` draws
    :class:`SimEnvError`. The targets are fitted to a recording's ground-truth motion statistics, never to SLAM
    results.
    """
    paths.check_speed(speed, 10.0 * speed if speed > 0 else 1.0)
    if not angular_speed_deg > 0:
        raise SimEnvError(f"angular_speed_deg must be positive, got {angular_speed_deg}")
    times = frame_times(n_frames, fps, t0)
    points = paths.interest(scene)
    focus = points[(points[:, 2] >= focus_height[0]) & (points[:, 2] <= focus_height[1])]
    if focus.shape[0] == 0:
        raise SimEnvError(f"the room has no interest point {focus_height[0]:g}-{focus_height[1]:g} m high to look at")
    lo, hi = paths.room_box(scene)
    target_rad = np.radians(angular_speed_deg)
    for _ in range(MAX_ATTEMPTS):
        eye0 = paths.random_free_point(scene, rng, height_range, margin + 0.2)
        if eye0 is None:
            continue
        target = paths.pick_target(rng, eye0, focus, distance, None, np.pi, max_pitch_rad=np.radians(70.0))
        if target is None:
            continue
        axes = look_at(eye0, target).as_matrix()[0]  # columns: the start camera's x, y, z in world coordinates
        offsets = _unit_rate_noise(rng, times, velocity_halftime_s, velocity_share) @ axes.T
        offsets -= offsets[0]
        base_speed = float(np.mean(np.linalg.norm(np.diff(offsets, axis=0), axis=1) / np.diff(times)))
        eyes = eye0 + offsets * (speed / base_speed)
        shake = _unit_rate_noise(rng, times, angular_rate_halftime_s, angular_rate_share)
        shake -= shake[0]
        inside = bool(np.all((eyes > lo + margin) & (eyes < hi - margin)))
        seen = np.linalg.norm(eyes - target, axis=1)
        inside &= bool(np.all((seen >= distance_limits[0]) & (seen <= distance_limits[1])))
        if not (inside and bool(np.all(scene.free_space(eyes, margin=margin)))):
            continue
        aim = look_at(eyes, target)

        def rate(c: float, aim: Rotation = aim, shake: np.ndarray = shake) -> tuple[float, Rotation]:
            rot = aim * Rotation.from_rotvec(c * shake)
            return float(np.mean((rot[:-1].inv() * rot[1:]).magnitude() / np.diff(times))), rot

        low, rot = rate(0.0)
        if low >= target_rad:
            continue
        c_lo, c_hi = 0.0, 1.0
        while rate(c_hi)[0] < target_rad and c_hi < 1e3:
            c_lo, c_hi = c_hi, 2.0 * c_hi
        for _ in range(60):
            mid = 0.5 * (c_lo + c_hi)
            value, rot = rate(mid)
            if abs(value / target_rad - 1.0) < 1e-3:
                break
            c_lo, c_hi = (mid, c_hi) if value < target_rad else (c_lo, mid)
        targets = np.repeat(target[None, :], len(times), axis=0)
        return Trajectory(times, poses_from(eyes, rot), kind="handheld_stats", targets=targets)
    raise SimEnvError(paths.gave_up("handheld_stats", scene))

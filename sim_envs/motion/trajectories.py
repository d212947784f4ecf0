"""Camera trajectories at 30 Hz: hand-held, pure rotation, loops, close to a textured plane, far structure, low texture,
recorded real motion replayed in a room and hand-held motion made to a recording's motion statistics (both from
:mod:`sim_envs.motion.recorded`).

A :class:`Trajectory` is a frozen pair of arrays, ``timestamps`` (N,) float64 seconds and ``T_world_cam`` (N, 4, 4)
float64 camera-to-world poses (OpenCV camera axes: x right, y down, z forward; world z up, metres), plus a continuous
:meth:`Trajectory.pose_at` (cubic spline on positions, :class:`scipy.spatial.transform.RotationSpline` on
rotations) for motion-blur sub-frames.

Generators take a scene (anything with ``bounds()``, ``interest_points()``, ``free_space(points, margin)`` and
``room_size``, see :class:`SceneLike`) and a ``numpy.random.Generator``; the same generator state gives the same
trajectory. They build smooth paths through waypoints with :class:`scipy.interpolate.CubicSpline`, aim the optical
axis at scene content (the scene's interest points), and check the result (free space, speeds) before returning it;
when a check fails they draw new waypoints, and after :data:`MAX_ATTEMPTS` they raise :class:`SimEnvError`.

The record and the pose helpers are defined in :mod:`sim_envs.motion.trajectory_core` and the generators' path-building
steps
(waypoint walks, rings, the acceptance check, :func:`sim_envs.motion.trajectory_paths.drive`) in
:mod:`sim_envs.motion.trajectory_paths`; this module holds the generators and their registry and re-exports the record
and the helpers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.motion import trajectory_paths as paths
from sim_envs.motion.recorded import (
    FR1_DESK_DEPTH_M,
    FR1_DESK_DEPTH_RANGE_M,
    FR1_DESK_MOTION,
    MotionStatistics,
    handheld_stats,
    motion_statistics,
    recorded_motion,
    replay,
)
from sim_envs.motion.trajectory_core import (
    FPS,
    MAX_ATTEMPTS,
    WORLD_UP,
    SceneLike,
    Trajectory,
    frame_times,
    look_at,
    poses_from,
    smooth_noise,
)

__all__ = [
    "FPS", "FR1_DESK_DEPTH_M", "FR1_DESK_DEPTH_RANGE_M", "FR1_DESK_MOTION", "MAX_ATTEMPTS", "MotionStatistics",
    "ROTATION_AXES", "TRAJECTORY_KINDS", "SceneLike", "Trajectory", "TrajectoryGenerator", "far_structure",
    "frame_times", "handheld", "handheld_stats", "look_at", "loop", "low_texture", "make_trajectory",
    "motion_statistics", "parse_axes", "plane_near", "poses_from", "recorded_motion", "replay", "rotation",
    "smooth_noise", "sweep_angles", "trajectory_params",
]  # fmt: skip


# --------------------------------------------------------------------------------------------------------------------
# Generators


def handheld(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    speed: float = 0.3,
    max_speed: float = 0.6,
    max_angular_speed_deg: float = 35.0,
    height_range: tuple[float, float] = (1.0, 1.8),
    margin: float = 0.4,
    target_distance: tuple[float, float] = (1.0, 4.0),
    roll_deg: float = 2.0,
) -> Trajectory:
    """A hand-held camera wandering through the room's free space while looking at scene content (like ICL-NUIM).

    The optical centre follows a natural cubic spline through a random walk of waypoints 0.5-1.2 m apart, at heights
    within ``height_range`` (m), every sample at least ``margin`` m from any surface; the optical axis is aimed at a
    spline through interest points ``target_distance`` (m) away; a smooth roll of about ``roll_deg`` degrees (std)
    is added. Segment durations follow the mean ``speed`` (m/s) and half of ``max_angular_speed_deg``; the whole
    path is slowed down until the sampled speeds stay within ``max_speed`` (m/s) and ``max_angular_speed_deg``.
    """
    paths.check_speed(speed, max_speed)
    times = frame_times(n_frames, fps, t0)
    duration = times[-1] - times[0]
    points = paths.interest(scene)
    z_inner = (height_range[0] + 0.1, height_range[1] - 0.1)
    max_ang = np.radians(max_angular_speed_deg)
    limits = paths.Limits(margin, max_speed, max_angular_speed_deg, height_range)
    for _ in range(MAX_ATTEMPTS):
        eyes = paths.waypoint_walk(scene, rng, speed * duration * 2.5 + 2.0, z_inner, margin + 0.1)
        if eyes is None:
            continue
        targets = paths.targets_for(rng, eyes, points, target_distance)
        if targets is None:
            continue
        base = paths.segment_durations(eyes, targets, speed, 0.5 * max_ang)
        roll = np.radians(smooth_noise(rng, times, roll_deg))
        found = paths.drive(scene, times, eyes, targets, base, roll, limits, "handheld", slow_downs=paths.SLOW_DOWNS)
        if found is not None:
            return found
    raise SimEnvError(paths.gave_up("handheld", scene))


def loop(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    speed: float = 0.3,
    max_speed: float = 0.6,
    max_angular_speed_deg: float = 35.0,
    height_range: tuple[float, float] = (1.2, 1.75),
    margin: float = 0.4,
    n_waypoints: int = 8,
    target_distance: tuple[float, float] = (1.0, 4.5),
    roll_deg: float = 2.0,
) -> Trajectory:
    """A hand-held loop that ends exactly where it started, looking at scene content (for loop closure).

    Like TUM fr3/long_office_household: ``n_waypoints`` free waypoints on a ring, joined by a periodic cubic spline
    and driven a whole number of laps at about ``speed`` m/s (the ring's radius is chosen for that), so the last
    frame's pose equals the first frame's. When the sequence leaves at least 2 pi / (0.45 ``max_angular_speed``)
    seconds per lap, the ring goes around the room centre looking inwards (the view turns a full circle per lap);
    in shorter sequences, or when no such ring fits the room, the ring lies in one half of the room and looks
    across at the other half (a lap per about 20 s, or one slower lap as a last resort). The optical axis follows
    a periodic spline through interest points. Speeds and free space are checked as in
    :func:`handheld`.
    """
    paths.check_speed(speed, max_speed)
    if n_waypoints < 3:
        raise SimEnvError(f"a loop needs at least 3 waypoints, got n_waypoints={n_waypoints}")
    times = frame_times(n_frames, fps, t0)
    duration = times[-1] - times[0]
    points = paths.interest(scene)
    lo, hi = paths.room_box(scene)
    centre = 0.5 * (lo + hi)
    max_ang = np.radians(max_angular_speed_deg)
    limits = paths.Limits(margin, max_speed, max_angular_speed_deg, height_range)
    min_lap = 2 * np.pi / (0.45 * max_ang)  # seconds for the view to turn a full circle at a comfortable rate
    modes = [(False, max(1, int(round(duration / 20.0))))]  # (inward, laps): looking across, a lap per ~20 s
    if duration >= min_lap:
        modes.insert(0, (True, max(1, int(duration // min_lap))))  # inward first; across when no ring fits
    modes.append((False, 1))  # last resort: one lap around any free spot, as large as the room allows (slower)
    attempts = 2 * MAX_ATTEMPTS  # rings fail often in cluttered rooms; an attempt costs milliseconds
    for attempt in range(attempts):
        mode = attempt * len(modes) // attempts
        inward, laps = modes[mode]
        # a ring of about this mean radius (m) gives the speed; varied per attempt to fit cluttered rooms
        radius = rng.uniform(0.7, 1.15) * speed * duration / (laps * 2 * np.pi)
        if inward:
            ring_centre, focus = centre + np.r_[rng.uniform(-0.4, 0.4, 2), 0.0], None
        else:
            heading = rng.uniform(0, 2 * np.pi)
            d = np.array([np.cos(heading), np.sin(heading), 0.0])
            ring_centre = centre - d * 0.3 * float(np.abs(d[:2]) @ (0.5 * (hi[:2] - lo[:2])))
            if mode == len(modes) - 1:
                spot = paths.random_free_point(scene, rng, (1.4, 1.6), margin + 0.2)
                if spot is None:
                    continue
                ring_centre = spot
                if np.linalg.norm((centre - spot)[:2]) > 0.3:
                    d = np.r_[paths.unit((centre - spot)[:2]), 0.0]
            focus = centre + d * 0.8 * float(np.abs(d[:2]) @ (0.5 * (hi[:2] - lo[:2])))
        z_inner = (height_range[0] + 0.05, height_range[1] - 0.05)  # room for the spline's overshoot
        eyes = paths.ring(scene, rng, ring_centre, n_waypoints, z_inner, margin + 0.1, radius)
        if eyes is None:
            continue
        targets = paths.ring_targets(rng, eyes, ring_centre, focus, points, target_distance)
        closed_eyes = np.vstack([eyes, eyes[:1]])
        closed_targets = np.vstack([targets, targets[:1]])
        cost = paths.segment_durations(closed_eyes, closed_targets, speed, 0.5 * max_ang)
        roll = np.radians(smooth_noise(rng, times, roll_deg, periodic=True))
        found = paths.drive(scene, times, closed_eyes, closed_targets, cost, roll, limits, "loop", lap=duration / laps)
        if found is not None:
            return found
    raise SimEnvError(paths.gave_up("loop", scene))


ROTATION_AXES: tuple[str, ...] = ("yaw", "pitch", "roll")
_DEFAULT_AMPLITUDE_DEG = {"yaw": 35.0, "pitch": 15.0, "roll": 25.0}
_SQUARENESS = 4.0  # tanh sharpness of the angular-velocity profile: near-constant speed with smooth reversals (ours)


def parse_axes(axes: str | Sequence[str]) -> tuple[str, ...]:
    """Rotation axes from ``"yaw"``, ``"pitch"``, ``"roll"``, ``"rpy"`` (all three), ``"yaw+pitch"`` or a sequence."""
    if isinstance(axes, str):
        names = list(ROTATION_AXES) if axes == "rpy" else [a.strip() for a in axes.split("+")]
    else:
        names = [str(a) for a in axes]
    bad = [a for a in names if a not in ROTATION_AXES]
    if bad or not names or len(set(names)) != len(names):
        raise UnknownNameError(
            f"bad rotation axes {axes!r}; use distinct names from {', '.join(ROTATION_AXES)}, joined by '+', or 'rpy'"
        )
    return tuple(a for a in ROTATION_AXES if a in names)


def _sweep_profile() -> tuple[np.ndarray, np.ndarray, float]:
    """Phase grid (2pi), normalised angle s(phase) in [-1, 1] and the plateau slope ds/dphase of the sweep."""
    phase = np.linspace(0.0, 2 * np.pi, 4097)
    g = np.tanh(_SQUARENESS * np.sin(phase)) / np.tanh(_SQUARENESS)
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(phase))])
    half = theta[np.searchsorted(phase, np.pi)]
    return phase, 2.0 * theta / half - 1.0, 2.0 / half


def sweep_angles(times: np.ndarray, amplitude_rad: float, speed_rad_s: float) -> np.ndarray:
    """(N,) float64 angles (radians) oscillating in [-amplitude, +amplitude], starting at 0 and moving up.

    The angular speed is ``speed_rad_s`` on the plateaus of each sweep and turns around smoothly at the ends (a
    tanh-squared sine), so a rotation stress sequence runs at its set speed most of the time.
    """
    phase_grid, s, slope = _sweep_profile()
    period = 2 * np.pi * amplitude_rad * slope / speed_rad_s
    phase = np.mod(np.pi / 2 + 2 * np.pi * (times - times[0]) / period, 2 * np.pi)
    return amplitude_rad * np.interp(phase, phase_grid, s)


def rotation(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    axes: str | Sequence[str] = "yaw",
    speed_deg_s: float = 30.0,
    amplitude_deg: float | None = None,
    height: float = 1.4,
    base_pitch_deg: float = -10.0,
    margin: float = 0.6,
) -> Trajectory:
    """Pure rotation about a fixed optical centre (like TUM fr1/rpy): yaw, pitch, roll or a combination.

    The optical centre is a free point near the room centre at ``height`` m; the base view is horizontal towards
    scene content, tilted by ``base_pitch_deg``. Each axis oscillates by +-``amplitude_deg`` (default yaw 35, pitch
    15, roll 25 degrees, so the view stays in the room) with angular speed ``speed_deg_s / sqrt(number of axes)`` on
    its sweeps, so the total angular speed is about ``speed_deg_s`` deg/s. Yaw turns about the world vertical
    through the optical centre, pitch about the camera x axis, roll about the optical axis. The optical centre
    does not move: every pose has exactly the same translation.
    """
    names = parse_axes(axes)
    if not speed_deg_s > 0:
        raise SimEnvError(f"speed_deg_s must be positive, got {speed_deg_s}")
    times = frame_times(n_frames, fps, t0)
    points = paths.interest(scene)
    lo, hi = paths.room_box(scene)
    centre = 0.5 * (lo + hi)
    for _ in range(MAX_ATTEMPTS):
        eye = paths.free_point_near(scene, rng, np.array([centre[0], centre[1], height]), margin)
        if eye is not None:
            break
    else:
        raise SimEnvError(paths.gave_up("rotation", scene))
    horizontal = points[:, :2] - eye[:2]
    far = np.flatnonzero(np.linalg.norm(horizontal, axis=1) >= 1.5)
    pick = points[rng.choice(far)] if far.size else points[rng.integers(points.shape[0])]
    yaw0 = float(np.arctan2(pick[1] - eye[1], pick[0] - eye[0]))
    forward = np.array([np.cos(yaw0), np.sin(yaw0), np.tan(np.radians(base_pitch_deg))])
    base = look_at(eye, eye + forward)
    speed = np.radians(speed_deg_s) / np.sqrt(len(names))
    angle = {}
    for name in ROTATION_AXES:
        amp = np.radians(_DEFAULT_AMPLITUDE_DEG[name] if amplitude_deg is None else amplitude_deg)
        angle[name] = sweep_angles(times, amp, speed) if name in names else np.zeros_like(times)
    yaw_world = Rotation.from_rotvec(np.outer(angle["yaw"], WORLD_UP))
    in_camera = Rotation.from_euler("xz", np.column_stack([angle["pitch"], angle["roll"]]))
    rot = yaw_world * base * in_camera
    eyes = np.repeat(eye[None, :], times.shape[0], axis=0)
    return Trajectory(times, poses_from(eyes, rot), kind="rotation")


def plane_near(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    distance_range: tuple[float, float] = (0.55, 0.85),
    tilt_deg: float = 20.0,
    speed: float = 0.15,
    loop: bool = True,
    path_size: tuple[float, float] = (0.8, 0.5),
    half_fov_deg: tuple[float, float] = (33.0, 26.0),
    roll_deg: float = 1.5,
) -> Trajectory:
    """Close to a textured floor, translating along it (like TUM fr3/nostructure_texture_near_withloop).

    The camera is ``distance_range`` m above a floor region whose view column holds no furniture (so it sees only
    the floor), looks down ``tilt_deg`` degrees off vertical with a fixed heading (the image's up direction), and
    moves over the floor on an ellipse of ``path_size`` (m, full axes; shrunk down to 20 %, and the height down to
    the lowest of ``distance_range``, in cluttered rooms) at about ``speed`` m/s when ``loop`` (whole laps, ending
    where it started), otherwise back and forth along the ellipse's long axis. ``half_fov_deg`` (horizontal,
    vertical) bounds the camera's half field of view for the furniture-free check of the floor seen (a search over
    all clear floor patches and 8 headings). The optical axis meets the floor at ``height / cos(tilt)`` m;
    ``targets`` are those floor points.
    """
    times = frame_times(n_frames, fps, t0)
    tilt = np.radians(tilt_deg)
    half_h, half_v = np.radians(half_fov_deg[0]), np.radians(half_fov_deg[1])
    h0 = rng.uniform(*distance_range)
    clear = paths.FloorGrid(scene, z_top=h0 + 0.2)
    # smaller paths in cluttered rooms, then also the lowest height (a smaller patch of floor seen)
    for shrink, h in ((1.0, h0), (0.8, h0), (0.6, h0), (0.4, h0), (0.4, distance_range[0]), (0.2, distance_range[0])):
        a, b = 0.5 * path_size[0] * shrink, 0.5 * path_size[1] * shrink
        # floor seen along the path, in (u, v) around the path centre: the image's vertical field of view is along u
        u_range = (-a - h * np.tan(max(half_v - tilt, 0.0)) - 0.1, a + h * np.tan(tilt + half_v) + 0.1)
        v_range = (-b - h * np.tan(half_h) / np.cos(tilt) - 0.1, b + h * np.tan(half_h) / np.cos(tilt) + 0.1)
        options = clear.rectangles(u_range, v_range, headings=rng.uniform(0, np.pi / 4) + np.arange(8) * np.pi / 4)
        if options:
            break
    else:
        size = np.round(np.asarray(scene.room_size, dtype=float), 2).tolist()
        raise SimEnvError(
            f"could not generate a 'plane_near' trajectory in a room of size {size} m: no floor patch is clear of "
            "furniture for the camera's view; try another seed or a smaller path_size / half_fov_deg"
        )
    c, heading = options[int(rng.integers(len(options)))]
    axis_u = np.array([np.cos(heading), np.sin(heading), 0.0])
    axis_v = np.array([-axis_u[1], axis_u[0], 0.0])
    centre = np.array([c[0], c[1], h])
    if loop:
        laps = max(1, int(round(speed * (times[-1] - times[0]) / paths.ellipse_length(a, b))))
        ang = 2 * np.pi * laps * (times - times[0]) / (times[-1] - times[0])
        u, v = a * np.cos(ang), b * np.sin(ang)
    else:
        u, v = a * np.sin(speed / a * (times - times[0])), np.zeros_like(times)
    eye = centre + np.outer(u, axis_u) + np.outer(v, axis_v)
    if loop:
        eye[-1] = eye[0]
    forward = np.cos(tilt) * np.array([0.0, 0.0, -1.0]) + np.sin(tilt) * axis_u
    roll = np.radians(smooth_noise(rng, times, roll_deg, periodic=loop))
    rot = look_at(eye, eye + forward, up=axis_u, roll_rad=roll)
    targets = eye + forward * (h / np.cos(tilt))
    return Trajectory(times, poses_from(eye, rot), kind="plane_near", targets=targets)


def far_structure(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    distance_range: tuple[float, float] = (2.0, 4.0),
    speed: float = 0.15,
    sweep_length: float = 1.5,
    height_range: tuple[float, float] = (1.2, 1.6),
    margin: float = 0.4,
    roll_deg: float = 1.5,
) -> Trajectory:
    """Looking across the room at structure 2-4 m away while sweeping sideways (like TUM fr3/structure_texture_far).

    The camera backs onto a wall, moves back and forth along it on a ``sweep_length`` m segment at about ``speed``
    m/s, and aims at a slowly moving spline through interest points ``distance_range`` m away in front of it; every
    sample's distance to its target lies in ``distance_range``.
    """
    times = frame_times(n_frames, fps, t0)
    points = paths.interest(scene)
    lo, hi = paths.room_box(scene)
    for _ in range(MAX_ATTEMPTS):
        wall_axis, wall_side = int(rng.integers(2)), int(rng.integers(2))
        inward = np.zeros(3)
        inward[wall_axis] = 1.0 if wall_side == 0 else -1.0
        along = np.array([-inward[1], inward[0], 0.0])
        back = rng.uniform(margin + 0.15, margin + 0.6)
        wall_coord = lo[wall_axis] if wall_side == 0 else hi[wall_axis]
        other = 1 - wall_axis
        mid = np.zeros(3)
        mid[wall_axis] = wall_coord + inward[wall_axis] * back
        span = hi[other] - lo[other]
        mid[other] = lo[other] + rng.uniform(0.3, 0.7) * span
        mid[2] = rng.uniform(*height_range)
        half = 0.5 * sweep_length
        if not paths.segment_free(scene, mid - half * along, mid + half * along, margin + 0.05):
            continue
        ends = [paths.pick_target(rng, mid, points, distance_range, None, np.pi, inward, np.radians(30.0))
                for _ in range(3)]
        if any(e is None for e in ends):
            continue
        omega = speed / half
        s = half * np.sin(omega * (times - times[0]))
        # hand-held: the sweep bobs up and down and drifts away from the wall a little, so the positions span a
        # plane (a perfectly straight dolly leaves a trajectory alignment's rotation about the line undetermined)
        phase = rng.uniform(0.0, 2.0 * np.pi, 2)
        bob = rng.uniform(0.06, 0.1) * np.sin(2.0 * np.pi / 7.0 * (times - times[0]) + phase[0])  # 7 s period
        drift = rng.uniform(0.1, 0.2) * 0.5 * (1.0 - np.cos(2.0 * np.pi / 19.0 * (times - times[0]) + phase[1]))
        eye = mid + np.outer(s, along) + np.outer(drift, inward) + np.outer(bob, [0.0, 0.0, 1.0])
        knots = np.linspace(times[0], times[-1], 3)
        tgt = CubicSpline(knots, np.stack(ends), bc_type="natural")(times)
        dist = np.linalg.norm(tgt - eye, axis=1)
        if dist.min() < distance_range[0] or dist.max() > distance_range[1]:
            continue
        roll = np.radians(smooth_noise(rng, times, roll_deg))
        rot = look_at(eye, tgt, roll_rad=roll)
        free, slow = paths.accept(scene, eye, rot, times, margin, 2.0 * speed + 0.05, 35.0, None)
        if free and slow:
            return Trajectory(times, poses_from(eye, rot), kind="far_structure", targets=tgt)
    raise SimEnvError(paths.gave_up("far_structure", scene))


def low_texture(
    scene: SceneLike,
    rng: np.random.Generator,
    n_frames: int,
    *,
    fps: float = FPS,
    t0: float = 0.0,
    distance_range: tuple[float, float] = (0.9, 1.3),
    height_range: tuple[float, float] = (1.5, 1.7),
    look_up: float = 0.35,
    speed: float = 0.1,
    sweep_length: float = 1.0,
    margin: float = 0.4,
    roll_deg: float = 1.0,
) -> Trajectory:
    """Facing a plain wall (the wall stretch with the fewest interest points where the camera fits), sliding slowly
    along it.

    The camera stands ``distance_range`` m from the wall at ``height_range`` m, aims ``look_up`` m above its own
    height (the upper wall, above furniture), and moves back and forth along the wall over ``sweep_length`` m at
    about ``speed`` m/s. ``targets`` are the wall points hit by the optical axis.
    """
    times = frame_times(n_frames, fps, t0)
    points = paths.interest(scene)
    lo, hi = paths.room_box(scene)
    candidates = []
    for wall_axis in (0, 1):
        other = 1 - wall_axis
        for wall_side in (0, 1):
            wall_coord = lo[wall_axis] if wall_side == 0 else hi[wall_axis]
            for pos in np.arange(lo[other] + 0.8, hi[other] - 0.8 + 1e-9, 0.25):
                near_wall = np.abs(points[:, wall_axis] - wall_coord) < 1.5
                near_pos = np.abs(points[:, other] - pos) < 0.5 * sweep_length + 1.0
                candidates.append((int(np.sum(near_wall & near_pos)), wall_axis, wall_side, pos))
    if not candidates:
        raise SimEnvError(paths.gave_up("low_texture", scene))
    order = rng.permutation(len(candidates))  # ties in a random order, then the plainest wall stretches first
    candidates = sorted((candidates[i] for i in order), key=lambda c: c[0])
    for k in range(3 * len(candidates)):
        _, wall_axis, wall_side, pos = candidates[k // 3]
        other = 1 - wall_axis
        outward = np.zeros(3)
        outward[wall_axis] = -1.0 if wall_side == 0 else 1.0  # from the room towards the wall
        along = np.zeros(3)
        along[other] = 1.0
        wall_coord = lo[wall_axis] if wall_side == 0 else hi[wall_axis]
        dist = rng.uniform(*distance_range)
        mid = np.zeros(3)
        mid[wall_axis] = wall_coord - outward[wall_axis] * dist
        mid[other] = pos
        mid[2] = rng.uniform(*height_range)
        half = 0.5 * sweep_length
        if not paths.segment_free(scene, mid - half * along, mid + half * along, margin):
            continue
        s = half * np.sin(speed / half * (times - times[0]))
        eye = mid + np.outer(s, along)
        tgt = eye + dist * outward
        tgt[:, 2] = min(mid[2] + look_up, hi[2] - 0.2)
        roll = np.radians(smooth_noise(rng, times, roll_deg))
        rot = look_at(eye, tgt, roll_rad=roll)
        return Trajectory(times, poses_from(eye, rot), kind="low_texture", targets=tgt)
    raise SimEnvError(paths.gave_up("low_texture", scene))


TrajectoryGenerator = Callable[..., Trajectory]

TRAJECTORY_KINDS: dict[str, TrajectoryGenerator] = {
    "handheld": handheld,
    "loop": loop,
    "rotation": rotation,
    "plane_near": plane_near,
    "far_structure": far_structure,
    "low_texture": low_texture,
    "replay": replay,
    "handheld_stats": handheld_stats,
}


def make_trajectory(kind: str, scene: SceneLike, rng: np.random.Generator, n_frames: int, **params: Any) -> Trajectory:
    """Generate a trajectory of a named ``kind`` (see :data:`TRAJECTORY_KINDS`) with its keyword parameters."""
    try:
        generator = TRAJECTORY_KINDS[kind]
    except KeyError:
        raise UnknownNameError(
            f"unknown trajectory kind {kind!r}; valid kinds: {', '.join(TRAJECTORY_KINDS)}"
        ) from None
    valid = _keyword_params(generator)
    bad = sorted(set(params) - set(valid))
    if bad:
        raise SimEnvError(f"trajectory kind {kind!r} takes no parameter(s) {', '.join(bad)}; valid: {', '.join(valid)}")
    return generator(scene, rng, n_frames, **params)


def trajectory_params(kind: str) -> list[str]:
    """Keyword parameters accepted by the generator of ``kind``."""
    if kind not in TRAJECTORY_KINDS:
        raise UnknownNameError(f"unknown trajectory kind {kind!r}; valid kinds: {', '.join(TRAJECTORY_KINDS)}")
    return _keyword_params(TRAJECTORY_KINDS[kind])


def _keyword_params(fn: Callable[..., Any]) -> list[str]:
    import inspect

    return [p.name for p in inspect.signature(fn).parameters.values() if p.kind is inspect.Parameter.KEYWORD_ONLY]

"""Camera trajectories at 30 Hz: hand-held, pure rotation, loops, close to a textured plane, far structure, low texture,
and recorded real motion replayed in a room (:func:`replay`).

A :class:`Trajectory` is a frozen pair of arrays, ``timestamps`` (N,) float64 seconds and ``T_world_cam`` (N, 4, 4)
float64 camera-to-world poses (OpenCV camera axes: x right, y down, z forward; world z up, metres), plus a continuous
:meth:`Trajectory.pose_at` (cubic spline on positions, :class:`scipy.spatial.transform.RotationSpline` on
rotations) for motion-blur sub-frames.

Generators take a scene (anything with ``bounds()``, ``interest_points()``, ``free_space(points, margin)`` and
``room_size``, see :class:`SceneLike`) and a ``numpy.random.Generator``; the same generator state gives the same
trajectory. They build smooth paths through waypoints with :class:`scipy.interpolate.CubicSpline`, aim the optical
axis at scene content (the scene's interest points), and check the result (free space, speeds) before returning it;
when a check fails they draw new waypoints, and after :data:`MAX_ATTEMPTS` they raise :class:`SimEnvError`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Protocol

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from sim_envs.errors import SimEnvError, UnknownNameError

FPS: float = 30.0  # frames per second of every generated trajectory (TUM and ICL-NUIM both record at 30 Hz)
MAX_ATTEMPTS: int = 60  # waypoint draws before a generator gives up (ours)
_WORLD_UP = np.array([0.0, 0.0, 1.0])


class SceneLike(Protocol):
    """What a trajectory generator needs from a scene (``sim_envs.scene.Scene`` provides it).

    ``room_size``: (3,) float64 extent of the room's interior, which spans ``[0, Lx] x [0, Ly] x [0, H]`` (metres,
    world z up, floor top at z = 0). ``bounds()``: (2, 3) float64 ``[min, max]`` corners of everything, walls included.
    ``interest_points()``: (M, 3) float64 points worth looking at. ``free_space(points (K, 3), margin)``: (K,) bool,
    True where a point is inside the room, at least ``margin`` metres from walls, floor, ceiling and furniture.
    """

    room_size: np.ndarray

    def bounds(self) -> np.ndarray: ...

    def interest_points(self) -> np.ndarray: ...

    def free_space(self, points: np.ndarray, margin: float = 0.3) -> np.ndarray: ...


@dataclass(frozen=True)
class Trajectory:
    """A camera trajectory sampled at frame times.

    timestamps: (N,) float64 seconds, strictly increasing. T_world_cam: (N, 4, 4) float64 camera-to-world, rotation
    part orthonormal with det +1, last row [0, 0, 0, 1]. kind: the generator's name. targets: optional (N, 3) float64
    world points the optical axis was aimed at (None where the generator aims at no point, e.g. pure rotation).
    Arrays are stored as read-only copies.
    """

    timestamps: np.ndarray
    T_world_cam: np.ndarray
    kind: str = "custom"
    targets: np.ndarray | None = None

    def __post_init__(self) -> None:
        ts = np.array(self.timestamps, dtype=np.float64).reshape(-1)
        T = np.array(self.T_world_cam, dtype=np.float64)
        if T.ndim != 3 or T.shape[1:] != (4, 4) or T.shape[0] != ts.shape[0]:
            raise SimEnvError(f"T_world_cam must be (N, 4, 4) with N = len(timestamps) = {ts.shape[0]}, got {T.shape}")
        if ts.shape[0] == 0:
            raise SimEnvError("a trajectory needs at least one pose")
        if not (np.isfinite(ts).all() and np.isfinite(T).all()):
            raise SimEnvError("timestamps and poses must be finite")
        if ts.shape[0] > 1 and not (np.diff(ts) > 0).all():
            raise SimEnvError("timestamps must be strictly increasing")
        R = T[:, :3, :3]
        ortho_err = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max()
        if ortho_err > 1e-6 or (np.linalg.det(R) < 0).any():
            raise SimEnvError(f"rotation parts must be proper rotations (orthonormality error {ortho_err:.2e})")
        if not np.allclose(T[:, 3, :], [0.0, 0.0, 0.0, 1.0]):
            raise SimEnvError("the last row of every pose must be [0, 0, 0, 1]")
        ts.setflags(write=False)
        T.setflags(write=False)
        object.__setattr__(self, "timestamps", ts)
        object.__setattr__(self, "T_world_cam", T)
        if self.targets is not None:
            tg = np.array(self.targets, dtype=np.float64)
            if tg.shape != (ts.shape[0], 3):
                raise SimEnvError(f"targets must be (N, 3) = ({ts.shape[0]}, 3), got {tg.shape}")
            tg.setflags(write=False)
            object.__setattr__(self, "targets", tg)

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to the last timestamp."""
        return float(self.timestamps[-1] - self.timestamps[0])

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) float64 optical centres in world coordinates, metres."""
        return self.T_world_cam[:, :3, 3].copy()

    @property
    def rotations(self) -> Rotation:
        """The N camera-to-world rotations."""
        return Rotation.from_matrix(self.T_world_cam[:, :3, :3])

    @cached_property
    def _splines(self) -> tuple[CubicSpline, RotationSpline] | None:
        if len(self) < 2:
            return None
        return CubicSpline(self.timestamps, self.positions, axis=0), RotationSpline(self.timestamps, self.rotations)

    def pose_at(self, t: float | np.ndarray) -> np.ndarray:
        """Camera-to-world pose at time(s) ``t`` (seconds), interpolated between frames.

        Positions follow a cubic spline through the frame positions, rotations a C2 rotation spline; both pass
        through the stored poses at the frame times. ``t`` outside the trajectory's time span is clamped to it.
        Returns (4, 4) float64 for a scalar ``t``, (M, 4, 4) for an array of M times.
        """
        t_arr = np.atleast_1d(np.asarray(t, dtype=np.float64))
        t_arr = np.clip(t_arr, self.timestamps[0], self.timestamps[-1])
        T = np.tile(np.eye(4), (t_arr.shape[0], 1, 1))
        if self._splines is None:
            T[:] = self.T_world_cam[0]
        else:
            pos_spline, rot_spline = self._splines
            T[:, :3, :3] = rot_spline(t_arr).as_matrix()
            T[:, :3, 3] = pos_spline(t_arr)
        return T[0] if np.ndim(t) == 0 else T

    def linear_speeds(self) -> np.ndarray:
        """(N-1,) float64 speed of the optical centre between consecutive frames, m/s."""
        return np.linalg.norm(np.diff(self.positions, axis=0), axis=1) / np.diff(self.timestamps)

    def angular_speeds_deg(self) -> np.ndarray:
        """(N-1,) float64 rotation angle between consecutive frames divided by the time step, degrees per second."""
        rots = self.rotations
        rel = rots[:-1].inv() * rots[1:]
        return np.degrees(rel.magnitude()) / np.diff(self.timestamps)


# --------------------------------------------------------------------------------------------------------------------
# Pose helpers


def look_at(
    eye: np.ndarray, target: np.ndarray, up: np.ndarray | None = None, roll_rad: np.ndarray | float = 0.0
) -> Rotation:
    """Camera-to-world rotations of cameras at ``eye`` whose optical axis (+z) points at ``target``.

    eye, target: (N, 3) or (3,) world points, metres. up: (3,) or (N, 3) world direction that appears up in the image
    (default world +z); it must not be parallel to the viewing direction. roll_rad: (N,) or scalar rotation about the
    optical axis applied after aiming (positive turns the camera's x axis towards its y axis: clockwise as
    seen from behind the camera, so the image content turns counter-clockwise). OpenCV axes: the camera's y axis
    points down in the image, so it is made to point along -up as nearly as possible.
    """
    eye = np.atleast_2d(np.asarray(eye, dtype=np.float64))
    target = np.atleast_2d(np.asarray(target, dtype=np.float64))
    up_arr = np.atleast_2d(_WORLD_UP if up is None else np.asarray(up, dtype=np.float64))
    z = target - eye
    z_norm = np.linalg.norm(z, axis=1, keepdims=True)
    if (z_norm < 1e-9).any():
        raise SimEnvError("look_at: a target coincides with its eye point")
    z = z / z_norm
    x = np.cross(z, up_arr)
    x_norm = np.linalg.norm(x, axis=1, keepdims=True)
    if (x_norm < 1e-6).any():
        raise SimEnvError("look_at: the viewing direction is parallel to the up direction")
    x = x / x_norm
    y = np.cross(z, x)
    rot = Rotation.from_matrix(np.stack([x, y, z], axis=2))
    roll = np.broadcast_to(np.asarray(roll_rad, dtype=np.float64), (len(rot),))
    return rot * Rotation.from_euler("z", roll[:, None])


def poses_from(positions: np.ndarray, rotations: Rotation) -> np.ndarray:
    """(N, 4, 4) float64 camera-to-world poses from (N, 3) optical centres and N camera-to-world rotations."""
    positions = np.atleast_2d(positions)
    T = np.tile(np.eye(4), (positions.shape[0], 1, 1))
    T[:, :3, :3] = rotations.as_matrix().reshape(-1, 3, 3)
    T[:, :3, 3] = positions
    return T


def frame_times(n_frames: int, fps: float = FPS, t0: float = 0.0) -> np.ndarray:
    """(n_frames,) float64 timestamps ``t0 + i / fps``, seconds."""
    if int(n_frames) < 2:
        raise SimEnvError(f"a trajectory needs at least 2 frames, got n_frames={n_frames}")
    if not fps > 0:
        raise SimEnvError(f"fps must be positive, got {fps}")
    return t0 + np.arange(int(n_frames), dtype=np.float64) / float(fps)


def smooth_noise(
    rng: np.random.Generator, times: np.ndarray, sigma: float, knot_spacing: float = 1.5, periodic: bool = False
) -> np.ndarray:
    """(N,) float64 smooth random signal of standard deviation about ``sigma``: a cubic spline through normal draws
    placed every ``knot_spacing`` seconds; ``periodic`` makes it end where it starts (value and derivatives)."""
    t0, t1 = float(times[0]), float(times[-1])
    n_knots = max(4, int(np.ceil((t1 - t0) / knot_spacing)) + 1)
    knots = np.linspace(t0, t1, n_knots)
    values = rng.normal(0.0, sigma, n_knots)
    if periodic:
        values[-1] = values[0]
        return CubicSpline(knots, values, bc_type="periodic")(times)
    return CubicSpline(knots, values, bc_type="natural")(times)


# --------------------------------------------------------------------------------------------------------------------
# Scene queries


def _room_box(scene: SceneLike) -> tuple[np.ndarray, np.ndarray]:
    """The room's interior box ``[0, room_size]`` (scene convention; ``bounds()`` also holds the walls' thickness)."""
    size = np.asarray(scene.room_size, dtype=np.float64)
    return np.zeros(3), size


def _interest(scene: SceneLike) -> np.ndarray:
    pts = np.asarray(scene.interest_points(), dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 0:
        raise SimEnvError("the scene has no interest points: nothing for a camera to look at")
    return pts


def _segment_free(scene: SceneLike, a: np.ndarray, b: np.ndarray, margin: float, step: float = 0.1) -> bool:
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    return bool(np.all(scene.free_space(pts, margin=margin)))


def _random_free_point(
    scene: SceneLike, rng: np.random.Generator, z_range: tuple[float, float], margin: float, tries: int = 400
) -> np.ndarray | None:
    lo, hi = _room_box(scene)
    pts = np.column_stack(
        [
            rng.uniform(lo[0] + margin, hi[0] - margin, tries),
            rng.uniform(lo[1] + margin, hi[1] - margin, tries),
            rng.uniform(z_range[0], z_range[1], tries),
        ]
    )
    ok = np.flatnonzero(scene.free_space(pts, margin=margin))
    return None if ok.size == 0 else pts[ok[0]]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in radians between direction vectors a and b (..., 3)."""
    return np.arccos(np.clip(np.sum(_unit(a) * _unit(b), axis=-1), -1.0, 1.0))


def _pick_target(
    rng: np.random.Generator,
    eye: np.ndarray,
    points: np.ndarray,
    distance: tuple[float, float],
    prev_dir: np.ndarray | None,
    max_turn_rad: float,
    preferred_dir: np.ndarray | None = None,
    max_off_preferred_rad: float = np.pi,
    max_pitch_rad: float = np.radians(55.0),
) -> np.ndarray | None:
    """A random interest point in the distance band, not steeper than ``max_pitch_rad``, within ``max_turn_rad`` of
    the previous viewing direction and ``max_off_preferred_rad`` of a preferred one (each where given)."""
    d = points - eye
    dist = np.linalg.norm(d, axis=1)
    ok = (dist >= distance[0]) & (dist <= distance[1])
    pitch = np.arcsin(np.clip(d[:, 2] / np.maximum(dist, 1e-9), -1.0, 1.0))
    ok &= np.abs(pitch) <= max_pitch_rad
    if prev_dir is not None:
        ok &= _angle_between(d, prev_dir[None, :]) <= max_turn_rad
    if preferred_dir is not None:
        ok &= _angle_between(d, preferred_dir[None, :]) <= max_off_preferred_rad
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None
    return points[rng.choice(idx)]


def _accept(
    scene: SceneLike,
    eye: np.ndarray,
    rot: Rotation,
    times: np.ndarray,
    margin: float,
    max_speed: float,
    max_angular_speed_deg: float,
    z_range: tuple[float, float] | None,
) -> tuple[bool, bool]:
    """(path is free and within heights, speeds are within limits) for sampled eye positions and rotations."""
    free = bool(np.all(scene.free_space(eye, margin=margin)))
    if z_range is not None:
        free &= bool(np.all((eye[:, 2] >= z_range[0] - 1e-9) & (eye[:, 2] <= z_range[1] + 1e-9)))
    dt = np.diff(times)
    lin = np.linalg.norm(np.diff(eye, axis=0), axis=1) / dt
    ang = np.degrees((rot[:-1].inv() * rot[1:]).magnitude()) / dt
    return free, bool(lin.max() <= max_speed and ang.max() <= max_angular_speed_deg)


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
    _check_speed(speed, max_speed)
    times = frame_times(n_frames, fps, t0)
    duration = times[-1] - times[0]
    points = _interest(scene)
    z_inner = (height_range[0] + 0.1, height_range[1] - 0.1)
    max_ang = np.radians(max_angular_speed_deg)
    for _ in range(MAX_ATTEMPTS):
        eyes = _waypoint_walk(scene, rng, speed * duration * 2.5 + 2.0, z_inner, margin + 0.1)
        if eyes is None:
            continue
        targets = _targets_for(rng, eyes, points, target_distance)
        if targets is None:
            continue
        base = _segment_durations(eyes, targets, speed, 0.5 * max_ang)
        roll = np.radians(smooth_noise(rng, times, roll_deg))
        for slow_down in (1.0, 1.3, 1.7, 2.2, 3.0):
            knots = times[0] + np.concatenate([[0.0], np.cumsum(base * slow_down)])
            if knots[-1] < times[-1]:
                break  # the walk is too short for this duration: draw a longer one
            eye = CubicSpline(knots, eyes, bc_type="natural")(times)
            tgt = CubicSpline(knots, targets, bc_type="natural")(times)
            rot = look_at(eye, tgt, roll_rad=roll)
            free, slow = _accept(scene, eye, rot, times, margin, max_speed, max_angular_speed_deg, height_range)
            if not free:
                break
            if slow:
                return Trajectory(times, poses_from(eye, rot), kind="handheld", targets=tgt)
    raise SimEnvError(_gave_up("handheld", scene))


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
    _check_speed(speed, max_speed)
    if n_waypoints < 3:
        raise SimEnvError(f"a loop needs at least 3 waypoints, got n_waypoints={n_waypoints}")
    times = frame_times(n_frames, fps, t0)
    duration = times[-1] - times[0]
    points = _interest(scene)
    lo, hi = _room_box(scene)
    centre = 0.5 * (lo + hi)
    max_ang = np.radians(max_angular_speed_deg)
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
                spot = _random_free_point(scene, rng, (1.4, 1.6), margin + 0.2)
                if spot is None:
                    continue
                ring_centre = spot
                if np.linalg.norm((centre - spot)[:2]) > 0.3:
                    d = np.r_[_unit((centre - spot)[:2]), 0.0]
            focus = centre + d * 0.8 * float(np.abs(d[:2]) @ (0.5 * (hi[:2] - lo[:2])))
        z_inner = (height_range[0] + 0.05, height_range[1] - 0.05)  # room for the spline's overshoot
        eyes = _ring(scene, rng, ring_centre, n_waypoints, z_inner, margin + 0.1, radius)
        if eyes is None:
            continue
        targets = _ring_targets(rng, eyes, ring_centre, focus, points, target_distance)
        closed_eyes = np.vstack([eyes, eyes[:1]])
        closed_targets = np.vstack([targets, targets[:1]])
        cost = _segment_durations(closed_eyes, closed_targets, speed, 0.5 * max_ang)
        roll = np.radians(smooth_noise(rng, times, roll_deg, periodic=True))
        lap = duration / laps
        knots = np.concatenate([[0.0], np.cumsum(cost)]) * (lap / cost.sum())
        phase = np.mod(times - times[0], lap)
        phase[-1] = knots[-1]  # the last frame closes the loop exactly
        eye = CubicSpline(knots, closed_eyes, bc_type="periodic")(phase)
        tgt = CubicSpline(knots, closed_targets, bc_type="periodic")(phase)
        eye[-1], tgt[-1] = eye[0], tgt[0]
        rot = look_at(eye, tgt, roll_rad=roll)
        free, slow = _accept(scene, eye, rot, times, margin, max_speed, max_angular_speed_deg, height_range)
        if free and slow:
            return Trajectory(times, poses_from(eye, rot), kind="loop", targets=tgt)
    raise SimEnvError(_gave_up("loop", scene))


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
    points = _interest(scene)
    lo, hi = _room_box(scene)
    centre = 0.5 * (lo + hi)
    for _ in range(MAX_ATTEMPTS):
        eye = _free_point_near(scene, rng, np.array([centre[0], centre[1], height]), margin)
        if eye is not None:
            break
    else:
        raise SimEnvError(_gave_up("rotation", scene))
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
    yaw_world = Rotation.from_rotvec(np.outer(angle["yaw"], _WORLD_UP))
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
    clear = _FloorGrid(scene, z_top=h0 + 0.2)
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
        laps = max(1, int(round(speed * (times[-1] - times[0]) / _ellipse_length(a, b))))
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
    points = _interest(scene)
    lo, hi = _room_box(scene)
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
        if not _segment_free(scene, mid - half * along, mid + half * along, margin + 0.05):
            continue
        ends = [_pick_target(rng, mid, points, distance_range, None, np.pi, inward, np.radians(30.0)) for _ in range(3)]
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
        free, slow = _accept(scene, eye, rot, times, margin, 2.0 * speed + 0.05, 35.0, None)
        if free and slow:
            return Trajectory(times, poses_from(eye, rot), kind="far_structure", targets=tgt)
    raise SimEnvError(_gave_up("far_structure", scene))


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
    points = _interest(scene)
    lo, hi = _room_box(scene)
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
        raise SimEnvError(_gave_up("low_texture", scene))
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
        if not _segment_free(scene, mid - half * along, mid + half * along, margin):
            continue
        s = half * np.sin(speed / half * (times - times[0]))
        eye = mid + np.outer(s, along)
        tgt = eye + dist * outward
        tgt[:, 2] = min(mid[2] + look_up, hi[2] - 0.2)
        roll = np.radians(smooth_noise(rng, times, roll_deg))
        rot = look_at(eye, tgt, roll_rad=roll)
        return Trajectory(times, poses_from(eye, rot), kind="low_texture", targets=tgt)
    raise SimEnvError(_gave_up("low_texture", scene))


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
    from scipy.spatial.transform import Slerp

    from sim_envs.formats import read_tum_trajectory

    stamps, T = read_tum_trajectory(file, duplicate_timestamps="first")
    times = frame_times(n_frames, fps, t0)
    src = stamps[0] + float(start_s) + (times - times[0])
    if start_s < 0:
        raise SimEnvError(f"start_s must be >= 0 seconds into the recording, got {start_s}")
    if src[-1] > stamps[-1]:
        raise SimEnvError(f"{file} covers {stamps[-1] - stamps[0]:.2f} s; {n_frames} frames at {fps:g} fps from "
                          f"{start_s:g} s need {src[-1] - stamps[0]:.2f} s")  # fmt: skip
    positions = np.column_stack([np.interp(src, stamps, T[:, k, 3]) for k in range(3)])
    rotations = Slerp(stamps, Rotation.from_matrix(T[:, :3, :3]))(src)
    recorded = poses_from(positions, rotations)
    relative = np.linalg.inv(recorded[0]) @ recorded  # T_first_cam: the motion in the first camera's axes
    points = _interest(scene)
    lo, hi = _room_box(scene)
    for _ in range(MAX_ATTEMPTS):
        eye = _random_free_point(scene, rng, height_range, margin)
        if eye is None:
            continue
        target = _pick_target(rng, eye, points, target_distance, None, np.pi)
        if target is None:
            continue
        poses = poses_from(eye, look_at(eye, target))[0] @ relative
        centres = poses[:, :3, 3]
        inside = bool(np.all((centres > lo + margin) & (centres < hi - margin)))
        if inside and bool(np.all(scene.free_space(centres, margin=margin))):
            return Trajectory(times, poses, kind="replay")
    raise SimEnvError(_gave_up("replay", scene))


TrajectoryGenerator = Callable[..., Trajectory]

TRAJECTORY_KINDS: dict[str, TrajectoryGenerator] = {
    "handheld": handheld,
    "loop": loop,
    "rotation": rotation,
    "plane_near": plane_near,
    "far_structure": far_structure,
    "low_texture": low_texture,
    "replay": replay,
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


# --------------------------------------------------------------------------------------------------------------------
# Internals of the generators


def _keyword_params(fn: Callable[..., Any]) -> list[str]:
    import inspect

    return [p.name for p in inspect.signature(fn).parameters.values() if p.kind is inspect.Parameter.KEYWORD_ONLY]


def _check_speed(speed: float, max_speed: float) -> None:
    if not 0 < speed < max_speed:
        raise SimEnvError(f"need 0 < speed < max_speed (m/s), got speed={speed}, max_speed={max_speed}")


def _gave_up(kind: str, scene: SceneLike) -> str:
    size = np.round(np.asarray(scene.room_size, dtype=float), 2).tolist()
    return (
        f"could not generate a {kind!r} trajectory in a room of size {size} m after {MAX_ATTEMPTS} attempts "
        "(too little free space for the requested margins and speeds); try another seed or relax the parameters"
    )


def _waypoint_walk(
    scene: SceneLike, rng: np.random.Generator, length: float, z_range: tuple[float, float], margin: float
) -> np.ndarray | None:
    """(K, 3) random walk of free waypoints 0.5-1.2 m apart, joined by free straight segments, of total length
    >= ``length`` m; headings change by at most 100 degrees per step, or (when that gets stuck, in small rooms)
    turn around with steps of 0.3-0.8 m. None when the walk gets stuck altogether."""
    start = _random_free_point(scene, rng, z_range, margin)
    if start is None:
        return None
    walk = [start]
    heading = rng.uniform(0, 2 * np.pi)
    total = 0.0
    while total < length:
        for attempt in range(60):
            wide = attempt >= 30
            h = heading + rng.uniform(-1.0, 1.0) * np.radians(180.0 if wide else 100.0)
            step = rng.uniform(0.3, 0.8) if wide else rng.uniform(0.5, 1.2)
            nxt = walk[-1] + np.array([step * np.cos(h), step * np.sin(h), 0.0])
            nxt[2] = rng.uniform(*z_range)
            if scene.free_space(nxt[None, :], margin=margin)[0] and _segment_free(scene, walk[-1], nxt, margin):
                walk.append(nxt)
                heading = h
                total += float(np.linalg.norm(nxt - walk[-2]))
                break
        else:
            return None
    return np.asarray(walk)


def _targets_for(
    rng: np.random.Generator, eyes: np.ndarray, points: np.ndarray, distance: tuple[float, float]
) -> np.ndarray | None:
    """One interest point per eye waypoint, turning at most 60 degrees from one to the next."""
    targets: list[np.ndarray] = []
    prev_dir = None
    for eye in eyes:
        tgt = _pick_target(rng, eye, points, distance, prev_dir, np.radians(60.0))
        if tgt is None:
            return None
        targets.append(tgt)
        prev_dir = tgt - eye
    return np.asarray(targets)


def _segment_durations(eyes: np.ndarray, targets: np.ndarray, speed: float, mean_ang_rate: float) -> np.ndarray:
    """(K-1,) seconds per waypoint segment: enough for the translation at ``speed`` (m/s) and for the change of
    viewing direction at ``mean_ang_rate`` (rad/s)."""
    lengths = np.linalg.norm(np.diff(eyes, axis=0), axis=1)
    dirs = targets - eyes
    turns = _angle_between(dirs[:-1], dirs[1:])
    return np.maximum(np.maximum(lengths / speed, turns / mean_ang_rate), 0.2)


def _ring(
    scene: SceneLike,
    rng: np.random.Generator,
    centre: np.ndarray,
    n: int,
    z_range: tuple[float, float],
    margin: float,
    radius: float,
) -> np.ndarray | None:
    """(n, 3) free waypoints around ``centre`` at evenly spaced angles (jittered), each at a random free distance
    of 0.6-1.4 x ``radius`` (m, within 30-90 % of the way to the wall) and a free height in ``z_range``, joined to
    the previous one (and the last to the first) by a free straight segment; None when none is found in this draw."""
    lo, hi = _room_box(scene)
    theta0 = rng.uniform(0, 2 * np.pi)
    eyes: list[np.ndarray] = []
    for k in range(n):
        chosen = None
        for _ in range(4):  # a few jittered rays per waypoint
            th = theta0 + 2 * np.pi * (k + rng.uniform(-0.3, 0.3)) / n
            d = np.array([np.cos(th), np.sin(th)])
            with np.errstate(divide="ignore"):
                t_wall = np.min(
                    np.where(d > 0, (hi[:2] - centre[:2]) / d, np.where(d < 0, (lo[:2] - centre[:2]) / d, np.inf))
                )
            r_lo, r_hi = max(0.3 * t_wall, 0.6 * radius), min(0.9 * t_wall, 1.4 * radius)
            if r_lo > r_hi:
                r_lo = r_hi = min(max(radius, 0.3 * t_wall), 0.9 * t_wall)
            dists, zs = np.meshgrid(np.linspace(r_lo, r_hi, 9), np.linspace(z_range[0], z_range[1], 4))
            order = rng.permutation(dists.size)
            dists, zs = dists.ravel()[order], zs.ravel()[order]
            cands = np.column_stack([centre[0] + dists * d[0], centre[1] + dists * d[1], zs])
            for idx in np.flatnonzero(scene.free_space(cands, margin=margin)):
                if not eyes or _segment_free(scene, eyes[-1], cands[idx], margin):
                    chosen = cands[idx]
                    break
            if chosen is not None:
                break
        if chosen is None:
            return None
        eyes.append(chosen)
    if not _segment_free(scene, eyes[-1], eyes[0], margin):
        return None
    return np.asarray(eyes)


def _ring_targets(
    rng: np.random.Generator,
    eyes: np.ndarray,
    centre: np.ndarray,
    focus: np.ndarray | None,
    points: np.ndarray,
    distance: tuple[float, float],
) -> np.ndarray:
    """One look-at point per ring waypoint: an interest point within 70 degrees of the inward direction (towards
    ``centre``), or 45 degrees of the direction to ``focus`` when given, preferably within 40 degrees of the previous
    viewing direction; where no interest point qualifies, the anchor (centre or focus) at table height."""
    targets: list[np.ndarray] = []
    prev_dir = None
    anchor = np.array(centre if focus is None else focus, dtype=np.float64)
    anchor[2] = 0.8
    off = np.radians(70.0 if focus is None else 45.0)
    for eye in eyes:
        preferred = anchor - eye
        preferred[2] = 0.0
        tgt = _pick_target(rng, eye, points, distance, prev_dir, np.radians(40.0), preferred, off)
        if tgt is None:
            tgt = _pick_target(rng, eye, points, distance, None, np.pi, preferred, off)
        if tgt is None:
            tgt = anchor
        targets.append(tgt)
        prev_dir = tgt - eye
    return np.asarray(targets)


def _free_point_near(scene: SceneLike, rng: np.random.Generator, point: np.ndarray, margin: float) -> np.ndarray | None:
    """The free point (at ``point``'s height) nearest to ``point`` among random candidates, or None."""
    lo, hi = _room_box(scene)
    cands = np.column_stack(
        [
            rng.uniform(lo[0] + margin, hi[0] - margin, 300),
            rng.uniform(lo[1] + margin, hi[1] - margin, 300),
            np.full(300, point[2]),
        ]
    )
    ok = np.flatnonzero(scene.free_space(cands, margin=margin))
    if ok.size == 0:
        return None
    dist = np.linalg.norm(cands[ok, :2] - point[:2], axis=1)
    return cands[ok[np.argmin(dist)]]


class _FloorGrid:
    """Which floor cells (``res`` m squares) have nothing but air above them from 0.15 m up to ``z_top`` (checked
    with ``free_space`` at a 0.1 m margin, so walls and furniture edges count as blocked)."""

    def __init__(self, scene: SceneLike, z_top: float, res: float = 0.1) -> None:
        size = np.asarray(scene.room_size, dtype=np.float64)
        self.res = res
        self.xs = np.arange(res / 2, size[0], res)
        self.ys = np.arange(res / 2, size[1], res)
        zs = np.arange(0.15, z_top + 1e-9, 0.15)
        gx, gy, gz = np.meshgrid(self.xs, self.ys, zs, indexing="ij")
        free = scene.free_space(np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()]), margin=0.1)
        self.clear = free.reshape(gx.shape).all(axis=2)

    def rectangles(
        self, u_range: tuple[float, float], v_range: tuple[float, float], headings: np.ndarray
    ) -> list[tuple[np.ndarray, float]]:
        """Every (centre (2,), heading) on a 0.2 m grid for which the rectangle ``u_range`` x ``v_range`` (m, u along
        the heading, v to its left) lies on clear floor cells."""
        uu, vv = np.meshgrid(
            np.arange(u_range[0], u_range[1] + 1e-9, self.res), np.arange(v_range[0], v_range[1] + 1e-9, self.res)
        )
        cx, cy = np.meshgrid(self.xs[1::2], self.ys[1::2], indexing="ij")
        centres = np.column_stack([cx.ravel(), cy.ravel()])
        found: list[tuple[np.ndarray, float]] = []
        for heading in headings:
            cu, su = np.cos(heading), np.sin(heading)
            off = np.column_stack([uu.ravel() * cu - vv.ravel() * su, uu.ravel() * su + vv.ravel() * cu])
            pts = centres[:, None, :] + off[None, :, :]  # (C, P, 2)
            ix = np.floor(pts[..., 0] / self.res).astype(int)
            iy = np.floor(pts[..., 1] / self.res).astype(int)
            inside = (ix >= 0) & (ix < self.xs.size) & (iy >= 0) & (iy < self.ys.size)
            ok = inside.all(axis=1)
            ok[ok] = self.clear[ix[ok], iy[ok]].all(axis=1)
            found += [(centres[k], float(heading)) for k in np.flatnonzero(ok)]
        return found


def _ellipse_length(a: float, b: float) -> float:
    """Perimeter of an ellipse with semi-axes a, b (Ramanujan's approximation), metres."""
    return float(np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b))))

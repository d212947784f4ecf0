"""The trajectory record and the pose helpers every camera path is built with: :class:`Trajectory` (timestamps and
``T_world_cam`` poses at 30 Hz, with a continuous :meth:`Trajectory.pose_at`), :func:`look_at`, :func:`poses_from`,
:func:`frame_times`, :func:`smooth_noise`, and :class:`SceneLike` (what a generator needs from a room).

The generators live in :mod:`sim_envs.motion.trajectories`, which re-exports these names; their path-building steps in
:mod:`sim_envs.motion.trajectory_paths`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from sim_envs.errors import SimEnvError

FPS: float = 30.0  # frames per second of every generated trajectory (TUM and ICL-NUIM both record at 30 Hz)
MAX_ATTEMPTS: int = 60  # waypoint draws before a generator gives up (ours)
WORLD_UP = np.array([0.0, 0.0, 1.0])  # the world's up direction (z up), the default "up" of :func:`look_at`


class SceneLike(Protocol):
    """What a trajectory generator needs from a scene (``sim_envs.scenes.scene.Scene`` provides it).

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
    up_arr = np.atleast_2d(WORLD_UP if up is None else np.asarray(up, dtype=np.float64))
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

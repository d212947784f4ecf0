"""Pose trajectories and the SE(3)/SO(3) helpers the metrics are built from.

A :class:`PoseTrajectory` is timestamps (N,) float64 seconds plus ``T_world_cam`` (N, 4, 4) float64 camera-to-world
poses (OpenCV camera axes). Functions are batched over the leading axis and named after the maths, like evo's
``lie_algebra``: ``relative_se3(T_a, T_b) = T_a^-1 T_b`` (here :func:`slamcommon.se3.relative_pose`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from eval.errors import EvalError
from slamcommon.errors import FormatError
from slamcommon.formats import (
    DuplicatePolicy,
    read_kitti_poses,
    read_tum_trajectory,
    write_kitti_poses,
    write_tum_trajectory,
)
from slamcommon.se3 import relative_pose, se3_inverse, sim3_matrix, transform_poses  # noqa: F401 - shared, re-exported


class TrajectoryError(EvalError):
    """A trajectory that cannot be used (bad shapes, unreadable file)."""


# ------------------------------------------------------------------------------------------------------ SE(3) maths
def so3_angle(R: np.ndarray) -> np.ndarray:
    """Rotation angle in radians, [0, pi], of rotation matrices (..., 3, 3).

    atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2): accurate near 0 and near pi, unlike arccos of the trace alone.
    """
    R = np.asarray(R, dtype=np.float64)
    cos = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    skew = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    sin = np.linalg.norm(skew, axis=-1) / 2.0
    return np.arctan2(sin, cos)


def path_length(positions: np.ndarray) -> float:
    """Length in metres of the polyline through positions (N, 3): sum of |p_{i+1} - p_i|."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if p.shape[0] > 1 else 0.0


def distances_along_path(positions: np.ndarray) -> np.ndarray:
    """Cumulative distance travelled (N,) metres, 0 at the first pose."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


# --------------------------------------------------------------------------------------------------- the data type
@dataclass(frozen=True, eq=False)
class PoseTrajectory:
    """Timestamps (N,) float64 seconds and ``T_world_cam`` (N, 4, 4) float64 camera-to-world poses.

    The arrays are copied and made read-only. Timestamps need not be increasing here (an association may repeat a
    pose); the file readers enforce increasing timestamps.
    """

    timestamps: np.ndarray
    T_world_cam: np.ndarray

    def __post_init__(self) -> None:
        stamps = np.array(self.timestamps, dtype=np.float64).reshape(-1)
        T = np.array(self.T_world_cam, dtype=np.float64)
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            raise TrajectoryError(f"T_world_cam must have shape (N, 4, 4), got {T.shape}")
        if T.shape[0] != stamps.shape[0]:
            raise TrajectoryError(f"{stamps.shape[0]} timestamps but {T.shape[0]} poses; they must pair one to one")
        if not (np.isfinite(stamps).all() and np.isfinite(T).all()):
            raise TrajectoryError("timestamps and poses must be finite numbers")
        stamps.flags.writeable = False
        T.flags.writeable = False
        object.__setattr__(self, "timestamps", stamps)
        object.__setattr__(self, "T_world_cam", T)

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) camera centres in the world, metres."""
        return self.T_world_cam[:, :3, 3]

    @property
    def rotations(self) -> np.ndarray:
        """(N, 3, 3) camera-to-world rotations."""
        return self.T_world_cam[:, :3, :3]

    def subset(self, indices: np.ndarray) -> PoseTrajectory:
        """The poses at ``indices`` (an int array; repeats allowed)."""
        idx = np.asarray(indices, dtype=np.int64)
        return PoseTrajectory(self.timestamps[idx], self.T_world_cam[idx])

    def length(self) -> float:
        """Path length in metres."""
        return path_length(self.positions)

    # ------------------------------------------------------------------------------------------------------ files
    @classmethod
    def from_tum_file(
        cls,
        path: str | Path,
        *,
        duplicate_timestamps: DuplicatePolicy = "error",
        on_duplicates: Callable[[str], None] | None = None,
    ) -> PoseTrajectory:
        """Read a TUM trajectory file (:func:`slamcommon.formats.read_tum_trajectory`; ``on_duplicates`` gets one
        message when poses of repeated timestamps were dropped)."""
        try:
            stamps, T = read_tum_trajectory(
                path, duplicate_timestamps=duplicate_timestamps, on_duplicates=on_duplicates
            )
        except FormatError as exc:
            raise TrajectoryError(str(exc)) from exc
        return cls(stamps, T)

    @classmethod
    def from_kitti_file(cls, path: str | Path, *, rate_hz: float = 10.0) -> PoseTrajectory:
        """Read a KITTI pose file; KITTI has no timestamps, so pose i gets ``i / rate_hz`` seconds."""
        try:
            T = read_kitti_poses(path)
        except FormatError as exc:
            raise TrajectoryError(str(exc)) from exc
        return cls(np.arange(T.shape[0]) / float(rate_hz), T)

    def to_tum_file(self, path: str | Path, *, header: str | None = None) -> Path:
        """Write as a TUM trajectory file."""
        return write_tum_trajectory(path, self.timestamps, self.T_world_cam, header=header)

    def to_kitti_file(self, path: str | Path) -> Path:
        """Write as a KITTI pose file (timestamps are dropped)."""
        return write_kitti_poses(path, self.T_world_cam)


# scene depth that weighs translation against rotation in rotation_share (ours: indoor rooms)
NOMINAL_DEPTH_M: float = 2.0


def rotation_share(T_world_cam: np.ndarray, depth_m: float = NOMINAL_DEPTH_M) -> float:
    """Share (0..1) of the image motion along a trajectory that is due to rotation.

    Per frame step, a rotation by angle a moves the image by about f * a pixels and a translation t by about
    f * |t| / d for a scene at depth d; the share is sum(a) / (sum(a) + sum(|t|) / d) over the steps.
    T_world_cam: (N, 4, 4); depth_m: the scene depth d in metres. NaN for a trajectory that does not move.
    """
    import math

    from scipy.spatial.transform import Rotation  # here: `cnnslam eval` imports this module and needs no scipy

    T = np.asarray(T_world_cam, dtype=np.float64)
    if T.shape[0] < 2:
        return math.nan
    rel = np.einsum("nji,njk->nik", T[:-1, :3, :3], T[1:, :3, :3])
    angles = Rotation.from_matrix(rel).magnitude()
    shifts = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1) / float(depth_m)
    total = float(angles.sum() + shifts.sum())
    return float(angles.sum() / total) if total > 0 else math.nan

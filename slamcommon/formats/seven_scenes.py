"""Microsoft 7-Scenes files as they ship: ``frame-XXXXXX.color.png`` (or ``.jpg``), ``frame-XXXXXX.depth.png``
(16-bit millimetres; 0 and 65535 = no measurement) and ``frame-XXXXXX.pose.txt`` (4x4 camera-to-world, metres).
There are no timestamps: frame XXXXXX is at XXXXXX / :data:`SEVEN_SCENES_FPS` s."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from slamcommon.errors import FormatError

SEVEN_SCENES_DEPTH_SCALE: float = 1000.0  # 7-Scenes: millimetres
SEVEN_SCENES_INVALID_DEPTH = 65535  # 7-Scenes marks no measurement by 0 and by 65535
SEVEN_SCENES_FPS: float = 30.0  # 7-Scenes has no timestamps; the Kinect's nominal rate
SEVEN_SCENES_COLOUR = re.compile(r"^(frame-(\d+))\.color\.(png|jpg)$")  # groups: file prefix, frame number, suffix
POSE_ROTATION_TOL: float = 1e-2  # max |R - nearest rotation| of a 7-Scenes pose (ours: its matrices are within 4e-4)


def read_pose_matrix(path: str | Path) -> np.ndarray:
    """A 7-Scenes ``frame-XXXXXX.pose.txt`` (4 rows of 4 numbers, camera-to-world, metres) -> (4, 4) float64
    ``T_world_cam``, the rotation block replaced by the nearest rotation (SVD, U V^T): 7-Scenes' KinectFusion
    matrices are orthonormal only to about 4e-4. A matrix with a non-finite entry (no pose) comes back all NaN.
    :class:`FormatError` (one line naming the file) for anything else that is not a pose: not 4 rows of 4 numbers,
    a last row other than 0 0 0 1, a reflection, a block farther than :data:`POSE_ROTATION_TOL` from a rotation."""
    path = Path(path)
    try:
        M = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except (OSError, ValueError) as exc:
        raise FormatError(f"{path}: not a 4x4 matrix of numbers ({exc})") from exc
    if M.shape != (4, 4):
        raise FormatError(f"{path}: expected 4 rows of 4 numbers (a 4x4 camera-to-world matrix), got {M.shape}")
    if not np.isfinite(M).all():
        return np.full((4, 4), np.nan)
    if not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
        raise FormatError(f"{path}: the last row of a pose must be 0 0 0 1, got {M[3].tolist()}")
    U, _, Vt = np.linalg.svd(M[:3, :3])
    R = U @ Vt
    if np.linalg.det(R) < 0:
        raise FormatError(f"{path}: the 3x3 block is a reflection (det < 0), not a rotation")
    deviation = float(np.abs(M[:3, :3] - R).max())
    if deviation > POSE_ROTATION_TOL:
        raise FormatError(f"{path}: the 3x3 block is {deviation:.3g} away from the nearest rotation; a pose needs a "
                          f"rotation (orthonormal to within {POSE_ROTATION_TOL:g}, det +1)")  # fmt: skip
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = M[:3, 3]
    return T

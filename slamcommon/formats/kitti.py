"""KITTI odometry pose files: 12 numbers per line, the first three rows of ``T_world_cam`` in row-major order; no
timestamps (the line index is the frame index). The text rules of :mod:`slamcommon.formats.lines`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamcommon.errors import FormatError
from slamcommon.formats.lines import data_lines, parse_numbers

ROTATION_TOL: float = 1e-4  # max |R^T R - I| accepted in KITTI files (ours; they print 6+ significant digits)


def read_kitti_poses(path: str | Path, *, rotation_tol: float = ROTATION_TOL) -> np.ndarray:
    """Read a KITTI odometry pose file: 12 numbers per line, rows 0-2 of ``T_world_cam`` row-major.

    Returns (N, 4, 4) float64. Raises :class:`FormatError` naming file and line on a column count other than 12, a
    non-number, or a rotation block that is not a rotation (``|R^T R - I| > rotation_tol`` or ``det R < 0``).
    """
    path = Path(path)
    layout = "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz"
    rows = data_lines(path)
    if not rows:
        raise FormatError(f"{path}: no poses found; expected lines '{layout}'")
    T = np.tile(np.eye(4), (len(rows), 1, 1))
    for k, (number, fields) in enumerate(rows):
        T[k, :3, :] = np.reshape(parse_numbers(path, number, fields, 12, layout), (3, 4))
        R = T[k, :3, :3]
        with np.errstate(over="ignore", invalid="ignore"):  # entries near 1e308: inf or nan, refused below
            deviation = float(np.abs(R.T @ R - np.eye(3)).max())
            det = float(np.linalg.det(R))
        if not deviation <= rotation_tol or not det > 0:
            raise FormatError(
                f"{path}:{number}: the 3x3 block is not a rotation (|R^T R - I| = {deviation:.3g}, det = "
                f"{det:.6g}); a pose needs an orthonormal R with det +1 (tolerance {rotation_tol:g})"
            )
    return T


def write_kitti_poses(path: str | Path, T_world_cam: np.ndarray, *, digits: int = 12) -> Path:
    """Write (N, 4, 4) poses as a KITTI pose file (``digits`` significant digits, like KITTI's %e output)."""
    path = Path(path)
    T = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    rows = T[:, :3, :].reshape(-1, 12)
    np.savetxt(path, rows, fmt=f"%.{digits}e", delimiter=" ")
    return path

"""Trajectory and index files of the usual SLAM benchmarks: TUM RGB-D and KITTI odometry.

TUM trajectory file (``groundtruth.txt``, and what SLAM systems write): one pose per line,
``timestamp tx ty tz qx qy qz qw``; ``timestamp`` in seconds, ``t`` the camera position in the world (metres),
``q`` the camera-to-world rotation as a Hamilton quaternion with w LAST; ``#`` starts a comment; fields are separated
by spaces, tabs or commas (as the TUM tools' ``associate.read_file_list`` accepts). Poses are returned as
``T_world_cam`` (4, 4) float64.

TUM image list (``rgb.txt``, ``depth.txt``): ``timestamp filename`` per line, same comment rules.

KITTI odometry poses: 12 numbers per line, the first three rows of ``T_world_cam`` in row-major order; no timestamps
(the line index is the frame index).

Reading is strict: the first bad line raises one :class:`~sim_envs.errors.FormatError` that names the file, the
line, what was found and what is valid. Non-unit quaternions are rejected beyond ``quaternion_tol`` (then
normalised); timestamps must strictly increase (the TUM ground truth of fr2/desk repeats one timestamp; pass
``duplicate_timestamps="last"`` to keep the last pose of a repeated timestamp, as the TUM tools' dictionary does).

Also here, because loading a TUM RGB-D folder needs it and the world must not import the judge:
:func:`associate_greedy`, the TUM tools' timestamp association (``associate.py``).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from sim_envs.errors import FormatError

DuplicatePolicy = Literal["error", "first", "last"]
DUPLICATE_POLICIES: tuple[str, ...] = ("error", "first", "last")

QUATERNION_TOL: float = 1e-3  # |‖q‖ - 1| accepted; TUM ground truth has 4 decimals (|‖q‖ - 1| up to 9e-5 seen)
ROTATION_TOL: float = 1e-4  # max |R^T R - I| accepted in KITTI files (ours; they print 6+ significant digits)
_SEPARATORS = re.compile(r"[\s,]+")


# ----------------------------------------------------------------------------------------------------------- lines
def _data_lines(path: Path) -> list[tuple[int, list[str]]]:
    """(1-based line number, fields) of every non-comment, non-blank line; ``#`` starts a comment anywhere."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise FormatError(f"{path}: cannot read the file: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise FormatError(f"{path}: not a text file (UTF-8 decoding failed at byte {exc.start})") from exc
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0].strip()
        if content:
            rows.append((number, [f for f in _SEPARATORS.split(content) if f]))
    return rows


def _parse_numbers(path: Path, number: int, fields: list[str], expected: int, layout: str) -> list[float]:
    if len(fields) != expected:
        raise FormatError(
            f"{path}:{number}: expected {expected} columns ({layout}), found {len(fields)}: {' '.join(fields)!r}"
        )
    values = []
    for column, field in enumerate(fields, start=1):
        try:
            value = float(field)
        except ValueError:
            raise FormatError(
                f"{path}:{number}: column {column} is {field!r}, not a number; valid lines are '{layout}'"
            ) from None
        if not np.isfinite(value):
            raise FormatError(f"{path}:{number}: column {column} is {field!r}; values must be finite numbers")
        values.append(value)
    return values


def _check_increasing(
    path: Path,
    numbers: list[int],
    stamps: np.ndarray,
    duplicates: DuplicatePolicy,
    on_duplicates: Callable[[str], None] | None = None,
) -> np.ndarray:
    """Indices of the rows to keep; raises on a decreasing timestamp, and on a repeated one unless told otherwise.
    ``on_duplicates`` gets one message (file, count, first line) when repeated timestamps were dropped."""
    if duplicates not in DUPLICATE_POLICIES:
        raise FormatError(f"duplicate_timestamps must be one of {DUPLICATE_POLICIES}, got {duplicates!r}")
    steps = np.diff(stamps)
    bad = np.flatnonzero(steps < 0) if duplicates != "error" else np.flatnonzero(steps <= 0)
    if bad.size:
        k = int(bad[0])
        what = "repeats" if steps[k] == 0 else "is smaller than"
        hint = (
            "; to keep one pose per repeated timestamp pass duplicate_timestamps='last' (what the TUM tools do) "
            "or 'first' (command line: --duplicates last)"
            if steps[k] == 0
            else ""
        )
        raise FormatError(
            f"{path}:{numbers[k + 1]}: timestamp {float(stamps[k + 1])!r} {what} the timestamp "
            f"{float(stamps[k])!r} of line {numbers[k]}; timestamps must strictly increase{hint}"
        )
    if duplicates == "error" or stamps.size == 0:
        return np.arange(stamps.size)
    repeated = steps == 0
    if on_duplicates is not None and repeated.any():
        k = int(np.flatnonzero(repeated)[0])
        on_duplicates(
            f"{path}: {int(repeated.sum())} repeated timestamp(s), the first {float(stamps[k])!r} on lines "
            f"{numbers[k]} and {numbers[k + 1]}; kept the {duplicates} pose of each"
        )
    if duplicates == "last":
        return np.flatnonzero(np.r_[~repeated, True])
    return np.flatnonzero(np.r_[True, ~repeated])


# ------------------------------------------------------------------------------------------------- TUM trajectory
def quaternions_to_matrices(positions: np.ndarray, quaternions_xyzw: np.ndarray) -> np.ndarray:
    """(N, 3) positions and (N, 4) Hamilton quaternions ``qx qy qz qw`` (normalised here) -> (N, 4, 4) float64."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    T = np.tile(np.eye(4), (positions.shape[0], 1, 1))
    if positions.shape[0]:
        T[:, :3, :3] = Rotation.from_quat(np.asarray(quaternions_xyzw, dtype=np.float64).reshape(-1, 4)).as_matrix()
        T[:, :3, 3] = positions
    return T


def matrices_to_quaternions(T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4, 4) poses -> positions (N, 3) and quaternions (N, 4) ``qx qy qz qw`` with qw >= 0."""
    T = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    if T.shape[0] == 0:
        return np.zeros((0, 3)), np.zeros((0, 4))
    return T[:, :3, 3].copy(), Rotation.from_matrix(T[:, :3, :3]).as_quat(canonical=True)


def read_tum_trajectory(
    path: str | Path,
    *,
    quaternion_tol: float = QUATERNION_TOL,
    duplicate_timestamps: DuplicatePolicy = "error",
    on_duplicates: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file.

    Returns ``timestamps`` (N,) float64 seconds, strictly increasing, and ``T_world_cam`` (N, 4, 4) float64.
    Raises :class:`FormatError` naming file and line on: a column count other than 8, a field that is not a finite
    number, a quaternion whose norm differs from 1 by more than ``quaternion_tol``, a timestamp that does not
    increase (see ``duplicate_timestamps``), an empty file. ``on_duplicates``: called once with a one-line message
    when ``"first"``/``"last"`` dropped poses of repeated timestamps (for a warning).
    """
    path = Path(path)
    layout = "timestamp tx ty tz qx qy qz qw"
    rows = _data_lines(path)
    if not rows:
        raise FormatError(f"{path}: no poses found (every line is blank or a comment); expected lines '{layout}'")
    values = np.empty((len(rows), 8))
    numbers = []
    for k, (number, fields) in enumerate(rows):
        values[k] = _parse_numbers(path, number, fields, 8, layout)
        numbers.append(number)
    with np.errstate(over="ignore"):  # a component near 1e308: its norm is inf, refused below
        norms = np.linalg.norm(values[:, 4:8], axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > quaternion_tol)
    if bad.size:
        k = int(bad[0])
        raise FormatError(
            f"{path}:{numbers[k]}: quaternion (qx qy qz qw) = {tuple(values[k, 4:8])} has norm {norms[k]:.6g}; "
            f"a rotation needs a unit quaternion (norm within {quaternion_tol:g} of 1)"
        )
    keep = _check_increasing(path, numbers, values[:, 0], duplicate_timestamps, on_duplicates)
    values = values[keep]
    return values[:, 0].copy(), quaternions_to_matrices(values[:, 1:4], values[:, 4:8])


def format_tum_trajectory(
    timestamps: np.ndarray, T_world_cam: np.ndarray, *, header: str | None = None, decimals: int = 9
) -> str:
    """The text of a TUM trajectory file. Timestamps are written exactly (shortest round-trip repr), pose values
    with ``decimals`` digits after the point. ``header`` lines are written as ``#`` comments."""
    timestamps = np.asarray(timestamps, dtype=np.float64).reshape(-1)
    T = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    if T.shape[0] != timestamps.shape[0]:
        raise FormatError(f"{timestamps.shape[0]} timestamps but {T.shape[0]} poses; they must pair one to one")
    positions, quats = matrices_to_quaternions(T)
    lines = [f"# {line}" for line in (header or "").splitlines()]
    lines.append("# timestamp tx ty tz qx qy qz qw")
    fmt = " ".join([f"%.{decimals}f"] * 7)
    body = np.hstack([positions, quats])
    lines += [f"{float(t)!r} " + fmt % tuple(row) for t, row in zip(timestamps, body, strict=True)]
    return "\n".join(lines) + "\n"


def write_tum_trajectory(
    path: str | Path,
    timestamps: np.ndarray,
    T_world_cam: np.ndarray,
    *,
    header: str | None = None,
    decimals: int = 9,
) -> Path:
    """Write ``timestamps`` (N,) seconds and ``T_world_cam`` (N, 4, 4) as a TUM trajectory file; returns the path."""
    path = Path(path)
    path.write_text(format_tum_trajectory(timestamps, T_world_cam, header=header, decimals=decimals))
    return path


# ------------------------------------------------------------------------------------------------ TUM image lists
def read_tum_image_list(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """Read ``rgb.txt`` / ``depth.txt``: ``timestamp filename`` per line.

    Returns timestamps (N,) float64 (strictly increasing) and the file names as written (relative to the folder).
    Extra columns after the file name are an error (file names with spaces are not supported by the format).
    """
    path = Path(path)
    rows = _data_lines(path)
    if not rows:
        raise FormatError(f"{path}: no entries found; expected lines 'timestamp filename'")
    stamps = np.empty(len(rows))
    names: list[str] = []
    numbers = []
    for k, (number, fields) in enumerate(rows):
        if len(fields) != 2:
            raise FormatError(
                f"{path}:{number}: expected 2 columns (timestamp filename), found {len(fields)}: {' '.join(fields)!r}"
            )
        stamps[k] = _parse_numbers(path, number, fields[:1], 1, "timestamp filename")[0]
        names.append(fields[1])
        numbers.append(number)
    _check_increasing(path, numbers, stamps, "error")
    return stamps, names


def write_tum_image_list(path: str | Path, timestamps: np.ndarray, filenames: Sequence[str], title: str) -> Path:
    """Write a TUM image list (``# title`` header like the TUM files, then ``timestamp filename`` lines)."""
    path = Path(path)
    timestamps = np.asarray(timestamps, dtype=np.float64).reshape(-1)
    if len(filenames) != timestamps.shape[0]:
        raise FormatError(f"{timestamps.shape[0]} timestamps but {len(filenames)} file names")
    lines = [f"# {title}", "# timestamp filename"]
    lines += [f"{float(t)!r} {name}" for t, name in zip(timestamps, filenames, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------------------------------------------------- KITTI
def read_kitti_poses(path: str | Path, *, rotation_tol: float = ROTATION_TOL) -> np.ndarray:
    """Read a KITTI odometry pose file: 12 numbers per line, rows 0-2 of ``T_world_cam`` row-major.

    Returns (N, 4, 4) float64. Raises :class:`FormatError` naming file and line on a column count other than 12, a
    non-number, or a rotation block that is not a rotation (``|R^T R - I| > rotation_tol`` or ``det R < 0``).
    """
    path = Path(path)
    layout = "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz"
    rows = _data_lines(path)
    if not rows:
        raise FormatError(f"{path}: no poses found; expected lines '{layout}'")
    T = np.tile(np.eye(4), (len(rows), 1, 1))
    for k, (number, fields) in enumerate(rows):
        T[k, :3, :] = np.reshape(_parse_numbers(path, number, fields, 12, layout), (3, 4))
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


# ---------------------------------------------------------------------------------------------------- association
def associate_greedy(
    stamps_first: np.ndarray, stamps_second: np.ndarray, max_difference: float = 0.02, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The TUM tools' association (``associate.py``): greedy one-to-one matching of two timestamp lists.

    Every pair (a, b) with ``|a - (b + offset)| < max_difference`` is a candidate; candidates are sorted by
    ``(|a - (b + offset)|, a, b)`` (the TUM tools sort tuples) and taken greedily while neither stamp is used yet.
    Returns index arrays (M,) into ``stamps_first`` and ``stamps_second``, sorted by the first. Both lists must be
    sorted increasing (as every reader here guarantees). Work: O((N1 + N2) log N) plus the candidates.
    """
    a = np.asarray(stamps_first, dtype=np.float64).reshape(-1)
    b = np.asarray(stamps_second, dtype=np.float64).reshape(-1)
    if not (max_difference > 0 and np.isfinite(max_difference)):
        raise FormatError(f"max_difference must be a positive number of seconds, got {max_difference!r}")
    shifted = b + offset
    lo = np.searchsorted(shifted, a - max_difference, side="left")
    hi = np.searchsorted(shifted, a + max_difference, side="right")
    counts = hi - lo
    i = np.repeat(np.arange(a.size), counts)
    j = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(lo, counts)
    diff = np.abs(a[i] - (b[j] + offset))
    keep = diff < max_difference
    i, j, diff = i[keep], j[keep], diff[keep]
    order = np.lexsort((b[j], a[i], diff))
    used_a, used_b = [False] * a.size, [False] * b.size
    first, second = [], []
    for ii, jj in zip(i[order].tolist(), j[order].tolist(), strict=True):
        if not used_a[ii] and not used_b[jj]:
            used_a[ii] = used_b[jj] = True
            first.append(ii)
            second.append(jj)
    first_arr, second_arr = np.asarray(first, dtype=np.int64), np.asarray(second, dtype=np.int64)
    sort = np.argsort(first_arr, kind="stable")
    return first_arr[sort], second_arr[sort]

"""TUM RGB-D files: trajectories (``groundtruth.txt``, and what SLAM systems write) and image lists (``rgb.txt``,
``depth.txt``).

TUM trajectory file: one pose per line, ``timestamp tx ty tz qx qy qz qw``; ``timestamp`` in seconds, ``t`` the
camera position in the world (metres), ``q`` the camera-to-world rotation as a Hamilton quaternion with w LAST; the
text rules of :mod:`slamcommon.formats.lines`. Poses are returned as ``T_world_cam`` (4, 4) float64. Non-unit
quaternions are rejected beyond ``quaternion_tol`` (then normalised); timestamps must strictly increase (the TUM
ground truth of fr2/desk repeats one timestamp; pass ``duplicate_timestamps="last"`` to keep the last pose of a
repeated timestamp, as the TUM tools' dictionary does).

:func:`read_tum_trajectory` reads in two ways with one result, bit for bit, and one set of errors:

- the fast path takes a text whose data lines hold only digits, ``+ - . e E``, blanks, tabs and commas (anything may
  follow ``#``), parses it with :func:`numpy.loadtxt` (which converts every field with CPython's own
  ``PyOS_string_to_double``, as ``float()`` does) and converts the quaternions with :func:`quaternions_to_matrices`
  (the same float operations, in the same order, as scipy's ``Rotation.from_quat(q).as_matrix()``, so the same
  bits, without importing scipy);
- everything else (an unreadable or non-UTF-8 file, another character, a line without 8 fields, a non-finite number,
  a non-unit quaternion, a timestamp that does not increase, no poses at all) goes to the line-by-line reader
  (:func:`read_tum_trajectory_by_line`), so every error names the file and line. Repeated timestamps under
  ``duplicate_timestamps="first"|"last"`` stay on the fast path, with the same warning.

TUM image list: ``timestamp filename`` per line, same comment rules.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from slamcommon.errors import FormatError
from slamcommon.formats.lines import (
    DUPLICATE_POLICIES,
    DuplicatePolicy,
    check_increasing,
    data_line_numbers,
    data_lines,
    drop_repeated,
    parse_numbers,
)

QUATERNION_TOL: float = 1e-3  # |‖q‖ - 1| accepted; TUM ground truth has 4 decimals (|‖q‖ - 1| up to 9e-5 seen)
TUM_TRAJECTORY_LINE = "timestamp tx ty tz qx qy qz qw"

# Characters str.splitlines() breaks lines at besides \n and \r (the line-by-line reader splits lines with it).
_OTHER_LINE_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_COMMENT = re.compile(r"#[^\n]*")
# What a plain decimal or exponent number and the separators use; any other character is left to the line reader.
_PLAIN_BYTES = b"0123456789+-.eE \t\n,"
# A line of commas and blanks only: no fields, an error for the line reader, a blank line for numpy.
_COMMAS_ONLY = re.compile(r"^[ \t,]*,[ \t,]*$", re.MULTILINE)


# ------------------------------------------------------------------------------------------------------ rotations
def quaternions_to_matrices(positions: np.ndarray, quaternions_xyzw: np.ndarray) -> np.ndarray:
    """(N, 3) positions and (N, 4) Hamilton quaternions ``qx qy qz qw`` (normalised here) -> (N, 4, 4) float64.

    Bit for bit scipy's ``Rotation.from_quat(q).as_matrix()`` (divide by ``sqrt(x*x + y*y + z*z + w*w)``, then the
    products below in the same order), without importing scipy.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(quaternions_xyzw, dtype=np.float64).reshape(-1, 4)
    T = np.zeros((positions.shape[0], 4, 4))
    T[:, 3, 3] = 1.0
    if positions.shape[0] == 0:
        return T
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    norm = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    T[:, 0, 0] = x2 - y2 - z2 + w2
    T[:, 1, 0] = 2 * (xy + zw)
    T[:, 2, 0] = 2 * (xz - yw)
    T[:, 0, 1] = 2 * (xy - zw)
    T[:, 1, 1] = -x2 + y2 - z2 + w2
    T[:, 2, 1] = 2 * (yz + xw)
    T[:, 0, 2] = 2 * (xz + yw)
    T[:, 1, 2] = 2 * (yz - xw)
    T[:, 2, 2] = -x2 - y2 + z2 + w2
    T[:, :3, 3] = positions
    return T


def matrices_to_quaternions(T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4, 4) poses -> positions (N, 3) and quaternions (N, 4) ``qx qy qz qw`` with qw >= 0."""
    from scipy.spatial.transform import Rotation  # only writers need it; reading stays scipy-free

    T = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    if T.shape[0] == 0:
        return np.zeros((0, 3)), np.zeros((0, 4))
    return T[:, :3, 3].copy(), Rotation.from_matrix(T[:, :3, :3]).as_quat(canonical=True)


# ------------------------------------------------------------------------------------------------- TUM trajectory
def parse_plain_tum_text(text: str) -> np.ndarray | None:
    """The (N, 8) values of a TUM trajectory text, or None when the fast path does not take it.

    Taken: lines broken by ``\\n``, ``\\r\\n`` or ``\\r``; ``#`` starts a comment anywhere; every other line blank
    or exactly 8 fields of ``[0-9+-.eE]`` separated by blanks, tabs or commas, each a finite number for ``float()``;
    at least one such line. Anything else returns None (the line reader then says what is wrong). The values are
    those ``float()`` gives (numpy's text reader converts with the same CPython routine).
    """
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")  # what reading in text mode does
    if any(c in text for c in _OTHER_LINE_BREAKS):
        return None
    if "#" in text:
        text = _COMMENT.sub("", text)
    try:
        plain = text.encode("ascii")
    except UnicodeEncodeError:
        return None
    if plain.translate(None, _PLAIN_BYTES):  # a character other than those
        return None
    if "," in text:
        if _COMMAS_ONLY.search(text):
            return None
        text = text.replace(",", " ")
    if not text.strip():
        return None
    try:
        values = np.loadtxt(io.StringIO(text), dtype=np.float64, comments=None, ndmin=2)
    except ValueError:  # a field that is not a number, or lines with different field counts
        return None
    if values.ndim != 2 or values.shape[1] != 8 or not np.isfinite(values).all():
        return None
    return values


def read_tum_trajectory(
    path: str | Path,
    *,
    quaternion_tol: float = QUATERNION_TOL,
    duplicate_timestamps: DuplicatePolicy = "error",
    on_duplicates: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file (the fast path where it applies, see the module docstring).

    Returns ``timestamps`` (N,) float64 seconds, strictly increasing, and ``T_world_cam`` (N, 4, 4) float64.
    Raises :class:`FormatError` naming file and line on: a column count other than 8, a field that is not a finite
    number, a quaternion whose norm differs from 1 by more than ``quaternion_tol``, a timestamp that does not
    increase (see ``duplicate_timestamps``), an empty file. ``on_duplicates``: called once with a one-line message
    when ``"first"``/``"last"`` dropped poses of repeated timestamps (for a warning).
    """
    path = Path(path)
    values = None
    text = ""
    if duplicate_timestamps in DUPLICATE_POLICIES:
        try:
            text = path.read_bytes().decode("utf-8")
            values = parse_plain_tum_text(text)
        except (OSError, UnicodeDecodeError):
            values = None  # unreadable: the line reader below raises its own error, naming the file
    if values is not None:
        with np.errstate(over="ignore"):  # a component near 1e308: norm inf, refused by the line reader
            norms = np.linalg.norm(values[:, 4:8], axis=1)  # the line reader's test, to the same bits
        unit = bool(np.all(np.abs(norms - 1.0) <= quaternion_tol))
        steps = np.diff(values[:, 0])
        if unit and (steps > 0).all():
            return values[:, 0].copy(), quaternions_to_matrices(values[:, 1:4], values[:, 4:8])
        if unit and duplicate_timestamps != "error" and (steps >= 0).all():
            numbers = data_line_numbers(text) if on_duplicates is not None else []
            keep = drop_repeated(path, numbers, values[:, 0], steps, duplicate_timestamps, on_duplicates)
            values = values[keep]
            return values[:, 0].copy(), quaternions_to_matrices(values[:, 1:4], values[:, 4:8])
    return read_tum_trajectory_by_line(
        path, quaternion_tol=quaternion_tol, duplicate_timestamps=duplicate_timestamps, on_duplicates=on_duplicates
    )


def read_tum_trajectory_by_line(
    path: str | Path,
    *,
    quaternion_tol: float = QUATERNION_TOL,
    duplicate_timestamps: DuplicatePolicy = "error",
    on_duplicates: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`read_tum_trajectory` line by line with ``float()``: the same values and errors, slower; the reference
    the fast path is tested against, and where every error is found."""
    path = Path(path)
    rows = data_lines(path)
    if not rows:
        raise FormatError(
            f"{path}: no poses found (every line is blank or a comment); expected lines '{TUM_TRAJECTORY_LINE}'"
        )
    values = np.empty((len(rows), 8))
    numbers = []
    for k, (number, fields) in enumerate(rows):
        values[k] = parse_numbers(path, number, fields, 8, TUM_TRAJECTORY_LINE)
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
    keep = check_increasing(path, numbers, values[:, 0], duplicate_timestamps, on_duplicates)
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
    lines.append(f"# {TUM_TRAJECTORY_LINE}")
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
    rows = data_lines(path)
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
        stamps[k] = parse_numbers(path, number, fields[:1], 1, "timestamp filename")[0]
        names.append(fields[1])
        numbers.append(number)
    check_increasing(path, numbers, stamps, "error")
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

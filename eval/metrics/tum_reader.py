"""Fast reading of TUM trajectory files for the judge: :func:`sim_envs.formats.read_tum_trajectory`'s contract, with
numpy's C parser and without importing the world (``sim_envs`` pulls in Gymnasium and scipy.interpolate on import,
which costs ``cnnslam eval`` more than parsing 100 000 poses).

:func:`read_tum_file` returns exactly what the reference returns, bit for bit, and raises exactly its messages:

- the fast path takes a file whose data lines hold only digits, ``+ - . e E``, blanks, tabs and commas (anything
  may follow ``#``), parses it with :func:`numpy.loadtxt` (which converts every field with CPython's own
  ``PyOS_string_to_double``, as ``float()`` does) and converts the quaternions with
  :func:`quaternions_to_matrices` (the same float operations, in the same order, as scipy's
  ``Rotation.from_quat(q).as_matrix()``, so the same bits);
- everything else (an unreadable or non-UTF-8 file, another character, a line without 8 fields, a non-finite
  number, a non-unit quaternion, a timestamp that does not increase, no poses at all) goes to the reference reader,
  imported only then, so every error names the file and line in the reference's words. Repeated timestamps under
  ``duplicate_timestamps="first"|"last"`` stay on the fast path, with the reference's warning.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

from eval.errors import EvalError

DuplicatePolicy = Literal["error", "first", "last"]
DUPLICATE_POLICIES: tuple[str, ...] = ("error", "first", "last")  # = sim_envs.formats.DUPLICATE_POLICIES (tested)
QUATERNION_TOL: float = 1e-3  # = sim_envs.formats.QUATERNION_TOL (tested)

# Characters str.splitlines() breaks lines at besides \n and \r (the reference splits lines with it).
_OTHER_LINE_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_COMMENT = re.compile(r"#[^\n]*")
# What a plain decimal or exponent number and the separators use; any other character is left to the reference.
_PLAIN_BYTES = b"0123456789+-.eE \t\n,"
# A line of commas and blanks only: no fields, an error for the reference, a blank line for numpy.
_COMMAS_ONLY = re.compile(r"^[ \t,]*,[ \t,]*$", re.MULTILINE)


class TumFileError(EvalError):
    """A TUM trajectory file that cannot be read; the message names the file and line (the reference's words)."""


def quaternions_to_matrices(positions: np.ndarray, quaternions_xyzw: np.ndarray) -> np.ndarray:
    """(N, 3) positions and (N, 4) Hamilton quaternions ``qx qy qz qw`` (normalised here) -> (N, 4, 4) float64.

    Bit for bit :func:`sim_envs.formats.quaternions_to_matrices` (scipy's ``Rotation.from_quat(q).as_matrix()``:
    divide by ``sqrt(x*x + y*y + z*z + w*w)``, then the products below in the same order), without importing scipy.
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


def parse_plain_tum_text(text: str) -> np.ndarray | None:
    """The (N, 8) values of a TUM trajectory text, or None when the fast path does not take it.

    Taken: lines broken by ``\\n``, ``\\r\\n`` or ``\\r``; ``#`` starts a comment anywhere; every other line blank
    or exactly 8 fields of ``[0-9+-.eE]`` separated by blanks, tabs or commas, each a finite number for ``float()``;
    at least one such line. Anything else returns None (the reference reader then says what is wrong). The values are
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


def data_line_numbers(text: str) -> list[int]:
    """1-based numbers of the lines that hold data (not blank, not only a comment), as the reference counts them."""
    return [n for n, line in enumerate(text.splitlines(), start=1) if line.split("#", 1)[0].strip()]


def read_tum_file(
    path: str | Path,
    *,
    quaternion_tol: float = QUATERNION_TOL,
    duplicate_timestamps: DuplicatePolicy = "error",
    on_duplicates: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file: ``timestamps`` (N,) float64 seconds, strictly increasing, and ``T_world_cam``
    (N, 4, 4) float64; the same values and the same errors (as :class:`TumFileError`) as
    :func:`sim_envs.formats.read_tum_trajectory` with the same arguments (see the module docstring)."""
    path = Path(path)
    values = None
    text = ""
    if duplicate_timestamps in DUPLICATE_POLICIES:
        try:
            text = path.read_bytes().decode("utf-8")
            values = parse_plain_tum_text(text)
        except (OSError, UnicodeDecodeError):
            values = None  # unreadable: the reference reader below raises its own error, naming the file
    if values is not None:
        with np.errstate(over="ignore"):  # a component near 1e308: norm inf, as the reference (which refuses it)
            norms = np.linalg.norm(values[:, 4:8], axis=1)  # the reference's test, to the same bits
        steps = np.diff(values[:, 0])
        if np.all(np.abs(norms - 1.0) <= quaternion_tol) and (steps > 0).all():
            return values[:, 0].copy(), quaternions_to_matrices(values[:, 1:4], values[:, 4:8])
        if np.all(np.abs(norms - 1.0) <= quaternion_tol) and duplicate_timestamps != "error" and (steps >= 0).all():
            keep = _drop_repeated(path, text, values[:, 0], steps, duplicate_timestamps, on_duplicates)
            values = values[keep]
            return values[:, 0].copy(), quaternions_to_matrices(values[:, 1:4], values[:, 4:8])
    return _read_reference(path, quaternion_tol, duplicate_timestamps, on_duplicates)


def _drop_repeated(
    path: Path,
    text: str,
    stamps: np.ndarray,
    steps: np.ndarray,
    duplicates: DuplicatePolicy,
    on_duplicates: Callable[[str], None] | None,
) -> np.ndarray:
    """Rows to keep of non-decreasing ``stamps`` with repeats, and the reference's one warning (file, count, lines)."""
    repeated = steps == 0
    if on_duplicates is not None:
        k = int(np.flatnonzero(repeated)[0])
        numbers = data_line_numbers(text)
        on_duplicates(
            f"{path}: {int(repeated.sum())} repeated timestamp(s), the first {float(stamps[k])!r} on lines "
            f"{numbers[k]} and {numbers[k + 1]}; kept the {duplicates} pose of each"
        )
    if duplicates == "last":
        return np.flatnonzero(np.r_[~repeated, True])
    return np.flatnonzero(np.r_[True, ~repeated])


def _read_reference(
    path: Path,
    quaternion_tol: float,
    duplicate_timestamps: DuplicatePolicy,
    on_duplicates: Callable[[str], None] | None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sim_envs.formats.read_tum_trajectory`, its :class:`~sim_envs.errors.FormatError` as
    :class:`TumFileError` (imported here: only files off the fast path pay for importing the world)."""
    from sim_envs.errors import FormatError
    from sim_envs.formats import read_tum_trajectory

    try:
        return read_tum_trajectory(
            path,
            quaternion_tol=quaternion_tol,
            duplicate_timestamps=duplicate_timestamps,
            on_duplicates=on_duplicates,
        )
    except FormatError as exc:
        raise TumFileError(str(exc)) from exc

"""The text rules every format here shares: ``#`` starts a comment anywhere, blank lines are skipped, fields are
separated by spaces, tabs or commas (as the TUM tools' ``associate.read_file_list`` accepts); numbers must be finite;
timestamps must strictly increase unless a policy for repeated ones is given. Every error is one
:class:`~slamcommon.errors.FormatError` line naming the file and the line."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

from slamcommon.errors import FormatError

DuplicatePolicy = Literal["error", "first", "last"]
DUPLICATE_POLICIES: tuple[str, ...] = ("error", "first", "last")
_SEPARATORS = re.compile(r"[\s,]+")


def data_lines(path: Path) -> list[tuple[int, list[str]]]:
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


def data_line_numbers(text: str) -> list[int]:
    """1-based numbers of the lines of ``text`` that hold data (not blank, not only a comment), as
    :func:`data_lines` counts them."""
    return [n for n, line in enumerate(text.splitlines(), start=1) if line.split("#", 1)[0].strip()]


def parse_numbers(path: Path, number: int, fields: list[str], expected: int, layout: str) -> list[float]:
    """``fields`` of line ``number`` as ``expected`` finite floats; ``layout`` names the columns in the error."""
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


def check_increasing(
    path: Path,
    numbers: list[int],
    stamps: np.ndarray,
    duplicates: DuplicatePolicy,
    on_duplicates: Callable[[str], None] | None = None,
) -> np.ndarray:
    """Indices of the rows to keep; raises on a decreasing timestamp, and on a repeated one unless told otherwise.
    ``numbers``: the file's line number of each row. ``on_duplicates`` gets one message (file, count, first line)
    when repeated timestamps were dropped."""
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
    return drop_repeated(path, numbers, stamps, steps, duplicates, on_duplicates)


def drop_repeated(
    path: Path,
    numbers: list[int],
    stamps: np.ndarray,
    steps: np.ndarray,
    duplicates: DuplicatePolicy,
    on_duplicates: Callable[[str], None] | None,
) -> np.ndarray:
    """Rows to keep of non-decreasing ``stamps`` (``steps`` = their differences): the first or last row of each
    repeated timestamp (``duplicates``), with one warning through ``on_duplicates`` when any were dropped."""
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

"""ICL-NUIM "TUM-compatible" index files: ``associations.txt`` with lines ``index depth/N.png index rgb/N.png``
(the text rules of :mod:`slamcommon.formats.lines`); its trajectory (``*.gt.freiburg``) is a TUM trajectory whose
timestamps are the same frame indices. ICL-NUIM renders at :data:`ICL_FPS`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from slamcommon.errors import FormatError
from slamcommon.formats.lines import data_lines

ICL_FPS: float = 30.0
ICL_ASSOCIATIONS_LINE = "index depth/N.png index rgb/N.png"


def read_icl_associations(path: str | Path) -> tuple[np.ndarray, list[str], list[str]]:
    """Read an ICL-NUIM ``associations.txt``: the frame indices (N,) float64 in increasing order (of the RGB
    column), and the RGB and depth file names (as written, relative to the folder) in that order.
    :class:`FormatError` (one line naming file and line) on a line without 4 columns, an index that is not a finite
    number, or no entries."""
    path = Path(path)
    rows = []
    layout = ICL_ASSOCIATIONS_LINE
    for number, fields in data_lines(path):
        if len(fields) != 4:
            raise FormatError(
                f"{path}:{number}: expected 4 columns ({layout}), found {len(fields)}: {' '.join(fields)!r}"
            )
        for column in (1, 3):
            try:
                value = float(fields[column - 1])
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise FormatError(f"{path}:{number}: column {column} is {fields[column - 1]!r}, not a frame index "
                                  f"(a finite number); valid lines are '{layout}'")  # fmt: skip
        rows.append((float(fields[2]), fields[3], fields[1]))
    if not rows:
        raise FormatError(f"{path}: no entries; expected lines '{layout}'")
    rows.sort()
    return np.array([r[0] for r in rows]), [r[1] for r in rows], [r[2] for r in rows]

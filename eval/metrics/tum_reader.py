"""The judge's TUM trajectory reader, now :func:`slamcommon.formats.read_tum_trajectory` (the fast path and the
line-by-line reader in one module that imports no Gymnasium and no scipy).

Re-exports, kept for users who import these names from here: ``read_tum_file`` is
:func:`slamcommon.formats.tum.read_tum_trajectory`, and ``TumFileError`` is the error it raises,
:class:`slamcommon.errors.FormatError` (a ``ProjectError``; it was an ``EvalError`` subclass before the move).
"""

from slamcommon.errors import FormatError as TumFileError
from slamcommon.formats.lines import DUPLICATE_POLICIES, DuplicatePolicy, data_line_numbers
from slamcommon.formats.tum import QUATERNION_TOL, parse_plain_tum_text, quaternions_to_matrices
from slamcommon.formats.tum import read_tum_trajectory as read_tum_file

__all__ = [
    "DUPLICATE_POLICIES",
    "QUATERNION_TOL",
    "DuplicatePolicy",
    "TumFileError",
    "data_line_numbers",
    "parse_plain_tum_text",
    "quaternions_to_matrices",
    "read_tum_file",
]

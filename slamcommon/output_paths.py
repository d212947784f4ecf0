"""Output paths checked before any work: a command that will write a file or a folder refuses a path it could not
write (a file where a folder goes, a folder where a file goes, a folder this user may not write) with one line,
before it reads, renders or computes anything, so that no run is lost to a traceback at its end.

Both checks try what the write will do: they create the missing folders and a temporary file in the folder that
will hold the output, then remove what they created (permission bits alone do not say what a user may write: ACLs,
read-only mounts, root). Shared by the agent's and the judge's commands (neither imports the other).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from slamcommon.errors import ProjectError


class OutputPathError(ProjectError):
    """An output file or folder that cannot be written; the message names the option, the path and what is valid."""


def _probe_folder(folder: Path, flag: str, what: str) -> None:
    """Create ``folder`` (and its missing parents) and a temporary file in it, then remove what was created;
    :class:`OutputPathError` naming ``flag`` and ``what`` when that fails."""
    created = []
    probe = folder
    while not probe.exists() and probe.parent != probe:
        created.append(probe)  # deepest first, removed in that order
        probe = probe.parent
    blocking = next((p for p in [probe, *probe.parents] if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise OutputPathError(f"{flag} {what}: {blocking} is a file, not a folder; name a path under a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".cnnslam-write-check-"):
            pass
    except OSError as exc:
        raise OutputPathError(f"{flag} {what}: cannot write in {folder} ({exc.strerror or type(exc).__name__}); "
                              "name a path this user can create and write") from None  # fmt: skip
    finally:
        for path in created:
            try:
                path.rmdir()
            except OSError:
                break


def check_output_folder(folder: str | Path, flag: str) -> Path:
    """``folder`` as a :class:`~pathlib.Path` when a command can create it (with its parents) and write files in it;
    :class:`OutputPathError` naming ``flag`` (the option that gave it) and the folder otherwise (a file where the
    folder or one of its parents goes, no permission). Leaves nothing behind."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputPathError(f"{flag} {folder}: a file, not a folder; name a folder (it is created when missing)")
    _probe_folder(folder, flag, str(folder))
    return folder


def check_output_file(path: str | Path, flag: str) -> Path:
    """``path`` as a :class:`~pathlib.Path` when a command can write a file there (its folder created when
    missing; an existing file is replaced); :class:`OutputPathError` naming ``flag`` and the path otherwise (a
    folder at the path, a file where one of its folders goes, no permission). Leaves nothing behind."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{flag} {path}: a folder, not a file; name a file to write")
    if path.name in ("", ".", ".."):
        raise OutputPathError(f"{flag} {str(path)!r}: not a file name; name a file")
    if path.exists():
        try:
            with open(path, "r+b"):
                pass
        except OSError as exc:
            raise OutputPathError(f"{flag} {path}: cannot replace the file ({exc.strerror or type(exc).__name__}); "
                                  "name a path this user can write") from None  # fmt: skip
    _probe_folder(path.parent, flag, str(path))
    return path

"""Prepared images of a real folder, stored once: later runs read them instead of decoding, undistorting and resizing.

An RGB-D folder's delivered RGB image (PNG or JPEG decoded, undistorted, resized: about 5 ms of CPU a frame at
640x480 -> 320x240) depends only on the image file and the conversion, so the image as delivered can be kept and
read back (about 0.1 ms for 320x240) by any later run that converts the same way. :class:`PreparedImages` keeps them
under a folder whose name is a hash (:func:`prepared_key`) of what decides the bytes: the reader's description of
the conversion (:meth:`sim_envs.folders.datasets.RgbdFolder.describe`: loader version, sizes, camera, undistortion),
the folder's content fingerprint, the reader's code (:func:`reader_code_hash`) and the OpenCV and NumPy versions.
Each image is one file ``NNNNNN.rgb`` (:data:`PREPARED_FORMAT`): a 32-byte header (magic, the source image file's
size and modification time in nanoseconds, height, width) and the uncompressed (H, W, 3) uint8 bytes (compression
would cost the first run more CPU than the disk it saves: a photograph's pixels compress by about 13 % with
Zstandard). An image is used only if its header names the source file's current size and modification time, so
an edited or replaced image is converted again; anything else unreadable (short, other magic) is converted again
and rewritten too. Files are written under a temporary name and renamed, so a reader never sees half a file and
two runs writing the same image leave one whole one.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np

PREPARED_FORMAT = "cnnslam-prepared-rgb/1"  # in the key: another layout of the files is never misread
_MAGIC = b"CNNRGB1\0"
_HEADER = struct.Struct("<8sQqII")  # magic, source size, source mtime_ns, height, width: 32 bytes
SUFFIX = ".rgb"


@lru_cache(maxsize=1)
def reader_code_hash() -> str:
    """SHA-256 (hex, 16 digits) of the code that converts a folder's images: ``sim_envs/folders/*.py`` and
    ``sim_envs/camera.py``, in path order."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in [*sorted((root / "folders").glob("*.py")), root / "camera.py"]:
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def prepared_key(description: dict[str, Any], fingerprint: dict[str, Any]) -> str:
    """The name of the folder of prepared images for a reader described by ``description`` (JSON-ready) over a
    folder of content ``fingerprint``, with this reader code and these OpenCV and NumPy versions."""
    text = json.dumps({"description": description, "content": fingerprint, "code": reader_code_hash(),
                       "opencv": cv2.__version__, "numpy": np.__version__, "format": PREPARED_FORMAT},
                      sort_keys=True, default=str)  # fmt: skip
    return hashlib.sha256(text.encode()).hexdigest()[:20]


class PreparedImages:
    """Delivered RGB images kept in ``folder`` (see the module docstring); ``shape`` (H, W, 3) of every image."""

    def __init__(self, folder: str | Path, shape: tuple[int, int, int]) -> None:
        self.folder = Path(folder)
        self.shape = (int(shape[0]), int(shape[1]), int(shape[2]))
        self._bytes = int(np.prod(self.shape))
        self.reads = 0  # images read back
        self.writes = 0  # images converted and stored

    def path(self, index: int) -> Path:
        """The file of frame ``index``."""
        return self.folder / f"{int(index):06d}{SUFFIX}"

    def load(self, index: int, source: Path) -> np.ndarray | None:
        """The stored image of frame ``index`` when there is one for ``source`` as it is now (its size and
        modification time), else None."""
        try:
            stat = source.stat()
            with open(self.path(index), "rb") as f:
                header = f.read(_HEADER.size)
                data = bytearray(self._bytes)
                got = f.readinto(data)
        except OSError:
            return None
        if len(header) != _HEADER.size or got != self._bytes:
            return None
        magic, size, mtime_ns, height, width = _HEADER.unpack(header)
        if (magic, size, mtime_ns, (height, width)) != (_MAGIC, stat.st_size, stat.st_mtime_ns, self.shape[:2]):
            return None
        self.reads += 1
        return np.frombuffer(data, dtype=np.uint8).reshape(self.shape)

    def store(self, index: int, source: Path, image: np.ndarray) -> None:
        """Keep ``image`` ((H, W, 3) uint8) as frame ``index``'s, converted from ``source`` as it is now. A failure
        to write (disk full, read-only folder) leaves nothing behind and is not an error: the image is converted
        again next time."""
        if image.shape != self.shape or image.dtype != np.uint8:
            return
        try:
            stat = source.stat()
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, prefix=".tmp-", suffix=SUFFIX)
        except OSError:
            return
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(_HEADER.pack(_MAGIC, stat.st_size, stat.st_mtime_ns, self.shape[0], self.shape[1]))
                f.write(np.ascontiguousarray(image).data)
            os.replace(tmp, self.path(index))
            self.writes += 1
        except OSError:
            Path(tmp).unlink(missing_ok=True)

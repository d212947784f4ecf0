"""A frame source whose frames, once rendered, are read back from disk: every run of a suite on a sequence renders
it once instead of once per run.

A simulated source is deterministic (same spec, same bytes: :mod:`sim_envs.source`), so a frame stored after its
first rendering is the frame any later rendering would give, as long as the world's code is the same: the cache
folder's name is a hash of the source's description, the renderer and the source text of ``sim_envs`` itself
(:func:`world_source_hash`), so an edited renderer or camera model never reads an old frame. Frames are stored one
``.npz`` file each (uncompressed, ~1.2 MB at 320x240 with labels, instances and sensor depth), written to a temporary
name and renamed, so two processes rendering the same frame at once leave one whole file.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from sim_envs.errors import SimEnvError
from sim_envs.frames import Frame

_ARRAYS = ("rgb", "depth", "T_world_cam", "labels", "instances", "sensor_depth")


@lru_cache(maxsize=1)
def world_source_hash() -> str:
    """SHA-256 (hex, 16 digits) of every ``.py`` file of the ``sim_envs`` package, in path order."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


# environment variables that select other code paths of the numeric libraries (and so maybe other last bits)
_NUMERIC_ENV_PREFIXES = ("OPENBLAS", "NPY_", "OPENCV", "NUMBA", "ATEN", "ONEDNN", "MKL", "OMP_", "PYOPENGL", "MUJOCO")


def cache_key(description: Any, renderer: str) -> str:
    """The cache folder's name for a source described by ``description`` (JSON-ready) rendered by ``renderer``,
    under this world's code and this process's numeric-library environment."""
    env = {k: v for k, v in sorted(os.environ.items()) if k.startswith(_NUMERIC_ENV_PREFIXES)}
    text = json.dumps({"source": description, "renderer": renderer, "world": world_source_hash(), "env": env},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


class CachedFrames:
    """``source`` (a :class:`sim_envs.source.FrameSource`) with its frames kept in ``folder``: ``frame(i)`` reads
    ``folder/i.npz`` when present, else asks ``source`` and stores the frame. Everything else is the source's."""

    def __init__(self, source: Any, folder: str | Path) -> None:
        self._source = source
        self.folder = Path(folder)

    def __len__(self) -> int:
        return len(self._source)

    def __getattr__(self, name: str) -> Any:  # name, intrinsics, timestamps, poses, describe, ...
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self._source, name)

    def frame(self, index: int) -> Frame:
        path = self.folder / f"{int(index):06d}.npz"
        if path.is_file():
            try:
                with np.load(path, allow_pickle=False) as data:
                    return Frame(int(data["index"]), float(data["timestamp"]),
                                 **{k: (data[k] if k in data.files else None) for k in _ARRAYS})
            except (OSError, ValueError, KeyError):  # a damaged file (an interrupted copy): render it again
                path.unlink(missing_ok=True)
        frame = self._source.frame(index)
        self._store(path, frame)
        return frame

    def _store(self, path: Path, frame: Frame) -> None:
        arrays = {k: getattr(frame, k) for k in _ARRAYS if getattr(frame, k) is not None}
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, suffix=".tmp")
            with os.fdopen(fd, "wb") as out:
                np.savez(out, index=np.int64(frame.index), timestamp=np.float64(frame.timestamp), **arrays)
            os.replace(tmp, path)
        except OSError as exc:
            raise SimEnvError(f"cannot store frame {frame.index} in the frame cache {self.folder}: {exc}") from exc

    def close(self) -> None:
        self._source.close()

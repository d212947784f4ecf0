"""A frame source whose frames, once rendered, are read back from disk: every run of a suite on a sequence renders
it once instead of once per run.

A simulated source is deterministic (same spec, same bytes: :mod:`sim_envs.source`), so a frame stored after its
first rendering is the frame any later rendering would give, as long as the world's code is the same: the cache
folder's name is a hash of the source's description, the renderer and the source text of ``sim_envs`` itself
(:func:`world_source_hash`) and of the stored format (:data:`CACHE_FORMAT`), so an edited renderer or camera model
never reads an old frame and a cache of another format is never misread. Frames are stored one file each
(``NNNNNN.frame``, :mod:`sim_envs.sources.frame_codec`: lossless, about 220 KB at 320x240 with labels, instances and
sensor
depth, against 1.2 MB as uncompressed ``.npz`` before), written to a temporary name and renamed, so two processes
rendering the same frame at once leave one whole file. :meth:`CachedFrames.rgb` decodes the image alone (about 1.4
ms a frame on a 2-core EPYC, against 20 ms to render it through the ``kinect`` camera).

A process that renders a whole sequence into the cache (a suite's rendering job) holds the folder's writer lock
(:meth:`CachedFrames.filling`, an exclusive ``flock`` on ``.writer.lock``); any other :class:`CachedFrames` of the
folder waits for it at its first access instead of rendering the same frames beside it, so that a suite can start
the runs of the sequences already rendered while the last ones render.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # not POSIX: no writer lock; a reader then renders what is missing itself (the same bytes)
    fcntl = None  # type: ignore[assignment]

import numpy as np

from sim_envs.errors import RendererUnavailableError, SimEnvError
from sim_envs.frames import Frame
from sim_envs.render.gl import gl_platform
from sim_envs.sources.frame_codec import FRAME_FORMAT, FrameCodecError, FrameEncoder, decode_frame

_ARRAYS = ("rgb", "depth", "T_world_cam", "labels", "instances", "sensor_depth")
CACHE_FORMAT = f"frames/2+{FRAME_FORMAT}"  # 1: one uncompressed .npz per frame; 2: sim_envs.sources.frame_codec files
FRAME_SUFFIX = ".frame"
TRAJECTORY_FILE = "trajectory.npz"  # the source's timestamps and poses (uncompressed .npz: exact float64)
WRITER_LOCK = ".writer.lock"  # flock'ed by the process filling the folder (CachedFrames.filling)


@lru_cache(maxsize=1)
def world_source_hash() -> str:
    """SHA-256 (hex, 16 digits) of every ``.py`` file of the ``sim_envs`` package, in path order."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


# environment variables that select other code paths of the numeric libraries (and so maybe other last bits)
_NUMERIC_ENV_PREFIXES = ("OPENBLAS", "NPY_", "OPENCV", "NUMBA", "ATEN", "ONEDNN", "MKL", "OMP_", "PYOPENGL", "MUJOCO")


# the GL platform's variables: in the key as the platform rendering uses (sim_envs.render.gl.gl_platform), which
# is the same before and after the renderer exported it (a process that has rendered kept another key before)
_GL_ENV = ("MUJOCO_GL", "PYOPENGL_PLATFORM")


def cache_key(description: Any, renderer: str) -> str:
    """The cache folder's name for a source described by ``description`` (JSON-ready) rendered by ``renderer``,
    under this world's code, this process's numeric-library environment and the offscreen GL platform rendering
    uses (``"none"`` where there is none)."""
    env = {k: v for k, v in sorted(os.environ.items()) if k.startswith(_NUMERIC_ENV_PREFIXES) and k not in _GL_ENV}
    try:
        gl = gl_platform()
    except RendererUnavailableError:
        gl = "none"
    text = json.dumps({"source": description, "renderer": renderer, "world": world_source_hash(), "env": env,
                       "gl": gl, "format": CACHE_FORMAT}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


class CachedFrames:
    """``source`` (a :class:`sim_envs.source.FrameSource`) with its frames kept in ``folder``: ``frame(i)`` reads
    ``folder/NNNNNN.frame`` when present, else asks ``source`` and stores the frame; ``rgb(i)`` reads the image
    alone from the same file (or stores the whole frame first). Everything else is the source's.

    ``reads``, ``read_seconds``, ``renders`` and ``render_seconds`` count the frames read from disk and rendered
    (stored) by this object, and the wall seconds they took (the run's profile, :mod:`eval.bench.run`);
    ``wait_seconds`` how long its first access waited for another process filling the folder (:meth:`filling`)."""

    def __init__(self, source: Any, folder: str | Path) -> None:
        self._source = source
        self.folder = Path(folder)
        self.reads = 0
        self.read_seconds = 0.0
        self.renders = 0
        self.render_seconds = 0.0
        self.wait_seconds = 0.0
        self._waited = False
        self._encoder = FrameEncoder()  # the sequence's frames are stored in order: its choices carry over

    @contextmanager
    def filling(self) -> Iterator[None]:
        """Hold the folder's writer lock while this object fills the folder: every other :class:`CachedFrames` of
        the folder (in any process) waits at its first access until the block ends (where ``fcntl`` is missing,
        nothing is locked and a reader renders what it misses itself: the same bytes)."""
        self._waited = True  # the writer never waits for itself
        if fcntl is None:
            yield
            return
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            lock = open(self.folder / WRITER_LOCK, "ab")  # noqa: SIM115 - held across the yield
        except OSError as exc:
            raise SimEnvError(f"cannot create the writer lock of the frame cache {self.folder}: {exc}") from exc
        with lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def wait_for_writer(self) -> None:
        """Wait while another process fills the folder (:meth:`filling`); done once, at the first access (or
        earlier, by a caller that does not want the wait inside its own timing)."""
        if self._waited:
            return
        self._waited = True
        if fcntl is None:
            return
        try:
            lock = open(self.folder / WRITER_LOCK, "rb")  # noqa: SIM115
        except OSError:  # never filled by a writer (or unreadable): nothing to wait for
            return
        t0 = time.perf_counter()
        with lock:
            fcntl.flock(lock, fcntl.LOCK_SH)
            fcntl.flock(lock, fcntl.LOCK_UN)
        self.wait_seconds += time.perf_counter() - t0

    def __len__(self) -> int:
        return len(self._source)

    def __getattr__(self, name: str) -> Any:  # name, intrinsics, scene, describe, ...
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self._source, name)

    @property
    def timestamps(self) -> np.ndarray:
        """(N,) float64 seconds: the source's, kept in ``folder/trajectory.npz`` with the poses once asked for, so
        that a later reader need not generate the room and the camera path (a second or two)."""
        return self._trajectory()[0]

    @property
    def poses(self) -> np.ndarray:
        """(N, 4, 4) float64 ground-truth camera-to-world poses: the source's, kept like :attr:`timestamps`."""
        return self._trajectory()[1]

    def _trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        cached = self.__dict__.get("_stamps_poses")
        if cached is not None:
            return cached
        self.wait_for_writer()
        path = self.folder / TRAJECTORY_FILE
        try:
            with np.load(path, allow_pickle=False) as data:
                cached = (data["timestamps"], data["poses"])
        except FileNotFoundError:
            cached = None
        except (OSError, ValueError, KeyError):  # a damaged file: made again from the source
            path.unlink(missing_ok=True)
            cached = None
        if cached is None:
            cached = (np.asarray(self._source.timestamps), np.asarray(self._source.poses))
            self._write(path, lambda out: np.savez(out, timestamps=cached[0], poses=cached[1]), "the trajectory")
        for array in cached:
            array.setflags(write=False)
        self.__dict__["_stamps_poses"] = cached
        return cached

    def path(self, index: int) -> Path:
        """The file of frame ``index``."""
        return self.folder / f"{int(index):06d}{FRAME_SUFFIX}"

    def has(self, index: int) -> bool:
        """Whether frame ``index`` is stored."""
        self.wait_for_writer()
        return self.path(index).is_file()

    def frame(self, index: int) -> Frame:
        """Frame ``index``, read back or rendered (and stored)."""
        stored = self._read(index, None)
        if stored is not None:
            return Frame(stored.index, stored.timestamp,
                         **{k: stored.arrays.get(k) for k in _ARRAYS})  # type: ignore[arg-type]
        return self._render(index)

    def rgb(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8 image of frame ``index`` (the bytes of ``frame(index).rgb``), decoded alone."""
        stored = self._read(index, ("rgb",))
        if stored is not None:
            return stored.arrays["rgb"]
        return self._render(index).rgb

    def _read(self, index: int, names: tuple[str, ...] | None) -> Any:
        self.wait_for_writer()
        path = self.path(index)
        t0 = time.perf_counter()
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise SimEnvError(f"cannot read frame {index} of the frame cache {self.folder}: {exc}") from exc
        try:
            stored = decode_frame(data, names)
        except FrameCodecError:  # a damaged file (an interrupted copy): render it again
            path.unlink(missing_ok=True)
            return None
        self.reads += 1
        self.read_seconds += time.perf_counter() - t0
        return stored

    def _render(self, index: int) -> Frame:
        t0 = time.perf_counter()
        frame = self._source.frame(index)
        self._store(self.path(index), frame)
        self.renders += 1
        self.render_seconds += time.perf_counter() - t0
        return frame

    def _store(self, path: Path, frame: Frame) -> None:
        arrays = {k: getattr(frame, k) for k in _ARRAYS if getattr(frame, k) is not None}
        data = self._encoder.encode(frame.index, frame.timestamp, arrays)
        self._write(path, lambda out: out.write(data), f"frame {frame.index}")

    def _write(self, path: Path, write: Any, what: str) -> None:
        """``write(file)`` into a temporary file of the folder, renamed to ``path`` (two writers leave one file)."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, suffix=".tmp")
            with os.fdopen(fd, "wb") as out:
                write(out)
            os.replace(tmp, path)
        except OSError as exc:
            raise SimEnvError(f"cannot store {what} in the frame cache {self.folder}: {exc}") from exc

    def close(self) -> None:
        self._source.close()

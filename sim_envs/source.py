"""The frame-source contract: anything the environment can replay (a simulated sequence, a TUM/ICL folder), and a
window of one (:class:`FrameWindow`)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Protocol, runtime_checkable

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError
from sim_envs.frames import Frame


@runtime_checkable
class FrameSource(Protocol):
    """A finite, indexable sequence of frames with ground truth.

    ``timestamps``: (N,) float64 seconds, increasing. ``poses``: (N, 4, 4) float64 ground-truth ``T_world_cam``.
    ``frame(i)`` renders or loads frame i (0 <= i < N) deterministically: the same i gives the same bytes.
    Sources create expensive resources (OpenGL contexts) lazily on first ``frame`` call, so they can be pickled to
    worker processes before use.
    """

    name: str
    intrinsics: Intrinsics
    timestamps: np.ndarray
    poses: np.ndarray

    def __len__(self) -> int: ...

    def frame(self, index: int) -> Frame: ...

    def close(self) -> None: ...


WINDOW_VERSION = "cnnslam-window/2"  # in a window's description; 2: every per-frame reader offset by start


class FrameWindow:
    """Frames ``start .. start + length - 1`` of ``source`` as a source of their own (a window of a sequence: a
    real sequence cut into samples of a simulated sequence's length).

    Window frame i is source frame ``start + i``, with its own index set to i; timestamps and poses are the source's,
    sliced (times and world frame unchanged, so a window's trajectory is scored in the source's world frame). The
    per-frame readers a source may have besides ``frame`` (``rgb``, ``raw_rgb``, ``depth``: the env reads ``rgb``
    alone when it hands out no ground truth) are offset the same way, and only those the source has exist.
    ``length`` None: to the end; ``name``: the window's (default the source's). Anything else (``intrinsics``,
    ``describe``, ...) is the source's.
    """

    PER_FRAME_READERS = ("rgb", "raw_rgb", "depth")  # a source's methods (index) -> array besides frame()

    def __init__(self, source: FrameSource, start: int, length: int | None = None, name: str | None = None) -> None:
        total = len(source)
        start = int(start)
        stop = total if length is None else start + int(length)
        if not (0 <= start < total) or not (start < stop <= total):
            raise SimEnvError(f"a window of {getattr(source, 'name', 'a source')} must lie within its {total} frames; "
                              f"got start {start}, length {length}")  # fmt: skip
        self._source = source
        self.name = name if name is not None else source.name
        self.start, self.stop = start, stop
        self.timestamps = np.asarray(source.timestamps)[start:stop]
        self.poses = np.asarray(source.poses)[start:stop]

    def __len__(self) -> int:
        return self.stop - self.start

    def __getattr__(self, name: str) -> Any:  # name, intrinsics, describe, ...
        if name.startswith("__") or name == "_source":
            raise AttributeError(name)
        value = getattr(self._source, name)
        if name in self.PER_FRAME_READERS and callable(value):  # window index -> the source's frame start + i
            return lambda index, _read=value: _read(self.start + self._check(index))
        return value

    def _check(self, index: int) -> int:
        if not 0 <= int(index) < len(self):
            raise IndexError(f"frame {index} of a {len(self)}-frame window")
        return int(index)

    def frame(self, index: int) -> Frame:
        return replace(self._source.frame(self.start + self._check(index)), index=int(index))

    def close(self) -> None:
        self._source.close()

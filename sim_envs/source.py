"""The frame-source contract: anything the environment can replay (a simulated sequence, a TUM/ICL folder)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from sim_envs.camera import Intrinsics
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

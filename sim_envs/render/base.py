"""What every renderer returns and offers: :class:`RenderOutput` and the :class:`Renderer` base class."""

from __future__ import annotations

import atexit
import sys
import weakref
from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError
from sim_envs.frames import NO_LABEL
from sim_envs.scenes.scene import Scene

OUTPUTS: tuple[str, ...] = ("rgb", "depth", "labels", "instances")
DEFAULT_ZNEAR = 0.02  # metres; nearest renderable surface (ours: a hand-held camera never gets closer)
# OpenCV camera axes (x right, y down, z forward) -> OpenGL/MuJoCo camera axes (x right, y up, looking down -z)
CV_TO_GL = np.diag([1.0, -1.0, -1.0])


# Renderers holding an OpenGL context: closed at exit, before the interpreter tears down the modules OpenGL needs.
_LIVE: weakref.WeakSet[Renderer] = weakref.WeakSet()


@atexit.register
def _close_live_renderers() -> None:
    """Close every renderer still holding an OpenGL context (at interpreter exit)."""
    for renderer in list(_LIVE):
        try:
            renderer.close()
        except Exception:  # noqa: BLE001 - at exit another library may have torn OpenGL down first
            pass


@dataclass(frozen=True)
class RenderOutput:
    """One rendered view; a field is None when it was not asked for.

    rgb: (H, W, 3) uint8; depth: (H, W) float32 planar z in metres, 0 where no surface; labels: (H, W) uint8
    :class:`~sim_envs.frames.SemanticClass` values, 255 where no surface; instances: (H, W) int32 instance ids of the
    scene, -1 where no surface.
    """

    rgb: np.ndarray | None = None
    depth: np.ndarray | None = None
    labels: np.ndarray | None = None
    instances: np.ndarray | None = None


def validate_outputs(outputs: Iterable[str]) -> frozenset[str]:
    """The requested outputs as a set; raises :class:`SimEnvError` naming the valid ones for an unknown name."""
    wanted = frozenset(outputs)
    unknown = sorted(wanted - set(OUTPUTS))
    if unknown:
        raise SimEnvError(f"unknown render output(s) {unknown}; valid outputs: {', '.join(OUTPUTS)}")
    if not wanted:
        raise SimEnvError(f"no render output asked for; valid outputs: {', '.join(OUTPUTS)}")
    return wanted


def validate_pose(T_world_cam: np.ndarray) -> np.ndarray:
    """``T_world_cam`` as a (4, 4) float64 rigid transform; raises :class:`SimEnvError` if it is not one."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise SimEnvError(f"T_world_cam must be a finite (4, 4) matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise SimEnvError("T_world_cam's rotation block is not a rotation matrix")
    return T


def far_plane(scene: Scene) -> float:
    """A far clipping distance (metres) beyond every point of ``scene`` from anywhere inside it."""
    lo, hi = scene.bounds()
    return float(np.linalg.norm(hi - lo)) * 1.5 + 1.0


class Renderer(ABC):
    """An offscreen renderer of one :class:`Scene` through one pinhole camera (abstract base).

    Use as a context manager or call :meth:`close`. The OpenGL context is created lazily on the first
    :meth:`render`, so a renderer (and a frame source holding one) can be pickled to a spawned worker before use.
    """

    backend: str = ""

    def __init__(self, scene: Scene, intrinsics: Intrinsics, znear: float = DEFAULT_ZNEAR) -> None:
        self.scene = scene
        self.intrinsics = intrinsics
        self.znear = float(znear)
        self.zfar = far_plane(scene)
        classes = scene.instance_classes()
        # instance id + 1 -> semantic class (index 0: no surface)
        self._class_of_instance = np.concatenate([[NO_LABEL], classes]).astype(np.uint8)
        self._gl: dict[str, Any] | None = None  # the backend's OpenGL objects, made on first render

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_gl"] = None  # OpenGL objects stay in the process that made them
        return state

    @abstractmethod
    def render(self, T_world_cam: np.ndarray, outputs: Iterable[str] = OUTPUTS) -> RenderOutput:
        """Render the view from ``T_world_cam`` ((4, 4) camera-to-world, OpenCV axes); only ``outputs`` are computed."""

    @abstractmethod
    def close(self) -> None:
        """Release the OpenGL context and GPU buffers (the renderer can render again afterwards, lazily)."""

    def _track(self) -> None:
        """Backends call this once they hold an OpenGL context, so that it is freed at interpreter exit."""
        _LIVE.add(self)

    def labels_of(self, instances: np.ndarray) -> np.ndarray:
        """(H, W) int32 instance ids (-1 none) -> (H, W) uint8 semantic labels (255 none)."""
        return self._class_of_instance[instances + 1]

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if sys.is_finalizing():  # too late to call into OpenGL; the atexit hook closed tracked renderers
            return
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown: nothing useful to report
            pass

"""Offscreen renderers of a :class:`~sim_envs.scenes.scene.Scene`: MuJoCo and pyrender, chosen by name.

>>> from sim_envs.camera import preset
>>> from sim_envs.scenes.scenegen import generate_scene
>>> with make_renderer(generate_scene("office", 0), preset("icl"), backend="mujoco") as r:  # doctest: +SKIP
...     out = r.render(T_world_cam, outputs=("rgb", "depth"))

Both backends return the same :class:`RenderOutput` (RGB uint8, planar z-depth float32 metres with 0 = no surface,
labels uint8 with 255 = none, instances int32 with -1 = none) for a ``T_world_cam`` in OpenCV camera axes. OpenGL is
EGL by default, OSMesa as fallback (:mod:`sim_envs.render.gl`); backends are imported only when used.
"""

from __future__ import annotations

from sim_envs.camera import Intrinsics
from sim_envs.errors import UnknownNameError
from sim_envs.render.base import DEFAULT_ZNEAR, OUTPUTS, Renderer, RenderOutput
from sim_envs.scenes.scene import Scene

BACKENDS: tuple[str, ...] = ("mujoco", "pyrender")

__all__ = ["BACKENDS", "OUTPUTS", "Renderer", "RenderOutput", "make_renderer"]


def make_renderer(
    scene: Scene, intrinsics: Intrinsics, backend: str = "mujoco", znear: float = DEFAULT_ZNEAR
) -> Renderer:
    """A renderer of ``scene`` through a camera with ``intrinsics``; ``backend`` is "mujoco" or "pyrender".

    Nothing touches OpenGL until the first ``render`` call. ``znear``: nearest visible distance in metres.
    """
    if backend == "mujoco":
        from sim_envs.render.mujoco_backend import MujocoRenderer

        return MujocoRenderer(scene, intrinsics, znear)
    if backend == "pyrender":
        from sim_envs.render.pyrender_backend import PyrenderRenderer

        return PyrenderRenderer(scene, intrinsics, znear)
    raise UnknownNameError(f"unknown renderer backend {backend!r}; valid backends: {', '.join(BACKENDS)}")

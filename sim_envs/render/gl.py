"""Choice of the offscreen OpenGL platform: EGL by default, OSMesa as fallback, one clear error when neither exists.

MuJoCo reads ``MUJOCO_GL`` and PyOpenGL reads ``PYOPENGL_PLATFORM`` when they are first imported, so
:func:`configure_gl` must run before either is imported for rendering; the backends of :mod:`sim_envs.render` call
it first and import ``mujoco`` / ``pyrender`` only inside functions. Values a user already set are respected.

Libraries (Debian package names): EGL is ``libEGL.so.1`` from ``libegl1`` plus Mesa's drivers ``libgl1-mesa-dri``
(software rendering through llvmpipe needs no GPU); OSMesa is ``libOSMesa.so`` from ``libosmesa6``.
"""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Callable

from sim_envs.errors import RendererUnavailableError

GL_PLATFORMS: tuple[str, ...] = ("egl", "osmesa")
# platform -> (shared libraries tried in order, what provides them on Debian/Ubuntu)
_LIBRARIES: dict[str, tuple[tuple[str, ...], str]] = {
    "egl": (("libEGL.so.1", "libEGL.so"), "libegl1 and Mesa's libgl1-mesa-dri"),
    "osmesa": (("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"), "libosmesa6"),
}


def library_loadable(name: str) -> bool:
    """Whether the shared library ``name`` (e.g. ``"libEGL.so.1"``) can be loaded by the dynamic linker."""
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def missing_library_message(platforms: tuple[str, ...] = GL_PLATFORMS) -> str:
    """The text of the error raised when none of ``platforms`` can be used: what to install."""
    parts = [f"{_LIBRARIES[p][0][0]} (Debian/Ubuntu package: {_LIBRARIES[p][1]})" for p in platforms]
    return (
        "no offscreen OpenGL platform is available: could not load " + " nor ".join(parts) + ". Install one, e.g. "
        "'apt-get install libegl1 libgl1-mesa-dri' (EGL, preferred) or 'apt-get install libosmesa6' (OSMesa), or set "
        "MUJOCO_GL and PYOPENGL_PLATFORM to a platform that works on this machine."
    )


def gl_platform(probe: Callable[[str], bool] = library_loadable) -> str:
    """The offscreen platform :func:`configure_gl` chooses (``"egl"`` or ``"osmesa"``), without exporting it.

    A platform already named by ``MUJOCO_GL`` or ``PYOPENGL_PLATFORM`` wins. Otherwise EGL is used when
    ``libEGL.so.1`` loads, else OSMesa when ``libOSMesa.so`` loads, else :class:`RendererUnavailableError` names
    both libraries. ``probe(library_name) -> bool`` tells whether a library loads (injected by tests).
    """
    mujoco_gl = os.environ.get("MUJOCO_GL", "").strip().lower()
    pyopengl = os.environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    chosen = mujoco_gl or pyopengl
    if chosen:
        if chosen not in GL_PLATFORMS:
            raise RendererUnavailableError(
                f"MUJOCO_GL / PYOPENGL_PLATFORM is {chosen!r}; offscreen rendering needs one of {GL_PLATFORMS}"
            )
        if mujoco_gl and pyopengl and mujoco_gl != pyopengl:
            raise RendererUnavailableError(
                f"MUJOCO_GL={mujoco_gl!r} and PYOPENGL_PLATFORM={pyopengl!r} disagree; set both to 'egl' or 'osmesa'"
            )
        return chosen
    for platform in GL_PLATFORMS:
        if any(probe(lib) for lib in _LIBRARIES[platform][0]):
            return platform
    raise RendererUnavailableError(missing_library_message())


def configure_gl(probe: Callable[[str], bool] = library_loadable) -> str:
    """Choose the offscreen platform (:func:`gl_platform`), export it to MuJoCo and PyOpenGL (``MUJOCO_GL`` and
    ``PYOPENGL_PLATFORM``, each where unset), and return it (``"egl"`` or ``"osmesa"``)."""
    chosen = gl_platform(probe)
    os.environ.setdefault("MUJOCO_GL", chosen)
    os.environ.setdefault("PYOPENGL_PLATFORM", chosen)
    _check_pyopengl_platform(chosen)
    return chosen


def _check_pyopengl_platform(chosen: str) -> None:
    """Raise if PyOpenGL was imported earlier with another platform (it cannot be switched afterwards)."""
    platform_module = sys.modules.get("OpenGL.platform")
    current = getattr(platform_module, "PLATFORM", None)
    if current is None:
        return
    name = type(current).__module__.lower()
    if chosen not in name:
        raise RendererUnavailableError(
            f"PyOpenGL was imported with the platform {type(current).__name__} before sim_envs.render chose "
            f"{chosen!r}; set PYOPENGL_PLATFORM={chosen} (and MUJOCO_GL={chosen}) before importing OpenGL or pyrender"
        )


def context_error(backend: str, platform: str, exc: BaseException) -> RendererUnavailableError:
    """The error to raise when creating an OpenGL context failed although the library loaded."""
    libs, package = _LIBRARIES.get(platform, ((platform,), platform))
    return RendererUnavailableError(
        f"{backend}: could not create an offscreen OpenGL context with {platform} ({type(exc).__name__}: {exc}). "
        f"{libs[0]} loaded but did not work: install {package}"
        + (" (Mesa's drivers; llvmpipe needs no GPU)" if platform == "egl" else "")
        + ", or try MUJOCO_GL=osmesa PYOPENGL_PLATFORM=osmesa with libosmesa6."
    )

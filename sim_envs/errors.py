"""Exceptions of the simulated world. One base class; subclasses where callers need to tell cases apart."""

from slamcommon.errors import FormatError as SharedFormatError
from slamcommon.errors import ProjectError


class SimEnvError(ProjectError):
    """Base class for every error raised by ``sim_envs`` (bad arguments, bad files, missing libraries)."""


class UnknownNameError(SimEnvError, KeyError):
    """A name (sequence, room style, camera preset, renderer) that is not registered; the message lists valid ones."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


class RendererUnavailableError(SimEnvError, RuntimeError):
    """No offscreen OpenGL backend could be created; the message names the missing system library."""


class FormatError(SimEnvError, SharedFormatError):
    """A file that does not follow its format; the message names the file and the line. Also the shared
    :class:`slamcommon.errors.FormatError`, which the readers of :mod:`slamcommon.formats` raise (the world's
    re-exports in :mod:`sim_envs.folders.formats` raise this one)."""

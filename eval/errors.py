"""Exceptions of the judge. One base class below the project's (:class:`slamcommon.errors.ProjectError`);
subclasses where callers need to tell cases apart."""

from slamcommon.errors import ProjectError


class EvalError(ProjectError):
    """Base class for every error raised by ``eval`` (bad trajectories, no associations, bad baselines)."""


class InputError(EvalError):
    """An argument or input file the judge was given that cannot be used (an unknown name, a value of the wrong type
    or range, an unreadable file), found before any run starts: a command exits 2 with this one line."""


class SuiteError(InputError):
    """An unknown suite, sequence or method selection."""


class RunnerError(EvalError):
    """A run that cannot be planned or stored (a bad output folder, an unreadable result)."""


class BrokenRunError(EvalError):
    """An output that is no result (no poses, a single pose: nothing to align or compare): a failed run, never a
    figure in a table."""

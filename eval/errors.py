"""Exceptions of the judge. One base class; subclasses where callers need to tell cases apart."""


class EvalError(ValueError):
    """Base class for every error raised by ``eval`` (bad trajectories, no associations, bad baselines)."""


class SuiteError(EvalError):
    """An unknown suite, sequence or method selection."""


class RunnerError(EvalError):
    """A run that cannot be planned or stored (a bad output folder, an unreadable result)."""

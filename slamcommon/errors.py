"""The project's exceptions, rooted once: every error the world, the agent, the judge and the shared concepts raise
on purpose derives from :class:`ProjectError`, so that a caller (a command line, a benchmark) tells the project's own
errors (a bad value, file or choice, the message naming it and what is valid) from bugs with one ``except``.

Each package has its own base below it (``sim_envs.errors.SimEnvError``, ``cnnslam.errors.CnnSlamError``,
``eval.errors.EvalError``, and :class:`MetricError` here), with subclasses where callers tell cases apart.
"""


class ProjectError(ValueError):
    """Base class of every error the project raises on purpose; the message names the bad value and what is valid.
    A ``ValueError``, as the package bases were before they shared it."""


class MetricError(ProjectError):
    """Inputs a shared metric or transform cannot use (shapes, unknown options); the message says what is valid."""


class ConfigError(ProjectError):
    """A configuration key or value that a configuration dataclass does not take (:mod:`slamcommon.config`): an
    unknown key, or a value of the wrong type; the message names the key, the value and what is valid."""


class FormatError(ProjectError):
    """A data file (a trajectory, an image list, a pose file) that does not follow its format
    (:mod:`slamcommon.formats`); the message names the file, the line, what was found and what is valid. The world
    raises it as ``sim_envs.errors.FormatError``, a subclass that is also a ``SimEnvError``."""

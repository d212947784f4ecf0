"""The one exception of the shared concepts."""


class MetricError(ValueError):
    """Inputs a shared metric or transform cannot use (shapes, unknown options); the message says what is valid."""

"""Error and warning hierarchy of sensorplan.

Every error raised on user input derives from :class:`SensorplanError` and
also from the matching built-in (``ValueError`` for bad input,
``RuntimeError`` for numerical failures), as scikit-learn's
``NotFittedError`` does.  The command line turns these into one-line messages.
"""

__all__ = [
    "SensorplanError",
    "ConfigError",
    "DataError",
    "SolverError",
    "ExecutorError",
    "SensorplanWarning",
]


class SensorplanError(Exception):
    """Base class of every error sensorplan raises on purpose."""


class ConfigError(SensorplanError, ValueError):
    """A parameter, a value object or a configuration file is invalid."""


class DataError(SensorplanError, ValueError):
    """A measurement file (CSV) is malformed or inconsistent with the case."""


class SolverError(SensorplanError, RuntimeError):
    """A numerical solver failed or returned an inaccurate solution."""


class ExecutorError(SensorplanError, RuntimeError):
    """The machinery running the work failed: an unreachable scheduler, a worker that died."""


class SensorplanWarning(UserWarning):
    """Base class of the warnings sensorplan emits."""

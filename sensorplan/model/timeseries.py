"""A logger's continuous record: time, one channel per sensor, optional temperatures."""

import math
from dataclasses import dataclass, field

import numpy as np

from .._errors import ConfigError, DataError

__all__ = ["TimeSeries", "LoggerFormat"]

# sample intervals [s] a logger record may have: 1 MHz to one sample a minute (a crossing lasts seconds)
MIN_SAMPLE_INTERVAL = 1e-6
MAX_SAMPLE_INTERVAL = 60.0

# Units a logger may write, as factors to SI (rad or m).
TILT_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "mdeg": math.pi / 180.0e3, "mm/m": 1e-3, "urad": 1e-6}
DEFLECTION_UNITS = {"m": 1.0, "mm": 1e-3}
# Time bases of a numeric time column, as factors to s.
TIME_UNITS = {"s": 1.0, "ms": 1e-3}


@dataclass(frozen=True)
class LoggerFormat:
    """How a logger export is laid out (the optional ``[logger]`` section of a case).

    Parameters
    ----------
    temperature_columns : tuple of str
        Columns holding temperatures [deg C]; read and averaged per crossing.
    tilt_unit : {"rad", "deg", "mdeg", "mm/m", "urad"}
        Unit of the tiltmeter columns.
    deflection_unit : {"m", "mm"}
        Unit of the deflection columns.
    time_unit : {"s", "ms"} or None
        Unit of a numeric time column; None: from the column's name
        (``time_s`` in s, ``time_ms`` in ms).  ISO 8601 timestamps need none.
    """

    temperature_columns: tuple = ()
    tilt_unit: str = "rad"
    deflection_unit: str = "m"
    time_unit: str | None = None

    def __post_init__(self):
        cols = self.temperature_columns
        if not isinstance(cols, (list, tuple)) or not all(isinstance(c, str) and c.strip() for c in cols):
            raise ConfigError("The 'temperature_columns' parameter of [logger] must be a list of column names, "
                              f"e.g. [\"T_deck\"]. Got {cols!r} instead.")
        object.__setattr__(self, "temperature_columns", tuple(c.strip() for c in cols))
        for key, units in (("tilt_unit", TILT_UNITS), ("deflection_unit", DEFLECTION_UNITS)):
            if getattr(self, key) not in units:
                raise ConfigError(f"The '{key}' parameter of [logger] must be one of "
                                  f"{', '.join(repr(u) for u in units)}. Got {getattr(self, key)!r} instead.")
        if self.time_unit is not None and self.time_unit not in TIME_UNITS:
            raise ConfigError("The 'time_unit' parameter of [logger] must be one of "
                              f"{', '.join(repr(u) for u in TIME_UNITS)}. Got {self.time_unit!r} instead.")

    def factor(self, kind):
        """Factor from the logger's unit of a ``kind`` sensor to SI."""
        return TILT_UNITS[self.tilt_unit] if kind == "rotation" else DEFLECTION_UNITS[self.deflection_unit]

    def unit(self, kind):
        """The logger's unit of a ``kind`` sensor and the [logger] key that states it."""
        return (self.tilt_unit, "tilt_unit") if kind == "rotation" else (self.deflection_unit, "deflection_unit")


@dataclass(frozen=True, eq=False)
class TimeSeries:
    """Continuous readings of the sensors.

    Attributes
    ----------
    time : ndarray (n_samples,)
        Time [s], strictly increasing.
    names : tuple of str
        Sensor names, one per row of ``values``.
    values : ndarray (n_channels, n_samples)
        Readings [rad or m].
    temperatures : dict of str -> ndarray (n_samples,)
        Temperature channels [deg C].
    start : str
        ISO 8601 timestamp of time 0 when the record had timestamps ('' otherwise).
    """

    time: np.ndarray
    names: tuple
    values: np.ndarray
    temperatures: dict = field(default_factory=dict)
    start: str = ""

    def __post_init__(self):
        time = np.asarray(self.time, dtype=float)
        values = np.atleast_2d(np.asarray(self.values, dtype=float))
        if time.ndim != 1 or time.size < 10:
            raise DataError(f"The logger record needs at least 10 samples. Got {time.size} instead.")
        if values.shape != (len(self.names), time.size):
            raise DataError(f"The logger values have shape {values.shape}, expected "
                            f"({len(self.names)}, {time.size}).")
        step = np.diff(time)
        if np.any(step <= 0.0):
            k = int(np.argmax(step <= 0.0))
            raise DataError(f"time_s must be strictly increasing; sample {k + 2} ({time[k + 1]:g} s) does not "
                            "follow the one before. Sort the logger export by time.")
        if not (np.all(np.isfinite(time)) and np.all(np.isfinite(values))):
            raise DataError("The logger record contains NaN or inf; remove or fill those samples.")
        interval = float(np.median(step))
        if not MIN_SAMPLE_INTERVAL <= interval <= MAX_SAMPLE_INTERVAL:
            raise DataError(f"time_s has a median sample interval of {interval:g} s, outside {MIN_SAMPLE_INTERVAL:g} "
                            f"to {MAX_SAMPLE_INTERVAL:g} s (1 MHz to one sample a minute); give time_s in seconds.")
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "names", tuple(self.names))

    @property
    def n_samples(self):
        return self.time.size

    @property
    def sample_interval(self):
        """Median time between samples [s]."""
        return float(np.median(np.diff(self.time)))

    @property
    def duration(self):
        """Time from the first to the last sample [s]."""
        return float(self.time[-1] - self.time[0])

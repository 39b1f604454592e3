"""Sensors: tiltmeters (rotation [rad]) and deflection sensors [m]."""

from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .._validation import as_float_array, as_float_tuple

__all__ = ["SensorLayout", "SENSOR_KINDS", "RESERVED_NAMES"]

SENSOR_KINDS = ("rotation", "deflection")
_UNITS = {"rotation": "rad", "deflection": "m"}


# Columns of the crossings CSV (and of the time series) that a sensor may not be named after.
RESERVED_NAMES = ("crossing", "position_m", "load_factor", "time_s")
_MAX_NAME = 64


def _check_name(name):
    """A sensor name is a CSV column and part of figure names (the CLI replaces unsafe characters there)."""
    problem = None
    if name.lower() in RESERVED_NAMES:
        problem = "is a reserved column of the crossings CSV"
    elif name in {".", ".."}:
        problem = "is '.' or '..'"
    elif any(not ch.isprintable() for ch in name):
        problem = "contains a control character (newline, tab, ...)"
    elif len(name) > _MAX_NAME:
        problem = f"is longer than {_MAX_NAME} characters"
    if problem:
        raise ConfigError(f"The sensor name {name!r} {problem}; rename the sensor in the 'names' of [sensors].")


def check_file_name(name):
    """Refuse a name that would be unsafe as part of a file name (case files: names become figure names)."""
    if any(ch in name for ch in '/\\'):
        problem = "contains a path separator"
    elif any(ch in name for ch in '"\'<>|:*?'):
        problem = "contains a quote or one of < > | : * ?"
    else:
        return
    raise ConfigError(f"The sensor name {name!r} {problem} (names become parts of file names); rename the sensor "
                      "in the 'names' of [sensors].")


def _as_tuple(values):
    try:
        return tuple(values)
    except TypeError:
        return None


@dataclass(frozen=True, eq=False)
class SensorLayout:
    """A set of sensors on the bridge.

    Parameters
    ----------
    positions : array_like
        Sensor positions [m] from the left end.
    kinds : sequence of str, optional
        ``"rotation"`` (default, reads rad, positive when the deck dips to the
        right) or ``"deflection"`` (reads m, positive downwards).
    names : sequence of str, optional
        Defaults to ``S1, S2, ...``.
    noise_std : float or sequence of float, optional
        Noise standard deviation of each sensor in its unit (rad or m).
    """

    positions: np.ndarray
    kinds: tuple = None  # type: ignore[assignment]  # None: all rotation (filled in by __post_init__)
    names: tuple = None  # type: ignore[assignment]  # None: S1, S2, ... (filled in by __post_init__)
    noise_std: tuple | None = None

    def __post_init__(self):
        pos = as_float_array(self.positions, "positions", "SensorLayout")
        n = pos.size
        if self.kinds is None:
            kinds = ("rotation",) * n
        elif isinstance(self.kinds, str):
            kinds = (self.kinds,) * n
        else:
            kinds = _as_tuple(self.kinds)
        if kinds is None or len(kinds) != n or any(k not in SENSOR_KINDS for k in kinds):
            raise ConfigError(
                f"The 'kinds' parameter of SensorLayout must list {n} entries, each 'rotation' "
                f"or 'deflection'. Got {self.kinds!r} instead.")
        if self.names is None:
            names = tuple(f"S{i + 1}" for i in range(n))
        elif isinstance(self.names, str):
            names = (self.names,)
        else:
            names = _as_tuple(self.names)
            if names is not None and not all(isinstance(x, (str, np.str_)) for x in names):
                names = None
        if names is not None:
            names = tuple(str(x) for x in names)
        if (names is None or len(names) != n or len(set(names)) != n
                or any(not name.strip() or name != name.strip() or "," in name for name in names)):
            raise ConfigError(
                f"The 'names' parameter of SensorLayout must list {n} distinct, non-empty names "
                f"without commas or surrounding spaces. Got {self.names!r} instead.")
        for name in names:
            _check_name(name)
        noise = None
        if self.noise_std is not None:
            noise = as_float_tuple(self.noise_std, "noise_std", "SensorLayout", length=n,
                                   low=0.0, low_open=True)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "kinds", kinds)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "noise_std", noise)

    @property
    def n_sensors(self):
        return self.positions.size

    @property
    def units(self):
        """Unit of each sensor's reading."""
        return tuple(_UNITS[k] for k in self.kinds)

    def subset(self, index):
        """The sensors at ``index`` (sequence of int) as a new layout."""
        index = [int(i) for i in np.atleast_1d(index)]
        return SensorLayout(
            self.positions[index],
            tuple(self.kinds[i] for i in index),
            tuple(self.names[i] for i in index),
            None if self.noise_std is None else tuple(self.noise_std[i] for i in index),
        )

    @classmethod
    def candidates(cls, positions, kind="rotation", noise_std=None):
        """Candidate sensors of one kind, named by position in m (e.g. ``"12.5"``)."""
        positions = np.atleast_1d(np.asarray(positions, dtype=float))
        names = tuple(f"{x:g}" for x in positions)
        if len(set(names)) != len(names):
            names = tuple(f"{x:.6g}" for x in positions)
        return cls(positions, (kind,) * positions.size, names, noise_std)

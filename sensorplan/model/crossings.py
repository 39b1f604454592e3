"""Measured or simulated crossings: readings per sensor and load position."""

from dataclasses import dataclass, field

import numpy as np

from .._errors import DataError

__all__ = ["Crossings", "Crossing"]


@dataclass(frozen=True, eq=False)
class Crossing:
    """One crossing of the vehicle.

    Attributes
    ----------
    label : str
    positions : ndarray (n_loads,)
        Reference-axle positions [m], strictly increasing.
    values : ndarray (n_sensors, n_loads)
        Readings [rad or m] in the order of ``Crossings.sensor_names``.
    load_factor : ndarray (n_loads,)
        Multiplier of the configured axle loads at each row (1 if absent).
    times : ndarray (n_loads,) or None
        Time of each row [s] when known (a logger's crossing); the noise
        model in time then uses them instead of positions / speed.
    """

    label: str
    positions: np.ndarray
    values: np.ndarray
    load_factor: np.ndarray
    times: np.ndarray | None = field(default=None, kw_only=True)

    @property
    def n_loads(self):
        return self.positions.size


@dataclass(frozen=True, eq=False)
class Crossings:
    """Any number of crossings with the same sensors."""

    sensor_names: tuple
    crossings: tuple

    def __post_init__(self):
        if not self.crossings:
            raise DataError("The data contain no crossing.")
        n = len(self.sensor_names)
        for c in self.crossings:
            if c.values.shape != (n, c.positions.size):
                raise DataError(f"Crossing {c.label!r} has values of shape {c.values.shape}, "
                                f"expected ({n}, {c.positions.size}).")

    def __len__(self):
        return len(self.crossings)

    def __iter__(self):
        return iter(self.crossings)

    def __getitem__(self, index):
        return self.crossings[index]

    @property
    def labels(self):
        return tuple(c.label for c in self.crossings)

    @property
    def n_sensors(self):
        return len(self.sensor_names)

    def select(self, labels):
        """Only the crossings with the given labels (in their original order)."""
        keep = set(labels)
        return Crossings(self.sensor_names, tuple(c for c in self.crossings if c.label in keep))

    def sensor_subset(self, names):
        """Only the sensors ``names`` (in that order)."""
        index = [self.sensor_names.index(n) for n in names]
        return Crossings(tuple(names), tuple(
            Crossing(c.label, c.positions, c.values[index], c.load_factor, times=c.times) for c in self.crossings))

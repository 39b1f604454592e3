"""Loads: multi-axle vehicles and load sweeps.

A vehicle travels in +x.  Its reference (front) axle sits at the sweep
position ``z``; axle ``a`` sits at ``z - axle_offsets[a]``.  Axles off the
bridge contribute nothing.  Loads [N] act downwards.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .._validation import as_float, as_float_array, as_float_tuple

__all__ = ["Vehicle", "LoadSweep"]

MAX_AXLES = 1000  # the work of every influence line grows with the axle count


@dataclass(frozen=True)
class Vehicle:
    """A vehicle as a set of axles.

    Parameters
    ----------
    axle_offsets : sequence of float
        Distance of each axle behind the reference (front) axle [m], >= 0.
    axle_loads : sequence of float
        Axle loads [N], > 0.

    Examples
    --------
    >>> truck = Vehicle(axle_offsets=(0.0, 2.0), axle_loads=(24.0e3, 24.0e3))
    >>> truck.total_load
    48000.0
    >>> Vehicle.point_load(1.0).n_axles
    1
    """

    axle_offsets: tuple
    axle_loads: tuple

    def __post_init__(self):
        offsets = as_float_tuple(self.axle_offsets, "axle_offsets", "Vehicle", low=0.0)
        loads = as_float_tuple(self.axle_loads, "axle_loads", "Vehicle", low=0.0, low_open=True)
        if len(offsets) > MAX_AXLES:
            raise ConfigError(f"The 'axle_offsets' parameter of Vehicle gives {len(offsets)} axles, more than "
                              f"{MAX_AXLES} (a long train); give the axles of one vehicle.")
        if len(offsets) != len(loads):
            raise ConfigError(
                "The 'axle_loads' parameter of Vehicle must have one entry per axle offset "
                f"({len(offsets)}). Got {len(loads)} instead.")
        object.__setattr__(self, "axle_offsets", offsets)
        object.__setattr__(self, "axle_loads", loads)

    @classmethod
    def point_load(cls, load=1.0):
        """A single axle of ``load`` [N]."""
        return cls((0.0,), (load,))

    @property
    def n_axles(self):
        return len(self.axle_offsets)

    @property
    def total_load(self):
        """Sum of the axle loads [N]."""
        return float(sum(self.axle_loads))

    @property
    def length(self):
        """Distance from the front to the rear axle [m]."""
        return float(max(self.axle_offsets))

    def axle_positions(self, positions):
        """Axle positions for reference-axle ``positions``; shape (n_loads, n_axles)."""
        positions = np.asarray(positions, dtype=float)
        return positions[:, None] - np.asarray(self.axle_offsets)[None, :]

    def scaled(self, factor):
        """The same vehicle with every axle load multiplied by ``factor``."""
        factor = as_float(factor, "factor", "Vehicle.scaled", low=0.0, low_open=True)
        return Vehicle(self.axle_offsets, tuple(factor * p for p in self.axle_loads))


@dataclass(frozen=True, eq=False)
class LoadSweep:
    """Positions of the reference axle during one crossing [m], increasing."""

    positions: np.ndarray

    def __post_init__(self):
        pos = as_float_array(self.positions, "positions", "LoadSweep")
        if np.any(np.diff(pos) <= 0.0):
            raise ConfigError(
                "The 'positions' parameter of LoadSweep must be strictly increasing. "
                "Sort the positions or remove duplicates.")
        object.__setattr__(self, "positions", pos)

    @classmethod
    def from_range(cls, start, stop, step):
        """Positions ``start, start + step, ...`` up to and including ``stop``."""
        start = as_float(start, "start", "LoadSweep")
        stop = as_float(stop, "stop", "LoadSweep")
        step = as_float(step, "step", "LoadSweep", low=0.0, low_open=True)
        if stop < start:
            raise ConfigError(
                f"The 'stop' parameter of LoadSweep must be >= start ({start:g}). Got {stop:g} instead.")
        count = np.floor((stop - start) / step + 1e-9) + 1  # a float: inf for a subnormal step
        n = int(count) if count <= 1_000_000 else 1_000_001
        if n > 1_000_000:
            raise ConfigError(f"The load sweep from {start:g} to {stop:g} m in steps of {step:g} m has "
                              f"{count:.3g} positions, more than 1000000. Use a larger 'step'.")
        return cls(start + step * np.arange(n))

    @classmethod
    def covering(cls, bridge, vehicle, step):
        """A sweep that moves the whole vehicle across the bridge."""
        return cls.from_range(0.0, bridge.length + vehicle.length, step)

    @property
    def n_loads(self):
        return self.positions.size

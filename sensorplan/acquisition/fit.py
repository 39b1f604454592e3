"""The case's vehicle as a template: influence lines of the logged channels against axle position.

A vehicle entering at ``t0`` with speed ``v`` has its reference axle at
``z = v (t - t0)``; channel ``c`` then reads ``a * IL_c(z)`` (``a`` the load
factor) on top of its noise.  The vehicle test (:mod:`.glr`) whitens this
template; no offset or drift line is fitted with it.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Template"]


@dataclass(frozen=True, eq=False)
class Template:
    """Influence lines of the logged channels on a fine grid of reference-axle positions.

    Attributes
    ----------
    positions : ndarray (n_grid,)
        Reference-axle positions [m] from 0 to ``length``.
    lines : ndarray (n_channels, n_grid)
        Readings [rad or m]; zero outside the grid (no axle on the bridge).
    length : float
        Bridge length plus vehicle length [m]: the distance the reference
        axle travels while an axle is on the bridge.
    """

    positions: np.ndarray
    lines: np.ndarray
    length: float

    @classmethod
    def from_case(cls, case, names, *, step=None):
        """Template of the sensors ``names`` of ``case`` (default step: length / 2000, at most 0.02 m)."""
        sensors = case.sensors.subset([case.sensors.names.index(n) for n in names])
        length = case.bridge.length + case.vehicle.length
        step = min(0.02, length / 2000.0) if step is None else step
        positions = np.linspace(0.0, length, int(np.ceil(length / step)) + 1)
        lines = case.influence_lines(sensors=sensors, positions=positions).predictions
        return cls(positions, np.array(lines), float(length))

    def predict(self, z):
        """Readings at reference-axle positions ``z`` (any shape): shape (n_channels, *z.shape)."""
        return np.stack([np.interp(z, self.positions, line, left=0.0, right=0.0) for line in self.lines])

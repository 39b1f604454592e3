"""Measurement noise: per-sensor standard deviation, optional AR(1) correlation.

Within one crossing the noise of a sensor is a stationary Gauss-Markov
(Ornstein-Uhlenbeck) process along the load position with correlation
exp(-|x_i - x_j| / correlation_length); crossings and sensors are
independent.  Its precision is tridiagonal, so whitening is a bidiagonal
recursion and no dense covariance is ever inverted.  For equally spaced
positions it is the AR(1) model with rho = exp(-step / correlation_length).
"""

from dataclasses import dataclass

import numpy as np

from .._validation import as_float, as_float_array

__all__ = ["NoiseModel"]

MAX_RHO = 1.0 - 1e-9


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Noise of each sensor.

    Parameters
    ----------
    std : array_like
        Standard deviation per sensor, in the sensor's unit (rad or m).
    correlation_length : float
        AR(1) correlation length along the load position [m]; 0 means
        independent noise.
    """

    std: np.ndarray
    correlation_length: float = 0.0

    def __post_init__(self):
        std = as_float_array(self.std, "std", "NoiseModel")
        if np.any(std <= 0.0):
            from .._errors import ConfigError

            raise ConfigError("The 'std' parameter of NoiseModel must be positive for every "
                              f"sensor. Got {std.tolist()!r} instead.")
        object.__setattr__(self, "std", std)
        object.__setattr__(self, "correlation_length",
                           as_float(self.correlation_length, "correlation_length", "NoiseModel",
                                    low=0.0))

    @property
    def n_sensors(self):
        return self.std.size

    def subset(self, index):
        return NoiseModel(self.std[np.atleast_1d(index)], self.correlation_length)

    def rho(self, positions):
        """Lag-one correlations between consecutive positions, shape (n_loads - 1,)."""
        positions = np.asarray(positions, dtype=float)
        if self.correlation_length < 1e-12:  # 0, or so short that exp(-step / length) is 0 (and may overflow)
            return np.zeros(max(positions.size - 1, 0))
        # Capped below 1: with a correlation length far beyond the load step, 1 - rho^2 would round to 0.
        return np.minimum(np.exp(-np.diff(positions) / self.correlation_length), MAX_RHO)

    def whiten(self, values, positions, sensor_axis=0):
        """Apply Gamma^{-1/2} / std along the load axis (axis ``sensor_axis + 1``).

        ``values`` has the sensors on ``sensor_axis`` and the load positions
        right after it; any trailing axes (e.g. parameters) are carried along.
        The result r satisfies r^T r = y^T Gamma^{-1} y / std^2 per sensor.
        """
        values = np.asarray(values, dtype=float)
        load_axis = sensor_axis + 1
        moved = np.moveaxis(values, (sensor_axis, load_axis), (0, 1))
        rho = self.rho(positions)
        out = moved.copy()
        if rho.size and np.any(rho > 0.0):
            scale = 1.0 / np.sqrt(1.0 - rho**2)
            shape = (1, -1) + (1,) * (moved.ndim - 2)
            out[:, 1:] = (moved[:, 1:] - rho.reshape(shape) * moved[:, :-1]) * scale.reshape(shape)
        out /= self.std.reshape((-1,) + (1,) * (moved.ndim - 1))
        return np.moveaxis(out, (0, 1), (sensor_axis, load_axis))

    def log_det_gamma(self, positions):
        """log det of the correlation matrix of one sensor in one crossing."""
        rho = self.rho(positions)
        return float(np.sum(np.log1p(-rho**2)))

    def sample(self, positions, rng, n_crossings=1):
        """Noise draws of shape (n_crossings, n_sensors, n_loads)."""
        rng = np.random.default_rng(rng)
        positions = np.asarray(positions, dtype=float)
        white = rng.standard_normal((n_crossings, self.n_sensors, positions.size))
        rho = self.rho(positions)
        out = white.copy()
        innov = np.sqrt(1.0 - rho**2)
        for k in range(1, positions.size):
            out[:, :, k] = rho[k - 1] * out[:, :, k - 1] + innov[k - 1] * white[:, :, k]
        return out * self.std[None, :, None]

"""Measurement noise of each sensor: one model, two ways to state it.

*In time* (what a logger shows): per sensor, white noise (``std``) + a
correlated Ornstein-Uhlenbeck part (``correlated_std``, ``correlation_time_s``)
+ slow wander, a random walk (``random_walk``, unit per sqrt(s)) whose level at
the start of each crossing is unknown and marginalised.  Readings at load
positions x are at times x / speed, so the crossing speed (``speed``, m/s)
maps the model onto a crossing; whitening is the Kalman filter of
:mod:`.statespace` (banded in the states, no dense covariance).

*Along the load position* (the older, simpler statement): the whole noise is
an AR(1) process in x with correlation exp(-|x_i - x_j| / correlation_length);
its precision is tridiagonal and whitening is a bidiagonal recursion.  With no
time part and no correlation length the noise is independent.

Crossings and sensors are independent in both.
"""

from dataclasses import dataclass, replace

import numpy as np

from .._cache import Cache, value_key
from .._validation import as_float, as_float_array
from .statespace import innovation_filter

__all__ = ["NoiseModel"]

MAX_RHO = 1.0 - 1e-9
# Filters of the time model, shared by every noise model: keyed by the values they depend on (a sensor's
# four parameters and the readings' times), so subsets and copies reuse them.  Each may hold a dense
# whitening matrix of up to 8 MB (statespace.DENSE_ROWS).
FILTERS = Cache(maxsize=64)
NO_SPEED = ("The time-correlated noise model needs the crossing 'speed' (m/s) to map load positions to times; "
            "give [noise] speed or --speed.")


def _per_sensor(value, n, name, *, allow_zero=True):
    """``value`` (a number or one per sensor) as a float array of n non-negative values."""
    arr = as_float_array(np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 else value,
                         name, "NoiseModel")
    if arr.size != n:
        from .._errors import ConfigError

        raise ConfigError(f"The '{name}' parameter of the noise model has {arr.size} values for {n} sensors; "
                          "give one value, or one per sensor.")
    if np.any(arr < 0.0) or (not allow_zero and np.any(arr == 0.0)):
        from .._errors import ConfigError

        raise ConfigError(f"The '{name}' parameter of the noise model must be "
                          f"{'non-negative' if allow_zero else 'positive'}. Got {arr.tolist()!r} instead.")
    return np.array(arr, dtype=float)


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Noise of each sensor.

    Parameters
    ----------
    std : array_like
        White-noise standard deviation per sensor, in the sensor's unit (rad
        or m); with ``correlation_length`` the std of the whole AR(1) noise.
    correlation_length : float
        AR(1) correlation length along the load position [m]; 0 means
        independent noise.  Not combined with the time model.
    correlated_std, correlation_time_s : float or array_like
        Ornstein-Uhlenbeck part per sensor: std [rad or m] and correlation
        time [s] (0: none).
    random_walk : float or array_like
        Wander per sensor [rad or m per sqrt(s)] (0: none); its level at the
        start of a crossing is an unknown offset, marginalised.
    speed : float, optional
        Crossing speed [m/s] mapping load positions to times: needed by the
        time model for readings given by load position (a case's crossings),
        not for a logger channel read in time; ignored without a time part.
    sample_rate : float, optional
        The logger's sampling rate [Hz], to which ``std`` refers (time model
        only).  Readings further apart in time than one sample stand for the
        mean of the samples between them, whose white part has std
        ``std / sqrt(rate * dt)`` (the correlated part and the wander do not
        average out): so slower or denser crossings gain until wander caps
        them.  None: every reading is one sample.
    """

    std: np.ndarray
    correlation_length: float = 0.0
    correlated_std: np.ndarray | float = 0.0
    correlation_time_s: np.ndarray | float = 0.0
    random_walk: np.ndarray | float = 0.0
    speed: float | None = None
    sample_rate: float | None = None

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
        for name in ("correlated_std", "correlation_time_s", "random_walk"):
            object.__setattr__(self, name, _per_sensor(getattr(self, name), std.size, name))
        for name in ("speed", "sample_rate"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, as_float(getattr(self, name), name, "NoiseModel", low=0.0,
                                                        low_open=True))
        self._check_time_model()

    def _check_time_model(self):
        from .._errors import ConfigError

        if not self.in_time:
            return
        missing = (self.correlated_std > 0.0) & (self.correlation_time_s <= 0.0)
        if np.any(missing):
            raise ConfigError("The noise model's 'correlated_std' needs a positive 'correlation_time_s' "
                              f"(s) for sensor {int(np.argmax(missing)) + 1}; give the correlation time.")
        if self.correlation_length > 0.0:
            raise ConfigError("Give the noise correlation either in time ('correlated_std', "
                              "'correlation_time_s', 'random_walk') or along the load position "
                              "('correlation_length'), not both.")

    @property
    def in_time(self):
        """Whether the noise has a time-correlated part (OU or wander)."""
        return bool(np.any(self.correlated_std > 0.0) or np.any(self.random_walk > 0.0))

    @property
    def cache_key(self):
        return ("NoiseModel", value_key(self.std), self.correlation_length, value_key(self.correlated_std),
                value_key(self.correlation_time_s), value_key(self.random_walk), self.speed, self.sample_rate)

    @property
    def n_sensors(self):
        return self.std.size

    def subset(self, index):
        index = np.atleast_1d(index)
        return NoiseModel(self.std[index], self.correlation_length, self.correlated_std[index],
                          self.correlation_time_s[index], self.random_walk[index], self.speed, self.sample_rate)

    def for_sensors(self, own_kinds, kinds, std):
        """The noise of other sensors of ``kinds`` with white std ``std``, in this model's correlation.

        Every time parameter of a new sensor is the median over this model's
        sensors of the same kind (``own_kinds``); the correlation length and
        the speed are shared.  This is the one rule by which a sensor that is
        not in the case gets its noise.
        """
        own_kinds = tuple(own_kinds)
        if not self.in_time:
            return NoiseModel(std, self.correlation_length)

        def median(values, kind):
            same = [v for k, v in zip(own_kinds, values) if k == kind]
            return float(np.median(same)) if same else 0.0

        params = {name: [median(getattr(self, name), kind) for kind in kinds]
                  for name in ("correlated_std", "correlation_time_s", "random_walk")}
        return NoiseModel(std, **params, speed=self.speed, sample_rate=self.sample_rate)

    def at_speed(self, speed):
        """The same noise for crossings at ``speed`` [m/s] (unchanged without a time model)."""
        if speed is None or not self.in_time or speed == self.speed:
            return self
        return replace(self, speed=speed)

    def times(self, positions):
        """Times [s] of readings at load ``positions`` [m] at the model's speed (time model only)."""
        if self.speed is None:
            from .._errors import ConfigError

            raise ConfigError(NO_SPEED)
        return (np.asarray(positions, dtype=float) - float(np.asarray(positions)[0])) / self.speed

    def filter(self, sensor, positions, times=None):
        """The :class:`~.statespace.InnovationFilter` of one sensor on readings at ``positions`` (or ``times``)."""
        t = self.times(positions) if times is None else np.asarray(times, dtype=float)
        params = dict(white=float(self.std[sensor]) / self.averaging(t), correlated=float(self.correlated_std[sensor]),
                      correlation_time=float(self.correlation_time_s[sensor]),
                      random_walk=float(self.random_walk[sensor]))
        return FILTERS.get(("filter", tuple(params.values()), t), lambda: innovation_filter(t, **params))

    def averaging(self, times):
        """sqrt of the logger samples a reading at ``times`` stands for (1 without a sample rate)."""
        if self.sample_rate is None or np.size(times) < 2:
            return 1.0
        return float(np.sqrt(max(1.0, self.sample_rate * float(np.median(np.diff(times))))))

    def rho(self, positions):
        """Lag-one correlations between consecutive positions, shape (n_loads - 1,) (AR(1) in x only)."""
        positions = np.asarray(positions, dtype=float)
        if self.correlation_length < 1e-12:  # 0, or so short that exp(-step / length) is 0 (and may overflow)
            return np.zeros(max(positions.size - 1, 0))
        # Capped below 1: with a correlation length far beyond the load step, 1 - rho^2 would round to 0.
        return np.minimum(np.exp(-np.diff(positions) / self.correlation_length), MAX_RHO)

    def whiten(self, values, positions, sensor_axis=0, *, times=None):
        """Apply Sigma^{-1/2} along the load axis (axis ``sensor_axis + 1``), sensor by sensor.

        ``values`` has the sensors on ``sensor_axis`` and the load positions
        right after it; any trailing axes (e.g. parameters) are carried along.
        The result r satisfies r^T r = y^T Sigma^{-1} y per sensor (with the
        time model's offset marginalised).  ``times`` [s], when the readings'
        times are known, replace positions / speed in the time model.
        """
        values = np.asarray(values, dtype=float)
        load_axis = sensor_axis + 1
        moved = np.moveaxis(values, (sensor_axis, load_axis), (0, 1))
        if self.in_time:
            out = np.stack([self.filter(i, positions, times).whiten(moved[i]) for i in range(moved.shape[0])])
            return np.moveaxis(out, (0, 1), (sensor_axis, load_axis))
        rho = self.rho(positions)
        out = moved.copy()
        if rho.size and np.any(rho > 0.0):
            scale = 1.0 / np.sqrt(1.0 - rho**2)
            shape = (1, -1) + (1,) * (moved.ndim - 2)
            out[:, 1:] = (moved[:, 1:] - rho.reshape(shape) * moved[:, :-1]) * scale.reshape(shape)
        out /= self.std.reshape((-1,) + (1,) * (moved.ndim - 1))
        return np.moveaxis(out, (0, 1), (sensor_axis, load_axis))

    def log_det_gamma(self, positions):
        """log det of the AR(1) correlation matrix of one sensor in one crossing (0 for the time model)."""
        rho = self.rho(positions)
        return float(np.sum(np.log1p(-rho**2)))

    def log_det(self, positions, *, times=None):
        """log det of the noise covariance of all sensors in one crossing at ``positions`` (or ``times``)."""
        positions = np.asarray(positions, dtype=float)
        if self.in_time:
            return float(sum(self.filter(i, positions, times).log_det() for i in range(self.n_sensors)))
        return self.log_det_gamma(positions) * self.n_sensors + 2.0 * positions.size * float(np.sum(np.log(self.std)))

    def dof(self, n_loads):
        """Readings per crossing that inform anything but the sensors' offsets (all, without wander)."""
        return int(n_loads) * self.n_sensors - int(np.sum(self.random_walk > 0.0)) * (int(n_loads) > 0)

    def sample(self, positions, rng, n_crossings=1):
        """Noise draws of shape (n_crossings, n_sensors, n_loads).

        The time model's wander starts at 0 at the first reading (the
        offset it leaves is arbitrary; inference marginalises it).
        """
        rng = np.random.default_rng(rng)
        positions = np.asarray(positions, dtype=float)
        if self.in_time:
            return self._sample_in_time(positions, rng, n_crossings)
        white = rng.standard_normal((n_crossings, self.n_sensors, positions.size))
        rho = self.rho(positions)
        out = white.copy()
        innov = np.sqrt(1.0 - rho**2)
        for k in range(1, positions.size):
            out[:, :, k] = rho[k - 1] * out[:, :, k - 1] + innov[k - 1] * white[:, :, k]
        return out * self.std[None, :, None]

    def _sample_in_time(self, positions, rng, n_crossings):
        dt = np.diff(self.times(positions))
        shape = (n_crossings, self.n_sensors, positions.size)
        out = rng.standard_normal(shape) * (self.std / self.averaging(self.times(positions)))[None, :, None]
        tau = np.where(self.correlation_time_s > 0.0, self.correlation_time_s, 1.0)[None, :]
        phi = np.exp(-dt[:, None] / tau)  # (n_loads - 1, sensors)
        ou = np.empty(shape)
        ou[:, :, 0] = rng.standard_normal(shape[:2])
        steps = rng.standard_normal(shape)
        for k in range(1, positions.size):
            ou[:, :, k] = phi[k - 1] * ou[:, :, k - 1] + np.sqrt(1.0 - phi[k - 1]**2) * steps[:, :, k]
        out += ou * self.correlated_std[None, :, None]
        walk = np.concatenate([np.zeros(shape[:2] + (1,)),
                               np.cumsum(rng.standard_normal(shape[:2] + (dt.size,)) * np.sqrt(dt), axis=2)], axis=2)
        return out + walk * self.random_walk[None, :, None]

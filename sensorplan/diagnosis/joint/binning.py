"""Dense records fitted in bins of consecutive whitened readings, with the exact model of a bin.

A data logger samples far more densely than the influence lines vary: a
tiltmeter at 100 Hz under a lorry at 5 m/s gives a reading every 0.05 m,
and every refit of the diagnosis costs time in proportion to the readings.
Here each crossing's readings are whitened (the noise model's
Gamma^{-1/2} / std, so that they are independent standard normals under the
model) and summed in bins of ``size`` consecutive rows, divided by
sqrt(size): the bins are again independent standard normals, exactly, for
white and for AR(1) noise alike.  The model of a bin is the same linear map
applied to the model at the recorded rows (lines, effects and load factors
at every reading, whitened and summed after): exact for every effect,
including the kinks where an axle enters the bridge.  What is lost is only
the variation of the whitened data within a bin.

Under the noise model in time (:mod:`sensorplan.model.statespace`) the
whitening is the Kalman filter's innovations L^{-1} (lower triangular,
dense): one map for every sensor up to its scale when the sensors' noise is
proportional (:func:`shared_shape`), else one map per sensor.  The bins of
the innovations are again independent standard normals; the wander's
unknown level at the start of the crossing enters them as the bins of the
whitened constant, u = B L^{-1} 1, and is marginalised exactly as on the
readings: projected out of the bins (the map is P_u B L^{-1}), one degree of
freedom per sensor and log |u|^2 in the restricted likelihood's determinant
(``n_offsets``, ``offset_log_det``).

The size is chosen from the information it keeps: the largest bin whose
posterior precision of log EI (the nominal model, the case's prior) keeps at
least ``KEEP`` of the unbinned one in every direction, i.e. the smallest
generalised eigenvalue of (F_bins + Q, F_rows + Q) is >= ``KEEP``.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy import linalg, sparse

from ..._cache import Cache, value_key
from ...inference.engine import data_sensors
from ...model.crossings import Crossing, Crossings
from ...model.forward import influence_lines
from ...model.noise import NoiseModel
from ...model.statespace import DENSE_ROWS

__all__ = ["KEEP", "BinnedCrossing", "bin_crossings", "bin_sum", "choose_size", "model_rows", "shared_shape"]

KEEP = 0.95  # least fraction of the posterior precision of log EI a bin keeps in any direction
MIN_ROWS = 160  # crossings with fewer rows are fitted row by row (fast enough; nothing to gain)
MIN_BINS = 40  # at least this many bins per crossing
BLOCK = 512  # columns of the identity per pass of the filter's recursion (long records)
MAPS = Cache(maxsize=16)  # bin maps of the noise in time (dense, bins x readings), by the values they depend on


@dataclass(frozen=True, eq=False)
class BinnedCrossing(Crossing):
    """A crossing's whitened bin sums (``values``; ``positions``: the bins' mean positions) and its readings.

    ``raw_positions``, ``raw_values`` and ``raw_load_factor`` hold ``size``
    rows per bin, in order (rows beyond the last whole bin are dropped);
    ``noise`` is the readings' noise model (sensors in the data's order);
    ``raw_times`` the readings' times [s] when recorded (noise in time only).
    ``n_offsets``, ``offset_log_det``: the offsets the map projects out (one
    per wandering sensor) and their log |u|^2 summed (see the module docstring).
    The map: ``bin_map`` (sparse, AR(1)), ``dense_map`` (noise in time, one
    for every sensor) or ``sensor_maps`` (noise in time, (S, bins, readings),
    each times its sensor's std); ``shared``: whether one map serves every sensor.
    """

    raw_positions: np.ndarray = None  # type: ignore[assignment]
    raw_values: np.ndarray = None  # type: ignore[assignment]
    raw_load_factor: np.ndarray = None  # type: ignore[assignment]
    noise: NoiseModel = None  # type: ignore[assignment]
    size: int = 1
    raw_times: np.ndarray | None = None

    def __post_init__(self):
        if self.raw_positions is not None:  # the whitening and binning as one sparse map, readings -> bins
            offsets, bin_map, maps = (0, 0.0), None, None
            if self.noise.in_time:  # dense maps (the filter's L^{-1}): products with dense arrays (BLAS)
                maps, offsets = _time_maps(self.noise, self.raw_positions, self.size, self.raw_times)
            else:
                bin_map = _bin_map(self.noise, self.raw_positions, self.size)
            object.__setattr__(self, "bin_map", bin_map)
            object.__setattr__(self, "dense_map", maps if maps is not None and maps.ndim == 2 else None)
            object.__setattr__(self, "sensor_maps", maps if maps is not None and maps.ndim == 3 else None)
            object.__setattr__(self, "n_offsets", offsets[0])
            object.__setattr__(self, "offset_log_det", offsets[1])
            object.__setattr__(self, "_factor_map", None)  # formed on first use (map_with)
            # crossings with equal keys have equal maps (a model mapped for one serves the others)
            in_time = (self.noise.cache_key, self.raw_times) if self.noise.in_time else ()
            object.__setattr__(self, "map_key", value_key(self.raw_positions, self.size, self.noise.std,
                                                          self.noise.correlation_length, *in_time))

    @property
    def shared(self):
        """Whether one map serves every sensor (the noise scale applied after it)."""
        return self.sensor_maps is None

    def map_with(self, load_factor):
        """The map readings -> bins after scaling the readings by ``load_factor`` (sparse; dense in time)."""
        if not np.array_equal(load_factor, self.raw_load_factor):
            return self._scaled_map(load_factor)
        if self._factor_map is None:  # the readings' own load factors: kept
            object.__setattr__(self, "_factor_map", self._scaled_map(load_factor))
        return self._factor_map

    def _scaled_map(self, load_factor):
        if self.dense_map is not None:  # a dense array for a dense map
            return self.dense_map * load_factor[None, :]
        return (self.bin_map @ sparse.diags(load_factor)).tocsr()

    def to_bins(self, values):
        """Whitened bin sums / sqrt(size) of model ``values`` at the readings (sensors first, rows next)."""
        return self.to_bins_first(np.asarray(values, dtype=float).swapaxes(0, 1)).swapaxes(0, 1)

    def to_bins_first(self, values):
        """As :meth:`to_bins` with the readings first and the sensors next, (readings, S, ...) -> (bins, S, ...)."""
        k, s = values.shape[:2]
        if self.sensor_maps is not None:  # each sensor its own map
            out = np.einsum("sbk,ks...->bs...", self.sensor_maps, values)
        else:
            bin_map = self.bin_map if self.dense_map is None else self.dense_map
            out = (bin_map @ values.reshape(k, -1)).reshape((-1,) + values.shape[1:])  # every sensor and column
        out /= self.noise.std.reshape((s,) + (1,) * (values.ndim - 2))
        return out

    def outer_to_bins(self, sensors, loads):
        """:meth:`to_bins_first` of the columns ``sensors[:, None, :] * loads[None, :, :]`` as such a product.

        ``sensors`` (S, n), ``loads`` (readings, n): the map acts on the
        readings, the noise scale on the sensors.  Returns (sensors (S, n),
        loads (bins, n)).  Only with one map for every sensor (``shared``).
        """
        bin_map = self.bin_map if self.dense_map is None else self.dense_map
        return sensors / self.noise.std[:, None], np.asarray(bin_map @ loads)


def _bin_map(noise, positions, size):
    """Sparse (bins x readings): the AR(1) whitening Gamma^{-1/2} followed by bin sums / sqrt(size)."""
    n = positions.size
    rho = noise.rho(positions)
    scale = np.concatenate([[1.0], 1.0 / np.sqrt(1.0 - rho**2)])
    white = sparse.diags([scale, -rho * scale[1:]], [0, -1], shape=(n, n), format="csr")
    bins = sparse.csr_matrix((np.full(n, 1.0 / np.sqrt(size)), (np.arange(n) // size, np.arange(n))),
                             shape=(n // size, n))
    return (bins @ white).tocsr()


def shared_shape(noise):
    """Whether every sensor's noise in time is the first sensor's scaled by its std (one filter shape for all)."""
    def same(values):
        return bool(np.allclose(values, values[0], rtol=1e-12, atol=0.0))

    timed = noise.correlated_std > 0.0  # all or none once the ratios agree
    return (same(noise.correlated_std / noise.std) and same(noise.random_walk / noise.std)
            and (not timed.any() or same(noise.correlation_time_s[timed])))


def _project(binned, ones):
    """``binned`` (bins first) with the bins' whitened constant ``ones`` projected out (the offset marginalised)."""
    coef = np.tensordot(ones, binned, axes=(0, 0)) / float(ones @ ones)
    return binned - ones.reshape((-1,) + (1,) * (binned.ndim - 1)) * coef[None, ...]


def _time_maps(noise, positions, size, times):
    """The maps P_u B L^{-1} of the noise in time, and (offsets projected out, their log |u|^2 summed).

    One map (bins x readings, the first sensor's times its std) when the
    sensors' noise has one shape (:func:`shared_shape`), else one per sensor
    (S, bins, readings), each times its std.  Kept in ``MAPS`` (crossings
    with the same readings share them); see the module docstring.
    """
    def build():
        if shared_shape(noise):
            binned, log_u = _sensor_map(noise, 0, positions, size, times)
            if log_u is None:
                return binned, (0, 0.0)
            # sensor s's |B L_s^{-1} 1|^2 = |B L_0^{-1} 1|^2 std_0^2 / std_s^2
            return binned, (noise.n_sensors, float(np.sum(log_u + 2.0 * np.log(noise.std[0] / noise.std))))
        parts = [_sensor_map(noise, s, positions, size, times) for s in range(noise.n_sensors)]
        logs = [log_u for _, log_u in parts if log_u is not None]
        return np.stack([m for m, _ in parts]), (len(logs), float(sum(logs)))

    return MAPS.get((), build, key=value_key("time bins", noise.cache_key, positions, size, times))


def _sensor_map(noise, s, positions, size, times):
    """std_s P_u B L_s^{-1} of sensor ``s`` (bins x readings) and log |B L_s^{-1} 1|^2 (None without wander)."""
    f = noise.filter(s, positions, times)
    n = np.asarray(positions).size
    if n <= DENSE_ROWS:  # the filter's own L^{-1}, summed over the bins' rows
        binned = bin_sum(f.matrix()[None], size)[0] * (noise.std[s] / np.sqrt(size))
    else:  # B L^{-1} a block of the identity's columns at a time: no n x n matrix
        binned = np.hstack([bin_sum(f.innovations(np.eye(n, min(BLOCK, n - j), -j))[None], size)[0]
                            for j in range(0, n, BLOCK)]) * (noise.std[s] / np.sqrt(size))
    if not f.offset:
        return binned, None
    ones = binned.sum(axis=1)  # B L^{-1} 1 (times the sensor's std)
    return _project(binned, ones), float(np.log(float(ones @ ones) / noise.std[s] ** 2))


def model_rows(crossing):
    """The positions and load factors at which the model of ``crossing`` is evaluated."""
    if isinstance(crossing, BinnedCrossing):
        return crossing.raw_positions, crossing.raw_load_factor
    return crossing.positions, crossing.load_factor


def bin_sum(values, size):
    """Sums over bins of ``size`` consecutive entries of axis 1 (sensors first); a no-op for size 1."""
    if size == 1:
        return values
    n = values.shape[1] // size
    return values[:, :n * size].reshape((values.shape[0], n, size) + values.shape[2:]).sum(axis=2)


def _information(white, size, ones=None):
    """Fisher information of log EI of one crossing's whitened Jacobian rows summed in bins of ``size``.

    ``ones`` (noise in time, (S, readings)): each sensor's whitened constant
    (0 without wander), projected out of its bins (the offset marginalised);
    ``white`` are then the innovations.
    """
    binned = bin_sum(white, size) / np.sqrt(size)
    if ones is not None:
        u = bin_sum(ones, size) / np.sqrt(size)
        norm = np.einsum("sb,sb->s", u, u)
        coef = np.einsum("sb,sbe->se", u, binned) / np.where(norm > 0.0, norm, 1.0)[:, None]
        binned = binned - u[:, :, None] * coef[:, None, :]
    binned = binned.reshape(-1, white.shape[-1])
    return binned.T @ binned


def choose_size(case, crossings, prior):
    """The bin size for ``crossings`` (1: fit row by row); see the module docstring."""
    n_rows = min(c.n_loads for c in crossings)
    if n_rows < MIN_ROWS or any(isinstance(c, BinnedCrossing) for c in crossings):
        return 1
    sensors, noise = data_sensors(case, crossings.sensor_names)
    groups = {}  # crossings with the same positions, load factors (and times) have the same information
    for c in crossings:
        key = value_key(c.positions, c.load_factor, *((c.times,) if noise.in_time else ()))
        groups.setdefault(key, [c, 0])[1] += 1
    whites = []  # the whitened log-EI Jacobian of each group (in time: innovations and L^{-1} 1), and its count
    for c, count in groups.values():
        lines = influence_lines(case.bridge, case.mesh, case.ei, sensors, case.vehicle, c.positions)
        jac = lines.jacobian("log_ei") * c.load_factor[None, :, None]
        if noise.in_time:  # each sensor's innovations and whitened constant (0 without wander)
            filters = [noise.filter(s, c.positions, c.times) for s in range(noise.n_sensors)]
            white = np.stack([f.innovations(j) for f, j in zip(filters, jac)])
            ones = np.stack([f.innovations(np.ones(c.n_loads)) * f.offset for f in filters])
            whites.append((white, ones, count))
        else:
            whites.append((noise.whiten(jac, c.positions), None, count))
    q = prior.precision(case.mesh.n_elements)
    full = q + sum(n * _information(w, 1, ones) for w, ones, n in whites)
    best = 1
    for size in range(2, n_rows // MIN_BINS + 1):
        # bin_sum drops an incomplete last bin
        kept = q + sum(n * _information(w, size, ones) for w, ones, n in whites)
        if linalg.eigh(kept, full, eigvals_only=True).min() < KEEP:
            break
        best = size
    return best


def bin_crossings(case, crossings, size):
    """``(case, crossings)`` fitted in whitened bins of ``size`` rows: unit white noise per bin."""
    if size == 1:
        return case, crossings
    noise = data_sensors(case, crossings.sensor_names)[1]
    out = []
    for c in crossings:
        n = c.n_loads // size * size
        x, lf = c.positions[:n], c.load_factor[:n]
        binned = BinnedCrossing(c.label, x.reshape(-1, size).mean(axis=1), np.zeros((len(crossings.sensor_names),
                                n // size)), lf.reshape(-1, size).mean(axis=1), x, c.values[:, :n], lf, noise, size,
                                raw_times=None if c.times is None else c.times[:n])
        out.append(replace(binned, values=binned.to_bins(binned.raw_values)))
    unit = NoiseModel(np.ones(case.sensors.n_sensors), 0.0)
    return replace(case, noise=unit), Crossings(crossings.sensor_names, tuple(out))

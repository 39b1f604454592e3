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
dense), the same for every sensor up to its scale when the sensors' noise
is proportional (:func:`shared_shape`; otherwise the record is fitted row by
row).  The bins of the innovations are again independent standard normals;
the wander's unknown level at the start of the crossing enters them as the
bins of the whitened constant, u = B L^{-1} 1, and is marginalised exactly
as on the readings: projected out of the bins (the map is P_u B L^{-1}), one
degree of freedom per sensor and log |u|^2 in the restricted likelihood's
determinant (``n_offsets``, ``offset_log_det``).

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
    """

    raw_positions: np.ndarray = None  # type: ignore[assignment]
    raw_values: np.ndarray = None  # type: ignore[assignment]
    raw_load_factor: np.ndarray = None  # type: ignore[assignment]
    noise: NoiseModel = None  # type: ignore[assignment]
    size: int = 1
    raw_times: np.ndarray | None = None

    def __post_init__(self):
        if self.raw_positions is not None:  # the whitening and binning as one sparse map, readings -> bins
            offsets = (0, 0.0)
            if self.noise.in_time:
                bin_map, offsets = _time_bin_map(self.noise, self.raw_positions, self.size, self.raw_times)
            else:
                bin_map = _bin_map(self.noise, self.raw_positions, self.size)
            # in time the map is dense (the filter's L^{-1}): products with it as a dense array (BLAS)
            object.__setattr__(self, "dense_map", bin_map.toarray() if self.noise.in_time else None)
            object.__setattr__(self, "bin_map", bin_map)
            object.__setattr__(self, "n_offsets", offsets[0])
            object.__setattr__(self, "offset_log_det", offsets[1])
            object.__setattr__(self, "_factor_map", None)  # formed on first use (map_with)
            # crossings with equal keys have equal maps (a model mapped for one serves the others)
            in_time = (self.noise.cache_key, self.raw_times) if self.noise.in_time else ()
            object.__setattr__(self, "map_key", value_key(self.raw_positions, self.size, self.noise.std,
                                                          self.noise.correlation_length, *in_time))

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
        bin_map = self.bin_map if self.dense_map is None else self.dense_map
        out = (bin_map @ values.reshape(k, -1)).reshape((-1,) + values.shape[1:])  # every sensor and column
        out /= self.noise.std.reshape((s,) + (1,) * (values.ndim - 2))
        return out

    def outer_to_bins(self, sensors, loads):
        """:meth:`to_bins_first` of the columns ``sensors[:, None, :] * loads[None, :, :]`` as such a product.

        ``sensors`` (S, n), ``loads`` (readings, n): the map acts on the
        readings, the noise scale on the sensors.  Returns (sensors (S, n),
        loads (bins, n)).
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


def _innovations(noise, positions, times, values):
    """L^{-1} values (readings first) of the first sensor's filter times its std, and the filter.

    Divided by a sensor's std this is that sensor's innovations when the
    noise has one shape (:func:`shared_shape`).
    """
    f = noise.filter(0, positions, times)
    return f.innovations(values) * noise.std[0], f


def _project(binned, ones):
    """``binned`` (bins first) with the bins' whitened constant ``ones`` projected out (the offset marginalised)."""
    coef = np.tensordot(ones, binned, axes=(0, 0)) / float(ones @ ones)
    return binned - ones.reshape((-1,) + (1,) * (binned.ndim - 1)) * coef[None, ...]


def _time_bin_map(noise, positions, size, times):
    """Sparse (bins x readings) P_u B L^{-1} of the noise in time (the first sensor's, times its std).

    Returns the map and (offsets projected out, their log |u|^2 summed over
    the sensors); see the module docstring.  Kept in ``MAPS`` (crossings
    with the same readings share it).
    """
    return MAPS.get((), lambda: _new_time_bin_map(noise, positions, size, times),
                    key=value_key("time bins", noise.cache_key, positions, size, times))


def _new_time_bin_map(noise, positions, size, times):
    f = noise.filter(0, positions, times)
    n = np.asarray(positions).size
    if n <= DENSE_ROWS:  # the filter's own L^{-1}, summed over the bins' rows
        binned = bin_sum(f.matrix()[None], size)[0] * (noise.std[0] / np.sqrt(size))
    else:  # B L^{-1} a block of the identity's columns at a time: no n x n matrix
        binned = np.hstack([bin_sum(f.innovations(np.eye(n, min(BLOCK, n - j), -j))[None], size)[0]
                            for j in range(0, n, BLOCK)]) * (noise.std[0] / np.sqrt(size))
    if not f.offset:
        return sparse.csr_matrix(binned), (0, 0.0)
    ones = binned.sum(axis=1)  # B L^{-1} 1 (times the first sensor's std)
    # sensor s's |B L_s^{-1} 1|^2 = |ones|^2 / std_s^2
    log_det = float(np.sum(np.log(float(ones @ ones) / noise.std**2)))
    return sparse.csr_matrix(_project(binned, ones)), (noise.n_sensors, log_det)


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

    ``ones`` (noise in time): the readings' whitened constant, projected out
    of the bins (the offset marginalised); ``white`` are then innovations.
    """
    binned = bin_sum(white, size) / np.sqrt(size)
    if ones is not None:
        binned = _project(binned.swapaxes(0, 1), bin_sum(ones[None, :], size)[0] / np.sqrt(size)).swapaxes(0, 1)
    binned = binned.reshape(-1, white.shape[-1])
    return binned.T @ binned


def choose_size(case, crossings, prior):
    """The bin size for ``crossings`` (1: fit row by row); see the module docstring."""
    n_rows = min(c.n_loads for c in crossings)
    if n_rows < MIN_ROWS or any(isinstance(c, BinnedCrossing) for c in crossings):
        return 1
    sensors, noise = data_sensors(case, crossings.sensor_names)
    if noise.in_time and not shared_shape(noise):  # one bin map serves every sensor only when they share it
        return 1
    groups = {}  # crossings with the same positions, load factors (and times) have the same information
    for c in crossings:
        key = value_key(c.positions, c.load_factor, *((c.times,) if noise.in_time else ()))
        groups.setdefault(key, [c, 0])[1] += 1
    whites = []  # the whitened log-EI Jacobian of each group (in time: innovations and L^{-1} 1), and its count
    for c, count in groups.values():
        lines = influence_lines(case.bridge, case.mesh, case.ei, sensors, case.vehicle, c.positions)
        jac = lines.jacobian("log_ei") * c.load_factor[None, :, None]
        if noise.in_time:
            white, f = _innovations(noise, c.positions, c.times, jac.swapaxes(0, 1))
            white = white.swapaxes(0, 1) / noise.std[:, None, None]
            ones = _innovations(noise, c.positions, c.times, np.ones(c.n_loads))[0] if f.offset else None
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

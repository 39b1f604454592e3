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

The size is chosen from the information it keeps: the largest bin whose
posterior precision of log EI (the nominal model, the case's prior) keeps at
least ``KEEP`` of the unbinned one in every direction, i.e. the smallest
generalised eigenvalue of (F_bins + Q, F_rows + Q) is >= ``KEEP``.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy import linalg, sparse

from ..._cache import value_key
from ...inference.engine import data_sensors
from ...model.crossings import Crossing, Crossings
from ...model.forward import influence_lines
from ...model.noise import NoiseModel

__all__ = ["KEEP", "BinnedCrossing", "bin_crossings", "bin_sum", "choose_size", "model_rows"]

KEEP = 0.95  # least fraction of the posterior precision of log EI a bin keeps in any direction
MIN_ROWS = 160  # crossings with fewer rows are fitted row by row (fast enough; nothing to gain)
MIN_BINS = 40  # at least this many bins per crossing


@dataclass(frozen=True, eq=False)
class BinnedCrossing(Crossing):
    """A crossing's whitened bin sums (``values``; ``positions``: the bins' mean positions) and its readings.

    ``raw_positions``, ``raw_values`` and ``raw_load_factor`` hold ``size``
    rows per bin, in order (rows beyond the last whole bin are dropped);
    ``noise`` is the readings' noise model (sensors in the data's order).
    """

    raw_positions: np.ndarray = None  # type: ignore[assignment]
    raw_values: np.ndarray = None  # type: ignore[assignment]
    raw_load_factor: np.ndarray = None  # type: ignore[assignment]
    noise: NoiseModel = None  # type: ignore[assignment]
    size: int = 1

    def __post_init__(self):
        if self.raw_positions is not None:  # the whitening and binning as one sparse map, readings -> bins
            object.__setattr__(self, "bin_map", _bin_map(self.noise, self.raw_positions, self.size))
            object.__setattr__(self, "_factor_map", None)  # formed on first use (map_with)
            # crossings with equal keys have equal maps (a model mapped for one serves the others)
            object.__setattr__(self, "map_key", value_key(self.raw_positions, self.size, self.noise.std,
                                                          self.noise.correlation_length))

    def map_with(self, load_factor):
        """The sparse map readings -> bins applied after scaling the readings by ``load_factor``."""
        if not np.array_equal(load_factor, self.raw_load_factor):
            return (self.bin_map @ sparse.diags(load_factor)).tocsr()
        if self._factor_map is None:  # the readings' own load factors: kept
            object.__setattr__(self, "_factor_map", (self.bin_map @ sparse.diags(load_factor)).tocsr())
        return self._factor_map

    def to_bins(self, values):
        """Whitened bin sums / sqrt(size) of model ``values`` at the readings (sensors first, rows next)."""
        return self.to_bins_first(np.asarray(values, dtype=float).swapaxes(0, 1)).swapaxes(0, 1)

    def to_bins_first(self, values):
        """As :meth:`to_bins` with the readings first and the sensors next, (readings, S, ...) -> (bins, S, ...)."""
        k, s = values.shape[:2]
        out = (self.bin_map @ values.reshape(k, -1)).reshape((-1,) + values.shape[1:])  # every sensor and column
        out /= self.noise.std.reshape((s,) + (1,) * (values.ndim - 2))
        return out

    def outer_to_bins(self, sensors, loads):
        """:meth:`to_bins_first` of the columns ``sensors[:, None, :] * loads[None, :, :]`` as such a product.

        ``sensors`` (S, n), ``loads`` (readings, n): the map acts on the
        readings, the noise scale on the sensors.  Returns (sensors (S, n),
        loads (bins, n)).
        """
        return sensors / self.noise.std[:, None], np.asarray(self.bin_map @ loads)


def _bin_map(noise, positions, size):
    """Sparse (bins x readings): the AR(1) whitening Gamma^{-1/2} followed by bin sums / sqrt(size)."""
    n = positions.size
    rho = noise.rho(positions)
    scale = np.concatenate([[1.0], 1.0 / np.sqrt(1.0 - rho**2)])
    white = sparse.diags([scale, -rho * scale[1:]], [0, -1], shape=(n, n), format="csr")
    bins = sparse.csr_matrix((np.full(n, 1.0 / np.sqrt(size)), (np.arange(n) // size, np.arange(n))),
                             shape=(n // size, n))
    return (bins @ white).tocsr()


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


def _information(white, size):
    """Fisher information of log EI of one crossing's whitened Jacobian rows summed in bins of ``size``."""
    binned = (bin_sum(white, size) / np.sqrt(size)).reshape(-1, white.shape[-1])
    return binned.T @ binned


def choose_size(case, crossings, prior):
    """The bin size for ``crossings`` (1: fit row by row); see the module docstring."""
    n_rows = min(c.n_loads for c in crossings)
    if n_rows < MIN_ROWS or any(isinstance(c, BinnedCrossing) for c in crossings):
        return 1
    sensors, noise = data_sensors(case, crossings.sensor_names)
    if noise.in_time:  # the bin map is the AR(1) whitening's; the time model's filter is not bidiagonal
        return 1
    groups = {}  # crossings with the same positions and load factors have the same information
    for c in crossings:
        groups.setdefault(value_key(c.positions, c.load_factor), [c, 0])[1] += 1
    whites = []  # the whitened log-EI Jacobian of each group, and its count
    for c, count in groups.values():
        lines = influence_lines(case.bridge, case.mesh, case.ei, sensors, case.vehicle, c.positions)
        whites.append((noise.whiten(lines.jacobian("log_ei") * c.load_factor[None, :, None], c.positions), count))
    q = prior.precision(case.mesh.n_elements)
    full = q + sum(n * _information(w, 1) for w, n in whites)
    best = 1
    for size in range(2, n_rows // MIN_BINS + 1):
        kept = q + sum(n * _information(w, size) for w, n in whites)  # bin_sum drops an incomplete last bin
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
                                n // size)), lf.reshape(-1, size).mean(axis=1), x, c.values[:, :n], lf, noise, size)
        out.append(replace(binned, values=binned.to_bins(binned.raw_values)))
    unit = NoiseModel(np.ones(case.sensors.n_sensors), 0.0)
    return replace(case, noise=unit), Crossings(crossings.sensor_names, tuple(out))

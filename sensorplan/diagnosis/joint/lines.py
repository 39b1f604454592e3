"""A crossing's vehicle lines read off the exact line interpolant, and their log-EI columns on the fitted rows.

A crossing's lines (:class:`CrossingLines`) carry the readings and spring
terms at once and form the element kernel (readings x sensors x elements,
the bulk of the work) only when a Jacobian asks for it -- for a binned
crossing on its bins directly, by mapping the interpolation weights
(:class:`InterpolationMaps`, independent of EI) onto the bins first.

Owns: :class:`CrossingLines`, :class:`InterpolationMaps`, the log-EI blocks.  May import: the cache, numpy, scipy.
"""

from functools import cached_property

import numpy as np
import scipy.sparse

from ..._cache import Cache, value_key
from .columns import Outer

__all__ = ["CrossingLines", "InterpolationMaps", "log_ei_blocks", "mapped_groups"]


class InterpolationMaps:
    """The sparse interpolation maps of the loads at ``n_rows`` positions (independent of EI).

    ``lines``: the vehicle's weights on the interpolant's table rows;
    ``basis``, ``structure``: what they were combined from (for the slopes
    and each axle's own map, formed when a Jacobian first asks for them:
    ``slopes``, ``axles``).  ``cache_key``: the values they were built from
    (the breakpoints, the positions, the axle loads, which end bearings are
    elastic).  ``derived`` keeps what is computed from them (a crossing's
    rows, the maps on the bins) while they are kept.
    """

    def __init__(self, cache_key, n_rows, basis, structure, lines):
        self.cache_key, self.n_rows = cache_key, n_rows
        self.basis, self.structure, self.lines = basis, structure, lines
        self.slopes = None
        self.axles = None
        self.derived = Cache()


class CrossingLines:
    """One crossing's vehicle lines: readings (S, N) now, the spring terms and element kernel on demand.

    ``rows``: the crossing's rows (a slice) of ``maps.lines``.
    ``cache_key``: the state the lines were read at (positions, sensor
    positions, bridge, axle factors, EI factor; at the problem's current EI);
    ``source_key``: that of the interpolant and maps they come from (lines
    with one source map onto bins in one product).
    """

    def __init__(self, interpolant, maps, rows, ei, stiffness, predictions, reactions, *, cache_key, source_key):
        self.interpolant, self.maps, self.rows = interpolant, maps, rows
        self.ei, self.spring_stiffness = ei, stiffness
        self.predictions, self.reactions = predictions, reactions
        self.cache_key, self.source_key = cache_key, source_key

    @cached_property
    def spring_kernel(self):
        """dy/dc (S, N, n_springs) of the elastic springs' compliances c = 1/k (formed when first asked for)."""
        return self.interpolant.sensor_reactions[:, None, :] * self.reactions[None, :, :]

    @property
    def weights(self):
        """The crossing's rows of the interpolation map (sliced when first asked for, then kept with the maps)."""
        return self.maps.derived.get((), lambda: self.maps.lines[self.rows],
                                     key=("rows", self.rows.start, self.rows.stop))

    @cached_property
    def kernel(self):
        """Element integrals dy/dv (S, N, E), v = 1/EI."""
        return self.interpolant.kernel(self.weights)

    def jacobian(self, parameterisation="log_ei"):
        """dy/dlog EI per element (S, N, E) (the only parameterisation the diagnosis uses)."""
        if parameterisation != "log_ei":
            raise ValueError(f"CrossingLines.jacobian supports 'log_ei' only. Got {parameterisation!r} instead.")
        return self.kernel * (-1.0 / self.ei)

    def spring_log_columns(self, factor, springs):
        """dy/dlog k of the elastic springs ``springs`` (their indices) times ``factor`` (N,), (S, N, len(springs)),
        as an :class:`~.columns.Outer` block.

        dy/dlog k = k dy/dk = -(dy/dc) / k with c = 1/k: the sensors' unit
        reactions times the loads' reactions, formed where it is written.
        """
        springs = np.asarray(springs, dtype=int)
        loads = self.reactions[:, springs] * (factor[:, None] * (-1.0 / self.spring_stiffness[springs]))
        return Outer(self.interpolant.sensor_reactions[:, springs], loads)

    @cached_property
    def log_ei_total(self):
        """d y / d(a common log EI shift) (S, N): minus the beam's share of the readings."""
        beam = self.predictions - self.spring_kernel @ (1.0 / self.spring_stiffness)
        return -beam


def mapped_groups(items, cache):
    """The binned items mapped onto their bins, per interpolant and set of maps (see :func:`log_ei_blocks`).

    Yields (members, lines, mapped, offsets, key): ``mapped`` (bins of every
    member x table rows), member ``j``'s bins in ``offsets[j]:offsets[j+1]``;
    ``key``: the values ``mapped`` was built from (the maps and the
    layout).  ``cache`` (a :class:`~sensorplan._cache.Cache`) keeps the bin
    maps side by side.
    """
    groups = {}
    for k, (lines, _, _) in enumerate(items):
        groups.setdefault(lines.source_key, []).append(k)
    for members in groups.values():
        lines = items[members[0]][0]
        weights = lines.maps.lines
        layout = ("layout", weights.shape[0],
                  tuple((items[k][0].rows.start, value_key(items[k][1]), items[k][2].map_key) for k in members))
        side_by_side, offsets = cache.get((), lambda: _side_by_side(items, members, weights.shape[0]), key=layout)
        # kept with the maps, as long as the loads stay where they are
        mapped = lines.maps.derived.get((), lambda: _product(side_by_side, weights), key=("mapped", layout))
        yield members, lines, mapped, offsets, (lines.maps.cache_key, layout)


def _product(side_by_side, weights):
    """The bin maps times the interpolation weights (a dense array when the maps are: the noise in time)."""
    if isinstance(side_by_side, np.ndarray):
        return np.ascontiguousarray((weights.T @ side_by_side.T).T)  # sparse times dense
    return side_by_side @ weights


def _side_by_side(items, members, n_rows):
    """The bin maps of ``members`` side by side on the rows of their common maps, and each one's first bin."""
    if items[members[0]][2].dense_map is not None:  # dense maps (noise in time; one noise model for all)
        parts = [items[k][2].map_with(items[k][1]) for k in members]
        offsets = np.cumsum([0] + [p.shape[0] for p in parts])
        out = np.zeros((offsets[-1], n_rows))
        for p, o, k in zip(parts, offsets, members):
            start = items[k][0].rows.start
            out[o:o + p.shape[0], start:start + p.shape[1]] = p
        return out, offsets
    parts = [items[k][2].map_with(items[k][1]).tocoo() for k in members]
    offsets = np.cumsum([0] + [p.shape[0] for p in parts])
    rows = np.concatenate([p.row + o for p, o in zip(parts, offsets)])
    cols = np.concatenate([p.col + items[k][0].rows.start for p, k in zip(parts, members)])
    return scipy.sparse.csr_matrix((np.concatenate([p.data for p in parts]), (rows, cols)),
                                   shape=(offsets[-1], n_rows)), offsets


def log_ei_blocks(items, cache):
    """dy/dlog EI times the load factor on the fitted rows (S, rows, E) of every (lines, load factor, binned).

    Rows: the readings, or ``binned``'s bins.  A binned crossing's weights
    are mapped onto its bins first (bins x breakpoints), so the kernel is
    formed on the bins only; the map and the load factor act linearly, so
    this equals binning the kernel at the readings.  The binned crossings
    whose lines come from one interpolant and one set of interpolation maps
    are mapped onto their bins in one sparse product (their bin maps side by
    side, kept in ``cache``: they depend on the bins and the rows' layout
    only) and their kernels formed in one product (the mapped weights kept
    with the maps, as long as the loads stay where they are): one sparse
    product per crossing would cost more in overhead than in arithmetic.
    Repeated items are formed once.
    """
    out, binned_items, first = [None] * len(items), [], {}
    for k, (lines, lf, binned) in enumerate(items):
        key = lines.cache_key, value_key(lf), None if binned is None else binned.map_key
        if key in first:
            out[k] = first[key]
            continue
        first[key] = k
        if binned is None:
            out[k] = lines.jacobian() * lf[None, :, None]
        elif not binned.shared:  # a map per sensor (noise in time): the kernel at the readings, mapped
            out[k] = binned.to_bins(lines.jacobian() * lf[None, :, None])
        else:
            binned_items.append(k)
    for members, lines, mapped, offsets, _ in mapped_groups([items[k] for k in binned_items], cache):
        kernel = lines.interpolant.kernel(mapped)
        for j, member in enumerate(members):
            k = binned_items[member]
            out[k] = kernel[:, offsets[j]:offsets[j + 1]] * (-1.0 / lines.ei / items[k][2].noise.std[:, None, None])
    return [out[b] if isinstance(b, int) else b for b in out]  # repeated items: their first

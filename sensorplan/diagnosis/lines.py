"""The vehicle's influence lines of every crossing, read off the exact line interpolant, for the diagnosis.

:class:`LineSource` is the part of :class:`~.joint.JointProblem` that turns
a model state (EI, springs, load and sensor positions, axle loads, a
crossing's own EI factor) into each crossing's lines.  Everything that does
not depend on EI is kept across evaluations: the interpolant's element
products (:mod:`sensorplan.model.interpolant`), and here the sparse
interpolation maps of the load positions.  A crossing's lines
(:class:`CrossingLines`) carry the readings and spring terms at once and
form the element kernel (readings x sensors x elements, the bulk of the
work) only when a Jacobian asks for it -- for a binned crossing on its bins
directly, by mapping the interpolation weights first.

Owns: the lines of the diagnosis model.  May import: the model layer.
"""

from functools import cached_property

import numpy as np
import scipy.sparse

from ..model.interpolant import LineInterpolant
from ..model.loads import Vehicle
from ..model.sensors import SensorLayout
from ._base import Outer
from ._entry import entry_ramp

__all__ = []


def _axle_key(state, x, axle, r, scale):
    """Cache key of one axle's unit-load response (independent of the axle loads)."""
    return ("axle", x.tobytes(), axle, r.tobytes(), state.bridge, scale)



class CrossingLines:
    """One crossing's vehicle lines: readings (S, N) now, the spring terms and element kernel on demand.

    ``rows``: the crossing's rows (a slice) of the sparse interpolation map
    ``maps["lines"]``; ``maps`` also keeps them, and them mapped onto bins,
    across evaluations.
    """

    def __init__(self, interpolant, maps, rows, ei, stiffness, predictions, reactions):
        self.interpolant, self._maps, self._rows = interpolant, maps, rows
        self.ei, self.spring_stiffness = ei, stiffness
        self.predictions, self._reactions = predictions, reactions

    @cached_property
    def spring_kernel(self):
        """dy/dc (S, N, n_springs) of the elastic springs' compliances c = 1/k (formed when first asked for)."""
        return self.interpolant.sensor_reactions[:, None, :] * self._reactions[None, :, :]

    @property
    def weights(self):
        """The crossing's rows of the interpolation map (sliced when first asked for, then kept)."""
        key = ("rows", self._rows.start)
        if key not in self._maps:
            self._maps[key] = self._maps["lines"][self._rows]
        return self._maps[key]

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
        as an :class:`~._base.Outer` block.

        dy/dlog k = k dy/dk = -(dy/dc) / k with c = 1/k: the sensors' unit
        reactions times the loads' reactions, formed where it is written.
        """
        springs = np.asarray(springs, dtype=int)
        loads = self._reactions[:, springs] * (factor[:, None] * (-1.0 / self.spring_stiffness[springs]))
        return Outer(self.interpolant.sensor_reactions[:, springs], loads)

    @cached_property
    def log_ei_total(self):
        """d y / d(a common log EI shift) (S, N): minus the beam's share of the readings."""
        beam = self.predictions - self.spring_kernel @ (1.0 / self.spring_stiffness)
        return -beam


def mapped_groups(items, kept):
    """The binned items mapped onto their bins, per interpolant and set of maps (see :func:`log_ei_blocks`).

    Yields (members, lines, mapped, offsets): ``mapped`` (bins of every
    member x table rows), member ``j``'s bins in ``offsets[j]:offsets[j+1]``.
    """
    groups = {}
    for k, (lines, lf, binned) in enumerate(items):
        groups.setdefault((id(lines.interpolant), id(lines._maps)), []).append(k)
    for members in groups.values():
        lines = items[members[0]][0]
        weights = lines._maps["lines"]
        layout = (weights.shape[0],) + tuple((items[k][0]._rows.start, items[k][1].tobytes(), items[k][2].map_key)
                                             for k in members)
        if layout not in kept:
            parts = [items[k][2].map_with(items[k][1]).tocoo() for k in members]
            offsets = np.cumsum([0] + [p.shape[0] for p in parts])
            rows = np.concatenate([p.row + o for p, o in zip(parts, offsets)])
            cols = np.concatenate([p.col + items[k][0]._rows.start for p, k in zip(parts, members)])
            kept[layout] = (scipy.sparse.csr_matrix((np.concatenate([p.data for p in parts]), (rows, cols)),
                                                    shape=(offsets[-1], weights.shape[0])), offsets)
        side_by_side, offsets = kept[layout]
        mapped = lines._maps.get(("mapped", layout))  # kept while the loads stay where they are
        if mapped is None:
            mapped = lines._maps[("mapped", layout)] = side_by_side @ weights
        yield members, lines, mapped, offsets


def log_ei_blocks(items, kept):
    """dy/dlog EI times the load factor on the fitted rows (S, rows, E) of every (lines, load factor, binned).

    Rows: the readings, or ``binned``'s bins.  A binned crossing's weights
    are mapped onto its bins first (bins x breakpoints), so the kernel is
    formed on the bins only; the map and the load factor act linearly, so
    this equals binning the kernel at the readings.  The binned crossings
    whose lines come from one interpolant and one set
    of interpolation maps are mapped onto their bins in one sparse product
    (their bin maps side by side, kept in ``kept`` across evaluations: they
    depend on the bins and the rows' layout only) and their kernels formed
    in one product (the mapped weights kept with the maps, as long as the
    loads stay where they are).  With loads moved by an effect they are new at every
    evaluation, and per crossing the sparse product cost ~0.7 ms of overhead
    for ~15k operations (three spans, twelve crossings: 17 of 54 ms per
    evaluation under the profiler).  Repeated items are formed once.
    """
    out, binned_items, first = [None] * len(items), [], {}
    for k, (lines, lf, binned) in enumerate(items):
        key = (id(lines), lf.tobytes(), None if binned is None else binned.map_key)
        if key in first:
            out[k] = first[key]
            continue
        first[key] = k
        if binned is None:
            out[k] = lines.jacobian() * lf[None, :, None]
        else:
            binned_items.append(k)
    for members, lines, mapped, offsets in mapped_groups([items[k] for k in binned_items], kept):
        kernel = lines.interpolant.kernel(mapped)
        for j, member in enumerate(members):
            k = binned_items[member]
            out[k] = kernel[:, offsets[j]:offsets[j + 1]] * (-1.0 / lines.ei / items[k][2].noise.std[:, None, None])
    return [out[b] if isinstance(b, int) else b for b in out]  # repeated items: their first


class LineSource:
    """The lines of every crossing at a model state, for :class:`~.joint.JointProblem` (a mixin).

    Uses the problem's ``case``, ``sensors``, ``n_crossings``, ``entry``,
    ``entry_moves``, ``axle_responses``, the current ``_ei`` and the caches
    ``_cache`` (per EI) and ``_weight_maps`` (independent of EI).
    """

    def interpolant(self, state, scale, sensor_positions=None):
        """The exact piecewise-cubic unit-load lines at the current EI (x exp(scale)), cached per EI and state."""
        r = state.sensor_positions if sensor_positions is None else sensor_positions
        key = ("interpolant", r.tobytes(), state.bridge, scale)
        if key not in self._cache:
            # a crossing's own EI factor (load-dependent stiffness) needs no solve without elastic springs
            scaled = None if scale == 0.0 else self.interpolant(state, 0.0, r).scaled(np.exp(scale))
            if scaled is None:
                sensors = SensorLayout(r, self.sensors.kinds, self.sensors.names)
                scaled = LineInterpolant(state.bridge, self.case.mesh, self._ei * np.exp(scale), sensors)
            self._cache[key] = scaled
        return self._cache[key]

    def _axles(self, state):
        return (np.asarray(self.case.vehicle.axle_offsets, float),
                np.asarray(self.case.vehicle.axle_loads, float) * state.axle_factors)

    def lines(self, state, c, *, positions=None, sensor_positions=None):
        """The vehicle's influence lines for crossing ``c`` (or at ``positions`` / ``sensor_positions``).

        Sums of the unit-load lines of every axle, read off the exact
        piecewise-cubic interpolant (:class:`~sensorplan.model.interpolant.LineInterpolant`):
        one small force-method solve per EI serves every crossing, shifted
        position and axle (the crossings' positions differ once an effect
        moves them).
        """
        x = state.positions[c] if positions is None else positions
        r = state.sensor_positions if sensor_positions is None else sensor_positions
        scale = float(state.ei_log_scale[c])
        key = self._lines_key(state, x, r, scale)
        if key not in self._cache:
            if positions is None:  # every crossing at these sensor positions at once (sensor-position Jacobian)
                self.prefetch(state, sensor_positions=r)
            else:
                self._fill(state, r, scale, {key: x})
        return self._cache[key]

    def prefetch(self, state, jacobian=False, sensor_positions=None):
        """The lines of every crossing, read off the interpolant in one sparse product per EI factor.

        With ``jacobian``, also the slopes in the load position (effects that
        move the loads) and each axle's own response (axle loads), from the
        same interpolation weights.
        """
        r = state.sensor_positions if sensor_positions is None else sensor_positions
        groups = {}
        for c in range(self.n_crossings):
            scale = float(state.ei_log_scale[c])
            x = state.positions[c]
            key = self._lines_key(state, x, r, scale)
            missing = key not in self._cache or jacobian and (
                (self.entry_moves and ("slope",) + key not in self._cache)
                or (self.axle_responses and _axle_key(state, x, 0, r, scale) not in self._cache))
            if missing:
                groups.setdefault(scale, {})[key] = x
        for scale, items in groups.items():
            self._fill(state, r, scale, items, jacobian)

    def _fill(self, state, r, scale, items, jacobian=False):
        """Cache the lines of every {key: positions} in ``items`` (one sparse product).

        With ``jacobian``, also their slopes in the load position (when an
        effect moves the loads) and each axle's own response (axle loads).
        """
        interpolant = self.interpolant(state, scale, r)
        every = np.concatenate(list(items.values()))
        maps = self._maps(interpolant, state, every, jacobian)
        # lines already read at these positions (the trial point a Jacobian is now asked at) are kept
        new = any(key not in self._cache for key in items)
        if new:
            predictions, reactions = interpolant.readings_and_reactions(maps["lines"])
        slopes = interpolant.readings(maps["slopes"]) if jacobian and "slopes" in maps else None
        axles = [interpolant.readings(w) for w in maps.get("axles", ())] if jacobian else []
        ei, stiffness = self._ei * np.exp(scale), state.bridge.spring_stiffness()
        start = 0
        for key, x in items.items():
            sl = slice(start, start + x.size)
            start += x.size
            if new:
                self._cache[key] = CrossingLines(interpolant, maps, sl, ei, stiffness, predictions[:, sl],
                                                 reactions[sl])
            if slopes is not None:
                self._cache[("slope",) + key] = slopes[:, sl]
            for a, unit in enumerate(axles):
                self._cache[_axle_key(state, x, a, r, scale)] = unit[:, sl]

    def _maps(self, interpolant, state, every, jacobian):
        """The interpolation maps of the loads at ``every``: lines, and with ``jacobian`` slopes and each axle.

        They depend on the positions, the breakpoints, the axle loads and
        which end bearings are elastic, not on EI: kept across evaluations.
        """
        offsets, loads = self._axles(state)
        vertical = state.bridge.vertical_springs
        key = (interpolant.points.tobytes(), every.tobytes(), loads.tobytes(),
               np.isinf(vertical[0]), np.isinf(vertical[-1]))
        kept = self._weight_maps
        maps = kept.get(key)
        if maps is None:
            basis = interpolant.basis(every[:, None] - offsets[None, :])  # every axle at once
            maps = kept[key] = {"rows_held": every.size, "basis": basis, "structure": interpolant.structure(basis)}
            maps["lines"] = self._weights(interpolant, state, every, basis, offsets, loads, structure=maps["structure"])
            # least recently used first out, beyond three times every crossing's rows: loads moved by an effect
            # make new maps at every evaluation (megabytes each on dense records), a crossing's own EI factor
            # one per crossing
            budget = 3 * sum(x.size for x in self.model_positions)
            while len(kept) > 1 and sum(m["rows_held"] for m in kept.values()) > budget:
                kept.pop(next(iter(kept)))
        else:
            kept.move_to_end(key)
        if jacobian and self.entry_moves and "slopes" not in maps:
            maps["slopes"] = self._weights(interpolant, state, every, maps["basis"], offsets, loads,
                                           structure=maps["structure"], derivative=True)
        if jacobian and self.axle_responses and "axles" not in maps:
            i, value, slope = maps["basis"]
            maps["axles"] = [self._weights(interpolant, state, every, (i[:, a:a + 1], value[:, a:a + 1],
                                                                       slope[:, a:a + 1]), offsets[a:a + 1], np.ones(1))
                             for a in range(offsets.size)]
        return maps

    def _weights(self, interpolant, state, x, basis, offsets, loads, *, structure=None, derivative=False):
        """Interpolation weights of the axles (``basis`` at ``x`` - offsets), with the entry ramps."""
        u = x[None, :] - offsets[:, None]
        ramp = self._ramp(state, u)
        if ramp is None:
            return interpolant.combine(basis, loads, derivative=derivative, structure=structure)
        g, dg = ramp
        length = state.bridge.length
        # on the bridge: the response at u scaled by g(u); outside: the response at the end scaled by g(u)
        weights = interpolant.combine(basis, (loads[:, None] * g).T, derivative=derivative, structure=structure)
        factor = dg if derivative else g
        if derivative:  # d/dx (g R) = g R' + g' R
            weights = weights + interpolant.combine(basis, (loads[:, None] * dg).T, structure=structure)
        before = loads @ np.where(u < 0.0, factor, 0.0)
        after = loads @ np.where(u > length, factor, 0.0)
        if before.any() or after.any():
            weights = weights + interpolant.end_weights(before, after)
        return weights

    def _lines_key(self, state, x, r, scale):
        return (x.tobytes(), r.tobytes(), state.bridge, state.axle_factors.tobytes(), scale)

    def line_slopes(self, state, c):
        """d(vehicle lines)/d(load position) for crossing ``c`` (S, K): exact, from the interpolant."""
        x, r, scale = state.positions[c], state.sensor_positions, float(state.ei_log_scale[c])
        key = self._lines_key(state, x, r, scale)
        if ("slope",) + key not in self._cache:
            self._fill(state, r, scale, {key: x}, jacobian=True)
        return self._cache[("slope",) + key]

    def _ramp(self, state, u):
        """The axles' entry ramps at elastic end bearings (see :func:`._entry.entry_ramp`)."""
        if not self.entry:
            return None
        vertical = state.bridge.vertical_springs
        return entry_ramp(u, state.bridge.length, self.entry,
                          (not np.isinf(vertical[0]), not np.isinf(vertical[-1])))

    def _vehicle(self, state):
        return Vehicle(self.case.vehicle.axle_offsets,
                       tuple(np.asarray(self.case.vehicle.axle_loads) * state.axle_factors))

    def axle_lines(self, state, c, axle):
        """Response to axle ``axle`` alone (with its current load), cached like :meth:`lines`."""
        x, r, scale = state.positions[c], state.sensor_positions, float(state.ei_log_scale[c])
        key = _axle_key(state, x, axle, r, scale)
        if key not in self._cache:
            self._fill(state, r, scale, {self._lines_key(state, x, r, scale): x}, jacobian=True)
        return self._cache[key] * (self.case.vehicle.axle_loads[axle] * state.axle_factors[axle])


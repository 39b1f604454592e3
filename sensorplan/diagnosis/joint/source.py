"""The vehicle's lines of every crossing at a model state: the part of the joint model that reads the interpolant.

:class:`LineSource` turns a model state (EI, springs, load and sensor
positions, axle loads, a crossing's own EI factor) into each crossing's
lines.  Everything that does not depend on EI is kept across evaluations:
the interpolant's element products (:mod:`sensorplan.model.interpolant`)
and here the sparse interpolation maps of the load positions.

Owns: :class:`LineSource`.  May import: the model layer, the cache.
"""

import numpy as np

from ..._cache import value_key
from ...model.interpolant import LineInterpolant
from ...model.sensors import SensorLayout
from .entry import entry_ramp
from .lines import CrossingLines, InterpolationMaps

__all__ = ["LineSource"]


class LineSource:
    """The lines of every crossing at a model state, for :class:`~.problem.JointProblem` (a mixin).

    Uses the problem's ``case``, ``sensors``, ``n_crossings``, ``entry``,
    ``entry_moves``, ``axle_responses``, the EI of the current evaluation
    ``current_ei`` and its value key ``ei_key``, and the problem's ``cache``
    (a :class:`~sensorplan._cache.Cache`): everything computed at an EI is
    keyed by it, the interpolation maps (independent of EI) are not.
    """

    # keys are tuples of value keys: the current EI's is formed once per evaluation, and a crossing's parts at
    # the state's own sensor positions once per state (state.keys), not walked again at every look-up
    def _parts(self, state, x, r, scale, kind):
        """Value key of what crossing lines at positions ``x`` and sensors ``r`` depend on besides EI and the bridge.

        ``kind`` "lines": with the axle factors; "axle": without (a unit load).
        """
        if kind == "lines":
            return value_key(x, r, state.axle_factors, scale)
        return value_key(x, r, scale)

    def _crossing_parts(self, state, c, kind):
        """:meth:`_parts` of crossing ``c`` at the state's own positions and sensors (formed once per state)."""
        parts = state.keys.get((kind, c))
        if parts is None:
            parts = state.keys[kind, c] = self._parts(state, state.positions[c], state.sensor_positions,
                                                      float(state.ei_log_scale[c]), kind)
        return parts

    def _lines_key(self, state, c, r=None, x=None):
        """Cache key of crossing ``c``'s lines (or at positions ``x``, sensors ``r``) at the current EI."""
        if r is None and x is None:
            parts = self._crossing_parts(state, c, "lines")
        else:
            parts = self._parts(state, state.positions[c] if x is None else x,
                                state.sensor_positions if r is None else r, float(state.ei_log_scale[c]), "lines")
        return "lines", self.ei_key, parts, state.bridge

    def _axle_key(self, state, c, axle, r=None):
        """Cache key of one axle's unit-load response in crossing ``c`` (independent of the axle loads)."""
        parts = (self._crossing_parts(state, c, "axle") if r is None else
                 self._parts(state, state.positions[c], r, float(state.ei_log_scale[c]), "axle"))
        return "axle", self.ei_key, parts, axle, state.bridge

    def _interpolant_key(self, state, r, scale):
        return "interpolant", self.ei_key, value_key(r, scale), state.bridge

    def interpolant(self, state, scale, sensor_positions=None):
        """The exact piecewise-cubic unit-load lines at the current EI (x exp(scale)), cached per EI and state."""
        r = state.sensor_positions if sensor_positions is None else sensor_positions
        key = self._interpolant_key(state, r, scale)
        return self.cache.get((), lambda: self._new_interpolant(state, scale, r), key=key)

    def _new_interpolant(self, state, scale, r):
        # a crossing's own EI factor (load-dependent stiffness) needs no solve without elastic springs
        scaled = None if scale == 0.0 else self.interpolant(state, 0.0, r).scaled(np.exp(scale))
        if scaled is None:
            sensors = SensorLayout(r, self.sensors.kinds, self.sensors.names)
            scaled = LineInterpolant(state.bridge, self.case.mesh, self.current_ei * np.exp(scale), sensors)
        return scaled

    def _held(self, key):
        """The cache's entry under ``key``, or None."""
        return self.cache.lookup((), key=key)[1]

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
        key = self._lines_key(state, c, sensor_positions, positions)
        held = self._held(key)
        if held is None:
            if positions is None:  # every crossing at these sensor positions at once (sensor-position Jacobian)
                self.prefetch(state, sensor_positions=sensor_positions)
            else:
                self._fill(state, r, float(state.ei_log_scale[c]), {key: (c, x)})
            held = self._held(key)
        return held

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
            key = self._lines_key(state, c, sensor_positions)
            missing = self._held(key) is None or jacobian and (
                (self.entry_moves and self._held(("slope", key)) is None)
                or (self.axle_responses and self._held(self._axle_key(state, c, 0, sensor_positions)) is None))
            if missing:
                groups.setdefault(scale, {})[key] = (c, state.positions[c])
        for scale, items in groups.items():
            self._fill(state, r, scale, items, jacobian, sensor_positions=sensor_positions)

    def _fill(self, state, r, scale, items, jacobian=False, *, sensor_positions=None):
        """Cache the lines of every {key: (crossing, positions)} in ``items`` (one sparse product).

        With ``jacobian``, also their slopes in the load position (when an
        effect moves the loads) and each axle's own response (axle loads).
        ``sensor_positions``: None when ``r`` are the state's own.
        """
        interpolant = self.interpolant(state, scale, r)
        every = np.concatenate([x for _, x in items.values()])
        maps = self._maps(interpolant, state, every, jacobian)
        # lines already read at these positions (the trial point a Jacobian is now asked at) are kept
        new = any(self._held(key) is None for key in items)
        if new:
            predictions, reactions = interpolant.readings_and_reactions(maps.lines)
        slopes = interpolant.readings(maps.slopes) if jacobian and maps.slopes is not None else None
        axles = [interpolant.readings(w) for w in (maps.axles or ())] if jacobian else []
        ei, stiffness = self.current_ei * np.exp(scale), state.bridge.spring_stiffness()
        source = (self._interpolant_key(state, r, scale), maps.cache_key)
        start = 0
        for key, (c, x) in items.items():
            sl = slice(start, start + x.size)
            start += x.size
            if new:
                self.cache.put((), CrossingLines(interpolant, maps, sl, ei, stiffness, predictions[:, sl],
                                                       reactions[sl], cache_key=key, source_key=source), key=key)
            if slopes is not None:
                self.cache.put((), slopes[:, sl], key=("slope", key))
            for a, unit in enumerate(axles):
                self.cache.put((), unit[:, sl], key=self._axle_key(state, c, a, sensor_positions))

    def _maps(self, interpolant, state, every, jacobian):
        """The interpolation maps of the loads at ``every``: lines, and with ``jacobian`` slopes and each axle.

        They depend on the positions, the breakpoints, the axle loads and
        which end bearings are elastic, not on EI: kept across evaluations.
        """
        offsets, loads = self._axles(state)
        vertical = state.bridge.vertical_springs
        key = value_key("maps", interpolant.points, every, loads, bool(np.isinf(vertical[0])),
                        bool(np.isinf(vertical[-1])))

        def build():
            basis = interpolant.basis(every[:, None] - offsets[None, :])  # every axle at once
            structure = interpolant.structure(basis)
            lines = self._weights(interpolant, state, every, basis, offsets, loads, structure=structure)
            return InterpolationMaps(key, every.size, basis, structure, lines)

        maps = self.cache.get((), build, key=key)
        if jacobian and self.entry_moves and maps.slopes is None:
            maps.slopes = self._weights(interpolant, state, every, maps.basis, offsets, loads,
                                        structure=maps.structure, derivative=True)
        if jacobian and self.axle_responses and maps.axles is None:
            i, value, slope = maps.basis
            maps.axles = [self._weights(interpolant, state, every, (i[:, a:a + 1], value[:, a:a + 1],
                                                                    slope[:, a:a + 1]), offsets[a:a + 1], np.ones(1))
                          for a in range(offsets.size)]
        return maps

    def _axles(self, state):
        return (np.asarray(self.case.vehicle.axle_offsets, float),
                np.asarray(self.case.vehicle.axle_loads, float) * state.axle_factors)

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

    def line_slopes(self, state, c):
        """d(vehicle lines)/d(load position) for crossing ``c`` (S, K): exact, from the interpolant."""
        key = self._lines_key(state, c)
        held = self._held(("slope", key))
        if held is None:
            self._fill(state, state.sensor_positions, float(state.ei_log_scale[c]), {key: (c, state.positions[c])},
                       jacobian=True)
            held = self._held(("slope", key))
        return held

    def _ramp(self, state, u):
        """The axles' entry ramps at elastic end bearings (see :func:`.entry.entry_ramp`)."""
        if not self.entry:
            return None
        vertical = state.bridge.vertical_springs
        return entry_ramp(u, state.bridge.length, self.entry,
                          (not np.isinf(vertical[0]), not np.isinf(vertical[-1])))

    def axle_lines(self, state, c, axle):
        """Response to axle ``axle`` alone (with its current load), cached like :meth:`lines`."""
        key = self._axle_key(state, c, axle)
        held = self._held(key)
        if held is None:
            self._fill(state, state.sensor_positions, float(state.ei_log_scale[c]),
                       {self._lines_key(state, c): (c, state.positions[c])}, jacobian=True)
            held = self._held(key)
        return held * (self.case.vehicle.axle_loads[axle] * state.axle_factors[axle])

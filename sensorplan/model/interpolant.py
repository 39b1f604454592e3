"""Influence lines as exact piecewise-cubic functions of the load position.

By reciprocity the reading of sensor r under a unit point load at x is the
deflection at x caused by the sensor's unit action, and its element integrals
int_j m_r M(s; x) ds are the deflections at x caused by the curvature m_r v
imposed on element j alone.  Curvature is piecewise linear between the mesh
edges and the sensor positions, so every one of these functions of x is a
cubic between those breakpoints (and C1 across them): Hermite interpolation
from the values and slopes at the breakpoints is exact.  The slope in x of
the response to a point load is the response to a unit couple at x
(d/dp of the ramp w (s - p)_+ is the step -w H(s - p)), so one force-method
solve with a unit load and a unit couple at every breakpoint gives the lines
at any load position -- and their derivative in it -- without a new solve.

Used where load positions change from one evaluation to the next (a fitted
position offset, each axle's response): the cost per EI is 2 x (breakpoints)
load cases instead of (crossings x positions x axles).  And not even those:
the free-body diagrams of the table rows and of the sensors, and their
element products with each other and with the unknown reactions' diagrams,
do not depend on EI (:class:`_Tables`, kept per support layout, mesh and
sensors); at a new EI or spring stiffness the actual kernels follow from the
force method's small solve for the unknowns and three matrix products.

Owns: the interpolant.  May import: the force method and the foundations.
"""

import copy

import numpy as np
import scipy.sparse

from .diagrams import RAMP, STEP, element_products, end_value_and_slope, point_actions
from .force_method import SharedCache, shared_force_method
from .forward import expand_ei, sensor_actions

__all__ = []

_MERGE = 1e-9  # m: a sensor this close to a mesh edge shares its breakpoint


def _hermite(t, h):
    """Hermite basis (values) and its x-derivative at fractions ``t`` of intervals of length ``h`` (last axis: 4)."""
    t2, t3 = t * t, t * t * t
    value = np.stack([2 * t3 - 3 * t2 + 1, (t3 - 2 * t2 + t) * h, -2 * t3 + 3 * t2, (t3 - t2) * h], axis=-1)
    slope = np.stack([(6 * t2 - 6 * t) / h, 3 * t2 - 4 * t + 1, (-6 * t2 + 6 * t) / h, 3 * t2 - 2 * t], axis=-1)
    return value, slope


class _Tables:
    """The interpolant's EI-independent element products, for one frame, mesh and sensor layout.

    The free-body diagrams of a unit load and a unit couple at every
    breakpoint (the table rows) and of the sensors' unit actions, and the
    element integrals of their products with each other and with the
    unknowns' diagrams: a new EI or spring stiffness then costs small
    solves and matrix products, not new diagrams.
    """

    def __init__(self, frame, edges, sensors):
        points = np.union1d(edges, sensors.positions)
        keep = np.concatenate([[True], np.diff(points) > _MERGE])
        points = points[keep]
        points[-1] = edges[-1]
        n = points.size
        self.points = points
        # a unit downward load (ramp of weight -1) and its derivative in position (step of weight +1)
        where = np.concatenate([points, points])[:, None]
        weights = np.concatenate([np.full(n, -1.0), np.full(n, 1.0)])[:, None]
        kinds = np.concatenate([np.full(n, RAMP), np.full(n, STEP)])[:, None]
        loads = point_actions(edges, where, weights, kinds)
        actions = sensor_actions(sensors)
        units = point_actions(edges, *actions)
        self.load_ends = end_value_and_slope(frame.length, where, weights, kinds)
        self.sensor_ends = end_value_and_slope(frame.length, *actions)
        self.free = np.ascontiguousarray(element_products(edges, units, loads).transpose(1, 0, 2))  # (2n, S, E)
        self.basis_loads = element_products(edges, frame.basis, loads)  # (n_u, 2n, E)
        self.basis_sensors = element_products(edges, frame.basis, units)  # (n_u, S, E)


_TABLES = SharedCache(8)  # each (2n, S, E) doubles: a few MB at most for a diagnosis-sized case


class LineInterpolant:
    """Unit point-load lines of ``sensors`` on ``bridge`` at ``ei``, exact at any load position.

    Parameters
    ----------
    bridge, mesh, ei, sensors
        As for :func:`~sensorplan.model.forward.influence_lines`.

    Notes
    -----
    :meth:`unit` returns what ``influence_lines`` returns for
    ``Vehicle.point_load(1.0)`` (predictions, kernel, spring kernel) to
    round-off; a load off the bridge gives zero.
    """

    def __init__(self, bridge, mesh, ei, sensors):
        ei = expand_ei(bridge, mesh, ei)
        method = shared_force_method(bridge, mesh, ei)
        edges = mesh.edges
        tables = _TABLES.get((method.frame.key, sensors.positions, tuple(sensors.kinds)),
                             lambda: _Tables(method.frame, edges, sensors))
        v, n_u = method.v, method.n_u
        n_sensors, n_rows, n_elements = tables.free.shape[1], tables.free.shape[0], edges.size - 1
        # the actual diagrams are the free ones plus the unknowns' diagrams b x: for sensor r and table row l,
        # int_j (m0_r + b x_r)(M0_l + b x_l) = free + x_r.(b M0_l) + x_l.(b m0_r) + x_r.(b b).x_l per element j
        loads = method.redundants(tables.basis_loads @ v, *tables.load_ends)  # (n_u, 2n), scaled
        units = method.redundants(tables.basis_sensors @ v, *tables.sensor_ends)  # (n_u, S)
        mixed = tables.basis_sensors.transpose(1, 0, 2) + np.einsum("us,uve->sve", units, method.frame.products)
        kernel = (tables.free
                  + (units.T @ tables.basis_loads.reshape(n_u, -1)).reshape(n_sensors, n_rows, n_elements)
                  .transpose(1, 0, 2)
                  + (loads.T @ mixed.transpose(1, 0, 2).reshape(n_u, -1)).reshape(n_rows, n_sensors, n_elements))
        load_reactions = loads * method.scale[:, None]
        sensor_reactions = units * method.scale[:, None]
        springs = method.spring_unknown
        self.bridge, self.length = bridge, float(bridge.length)
        self.points = tables.points
        self.n_sensors, self.n_elements = n_sensors, n_elements
        self.sensor_reactions = sensor_reactions[springs].T  # (S, n_springs)
        # tables over [values at the breakpoints, slopes at the breakpoints] (2n rows), read by weights()
        self._predictions = kernel @ v + np.einsum("ur,u,uk->kr", sensor_reactions, method.compliance,
                                                   load_reactions)  # (2n, S)
        self._kernel = kernel.reshape(n_rows, -1)  # (2n, S E)
        self._reactions = np.ascontiguousarray(load_reactions[springs].T)  # (2n, n_springs)
        self._both = np.concatenate([self._predictions, self._reactions], axis=1)  # (2n, S + n_springs)

    @property
    def kernel_table(self):
        """The kernel's tables over the breakpoints' values and slopes (2n, S E), as :meth:`kernel` reads them."""
        return self._kernel

    def scaled(self, factor):
        """The interpolant at EI x ``factor``, without a solve, on a bridge without elastic springs (else None).

        With rigid or free supports only, a uniform factor on EI leaves the
        moment diagrams unchanged (the redundants depend on ratios of EI) and
        divides every deflection and rotation by it.
        """
        if self._reactions.shape[1]:
            return None
        out = copy.copy(self)
        out._predictions = self._predictions / factor
        out._both = out._predictions  # no springs: no reactions beside the readings
        return out

    def weights(self, x, offsets=(0.0,), loads=(1.0,), *, derivative=False):
        """Sparse (N, 2n) map from the tables to a vehicle at reference positions ``x`` (or its x-derivative).

        ``offsets``, ``loads``: the axles (behind the reference axle, and their
        loads); an axle off the bridge contributes nothing.
        """
        x = np.asarray(x, dtype=float)
        offsets = np.asarray(offsets, dtype=float)
        basis = self.basis(x[:, None] - offsets[None, :])
        return self.combine(basis, np.asarray(loads, dtype=float), derivative=derivative)

    def combine(self, basis, loads, *, derivative=False, structure=None):
        """:meth:`weights` from the :meth:`basis` of every position and axle (shared by several combinations).

        ``loads``: one per axle (A,), or one per position and axle (N, A) (a
        load that varies along the sweep).  ``structure``: :meth:`structure`
        of ``basis``, when several combinations of it are formed.
        """
        i, value, slope = basis
        # a shared structure is copied: scipy may sort a matrix's indices in place
        cols, indptr = self.structure(basis) if structure is None else (structure[0].copy(), structure[1].copy())
        # built as CSR directly, row by row: the four Hermite weights of each axle (duplicates add up)
        vals = (slope if derivative else value) * loads[..., None]
        return scipy.sparse.csr_matrix((vals.ravel(), cols, indptr), shape=(i.shape[0], 2 * self.points.size))

    def structure(self, basis):
        """The column indices and row pointers of :meth:`combine`'s sparse weights of ``basis``."""
        i = basis[0]
        n = self.points.size
        cols = np.stack([i, n + i, i + 1, n + i + 1], axis=-1)  # (N, A, 4): a row's entries, axle by axle
        return cols.ravel(), np.arange(0, cols.size + 1, 4 * i.shape[1])

    def end_weights(self, before, after):
        """Sparse (N, 2n) weights of the responses to a unit load at x = 0 and x = L."""
        n = self.points.size
        rows = np.concatenate([np.arange(before.size)] * 2)
        cols = np.concatenate([np.zeros(before.size, int), np.full(after.size, n - 1)])
        return scipy.sparse.csr_matrix((np.concatenate([before, after]), (rows, cols)), shape=(before.size, 2 * n))

    def readings(self, weights):
        """Readings (S, N) of the loads described by ``weights``."""
        return np.asarray(weights @ self._predictions).T

    def kernel(self, weights):
        """Element kernels dy/dv (S, N, E) of the loads described by ``weights`` (v = 1/EI)."""
        count = weights.shape[0]
        return np.asarray(weights @ self._kernel).reshape(count, self.n_sensors, self.n_elements).transpose(1, 0, 2)

    def spring_terms(self, weights):
        """dy/dc (S, N, n_springs) of the elastic springs' compliances c = 1/k."""
        return self.sensor_reactions[:, None, :] * self.spring_reactions(weights)[None, :, :]

    def readings_and_reactions(self, weights):
        """:meth:`readings` and :meth:`spring_reactions` of ``weights`` in one sparse product."""
        both = np.asarray(weights @ self._both)
        return both[:, :self.n_sensors].T, both[:, self.n_sensors:]

    def spring_reactions(self, weights):
        """The elastic springs' reactions (N, n_springs) to the loads of ``weights``, in the units of the table.

        ``spring_terms`` is ``sensor_reactions[:, None, :] * spring_reactions(w)[None]``.
        """
        return np.asarray(weights @ self._reactions)

    def lines(self, weights):
        """(predictions (S, N), kernel (S, N, E), spring kernel (S, N, n_springs)) of ``weights``."""
        return self.readings(weights), self.kernel(weights), self.spring_terms(weights)

    def basis(self, x):
        """Interval index (N, A), Hermite weights and x-derivatives (N, A, 4) at ``x`` (N, A) (0 off the bridge).

        ``x``: every position (rows) of every axle (columns).
        """
        on = (x >= 0.0) & (x <= self.length)
        i = np.clip(np.searchsorted(self.points, x, side="right") - 1, 0, self.points.size - 2)
        h = self.points[i + 1] - self.points[i]
        t = np.clip((x - self.points[i]) / h, 0.0, 1.0)
        value, slope = _hermite(t, h)
        return i, value * on[..., None], slope * on[..., None]

    def unit(self, x):
        """(predictions, kernel, spring kernel) of a unit point load at each of ``x``."""
        return self.lines(self.weights(x))

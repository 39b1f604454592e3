"""Influence lines of fixed sensors and load positions at any EI: the EI-independent integrals formed once.

A fit evaluates the forward model (:func:`sensorplan.model.forward.influence_lines`)
at many EI and spring stiffnesses for the same sensors, vehicle and load
positions.  In the force method the actual moment diagrams are M = F + X^T b
(loads) and m = f + x^T b (the sensors' unit actions), with F, f the free-body
diagrams, b the unit diagrams of the unknown reactions and X, x the redundants,
which depend on EI only through a small solve.  Every element integral the
lines need is therefore a combination of EI-independent ones:

    int_e b_u M_k   = int_e b_u F_k + sum_w X_wk int_e b_u b_w,
    int_e m_s M_k   = int_e f_s F_k + sum_w X_wk int_e f_s b_w + sum_u x_us int_e b_u M_k,

and the right-hand sides of the redundants' solve are (int_e b F) @ v with
v = 1 / EI.  :class:`FixedLines` forms int f F, int b F and int b f exactly
(:func:`~sensorplan.model.diagrams.element_products`) once per sensors,
vehicle, positions and support layout (kept by value and shared by every
problem with the same inputs); an evaluation costs the force method's
factorisation at the new EI and a few small tensor contractions.  The lines
equal :func:`~sensorplan.model.forward.influence_lines`'s to rounding.

Owns: :class:`FixedLines`.  May import: model and the foundations.
"""

import numpy as np

from ..model.diagrams import element_products
from ..model.force_method import SharedCache, free_actions, shared_force_method
from ..model.forward import InfluenceLines, expand_ei, load_actions, sensor_actions

__all__ = ["FixedLines"]

_PRODUCTS = SharedCache(16)  # the EI-independent integrals of the last few (mesh, actions, support layout)


class FixedLines:
    """The influence lines of ``sensors`` for ``vehicle`` at ``positions`` on ``mesh``, at any EI (:meth:`at`).

    Parameters
    ----------
    bridge : Bridge
        Its length and supports (stiffnesses may differ at :meth:`at`).
    mesh : Mesh
    sensors : SensorLayout
    vehicle : Vehicle
    positions : array_like
        Reference-axle positions [m].
    """

    def __init__(self, bridge, mesh, sensors, vehicle, positions):
        mesh.check_fits(bridge)
        bridge.check_on_bridge(sensors.positions, "positions", "SensorLayout")
        self.mesh, self.sensors, self.vehicle = mesh, sensors, vehicle
        self.positions = np.asarray(positions, dtype=float)
        edges, length = mesh.edges, float(bridge.length)
        self.load_actions = (edges, length) + load_actions(bridge, vehicle, self.positions)
        self.unit_actions = (edges, length) + sensor_actions(sensors)
        self.loads = free_actions(*self.load_actions)  # free-body diagrams F and their end values
        self.units = free_actions(*self.unit_actions)  # free-body diagrams f of the sensors' unit actions
        self._last = (None, None)  # (frame, its products): a fit keeps one support layout

    def _products(self, method):
        """(int f F (S, K, E), int b F (U, K, E), int b f (U, S, E), int b b (U, U, E)) for ``method``'s frame."""
        frame = method.frame
        if self._last[0] is frame:
            return self._last[1]

        def make():
            edges = self.mesh.edges
            out = (element_products(edges, self.units[0], self.loads[0]),
                   element_products(edges, frame.basis, self.loads[0]),
                   element_products(edges, frame.basis, self.units[0]), frame.products)
            for arr in out[:3]:
                arr.setflags(write=False)
            return out

        products = _PRODUCTS.get(("fixed lines", frame.key, self.load_actions, self.unit_actions), make)
        self._last = (frame, products)
        return products

    def at(self, bridge, ei):
        """:class:`~sensorplan.model.forward.InfluenceLines` at ``ei`` (per element, per span or scalar) on ``bridge``."""
        ei = expand_ei(bridge, self.mesh, ei)
        method = shared_force_method(bridge, self.mesh, ei)
        unit_load, basis_load, basis_unit, basis_basis = self._products(method)
        v = method.v
        n_u, n_loads, n_el = basis_load.shape
        # the scaled unknowns of the loads (U, K) and of the sensors' unit actions (U, S), one solve
        ends = [np.concatenate([a, b]) for a, b in zip(self.loads[1], self.units[1])]
        x = method.redundants(np.hstack([basis_load @ v, basis_unit @ v]), *ends)
        x_load, x_unit = x[:, :n_loads], x[:, n_loads:]
        # int b_u M_k, then int m_s M_k (the kernel), as in the module docstring
        basis_actual = basis_load + np.matmul(basis_basis.transpose(0, 2, 1), x_load).transpose(0, 2, 1)
        kernel = (unit_load + np.matmul(basis_unit.transpose(1, 2, 0), x_load).transpose(0, 2, 1)
                  + (x_unit.T @ basis_actual.reshape(n_u, -1)).reshape(-1, n_loads, n_el))
        load_reactions = x_load * method.scale[:, None]  # physical R [N] and C [N m]
        unit_reactions = x_unit * method.scale[:, None]
        springs = method.spring_unknown
        spring_kernel = unit_reactions[springs].T[:, None, :] * load_reactions[springs].T[None, :, :]
        predictions = kernel @ v + np.einsum("ur,u,uk->rk", unit_reactions, method.compliance, load_reactions)
        for arr in (kernel, spring_kernel, predictions):
            arr.setflags(write=False)
        return InfluenceLines(bridge, self.mesh, self.sensors, self.vehicle, self.positions, ei,
                              bridge.spring_stiffness(), predictions, kernel, spring_kernel)

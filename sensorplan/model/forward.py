"""Exact forward model: influence lines of rotation and deflection, with Jacobians.

The beam is released into a free body loaded by the point actions (axle
loads, or the unit couple / unit force of a sensor) and by the support
reactions X: a vertical force R_i at every support and a couple C_i at every
support with a rotational spring (0 < k <= inf).  The reactions follow from
the principle of minimum complementary energy (force method)

    min_X  1/2 int M(s)^2 v(s) ds + 1/2 sum_u c_u X_u^2     s.t. equilibrium,

where M = M_0 + sum_u X_u b_u is the free-body moment (sagging positive),
v = 1/EI is piecewise constant and c_u = 1/k_u is the compliance of the
spring carrying X_u (0 when rigid).  It is a small equality-constrained
quadratic programme, solved exactly once for all load positions at once.

With the actual (indeterminate) moment diagrams M(s; z) of the load and m_r(s)
of the unit action conjugate to the sensor reading (unit couple for a
rotation, unit force for a deflection), the unit-load theorem gives

    y_r(z) = int m_r M v ds + sum_u c_u X_u^r X_u^z,

and, because both diagrams are the actual ones, the same element integrals
are the exact Jacobian: dy/dv_j = A_(r,z),j = int_element_j m_r M ds and
dy/dc_u = X_u^r X_u^z (the adjoint identity).  y is homogeneous of degree 1
in (v, c).

Signs: w(x) downward, theta = dw/dx, x from the left end.  Under a sagging
load a tiltmeter near a span's left support reads positive.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from .._errors import ConfigError
from .._threads import single_threaded
from .._validation import as_float_array
from .diagrams import (
    RAMP,
    STEP,
    Diagrams,
    element_products,
    weighted_products,
)
from .force_method import ForceMethod, shared_force_method
from .loads import LoadSweep, Vehicle
from .sensors import SensorLayout
from .structure import Bridge, Mesh

__all__ = ["InfluenceLines", "influence_lines", "readings", "response_change", "ZoneChanges", "bending_moments",
           "support_reactions", "expand_ei", "sensor_actions", "load_actions"]

PARAMETERISATIONS = ("compliance", "ei", "log_ei")


@dataclass(frozen=True, eq=False)
class InfluenceLines:
    """Predicted influence lines and their exact Jacobians.

    Attributes
    ----------
    predictions : ndarray, shape (n_sensors, n_loads)
        Sensor readings [rad or m] for each reference-axle position.
    kernel : ndarray, shape (n_sensors, n_loads, n_elements)
        Element integrals A = dy/dv with v = 1/EI (compliance Jacobian) [unit * N m^2].
    spring_kernel : ndarray, shape (n_sensors, n_loads, n_springs)
        dy/dc for the spring compliances c = 1/k of ``bridge.spring_parameters``.
    ei : ndarray, shape (n_elements,)
        The EI [N m^2] the lines were computed for.
    spring_stiffness : ndarray, shape (n_springs,)
    """

    bridge: Bridge
    mesh: Mesh
    sensors: SensorLayout
    vehicle: Vehicle
    positions: np.ndarray
    ei: np.ndarray
    spring_stiffness: np.ndarray
    predictions: np.ndarray
    kernel: np.ndarray
    spring_kernel: np.ndarray

    @property
    def n_sensors(self):
        return self.predictions.shape[0]

    @property
    def n_loads(self):
        return self.predictions.shape[1]

    @property
    def n_elements(self):
        return self.ei.size

    @property
    def n_springs(self):
        return self.spring_stiffness.size

    def jacobian(self, parameterisation="log_ei", *, springs=False):
        """Jacobian of the predictions, shape (n_sensors, n_loads, n_params).

        Parameters
        ----------
        parameterisation : {"compliance", "ei", "log_ei"}
            Derivative with respect to v = 1/EI [1/(N m^2)], EI [N m^2] or
            log EI (dimensionless), by the chain rules
            dy/dEI = -dy/dv / EI^2 and dy/dlog EI = -dy/dv / EI.
        springs : bool
            Append the derivatives with respect to the log stiffnesses of the
            elastic springs (dy/dlog k = -dy/dc / k).
        """
        jac = self.kernel * _chain_factor(self.ei, parameterisation)
        if springs:
            jac = np.concatenate([jac, self.spring_log_jacobian], axis=2)
        return jac

    @cached_property
    def spring_log_jacobian(self):
        """dy/dlog k for the elastic springs, shape (n_sensors, n_loads, n_springs)."""
        return -self.spring_kernel / self.spring_stiffness


def _chain_factor(ei, parameterisation):
    if parameterisation == "compliance":
        return np.ones_like(ei)
    if parameterisation == "ei":
        return -1.0 / ei**2
    if parameterisation == "log_ei":
        return -1.0 / ei
    raise ConfigError(
        f"The 'parameterisation' parameter must be one of {PARAMETERISATIONS}. "
        f"Got {parameterisation!r} instead.")


def expand_ei(bridge, mesh, ei):
    """EI per element from a scalar, one value per span, or one per element."""
    arr = as_float_array(ei, "ei", "the forward model")
    if arr.size == 1:
        arr = np.full(mesh.n_elements, float(arr[0]))
    elif arr.size == bridge.n_spans and arr.size != mesh.n_elements:
        arr = mesh.span_values(bridge, arr)
    elif arr.size != mesh.n_elements:
        raise ConfigError(
            f"The 'ei' parameter must be a scalar, one value per span ({bridge.n_spans}) or one "
            f"per element ({mesh.n_elements}). Got {arr.size} values instead.")
    arr = np.array(arr, dtype=float)
    if np.any(arr <= 0.0):
        raise ConfigError("The 'ei' parameter of the forward model must be positive everywhere. "
                          f"Got a minimum of {arr.min()!r} instead.")
    return arr


def sensor_actions(sensors):
    """Point actions (positions, weights, kinds), each (S, 1), of the sensors' unit couple or unit downward force."""
    kinds = np.array([STEP if k == "rotation" else RAMP for k in sensors.kinds])
    weights = np.where(kinds == STEP, 1.0, -1.0)  # unit couple / unit downward force
    return sensors.positions[:, None], weights[:, None], kinds[:, None]


def load_actions(bridge, vehicle, positions):
    """Point actions (positions, weights, kinds), each (n_loads, n_axles), of the vehicle's axles on the bridge."""
    axles = vehicle.axle_positions(positions)
    on = (axles >= 0.0) & (axles <= bridge.length)
    weights = np.where(on, -np.asarray(vehicle.axle_loads)[None, :], 0.0)
    axles = np.where(on, axles, 0.0)
    return axles, weights, np.full(axles.shape, RAMP)


def _check_inputs(bridge, mesh, sensors, positions):
    mesh.check_fits(bridge)
    if sensors is not None:
        bridge.check_on_bridge(sensors.positions, "positions", "SensorLayout")
    positions = positions.positions if isinstance(positions, LoadSweep) else positions
    return as_float_array(positions, "positions", "the load sweep")


@single_threaded
def influence_lines(bridge: Bridge, mesh: Mesh, ei: "ArrayLike", sensors: SensorLayout, vehicle: Vehicle,
                    positions: "ArrayLike") -> "InfluenceLines":
    """Influence lines of ``sensors`` for ``vehicle`` at reference-axle ``positions``.

    Parameters
    ----------
    bridge : Bridge
    mesh : Mesh
        Element mesh of EI; its edges must include every support.
    ei : float or array_like
        EI [N m^2]: scalar, one per span, or one per element.
    sensors : SensorLayout
    vehicle : Vehicle
    positions : LoadSweep or array_like
        Reference (front) axle positions [m].

    Returns
    -------
    InfluenceLines
        Predictions and exact Jacobians (exact for piecewise-constant EI).

    Examples
    --------
    >>> from sensorplan import Bridge, Mesh, SensorLayout, Vehicle
    >>> bridge = Bridge(spans=(20.0,))
    >>> lines = influence_lines(bridge, Mesh.uniform(bridge, 10), 1e10,
    ...                         SensorLayout([0.0]), Vehicle.point_load(1e5), [10.0])
    >>> # closed form P L^2 / (16 EI) for a central load on a simple span
    >>> bool(abs(lines.predictions[0, 0] - 1e5 * 20.0**2 / (16 * 1e10)) < 1e-15)
    True
    """
    positions = _check_inputs(bridge, mesh, sensors, positions)
    ei = expand_ei(bridge, mesh, ei)
    method, (sensor_diagrams, sensor_reactions), (load_diagrams, load_reactions) = _solved(
        bridge, mesh, ei, sensors, vehicle, positions)
    kernel = element_products(mesh.edges, sensor_diagrams, load_diagrams)
    springs = method.spring_unknown
    spring_kernel = sensor_reactions[springs].T[:, None, :] * load_reactions[springs].T[None, :, :]
    predictions = kernel @ method.v + _spring_readings(method, sensor_reactions, load_reactions)
    for arr in (kernel, spring_kernel, predictions):
        arr.setflags(write=False)
    return InfluenceLines(bridge, mesh, sensors, vehicle, np.asarray(positions), np.asarray(ei),
                          bridge.spring_stiffness(), predictions, kernel, spring_kernel)


def _solved(bridge, mesh, ei, sensors, vehicle, positions):
    """The force method at ``ei``, then (diagrams, reactions) of the sensors' unit actions and of the loads."""
    method = shared_force_method(bridge, mesh, ei)
    return (method, method.solve(*sensor_actions(sensors)),
            method.solve(*load_actions(bridge, vehicle, positions)))


def _spring_readings(method, sensor_reactions, load_reactions):
    """The springs' part sum_u c_u X_u^r X_u^z of the readings (S, K)."""
    return np.einsum("ur,u,uk->rk", sensor_reactions, method.compliance, load_reactions)


@single_threaded
def readings(bridge: Bridge, mesh: Mesh, ei: "ArrayLike", sensors: SensorLayout, vehicle: Vehicle,
             positions: "ArrayLike") -> np.ndarray:
    """Noise-free readings (n_sensors, n_loads): :func:`influence_lines`' predictions without the Jacobians.

    The element sums are matrix products (:func:`~.diagrams.weighted_products`),
    so many sensors and load positions on a fine mesh cost neither the time
    nor the memory of the (n_sensors, n_loads, n_elements) kernel.
    """
    positions = _check_inputs(bridge, mesh, sensors, positions)
    ei = expand_ei(bridge, mesh, ei)
    method, (sensor_diagrams, sensor_reactions), (load_diagrams, load_reactions) = _solved(
        bridge, mesh, ei, sensors, vehicle, positions)
    return (weighted_products(mesh.edges, sensor_diagrams, load_diagrams, method.v)
            + _spring_readings(method, sensor_reactions, load_reactions))


@single_threaded
def response_change(bridge: Bridge, mesh: Mesh, ei: "ArrayLike", changed_ei: "ArrayLike", sensors: SensorLayout,
                    vehicle: Vehicle, positions: "ArrayLike") -> np.ndarray:
    """Readings with ``changed_ei`` minus readings with ``ei``, shape (n_sensors, n_loads).

    Exact, and formed on the changed elements only: with m_r the actual
    diagram of the sensor's unit action at ``ei`` and M' the actual load
    diagram at ``changed_ei``, the self-equilibrated field M' - M does no
    virtual work on the compatible state of m_r, so

        y' - y = sum over the changed elements j of (v'_j - v_j) int_j m_r M' ds

    (v = 1/EI; the spring terms cancel).  Costs two force-method solves
    and the element integrals of the changed elements.
    """
    at = np.asarray(_check_inputs(bridge, mesh, sensors, positions), dtype=float)
    v0 = 1.0 / expand_ei(bridge, mesh, ei)
    dv = 1.0 / expand_ei(bridge, mesh, changed_ei) - v0
    changed = np.nonzero(dv != 0.0)[0]
    if changed.size == 0:
        return np.zeros((sensors.n_sensors, at.size))
    j0, j1 = int(changed[0]), int(changed[-1]) + 1
    loads, _ = ForceMethod(bridge, mesh, 1.0 / (v0 + dv)).solve(*load_actions(bridge, vehicle, at))
    units, _ = ForceMethod(bridge, mesh, 1.0 / v0).solve(*sensor_actions(sensors))
    return weighted_products(mesh.edges[j0:j1 + 1], _restrict(units, j0, j1), _restrict(loads, j0, j1), dv[j0:j1])


class ZoneChanges:
    """Exact reading changes when the EI of a few consecutive elements drops, for many such zones.

    The undamaged actual diagrams of the loads (M) and of the sensors' unit
    actions (m_r) are formed once on ``mesh``.  Lowering EI on the elements
    j0 .. j1 - 1 (compliance increase dv there) changes the redundants of the
    force method by delta with

        (K + E D E^T) delta = -E h,   D = int dv b b^T / ref,   h = int dv b M / ref

    (K the force method's optimality matrix, b its unknowns' unit diagrams,
    E the injection of the unknowns; the free-body diagrams and equilibrium
    rows do not change), so delta = -G (I + D G)^-1 h with G the unknowns'
    block of K^-1 (Woodbury), and, as in :func:`response_change`,

        y' - y = int dv m_r (M + delta^T b)

    with every integral over the zone's elements only: no force-method solve
    per zone.  Agrees with :func:`response_change` on a mesh holding the
    zone edges to rounding.
    """

    def __init__(self, bridge: Bridge, mesh: Mesh, ei: "ArrayLike", sensors: SensorLayout, vehicle: Vehicle,
                 positions: "ArrayLike"):
        at = np.asarray(_check_inputs(bridge, mesh, sensors, positions), dtype=float)
        self.mesh, self.ei = mesh, expand_ei(bridge, mesh, ei)
        self.method = method = shared_force_method(bridge, mesh, self.ei)
        self.loads, _ = method.solve(*load_actions(bridge, vehicle, at))
        self.units, _ = method.solve(*sensor_actions(sensors))
        self.g = scipy.linalg.lu_solve(method.lu, np.eye(method.n_u + 2))[:method.n_u, :method.n_u]

    def change(self, j0, j1, factor):
        """y' - y (n_sensors, n_loads) with EI times ``factor`` (> 0) on the elements j0 .. j1 - 1."""
        edges = self.mesh.edges[j0:j1 + 1]
        dv = (1.0 / factor - 1.0) / self.ei[j0:j1]
        units, loads, basis = (_restrict(d, j0, j1) for d in (self.units, self.loads, self.method.basis))
        ref = self.method.ref
        d = weighted_products(edges, basis, basis, dv) / ref
        h = weighted_products(edges, basis, loads, dv) / ref
        delta = -self.g @ np.linalg.solve(np.eye(d.shape[0]) + d @ self.g, h)
        return weighted_products(edges, units, loads, dv) + weighted_products(edges, units, basis, dv) @ delta


def _restrict(diagrams, j0, j1):
    """The diagrams on elements j0 .. j1 - 1 only (element indices renumbered from 0)."""
    keep = (diagrams.atom_elem >= j0) & (diagrams.atom_elem < j1)
    return Diagrams(diagrams.left[:, j0:j1], diagrams.right[:, j0:j1], diagrams.atom_func[keep],
                    diagrams.atom_elem[keep] - j0, diagrams.atom_pos[keep], diagrams.atom_kind[keep],
                    diagrams.atom_weight[keep])


def bending_moments(bridge, mesh, ei, vehicle, positions, x):
    """Actual bending moment [N m] (sagging positive) at ``x`` for each load position.

    Returns an array of shape (n_loads, len(x)); at a support couple the
    value right of the support is returned.
    """
    positions = _check_inputs(bridge, mesh, None, positions)
    method = shared_force_method(bridge, mesh, expand_ei(bridge, mesh, ei))
    diagrams, _ = method.solve(*load_actions(bridge, vehicle, positions))
    return diagrams.evaluate(mesh.edges, x)


def support_reactions(bridge, mesh, ei, vehicle, positions):
    """Support reactions for each load position.

    Returns ``(forces, couples)``: upward vertical reactions [N] of shape
    (n_loads, n_supports) and support couples [N m] of shape
    (n_loads, n_supports) (zero at pins).  A couple is the jump it causes in
    the sagging moment, left to right.
    """
    positions = _check_inputs(bridge, mesh, None, positions)
    method = shared_force_method(bridge, mesh, expand_ei(bridge, mesh, ei))
    _, reactions = method.solve(*load_actions(bridge, vehicle, positions))
    n_sup = bridge.support_positions.size
    forces = np.zeros((positions.size, n_sup))
    couples = np.zeros((positions.size, n_sup))
    for u in range(method.n_u):
        target = forces if method.kind[u] == RAMP else couples
        target[:, method.support[u]] = reactions[u]
    return forces, couples

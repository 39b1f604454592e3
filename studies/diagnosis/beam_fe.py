"""An independent beam model for effects outside the diagnosis's library: shear deformation and bearing lift-off.

The package's forward model is an Euler-Bernoulli beam solved by the force
method; the diagnosis's library extends it.  The effects here cannot be
written in that model, so the study simulates them with a model of its own:
a finite-element beam (two-node Timoshenko elements, exact for a constant
EI and shear rigidity kGA under end loads, Przemieniecki's stiffness with
phi = 12 EI / (kGA l^2); phi = 0 is the Euler-Bernoulli element), nodes
every ``step`` metres and at every support, sensor and EI edge, vertical
and rotational springs as the bridge has them (rigid: a penalty 1e6 times
the largest element stiffness).

A load between two nodes is split between them linearly (force and moment
kept); a reading is then the linear interpolation of its values for the
load at the nodes, so the influence lines are computed once per bridge, at
the nodes.

Readings: a tiltmeter reads the slope of the deck dw/dx = theta + gamma
(section rotation plus shear strain, the mean of the two elements at the
sensor's node); a deflection sensor reads w.  Signs as the package's: w
downward, x from the left end.

* :func:`shear_lines`: influence lines of a Timoshenko beam (shear
  deformation: the deck's shear flexibility adds gamma = V / kGA to the slope
  and its integral to the deflection).
* :func:`liftoff_readings`: readings of a vehicle on a beam one of whose
  bearings is a one-sided contact with a gap: it carries no reaction while
  the deck above it deflects less than the gap (light or distant load) and
  none in tension (the deck lifts off it when the load is on the next span).
"""

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

PENALTY = 1e6


def _nodes(bridge, sensors, ei_edges, step):
    """Node positions: a grid of about ``step`` and every support, sensor and EI edge (merged within 1 mm)."""
    length = bridge.length
    grid = np.linspace(0.0, length, int(np.ceil(length / step)) + 1)
    x = np.unique(np.concatenate([grid, bridge.support_positions, sensors.positions, ei_edges]))
    keep = np.concatenate([[True], np.diff(x) > 1e-3])
    x = x[keep]
    for forced in np.concatenate([bridge.support_positions, sensors.positions]):  # exact positions win the merge
        x[np.argmin(np.abs(x - forced))] = forced
    return x


def _element(ei, kga, length):
    """The 4 x 4 Timoshenko element stiffness (w1, theta1, w2, theta2) and its shear factor phi / (1 + phi)."""
    phi = 0.0 if not np.isfinite(kga) else 12.0 * ei / (kga * length**2)
    c = ei / ((1.0 + phi) * length**3)
    el = length
    k = c * np.array([[12, 6 * el, -12, 6 * el],
                      [6 * el, (4 + phi) * el**2, -6 * el, (2 - phi) * el**2],
                      [-12, -6 * el, 12, -6 * el],
                      [6 * el, (2 - phi) * el**2, -6 * el, (4 + phi) * el**2]])
    return k, phi / (1.0 + phi)


class BeamModel:
    """A beam on the bridge's supports, with EI from ``ei_at(x)`` and shear rigidity ``kga`` (inf: none).

    ``removed``: the index of a support left out (its vertical spring and
    rotational restraint), for the lift-off's free structure.
    """

    def __init__(self, bridge, ei_at, sensors, *, kga=np.inf, step=0.1, ei_edges=(), removed=None):
        self.bridge, self.sensors = bridge, sensors
        self.x = _nodes(bridge, sensors, np.asarray(ei_edges, float), step)
        n = self.x.size
        lengths = np.diff(self.x)
        ei = np.asarray(ei_at(0.5 * (self.x[1:] + self.x[:-1])), float)
        self.factors = np.empty(n - 1)
        rows, cols, vals = [], [], []
        index = np.arange(4)
        for e in range(n - 1):
            k, self.factors[e] = _element(ei[e], kga, lengths[e])
            rows.append(np.repeat(2 * e + index, 4))
            cols.append(np.tile(2 * e + index, 4))
            vals.append(k.ravel())
        stiffness = scipy.sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                            shape=(2 * n, 2 * n)).tolil()
        big = PENALTY * float(np.max(stiffness.diagonal()))
        for i, (xs, kv, kr) in enumerate(zip(bridge.support_positions, bridge.vertical_springs,
                                             bridge.rotational_springs)):
            if i == removed:
                continue
            j = int(np.argmin(np.abs(self.x - xs)))
            stiffness[2 * j, 2 * j] += big if not np.isfinite(kv) else kv
            stiffness[2 * j + 1, 2 * j + 1] += big if not np.isfinite(kr) else kr
        self.lengths = lengths
        self.lu = scipy.sparse.linalg.splu(stiffness.tocsc())
        self.sensor_nodes = np.array([int(np.argmin(np.abs(self.x - p))) for p in sensors.positions])

    def displacements(self, loads):
        """Nodal displacements (2 n, m) for downward nodal forces ``loads`` (n, m)."""
        rhs = np.zeros((2 * self.x.size, loads.shape[1]))
        rhs[0::2] = loads
        return self.lu.solve(rhs)

    def readings(self, u):
        """Sensor readings (S, m) of nodal displacements ``u`` (2 n, m)."""
        w, theta = u[0::2], u[1::2]
        gamma = self.factors[:, None] * (np.diff(w, axis=0) / self.lengths[:, None]
                                         - 0.5 * (theta[1:] + theta[:-1]))
        out = np.empty((self.sensors.n_sensors, u.shape[1]))
        last = self.x.size - 1
        for s, (j, kind) in enumerate(zip(self.sensor_nodes, self.sensors.kinds)):
            if kind == "rotation":
                sides = [gamma[e] for e in (j - 1, j) if 0 <= e < last]
                out[s] = theta[j] + np.mean(sides, axis=0)
            else:
                out[s] = w[j]
        return out

    def unit_lines(self):
        """Readings (S, n) and nodal deflections (n, n) for a unit downward load at each node."""
        u = self.displacements(np.eye(self.x.size))
        return self.readings(u), u[0::2]

    def vehicle(self, lines, vehicle, positions):
        """Readings of ``vehicle`` at reference-axle ``positions`` from node-wise unit ``lines`` (R, n)."""
        axles = vehicle.axle_positions(positions)
        out = np.zeros((lines.shape[0], axles.shape[0]))
        for k, load in enumerate(vehicle.axle_loads):
            a = axles[:, k]
            on = (a >= 0.0) & (a <= self.bridge.length)
            values = np.stack([np.interp(a, self.x, row) for row in lines])
            out += load * np.where(on[None, :], values, 0.0)
        return out


def shear_lines(bridge, ei_at, sensors, vehicle, positions, *, kga, ei_edges=(), step=0.1):
    """(Timoshenko readings, Euler-Bernoulli readings) of ``vehicle`` at ``positions``, each (S, m)."""
    out = []
    for k in (kga, np.inf):
        model = BeamModel(bridge, ei_at, sensors, kga=k, step=step, ei_edges=ei_edges)
        out.append(model.vehicle(model.unit_lines()[0], vehicle, positions))
    return out[0], out[1]


def liftoff_readings(bridge, ei_at, sensors, vehicle, positions, *, support, gap_fraction, ei_edges=(), step=0.1):
    """(readings with bearing ``support`` a one-sided contact with a gap, readings with it bearing), each (S, m).

    The gap is ``gap_fraction`` of the largest deflection above the bearing
    without it during the crossing.  The free structure (the bearing left
    out) is solved once; at each load position the bearing's reaction is
    R = max(0, w_free - gap) / (f + 1 / k) (f: the free structure's
    deflection there under a unit force; k: the bearing's vertical
    stiffness, rigid: 1 / k = 0), the readings y_free - R y_unit; with the
    bearing in full contact (no gap, tension allowed) R = w_free / (f + 1 / k).
    """
    model = BeamModel(bridge, ei_at, sensors, step=step, ei_edges=ei_edges, removed=support)
    lines, w = model.unit_lines()
    j = int(np.argmin(np.abs(model.x - bridge.support_positions[support])))
    free = model.vehicle(lines, vehicle, positions)
    w_free = model.vehicle(w[j:j + 1], vehicle, positions)[0]
    kv = bridge.vertical_springs[support]
    compliance = float(w[j, j]) + (0.0 if not np.isfinite(kv) else 1.0 / kv)
    gap = gap_fraction * float(np.max(w_free))
    lifted = free - (np.clip(w_free - gap, 0.0, None) / compliance)[None, :] * lines[:, j][:, None]
    bearing = free - (w_free / compliance)[None, :] * lines[:, j][:, None]
    return lifted, bearing

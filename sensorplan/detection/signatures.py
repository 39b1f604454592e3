"""Whitened damage signatures and nuisance columns, sensor by sensor.

A loss of ``severity`` s over exactly [c - l/2, c + l/2] is modelled on a
mesh whose edges are the case mesh's edges, the two zone edges and the
supports: nominal EI at the element midpoints, times (1 - s) inside the
zone (the zone is not snapped to the case's elements).  For sensor i:

* the *damage signature* s_i(c) is the whitened difference between the
  damaged and the undamaged noise-free readings of one crossing, with the
  exact forward model (not linearised);
* the *unit signature* u_i(c) is the whitened derivative of the readings
  with respect to r, the relative compliance increase over the zone
  (1/EI -> (1 + r)/EI there; a loss s is r = s / (1 - s)).  It is exact to
  first order and exact for statically determinate bridges, where the
  readings are linear in the compliance;
* the *nuisance* N_i is the whitened Jacobian, at the undamaged bridge, of
  what the detector must not mistake for damage: ``"levels"``, one common
  factor on each span's EI (d y / d log factor); ``"smooth"``, log EI =
  log EI_nominal + a + b xi + c xi^2 within each span, with xi the position
  relative to the span centre divided by the span length (derivatives with
  respect to a, b, c, i.e. the log-EI Jacobian columns weighted by the
  element averages of 1, xi, xi^2); in both cases also the log stiffness
  of every elastic support spring (0 < k < inf).

Whitening uses the noise model, AR(1) included: each sensor's readings are
whitened along the load positions and divided by its std, so that crossings
and sensors are independent with unit variance.  The optimal (matched
filter) detection statistic against the nuisance then has the
non-centrality d^2 = |P s|^2 per crossing, where P projects out the
nuisance columns; stacked over sensors and written with the Gram matrices
G_i = [s_i N_i]^T [s_i N_i] and A = sum_i w_i G_i it is the Schur complement
d^2 = A_ss - A_sN A_NN^+ A_Ns (:func:`schur_d_squared`), which a design
criterion can sum over any weighted layout.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .._threads import single_threaded
from ..model.forward import ZoneChanges, influence_lines
from ..model.structure import Mesh
from .nuisance import NUISANCES, nuisance_matrix

__all__ = ["NUISANCES", "Signatures", "SignatureModel", "whitened_signatures", "nuisance_jacobian", "schur_d_squared",
           "gram_matrices", "centre_grid", "zone_mesh_edges", "IDENTIFIABLE_RTOL"]

# Nuisance directions whose singular value, after scaling every column to unit
# norm, is below this fraction of the largest are taken as not identifiable
# from the layout and are not projected out (pseudo-inverse cut-off).
IDENTIFIABLE_RTOL = 1e-6
_CENTRES_PER_SOLVE = 64  # centres whose zone edges share one mesh for the unit signatures
_KERNEL_BYTES = 2**27  # influence-line kernel of one group of sensors (128 MiB) when the nuisance is formed
_LABELS = ("level", "slope", "curvature")


@dataclass(frozen=True, eq=False)
class Signatures:
    """Whitened signatures of local losses and the nuisance, per sensor, for one crossing.

    Attributes
    ----------
    centres : ndarray, shape (n_centres,)
        Centres of the damaged zones [m].
    damage : ndarray, shape (n_centres, n_sensors, n_loads)
        Whitened exact differences damaged - undamaged (dimensionless).
    unit : ndarray, shape (n_centres, n_sensors, n_loads)
        Whitened derivatives with respect to the relative compliance increase
        r over the zone (a loss s is r = s / (1 - s)).
    nuisance : ndarray, shape (n_sensors, n_loads, n_nuisance)
        Whitened nuisance Jacobian at the undamaged bridge.
    nuisance_names : tuple of str
        e.g. ``"span1_level"``, ``"span1_slope"``, ``"span1_curvature"``,
        ``"log_k_rotational_0"``.
    severity, length : float
        Loss fraction and zone length [m] of :attr:`damage`.
    """

    centres: np.ndarray
    damage: np.ndarray
    unit: np.ndarray
    nuisance: np.ndarray
    nuisance_names: tuple
    severity: float
    length: float

    @property
    def n_centres(self):
        return self.centres.size

    @property
    def n_sensors(self):
        return self.nuisance.shape[0]

    @property
    def n_nuisance(self):
        return self.nuisance.shape[2]

    def _signal(self, which):
        if which not in ("damage", "unit"):
            raise ConfigError(f"The 'which' parameter must be 'damage' or 'unit'. Got {which!r} instead.")
        return self.damage if which == "damage" else self.unit

    def grams(self, which="damage"):
        """Per-sensor Gram matrices G_i(c) = [s_i N_i]^T [s_i N_i].

        Returns an array of shape (n_sensors, n_centres, 1 + n_nuisance,
        1 + n_nuisance): entry [i, c] is G_i for centre c; index 0 is the
        signature, 1: the nuisance columns.  For a layout with weights w
        (e.g. crossings per sensor), d^2 = :func:`schur_d_squared` of
        sum_i w_i G_i.  ``which`` is ``"damage"`` (exact) or ``"unit"``.
        """
        return gram_matrices(self._signal(which), self.nuisance)

    def projected_norms(self, which="damage"):
        """|P s| over all sensors for each centre (one crossing), shape (n_centres,).

        P projects out the nuisance columns (stacked over sensors and load
        positions) by an SVD of the column-normalised nuisance, with the
        cut-off :data:`IDENTIFIABLE_RTOL`; it agrees with
        :func:`schur_d_squared` of the summed :meth:`grams`, but avoids
        squaring the condition number.
        """
        signal = self._signal(which).reshape(self.n_centres, -1)
        basis = _nuisance_basis(self.nuisance.reshape(-1, self.n_nuisance))
        residual = signal - (signal @ basis) @ basis.T
        return np.sqrt(np.einsum("ck,ck->c", residual, residual))


def gram_matrices(signal, nuisance):
    """Per-sensor Gram matrices [s_i N_i]^T [s_i N_i], shape (n_sensors, n_centres, 1 + n, 1 + n).

    ``signal`` (n_centres, n_sensors, n_loads) and ``nuisance`` (n_sensors,
    n_loads, n) are whitened (see :meth:`Signatures.grams`).
    """
    n_centres, n_sensors, _ = signal.shape
    n = nuisance.shape[2]
    out = np.empty((n_sensors, n_centres, n + 1, n + 1))
    out[:, :, 0, 0] = np.einsum("csk,csk->sc", signal, signal)
    cross = np.einsum("csk,skn->scn", signal, nuisance)
    out[:, :, 0, 1:] = cross
    out[:, :, 1:, 0] = cross
    out[:, :, 1:, 1:] = np.einsum("skm,skn->smn", nuisance, nuisance)[:, None]
    return out


def _nuisance_basis(columns):
    """Orthonormal basis of the identifiable span of ``columns`` (rows: data)."""
    norms = np.linalg.norm(columns, axis=0)
    seen = norms > 0.0
    if not np.any(seen):
        return np.zeros((columns.shape[0], 0))
    u, sv, _ = np.linalg.svd(columns[:, seen] / norms[seen], full_matrices=False)
    return u[:, sv > IDENTIFIABLE_RTOL * sv[0]]


def schur_d_squared(grams, weights=None):
    """d^2 = A_ss - A_sN A_NN^+ A_Ns with A = sum_i w_i G_i, per centre.

    Parameters
    ----------
    grams : ndarray, shape (n_sensors, n_centres, 1 + n, 1 + n)
        From :meth:`Signatures.grams`.
    weights : array_like, shape (n_sensors,), optional
        Weight of each sensor (default all ones; 0 drops a sensor).

    A_NN is inverted after scaling it to unit diagonal; a nuisance direction
    is projected out only if it is identifiable from the weighted layout
    (eigenvalue above IDENTIFIABLE_RTOL^2 of the largest); the others, and
    nuisance columns the layout does not see at all, are left out (a
    pseudo-inverse).  Returns an array of shape (n_centres,), >= 0.
    """
    grams = np.asarray(grams, dtype=float)
    weights = np.ones(grams.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    if weights.shape != grams.shape[:1]:
        raise ConfigError(f"The 'weights' parameter must have {grams.shape[0]} entries. "
                          f"Got shape {weights.shape} instead.")
    total = np.tensordot(weights, grams, axes=1)  # (C, 1 + n, 1 + n)
    a_ss = total[:, 0, 0]
    a_sn = total[:, 0, 1:]
    a_nn = total[:, 1:, 1:]
    diag = np.einsum("cnn->cn", a_nn)
    scale = np.where(diag > 0.0, 1.0 / np.sqrt(np.where(diag > 0.0, diag, 1.0)), 0.0)
    values, vectors = np.linalg.eigh(a_nn * scale[:, :, None] * scale[:, None, :])
    top = values.max(axis=1, keepdims=True)
    keep = values > IDENTIFIABLE_RTOL**2 * np.where(top > 0.0, top, np.inf)
    proj = np.einsum("cnm,cn->cm", vectors, a_sn * scale)
    explained = np.where(keep, proj**2 / np.where(keep, values, 1.0), 0.0).sum(axis=1)
    return np.maximum(a_ss - explained, 0.0)


def centre_grid(bridge_length, length, step):
    """Zone centres l/2, l/2 + step, ... up to L - l/2 [m]."""
    count = int(np.floor((bridge_length - length) / step + 1e-9)) + 1
    return length / 2 + step * np.arange(count)


def zone_mesh_edges(mesh, bridge, points):
    """The mesh's edges with ``points`` and the supports added (near-duplicates merged)."""
    tol = 1e-9 * max(1.0, bridge.length)
    base = mesh.edges
    extra = np.unique(np.concatenate([np.asarray(points, dtype=float).ravel(), bridge.support_positions]))
    idx = np.clip(np.searchsorted(base, extra), 1, base.size - 1)
    near = np.minimum(np.abs(extra - base[idx - 1]), np.abs(base[idx] - extra)) <= tol
    extra = extra[~near]
    if extra.size:
        extra = extra[np.concatenate([[True], np.diff(extra) > tol])]
    return np.union1d(base, extra)


def nuisance_jacobian(case, lines, nuisance):
    """Nuisance Jacobian (n_sensors, n_loads, n_nuisance) and names, from undamaged ``lines``.

    ``lines`` are the case's influence lines on ``case.mesh`` at nominal EI;
    the columns on log EI come from :func:`.nuisance.nuisance_matrix`.
    """
    bridge = case.bridge
    columns = lines.jacobian("log_ei") @ nuisance_matrix(bridge, case.mesh, nuisance)
    powers = (0,) if nuisance == "levels" else (0, 1, 2)
    names = [f"span{i + 1}_{_LABELS[p]}" for i in range(bridge.n_spans) for p in powers]
    names += [f"log_k_{name}" for name in bridge.spring_names]
    return np.concatenate([columns, lines.spring_log_jacobian], axis=2), tuple(names)


def _inside(edges, low, high):
    mid = 0.5 * (edges[1:] + edges[:-1])
    return (mid > low) & (mid < high)


def _zone_changes(case, sensors, positions, lows, highs):
    """(ZoneChanges on a mesh holding every zone's edges, the zones' element ranges (n_zones, 2))."""
    edges = zone_mesh_edges(case.mesh, case.bridge, np.concatenate([lows, highs]))
    mesh = Mesh(edges)
    changes = ZoneChanges(case.bridge, mesh, case.ei_at(mesh.midpoints), sensors, case.vehicle, positions)
    ranges = np.empty((lows.size, 2), dtype=int)
    for c, (low, high) in enumerate(zip(lows, highs)):
        inside = np.nonzero(_inside(edges, low, high))[0]
        ranges[c] = inside[0], inside[-1] + 1
    return changes, ranges


def _exact_differences(case, sensors, positions, lows, highs, severities):
    """Damaged minus undamaged readings, exact, per zone: (n_centres, S, K).

    :class:`~sensorplan.model.forward.ZoneChanges` forms the undamaged
    diagrams once, on a mesh holding every zone's edges, and each zone's
    change from its own elements' integrals (agrees with the difference of
    two full forward solves on that zone's mesh to ~1e-13 relative on the
    embedded examples).
    """
    changes, ranges = _zone_changes(case, sensors, positions, lows, highs)
    out = np.empty((lows.size, sensors.n_sensors, np.asarray(positions).size))
    for c, ((j0, j1), severity) in enumerate(zip(ranges, severities)):
        out[c] = changes.change(j0, j1, 1.0 - severity)
    return out


def _unit_signatures(case, sensors, positions, lows, highs):
    """dy/dr for a relative compliance increase r over each zone: (n_centres, S, K).

    One undamaged solve per group of zones, on a mesh holding all their edges:
    dy/dr = sum over the zone's elements of the element integrals times 1/EI.
    """
    out = np.empty((lows.size, sensors.n_sensors, positions.size))
    for start in range(0, lows.size, _CENTRES_PER_SOLVE):
        part = slice(start, start + _CENTRES_PER_SOLVE)
        edges = zone_mesh_edges(case.mesh, case.bridge, np.concatenate([lows[part], highs[part]]))
        mesh = Mesh(edges)
        ei = case.ei_at(mesh.midpoints)
        kernel = influence_lines(case.bridge, mesh, ei, sensors, case.vehicle, positions).kernel
        zones = np.array([_inside(edges, lo, hi) for lo, hi in zip(lows[part], highs[part])])
        out[part] = np.moveaxis(kernel @ (zones / ei).T, 2, 0)
    return out


class SignatureModel:
    """Whitened signatures of zones of ``length`` for one case, sensors, noise and nuisance.

    Holds the undamaged readings, the whitened nuisance Jacobian (computed
    once) and its identifiable basis, so that exact damaged readings can be
    evaluated for any centres and losses (per call, the undamaged diagrams
    once on a mesh holding every zone edge, and each zone's exact change
    from its own elements: :class:`~sensorplan.model.forward.ZoneChanges`).
    """

    def __init__(self, case, sensors, noise, nuisance, length):
        self.case, self.sensors, self.noise, self.length = case, sensors, noise, float(length)
        self.positions = case.sweep.positions
        # a group of sensors at a time: their influence-line kernel (sensors x loads x elements) is the
        # largest array here, and only its nuisance columns are kept
        group = max(1, _KERNEL_BYTES // (8 * self.positions.size * case.n_elements))
        reference, columns = [], []
        for start in range(0, sensors.n_sensors, group):
            part = sensors.subset(range(start, min(start + group, sensors.n_sensors)))
            lines = influence_lines(case.bridge, case.mesh, case.ei, part, case.vehicle, self.positions)
            reference.append(lines.predictions)
            cols, self.nuisance_names = nuisance_jacobian(case, lines, nuisance)
            columns.append(cols)
        self.reference = np.concatenate(reference)
        self.nuisance = noise.whiten(np.concatenate(columns), self.positions)
        self.basis = _nuisance_basis(self.nuisance.reshape(-1, self.nuisance.shape[2]))

    def _zones(self, centres):
        centres = np.asarray(centres, dtype=float)
        return centres - self.length / 2, centres + self.length / 2

    def damage(self, centres, severities):
        """Whitened exact differences (n_centres, S, K) for a loss ``severities`` (one per centre or scalar)."""
        lows, highs = self._zones(centres)
        severities = np.broadcast_to(np.asarray(severities, dtype=float), lows.shape)
        diff = _exact_differences(self.case, self.sensors, self.positions, lows, highs, severities)
        return self.noise.whiten(diff, self.positions, sensor_axis=1)

    def damage_each(self, centres, severity):
        """Whitened exact differences (S, K) of a loss ``severity`` at each of ``centres`` in turn (a
        generator: one centre's signatures at a time, the undamaged diagrams formed once)."""
        lows, highs = self._zones(centres)
        changes, ranges = _zone_changes(self.case, self.sensors, self.positions, lows, highs)
        for j0, j1 in ranges:
            yield self.noise.whiten(changes.change(j0, j1, 1.0 - severity), self.positions)

    def unit(self, centres):
        """Whitened dy/dr (n_centres, S, K), r the relative compliance increase over the zone."""
        lows, highs = self._zones(centres)
        unit = _unit_signatures(self.case, self.sensors, self.positions, lows, highs)
        return self.noise.whiten(unit, self.positions, sensor_axis=1)

    def projected_norms(self, whitened):
        """|P s| per centre over all sensors (one crossing), for whitened signals (n_centres, S, K)."""
        signal = whitened.reshape(whitened.shape[0], -1)
        residual = signal - (signal @ self.basis) @ self.basis.T
        return np.sqrt(np.einsum("ck,ck->c", residual, residual))


@single_threaded
def whitened_signatures(case, sensors, noise, centres, *, severity, length, nuisance="smooth"):
    """Whitened damage, unit and nuisance signatures of ``sensors`` for zones at ``centres``.

    Parameters
    ----------
    case : Case
        Bridge, mesh and nominal EI, vehicle and load sweep.
    sensors : SensorLayout
    noise : NoiseModel
        One std per sensor and the AR(1) correlation length.
    centres : array_like
        Zone centres [m]; each zone [c - length/2, c + length/2] must lie on the bridge.
    severity : float
        Fraction of EI lost in the zone, in (0, 1).
    length : float
        Zone length [m].
    nuisance : {"smooth", "levels"}

    Returns
    -------
    Signatures
        For one crossing.  The undamaged diagrams and the nuisance Jacobian
        are computed once; each centre costs its zone's element integrals.
    """
    centres = np.array(centres, dtype=float, ndmin=1)
    model = SignatureModel(case, sensors, noise, nuisance, length)
    arrays = (centres, model.damage(centres, severity), model.unit(centres), model.nuisance)
    for arr in arrays:
        arr.setflags(write=False)
    return Signatures(*arrays, model.nuisance_names, float(severity), float(length))

"""Structured Fisher blocks of candidate sensors from the force method (see :mod:`.algebra` for the structure).

The same numbers as :func:`sensorplan.model.fisher.fisher_blocks` (log-EI
parameters, optionally the springs' log-stiffnesses), up to round-off: the
kernel A_c[p, j] = int_j m_c M_p ds is split as in :mod:`.algebra` into the
reactions' unit diagrams times the sensor's scaled reactions, the load
moment's integrals against 1 and s on the elements after the sensor, and the
exact integral over the part of the sensor's own element after it.  Every
step is linear in the readings, so the whitening of a group of candidates
with the same noise parameters is applied once to the fixed matrices.

Owns: structured_fisher.  May import: model, design.blocks.
"""

import numpy as np

from ...model.fisher import fisher_blocks
from ...model.diagrams import STEP, Diagrams, element_products, point_actions
from ...model.force_method import shared_force_method
from ...model.forward import expand_ei, load_actions, sensor_actions
from .algebra import BlockFamily
from .structured import StructuredBlocks

__all__ = ["structured_fisher", "candidate_information"]


def structured_fisher(case, sensors, noise, *, n_crossings=1, springs=False):
    """:class:`StructuredBlocks` of ``sensors`` (a SensorLayout) with ``noise`` (a NoiseModel of them)."""
    bridge, mesh = case.bridge, case.mesh
    ei = expand_ei(bridge, mesh, case.ei)
    positions = np.asarray(case.sweep.positions, dtype=float)
    method = shared_force_method(bridge, mesh, ei)
    loads, load_reactions = method.solve(*load_actions(bridge, case.vehicle, positions))
    psi = _fixed_matrices(case, method, loads, load_reactions, ei, springs)
    x, weights, kinds = sensor_actions(sensors)
    _, reactions = method.solve(x, weights, kinds)
    elem = np.clip(np.searchsorted(mesh.edges, x[:, 0], side="right") - 1, 0, mesh.n_elements - 1)
    atom = np.where(kinds == STEP, np.hstack([weights, 0.0 * weights]), np.hstack([-weights * x, weights]))
    coef = np.hstack([(reactions / method.scale[:, None]).T, atom])
    partial = _partial_columns(mesh.edges, loads, x, weights, kinds, elem) * (-1.0 / ei[elem])[:, None]
    families = []
    for members in _noise_groups(noise):
        families.append(_family(psi, method.n_u, coef[members], elem[members], partial[members], members,
                                noise.subset([members[0]]), positions, n_crossings))
    return StructuredBlocks(families, sensors.n_sensors)


def candidate_information(case, cands, *, n_crossings=1, springs=False):
    """(StructuredBlocks of the candidates of a CandidateSet, the existing sensors' summed dense blocks), in log EI."""
    layout = cands.layout()
    noise = case.noise_for(layout)
    n = cands.n_candidates
    if noise is None:  # the error that names the missing noise level
        fisher_blocks(case, sensors=layout, parameterisation="log_ei")
    own = np.arange(n)
    blocks = structured_fisher(case, layout.subset(own), noise.subset(own), n_crossings=n_crossings, springs=springs)
    fixed = np.zeros((blocks.n_params, blocks.n_params))
    if layout.n_sensors > n:
        rest = np.arange(n, layout.n_sensors)
        fixed = fisher_blocks(case, sensors=layout.subset(rest), noise=noise.subset(rest), parameterisation="log_ei",
                              springs=springs, n_crossings=n_crossings).blocks.sum(axis=0)
    return blocks, fixed


def _fixed_matrices(case, method, loads, load_reactions, ei, springs):
    """Psi (A, n_loads, P): the reactions' element integrals (with the spring columns), then the load moment's
    integrals against 1 and s, in log-EI columns."""
    edges, n_el = case.mesh.edges, case.mesh.n_elements
    a, b = edges[:-1], edges[1:]
    n_springs = len(case.bridge.spring_parameters) if springs else 0
    n_u = method.n_u
    psi = np.zeros((n_u + 2, loads.n_funcs, n_el + n_springs))
    empty = np.zeros(0, dtype=int)
    lin = Diagrams(np.vstack([np.ones(n_el), a]), np.vstack([np.ones(n_el), b]), empty, empty, empty.astype(float),
                   empty, empty.astype(float))
    psi[:n_u, :, :n_el] = element_products(edges, method.basis, loads)
    psi[n_u:, :, :n_el] = element_products(edges, lin, loads)
    psi[:, :, :n_el] *= -1.0 / ei  # dy / dlog EI = -dy / dv / EI
    if n_springs:
        stiffness = case.bridge.spring_stiffness()
        for s, u in enumerate(method.spring_unknown):  # dy / dlog k = -X_u^r X_u^z / k
            psi[u, :, n_el + s] = -method.scale[u] * load_reactions[u] / stiffness[s]
    return psi


def _partial_columns(edges, loads, x, weights, kinds, elem):
    """(S, n_loads): int over [x, b_j] of the sensor's free-body atom times the load moment, j its element."""
    out = np.zeros((x.shape[0], loads.n_funcs))
    by_elem = np.argsort(loads.atom_elem, kind="stable")
    atom_elems = loads.atom_elem[by_elem]
    for j in np.unique(elem):
        sel = np.flatnonzero(elem == j)
        sub = edges[j:j + 2]
        k = by_elem[np.searchsorted(atom_elems, j, side="left"):np.searchsorted(atom_elems, j, side="right")]
        load_j = Diagrams(loads.left[:, j:j + 1], loads.right[:, j:j + 1], loads.atom_func[k],
                          np.zeros(k.size, dtype=int), loads.atom_pos[k], loads.atom_kind[k], loads.atom_weight[k])
        own = point_actions(sub, x[sel], weights[sel], kinds[sel])
        out[sel] = element_products(sub, own, load_j)[:, :, 0]
    return out


def _noise_groups(noise):
    """Candidates with the same noise parameters (one whitening each), as index arrays."""
    keys = np.column_stack([noise.std, noise.correlated_std, noise.correlation_time_s, noise.random_walk])
    _, group = np.unique(keys, axis=0, return_inverse=True)
    return [np.flatnonzero(group.ravel() == k) for k in range(int(group.max()) + 1)]


def _family(psi, n_u, coef, elem, partial, members, noise, positions, n_crossings):
    """One :class:`BlockFamily`: the fixed matrices and the partial columns whitened by the group's noise."""
    keep = _used(psi, coef, n_u)
    psi, coef, n_u = psi[keep], coef[:, keep], int(np.count_nonzero(keep[:n_u]))
    n_a, n_loads, p = psi.shape
    stack = np.concatenate([psi.transpose(1, 0, 2).reshape(n_loads, n_a * p), partial.T], axis=1)
    white = noise.whiten(stack[None], positions)[0] * np.sqrt(n_crossings)
    fixed, g = white[:, :n_a * p], white[:, n_a * p:]
    products = (fixed.T @ fixed).reshape(n_a, p, n_a, p)
    h = (fixed.T @ g).reshape(n_a, p, members.size)  # Psi_a^T g_c
    masked = np.arange(p)[None, :] > elem[:, None]
    cross = np.einsum("ca,apc->cp", coef[:, :n_u], h[:n_u]) + np.einsum("ca,apc->cp", coef[:, n_u:], h[n_u:]) * masked
    readings = np.ascontiguousarray(fixed.reshape(-1, n_a, p)[:, :n_u].transpose(1, 0, 2))  # the free Psi_a
    return BlockFamily(members, products, n_u, coef, elem, cross, np.einsum("lc,lc->c", g, g), readings)


def _used(psi, coef, n_u):
    """The fixed matrices a family uses (boolean over Psi's first axis): those with a coefficient not zero for
    some member and not zero themselves (e.g. the integral against s for rotations, or the diagram of a redundant
    without load moment).  The others add exact zeros to every block, so dropping them changes no sum and saves
    their share of every product over the structure; one free and one masked matrix are always kept."""
    keep = np.any(coef != 0.0, axis=0) & np.any(psi != 0.0, axis=(1, 2))
    for part in (slice(0, n_u), slice(n_u, None)):
        if not keep[part].any():
            keep[np.arange(keep.size)[part][0]] = True
    return keep

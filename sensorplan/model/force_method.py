"""The force method: support reactions by minimum complementary energy (see :mod:`.forward`).

It is split where EI enters.  :class:`_Frame` holds what depends on the
supports and the mesh only -- the unknown reactions, their moment diagrams,
the equilibrium rows and the element products of those diagrams -- and is
shared by every EI and spring stiffness.  :class:`ForceMethod` is the
factorised optimality system at one EI and set of stiffnesses; a fit, which
changes EI at every step, forms only that part again.  Both are kept for the
last few inputs (:class:`SharedCache`), so that the lines at one EI asked for
several times (the crossings' positions, the ends, each axle) cost one
factorisation.

Owns: the force method, :class:`SharedCache`.  May import: the diagrams and the foundations.
"""

import threading

import numpy as np
import scipy.linalg

from .._cache import Cache
from .._errors import ConfigError
from .diagrams import RAMP, STEP, element_products, end_value_and_slope, point_actions, weighted_products

__all__ = ["ForceMethod", "SharedCache", "shared_force_method", "free_actions"]


class SharedCache:
    """A :class:`~sensorplan._cache.Cache` of ``maxsize`` entries shared by threads (values made outside the lock).

    The model's module-level memos (frames, force methods, interpolant
    tables): threads of an executor may ask for the same inputs at once.
    """

    def __init__(self, maxsize):
        self.cache = Cache(maxsize=maxsize)
        self._lock = threading.Lock()

    def get(self, parts, make):
        """The value kept under the values ``parts`` (a tuple), made by ``make()`` if absent."""
        key = self.cache.key(parts)
        with self._lock:
            found, value = self.cache.lookup((), key=key)
        if found:
            return value
        value = make()
        with self._lock:
            self.cache.put((), value, key=key)
        return value

    def clear(self):
        """Forget every kept value."""
        with self._lock:
            self.cache.clear()


class _Frame:
    """The EI-independent part of the force method of one support layout on one mesh.

    Unknowns: R_i at every support, then C_i where a rotational restraint
    exists (0 < k <= inf); couples are scaled by the length so that all
    unknowns have comparable size.  ``products`` (n_u, n_u, n_elements) are
    the element integrals of the unknowns' unit diagrams.
    """

    def __init__(self, key, bridge, edges):
        self.key = key
        xs = bridge.support_positions
        has_couple = np.asarray(bridge.rotational_springs) > 0.0
        self.has_couple = has_couple
        self.length = bridge.length
        self.kind = np.concatenate([np.full(xs.size, RAMP), np.full(has_couple.sum(), STEP)])
        self.where = np.concatenate([xs, xs[has_couple]])
        self.support = np.concatenate([np.arange(xs.size), np.nonzero(has_couple)[0]])
        self.scale = np.where(self.kind == STEP, self.length, 1.0)
        self.n_u = n_u = self.kind.size
        self.basis = point_actions(edges, np.broadcast_to(self.where, (n_u, n_u)), np.diag(self.scale),
                                   np.broadcast_to(self.kind, (n_u, n_u)))
        self.products = element_products(edges, self.basis, self.basis)
        value_row = np.where(self.kind == RAMP, self.length - self.where, self.scale)
        slope_row = np.where(self.kind == RAMP, 1.0, 0.0)
        self.constraints = np.vstack([slope_row, value_row / self.length])


_FRAMES = SharedCache(16)


def _frame(bridge, edges):
    """:class:`_Frame` of ``bridge``'s supports on the mesh ``edges`` (shared by every EI and stiffness)."""
    key = ("frame", np.asarray(bridge.support_positions, float), np.asarray(bridge.rotational_springs) > 0.0, edges)
    return _FRAMES.get(key, lambda: _Frame(key, bridge, edges))


class ForceMethod:
    """Support reactions by minimum complementary energy, for one bridge and EI."""

    def __init__(self, bridge, mesh, ei):
        frame = _frame(bridge, mesh.edges)
        self.bridge, self.frame = bridge, frame
        self.edges = mesh.edges
        self.length = frame.length
        self.v = 1.0 / ei
        self.kind, self.where, self.support, self.scale = frame.kind, frame.where, frame.support, frame.scale
        self.basis, self.n_u = frame.basis, frame.n_u
        rot = np.asarray(bridge.rotational_springs)
        vert = np.asarray(bridge.vertical_springs)
        self.compliance = 1.0 / np.concatenate([vert, rot[frame.has_couple]])  # 0 for rigid restraints
        # Map each elastic spring parameter of the bridge to its unknown.
        self.spring_unknown = []
        for i, kind in bridge.spring_parameters:
            want = RAMP if kind == "vertical" else STEP
            self.spring_unknown.append(int(np.nonzero((self.support == i) & (self.kind == want))[0][0]))
        self.spring_unknown = np.array(self.spring_unknown, dtype=int)
        # Energy matrix and equilibrium rows (scaled).
        n_u = self.n_u
        self.v_ref = float(np.mean(self.v))
        self.ref = ref = self.v_ref * self.length**3
        energy = frame.products @ self.v + np.diag(self.compliance * self.scale**2)
        kkt = np.zeros((n_u + 2, n_u + 2))
        kkt[:n_u, :n_u] = energy / ref
        kkt[:n_u, n_u:] = frame.constraints.T
        kkt[n_u:, :n_u] = frame.constraints
        try:
            self.lu = scipy.linalg.lu_factor(kkt, check_finite=True)
        except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - defensive
            raise ConfigError(f"The bridge is not stable (singular equilibrium): {exc}") from exc
        cond = np.linalg.cond(kkt)
        if not np.isfinite(cond) or cond > 1e13:
            raise ConfigError(
                "The bridge is unstable or nearly so (the force-method system is singular, "
                f"condition number {cond:.2e}). Check the support springs.")

    def redundants(self, g, value, slope):
        """Scaled unknowns (n_u, n_funcs) of free-body diagrams M0 with int b_u M0 v ds = ``g``.

        ``value`` and ``slope``: M0 just beyond the right end (the equilibrium of the free beam).
        """
        rhs = np.vstack([-g / self.ref, -slope[None, :], -value[None, :] / self.length])
        return scipy.linalg.lu_solve(self.lu, rhs)[:self.n_u]

    def solve(self, positions, weights, kinds):
        """Actual diagrams and reactions for free-body atoms (n_funcs, n_actions)."""
        free, ends = free_actions(self.edges, self.length, positions, weights, kinds)
        g = weighted_products(self.edges, self.basis, free, self.v)  # (n_u, n_funcs)
        x_scaled = self.redundants(g, *ends)
        reactions = x_scaled * self.scale[:, None]  # physical R [N] and C [N m]
        return free.plus_linear(x_scaled.T @ self.basis.left, x_scaled.T @ self.basis.right), reactions


_FREE = SharedCache(32)  # the free-body diagrams of the last few sets of actions (loads, sensors)


def free_actions(edges, length, positions, weights, kinds):
    """Free-body diagrams of actions and their value and slope beyond the right end, kept by their values.

    They do not depend on EI: a fit asks for the same load positions and
    sensors at every EI it tries.
    """
    def make():
        free = point_actions(edges, positions, weights, kinds)
        for arr in (free.left, free.right, free.atom_func, free.atom_elem, free.atom_pos, free.atom_kind,
                    free.atom_weight):
            arr.setflags(write=False)
        return free, end_value_and_slope(length, positions, weights, kinds)

    return _FREE.get((edges, float(length), np.asarray(positions, dtype=float), np.asarray(weights, dtype=float),
                      np.asarray(kinds)), make)


_METHODS = SharedCache(8)  # the last few force methods, by (bridge, mesh, EI)


def shared_force_method(bridge, mesh, ei):
    """:class:`ForceMethod` of ``bridge`` at ``ei``, shared by calls at the same bridge, mesh and EI.

    A fit asks for the lines at one EI several times (the crossings' load
    positions, the ends, each axle): the factorisation is done once.
    """
    return _METHODS.get((bridge, mesh.edges, np.asarray(ei, dtype=float)), lambda: ForceMethod(bridge, mesh, ei))

"""Exact algebra of piecewise-linear bending-moment diagrams on an element mesh.

A family of ``n_funcs`` diagrams is stored per element ``j = [a_j, b_j]`` as
a linear part, given by its values at ``a_j`` (right limit) and ``b_j``, plus
*atoms* strictly inside elements: ramps ``w (s - p)_+`` (from point forces)
and steps ``w H(s - p)`` (from point couples).  Point actions at element
edges need no atom: they only change the linear part of later elements.

The product of two diagrams is piecewise quadratic, so its integral over an
element is exact in closed form: Simpson's rule for the linear parts,
explicit antiderivatives for the atoms.  This gives the paper's element
integrals A_(r,k),j = int_element m_r(s) M(s; z_k) ds (eq. A_entries_element).
"""

from dataclasses import dataclass

import numpy as np

__all__ = []

RAMP = 0
STEP = 1


@dataclass(frozen=True, eq=False)
class Diagrams:
    """A family of piecewise-linear functions on a mesh (internal)."""

    left: np.ndarray  # (n_funcs, n_elements) value of the linear part at a_j
    right: np.ndarray  # (n_funcs, n_elements) value of the linear part at b_j
    atom_func: np.ndarray  # (n_atoms,) function index
    atom_elem: np.ndarray  # (n_atoms,) element index
    atom_pos: np.ndarray  # (n_atoms,) position [m]
    atom_kind: np.ndarray  # (n_atoms,) RAMP or STEP
    atom_weight: np.ndarray  # (n_atoms,)

    @property
    def n_funcs(self):
        return self.left.shape[0]

    def plus_linear(self, left, right):
        """The same atoms with ``left``/``right`` added to the linear part."""
        return Diagrams(self.left + left, self.right + right, self.atom_func, self.atom_elem,
                        self.atom_pos, self.atom_kind, self.atom_weight)

    def evaluate(self, edges, x):
        """Values at positions ``x`` (right limits at jumps); shape (n_funcs, len(x))."""
        x = np.asarray(x, dtype=float)
        n_el = edges.size - 1
        j = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_el - 1)
        a, b = edges[j], edges[j + 1]
        t = (x - a) / (b - a)
        out = self.left[:, j] * (1.0 - t) + self.right[:, j] * t
        for f, e, p, kind, w in zip(self.atom_func, self.atom_elem, self.atom_pos,
                                    self.atom_kind, self.atom_weight):
            hit = (j == e) & (x >= p)
            if kind == RAMP:
                out[f, hit] += w * (x[hit] - p)
            else:
                out[f, hit] += w
        return out


def point_actions(edges, positions, weights, kinds):
    """Diagrams of free-body moments ``sum_a w_a phi(s - p_a)`` for each function.

    Parameters
    ----------
    edges : (n_elements + 1,) array
    positions, weights : (n_funcs, n_actions) arrays
        Atom positions [m] and weights; zero weights are ignored.
    kinds : (n_funcs, n_actions) int array of RAMP / STEP

    Returns
    -------
    Diagrams
    """
    positions = np.asarray(positions, dtype=float)
    weights = np.asarray(weights, dtype=float)
    kinds = np.broadcast_to(np.asarray(kinds), positions.shape)
    a = edges[:-1]
    b = edges[1:]
    n_el = a.size
    # An action at or left of an element's start adds w (s - p) (ramp) or w (step) to its linear part:
    # with S0 = sum of ramp weights, S1 = sum of ramp weights times positions and T = sum of step weights
    # over those actions, the values at a_j and b_j are a_j S0 - S1 + T and b_j S0 - S1 + T.  An action
    # at p counts for the elements from the first j with a_j >= p on: the sums are cumulative sums of
    # the weights scattered at those indices, (n_funcs, n_elements) work whatever the number of actions.
    n_funcs = positions.shape[0]
    first = np.searchsorted(a, positions, side="left")  # n_el: left of no element start
    flat = (np.arange(n_funcs)[:, None] * (n_el + 1) + first).ravel()
    is_ramp = (kinds == RAMP).ravel()
    w = weights.ravel()

    def cumulative(values):
        spread = np.bincount(flat, values, minlength=n_funcs * (n_el + 1)).reshape(n_funcs, n_el + 1)
        return np.cumsum(spread[:, :n_el], axis=1)

    s0 = cumulative(np.where(is_ramp, w, 0.0))
    t = cumulative(np.where(is_ramp, -w * positions.ravel(), w))  # T - S1
    left = a * s0 + t
    right = b * s0 + t
    elem = np.searchsorted(edges, positions, side="right") - 1
    inside = (weights != 0.0) & (elem >= 0) & (elem < n_el)
    elem_c = np.clip(elem, 0, n_el - 1)
    inside &= (positions > a[elem_c]) & (positions < b[elem_c])
    fi, ai = np.nonzero(inside)
    return Diagrams(left, right, fi, elem[fi, ai], positions[fi, ai], kinds[fi, ai].astype(int),
                    weights[fi, ai])


def end_value_and_slope(length, positions, weights, kinds):
    """Value and slope just beyond the right end of free-body atom sums.

    Returns arrays (n_funcs,) used by the equilibrium of the free beam.
    """
    positions = np.asarray(positions, dtype=float)
    weights = np.asarray(weights, dtype=float)
    ramp = np.broadcast_to(np.asarray(kinds), positions.shape) == RAMP
    value = np.where(ramp, weights * (length - positions), weights).sum(axis=1)
    slope = np.where(ramp, weights, 0.0).sum(axis=1)
    return value, slope


def _atom_linear_coefficients(a, b, p, kind):
    """Coefficients (c_left, c_right) with int_a^b l(s) atom(s) ds = c_left l(a) + c_right l(b)."""
    h = b - a
    big = b - p
    t = (p - a) / h
    is_ramp = kind == RAMP
    c_left = np.where(is_ramp, (1 - t) * big**2 / 2 - big**3 / (3 * h), (1 - t) * big - big**2 / (2 * h))
    c_right = np.where(is_ramp, t * big**2 / 2 + big**3 / (3 * h), t * big + big**2 / (2 * h))
    return c_left, c_right


def _atom_atom(b, p, kind_p, q, kind_q):
    """int_max(p,q)^b atom_p(s) atom_q(s) ds for unit weights (same element)."""
    m = np.maximum(p, q)
    big = b - m
    alpha = m - p
    beta = m - q
    rr = big**3 / 3 + (alpha + beta) * big**2 / 2 + alpha * beta * big
    rs = big**2 / 2 + alpha * big  # ramp at p, step at q
    sr = big**2 / 2 + beta * big  # step at p, ramp at q
    ss = big
    p_ramp = kind_p == RAMP
    q_ramp = kind_q == RAMP
    return np.where(p_ramp, np.where(q_ramp, rr, rs), np.where(q_ramp, sr, ss))


def element_products(edges, first, second, out=None):
    """Exact element integrals int_element f(s) g(s) ds for all pairs.

    Returns an array of shape (first.n_funcs, second.n_funcs, n_elements).
    """
    a = edges[:-1]
    b = edges[1:]
    h = b - a
    # Simpson (exact for the product of two linear functions).
    p_coef = (2.0 * second.left + second.right) * (h / 6.0)
    q_coef = (second.left + 2.0 * second.right) * (h / 6.0)
    shape = (first.n_funcs, second.n_funcs, h.size)
    if out is None:
        out = np.empty(shape)
    np.multiply(first.left[:, None, :], p_coef[None, :, :], out=out)
    tmp = first.right[:, None, :] * q_coef[None, :, :]
    out += tmp
    del tmp
    _add_atoms_times_linear(out, edges, first, second, transpose=False)
    _add_atoms_times_linear(out, edges, second, first, transpose=True)
    _add_atom_pairs(out, edges, first, second)
    return out


def weighted_products(edges, first, second, weights):
    """``element_products(edges, first, second) @ weights`` without the (n_first, n_second, n_elements) array.

    The sums over elements are matrix products, so a force-method solve of
    thousands of load positions costs (n_first x n_elements) x (n_elements x
    n_second) products instead of a three-index array.
    """
    a = edges[:-1]
    h = edges[1:] - a
    fl, fr = first.left * weights, first.right * weights
    # Simpson (exact for the product of two linear functions), summed over the elements
    out = (2.0 * fl + fr) @ (second.left * (h / 6.0)).T + (fl + 2.0 * fr) @ (second.right * (h / 6.0)).T
    _add_weighted_atoms(out, edges, first, second, weights, transpose=False)
    _add_weighted_atoms(out, edges, second, first, weights, transpose=True)
    _add_atom_pairs(out, edges, first, second, weights)
    return out


def _add_weighted_atoms(out, edges, atoms, linear, weights, *, transpose):
    if atoms.atom_func.size == 0:
        return
    # each atom times the other family's linear part on its element, weighted by its element's weight
    vals = weights[atoms.atom_elem][:, None] * _atoms_times_linear(edges, atoms, linear)
    if transpose:
        np.add.at(out.T, atoms.atom_func, vals)
    else:
        np.add.at(out, atoms.atom_func, vals)


def _add_atoms_times_linear(out, edges, atoms, linear, *, transpose):
    if atoms.atom_func.size == 0:
        return
    e = atoms.atom_elem
    vals = _atoms_times_linear(edges, atoms, linear)
    if transpose:
        np.add.at(out, (slice(None), atoms.atom_func, e), vals.T)
    else:
        np.add.at(out, (atoms.atom_func, slice(None), e), vals)


def _atoms_times_linear(edges, atoms, linear):
    """(n_atoms, linear.n_funcs): integral of each atom times each linear part over the atom's element."""
    e = atoms.atom_elem
    c_left, c_right = _atom_linear_coefficients(edges[e], edges[e + 1], atoms.atom_pos, atoms.atom_kind)
    return atoms.atom_weight[:, None] * (c_left[:, None] * linear.left[:, e].T
                                         + c_right[:, None] * linear.right[:, e].T)


def _add_atom_pairs(out, edges, first, second, weights=None):
    """Add the products of atoms sharing an element: to ``out`` (F, S, E), or weighted and summed over the
    elements to ``out`` (F, S) when ``weights`` (E,) is given."""
    if first.atom_func.size == 0 or second.atom_func.size == 0:
        return
    order = np.argsort(second.atom_elem, kind="stable")
    elems = second.atom_elem[order]
    lo = np.searchsorted(elems, first.atom_elem, side="left")
    hi = np.searchsorted(elems, first.atom_elem, side="right")
    counts = hi - lo
    if counts.sum() == 0:
        return
    i1 = np.repeat(np.arange(first.atom_func.size), counts)
    i2 = order[np.concatenate([np.arange(l, r) for l, r in zip(lo, hi)])]
    e = first.atom_elem[i1]
    vals = (first.atom_weight[i1] * second.atom_weight[i2]
            * _atom_atom(edges[e + 1], first.atom_pos[i1], first.atom_kind[i1],
                         second.atom_pos[i2], second.atom_kind[i2]))
    if weights is None:
        np.add.at(out, (first.atom_func[i1], second.atom_func[i2], e), vals)
    else:
        np.add.at(out, (first.atom_func[i1], second.atom_func[i2]), vals * weights[e])

"""The packed information of the detect criterion and the d^2 algebra on it.

A sensor's Gram matrix at damage centre c is G(c) = [s(c) N]^T [s(c) N]
(whitened damage signature s(c), whitened nuisance Jacobian N).  Its
nuisance block N^T N does not depend on the centre, so a sensor's
information over all centres is stored once, packed in one vector:

    [ s(c)^T s(c), s(c)^T N  for every centre c  |  N^T N ]
      n_centres x (1 + n) numbers                  n x n numbers

(:class:`PackedLayout`).  Sums over sensors (weighted or not) stay in this
form, so the placement problem's "precision" Q(w) = Q_0 + sum_i w_i I_i is
a vector of that length, and with A = Q(w), a_c its row at centre c
(a_ss, a_sN) and A_NN its common nuisance block

    d^2_c = a_ss(c) - a_sN(c) A_NN^+ a_Ns(c)

costs one factorisation of A_NN for all centres instead of one per centre.
The exact value (:func:`exact_d_squared`) follows
:func:`~sensorplan.detection.signatures.schur_d_squared`: A_NN scaled to unit
diagonal, a nuisance direction projected out only when identifiable; its
fast path is the Cholesky factor of the scaled A_NN (falling back to the
eigen-decomposition with the cut-off of ``schur_d_squared`` when a pivot is
below 1e-8).  The relaxation uses the ridged d^2 (A_NN + diag(ridge)),
smooth and concave in the weights, whose gradient along a sensor's packed
information b is u_c^T B(c) u_c with u_c = [1; -x_c], x_c = (A_NN + ridge)^-1
a_Ns(c), and whose Hessian is -2 R_c^T (A_NN + ridge)^-1 R_c with R_c the
nuisance rows of B(c) u_c.

Owns: the packed layout and its d^2 algebra.  May import: errors, detection.
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ...detection.signatures import schur_d_squared

__all__ = ["PackedLayout", "NuisanceFactors", "exact_d_squared", "exact_solution", "ridged_parts", "gradients",
           "HessianFactors"]

PIVOT_FLOOR = 1e-8  # a smaller pivot of the unit-diagonal nuisance block: eigen-decomposition with a cut-off


@dataclass(frozen=True)
class PackedLayout:
    """Where the centres' rows and the common nuisance block sit in a packed vector (module docstring)."""

    n_centres: int
    n_nuisance: int

    @property
    def size(self):
        return self.n_centres * (1 + self.n_nuisance) + self.n_nuisance**2

    @property
    def split(self):
        return self.n_centres * (1 + self.n_nuisance)

    def rows(self, q):
        """(..., n_centres, 1 + n): [a_ss, a_sN] per centre (a view)."""
        q = np.asarray(q)
        return q[..., :self.split].reshape(q.shape[:-1] + (self.n_centres, 1 + self.n_nuisance))

    def nuisance(self, q):
        """(..., n, n): the common nuisance block (a view)."""
        q = np.asarray(q)
        return q[..., self.split:].reshape(q.shape[:-1] + (self.n_nuisance, self.n_nuisance))

    def pack(self, rows, nuisance):
        """The packed vectors of ``rows`` (..., n_centres, 1 + n) and ``nuisance`` (..., n, n)."""
        lead = rows.shape[:-2]
        return np.concatenate([rows.reshape(lead + (-1,)), nuisance.reshape(lead + (-1,))], axis=-1)

    def dense(self, q):
        """(..., n_centres, 1 + n, 1 + n): the per-centre Gram matrices [[a_ss, a_sN], [a_Ns, A_NN]]."""
        rows, nn = self.rows(q), self.nuisance(q)
        m = 1 + self.n_nuisance
        out = np.empty(rows.shape[:-1] + (m, m))
        out[..., 0, :] = rows
        out[..., 1:, 0] = rows[..., 1:]
        out[..., 1:, 1:] = nn[..., None, :, :]
        return out


def _unit_scale(nn):
    """The nuisance blocks (..., n, n) scaled to unit diagonal (unseen directions: identity rows), the scales."""
    diag = np.diagonal(nn, axis1=-2, axis2=-1)
    seen = diag > 0.0
    scale = np.where(seen, 1.0 / np.sqrt(np.where(seen, diag, 1.0)), 0.0)
    scaled = nn * scale[..., :, None] * scale[..., None, :]
    idx = np.arange(diag.shape[-1])
    scaled[..., idx, idx] = 1.0
    return scaled, scale


def _cholesky(scaled):
    """Lower Cholesky factors of a stack (k, n, n) and the rows where it failed or a pivot is tiny."""
    try:
        chol = np.linalg.cholesky(scaled)
        bad = np.zeros(scaled.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        chol, bad = np.zeros_like(scaled), np.ones(scaled.shape[0], dtype=bool)
        for k, mat in enumerate(scaled):
            try:
                chol[k], bad[k] = np.linalg.cholesky(mat), False
            except np.linalg.LinAlgError:
                pass
    piv = np.diagonal(chol, axis1=-2, axis2=-1) ** 2
    return chol, bad | np.any(piv < PIVOT_FLOOR, axis=-1)


@dataclass(frozen=True, eq=False)
class NuisanceFactors:
    """The common nuisance blocks (k, n, n) of k packed vectors, factorised once for every centre.

    ``d_squared(rows)`` gives the exact d^2 of rows (k, g, 1 + n) at any g centres: with the unit-diagonal
    scaling D and the Cholesky factor L of D A_NN D, d^2 = a_ss (1 - |L^-1 D a_Ns|^2 / a_ss); a layout
    whose factorisation failed or has a pivot below PIVOT_FLOOR takes ``schur_d_squared`` (eigen-
    decomposition with its cut-off).
    """

    nn: np.ndarray
    scale: np.ndarray
    inverse: np.ndarray  # L^-1, (k, n, n)
    bad: np.ndarray

    @classmethod
    def of(cls, nn):
        scaled, scale = _unit_scale(nn)
        chol, bad = _cholesky(scaled)
        chol[bad] = np.eye(nn.shape[-1])
        return cls(nn, scale, np.linalg.inv(chol), bad)

    def d_squared(self, rows):
        a_ss = rows[..., 0]
        y = np.matmul(rows[..., 1:] * self.scale[:, None, :], self.inverse.transpose(0, 2, 1))
        explained = np.einsum("kcn,kcn->kc", y, y)
        positive = a_ss > 0.0
        d2 = np.where(positive, np.maximum(1.0 - explained / np.where(positive, a_ss, 1.0), 0.0) * a_ss, 0.0)
        if self.bad.any():
            n = self.nn.shape[-1]
            layout = PackedLayout(rows.shape[1], n)
            for k in np.nonzero(self.bad)[0]:
                d2[k] = schur_d_squared(layout.dense(layout.pack(rows[k], self.nn[k]))[None])
        return d2


def exact_d_squared(layout, q):
    """Exact d^2 (..., n_centres) of packed ``q`` (..., P), as ``schur_d_squared`` computes it."""
    q = np.asarray(q, dtype=float)
    flat = q.reshape(-1, layout.size)
    d2 = NuisanceFactors.of(layout.nuisance(flat)).d_squared(layout.rows(flat))
    return d2.reshape(q.shape[:-1] + (layout.n_centres,))


def exact_solution(layout, q):
    """(d^2, x) of one packed ``q``: d^2 as :func:`exact_d_squared`, x (n_centres, n) the nuisance
    coefficients with d^2 = [1; -x]^T A_c [1; -x] (pseudo-inverse with a 1e-12 relative cut-off)."""
    rows, nn = layout.rows(q), layout.nuisance(q)
    scaled, scale = _unit_scale(nn)
    vals, vecs = np.linalg.eigh(scaled)
    keep = vals > 1e-12 * vals.max() if vals.size else vals > 0
    p = (rows[:, 1:] * scale) @ vecs
    coef = np.where(keep, p / np.where(keep, vals, 1.0), 0.0)
    return exact_d_squared(layout, q), (coef @ vecs.T) * scale


def ridged_parts(layout, q, ridge, centres=None):
    """(ridged d^2 (n_c,), x (n_c, n), lower Cholesky factor of A_NN + diag(ridge)) of one packed ``q``,
    at ``centres`` (an index; default all); (None, None, None) if A_NN + ridge is not positive definite."""
    rows = layout.rows(q)
    rows = rows if centres is None else rows[centres]
    try:
        chol = np.linalg.cholesky(layout.nuisance(q) + np.diag(ridge))
    except np.linalg.LinAlgError:
        return None, None, None
    x = scipy.linalg.cho_solve((chol, True), rows[:, 1:].T).T
    return rows[:, 0] - np.einsum("cn,cn->c", rows[:, 1:], x), x, chol


def gradients(layout, blocks, x, centres=None):
    """u_c^T B_i(c) u_c (n_blocks, n_c) for packed ``blocks`` (n_blocks, P), u_c = [1; -x_c], at ``centres``."""
    rows = layout.rows(blocks)
    rows = rows if centres is None else rows[:, centres]
    v = np.concatenate([np.ones((x.shape[0], 1)), -2.0 * x], axis=1)
    out = np.einsum("icj,cj->ic", rows, v)
    n = layout.n_nuisance
    if n:
        out += layout.nuisance(blocks).reshape(-1, n * n) @ (x[:, :, None] * x[:, None, :]).reshape(-1, n * n).T
    return out


@dataclass(frozen=True, eq=False)
class HessianFactors:
    """Packed ``blocks`` (m, P) laid out for the Hessian of the ridged d^2, formed once for many points.

    ``rows`` (n, n_centres, m) holds b_Ns,i(c) and ``nuisance`` (n, n, m) B_NN,i, both with the block
    index last, so that the nuisance rows R_c = b_Ns,i(c) - B_NN,i x_c of every centre come out of one
    batched product in the layout of the roots (no transposed copy per point).
    """

    rows: np.ndarray
    nuisance: np.ndarray

    @classmethod
    def of(cls, layout, blocks):
        return cls(np.ascontiguousarray(layout.rows(blocks)[..., 1:].transpose(2, 1, 0)),
                   np.ascontiguousarray(layout.nuisance(blocks).transpose(1, 2, 0)))

    def roots(self, x, chol):
        """Y (n, n_c, m) with d^2 d^2_c / dw_i dw_j = -2 sum_a Y[a, c, i] Y[a, c, j], at the nuisance
        coefficients ``x`` (n_c, n) and the Cholesky factor of :func:`ridged_parts`; C-contiguous."""
        n = x.shape[1]
        r = self.rows - np.matmul(x[None], self.nuisance)  # (n, n_c, m): the transposed nuisance rows
        inverse = scipy.linalg.solve_triangular(chol, np.eye(n), lower=True)
        return (inverse @ r.reshape(n, -1)).reshape(r.shape)

"""Sums and inner products of a working set's structured Fisher blocks, many times over the same set.

The Newton-CG interior point (:mod:`.newton_cg`) applies S = sum_i v_i I_i
and <G, I_i> to the same working set a few hundred times.  The
:class:`~sensorplan.design.blocks.StructuredBlocks` forms give both in
O(A^2 P^2) from the family's fixed products X_ab (see
:mod:`sensorplan.design.blocks.algebra` for the algebra); here the products
are laid out once per working set in the order the contractions read them
(free-free pairs as rows of P^2, free-masked and masked-masked pairs last,
per column), so that each sum or inner product is a few matrix-vector
products and no transposed copy of the products is made per call.

Owns: WorkingBlocks.  May import: design.blocks.
"""

import numpy as np
import scipy.sparse

from ..blocks.sums import suffix_sums, sums_by_start

__all__ = ["WorkingBlocks"]


class _Family:
    """One :class:`~sensorplan.design.blocks.BlockFamily`'s members, with its products laid out for the
    contractions (``index`` the members' positions in the working set)."""

    def __init__(self, fam, dtype):
        x, f, p = fam.products.astype(dtype), fam.n_free, fam.n_params
        n_m = x.shape[0] - f
        self.index, self.f, self.p = np.asarray(fam.index), f, p
        self.coef, self.cross, self.own = fam.coef.astype(dtype), fam.cross.astype(dtype), fam.own.astype(dtype)
        self.elem, self.dtype = fam.elem, dtype
        self.start = fam.elem + 1
        # the free-free pairs enter as the symmetric S_ab = X_ab + X_ba (a < b) and S_aa = X_aa, flattened (the
        # sums and inner products are symmetric in (a, b): half the pairs; whole matrices: no triangle gathered)
        self.pairs = np.triu_indices(f)
        a, b = self.pairs
        sym = x[a, :, b, :] + np.where((a < b)[:, None, None], np.swapaxes(x[a, :, b, :], 1, 2), 0.0)
        self.uu = np.ascontiguousarray(sym.reshape(len(a), p * p))
        # um[j, i, (a, b)] = X_ab[i, j] (a free, b masked); mm[i, j, (a, b)] = X_ab[i, j] (both masked)
        self.um = np.ascontiguousarray(x[:f, :, f:, :].transpose(3, 1, 0, 2).reshape(p, p, f * n_m))
        mm = x[f:, :, f:, :].transpose(1, 3, 0, 2).reshape(p, p, n_m * n_m)
        upper = np.triu(np.ones((p, p)))[:, :, None]
        # mm[i, j] where j >= i, and (transposed: row j, column i) where i > j: each pair is reduced by a
        # stack of vector-matrix products over its smaller index, with no gathered copy
        self.mm_upper = np.ascontiguousarray(mm * upper)
        self.mm_lower_t = np.ascontiguousarray((mm * (1.0 - upper)).transpose(1, 0, 2))

    def weighted(self, w):
        """sum_c w_c F_c over the members (not yet symmetrised)."""
        f, p, t = self.f, self.p, self.coef
        wt = t * w[:, None]
        out = ((wt[:, :f].T @ t[:, :f])[self.pairs] @ self.uu).reshape(p, p)
        s = sums_by_start((wt[:, :f, None] * t[:, None, f:]).reshape(len(w), -1), self.start, p)  # (P, f * m)
        y = np.matmul(self.um, s[:, :, None])[:, :, 0]  # y[j, i] = sum_k X_k[i, j] s[j, k]
        out += y + y.T
        s2 = sums_by_start((wt[:, f:, None] * t[:, None, f:]).reshape(len(w), -1), self.start, p)  # (P, m * m)
        out += np.einsum("ijk,ik->ij", self.mm_upper, s2)  # sum_k X_k[i, j] s2[min(i, j), k]
        out += np.einsum("ijk,ik->ij", self.mm_lower_t, s2).T
        # sum_c w_c (e_j r_c^T + r_c e_j^T): the rows r_c summed by element (a sparse (P, members) product)
        part = scipy.sparse.csr_matrix((w, (self.elem, np.arange(w.size))), shape=(p, w.size)) @ self.cross
        out += part + part.T
        out[np.diag_indices(p)] += np.bincount(self.elem, weights=w * self.own, minlength=p).astype(self.dtype)
        return out

    def dot(self, g):
        """<G, F_c> for every member (``g`` symmetric)."""
        f, p, t = self.f, self.p, self.coef
        tu, tm = t[:, :f], t[:, f:]
        zu = np.zeros((f, f), dtype=self.dtype)
        zu[self.pairs] = self.uu @ g.ravel()  # <S_ab, G> = 2 <X_ab, G> (a < b), <X_aa, G>
        zu = (zu + zu.T) / 2.0
        out = np.einsum("ca,ab,cb->c", tu, zu, tu)
        v = suffix_sums(np.matmul(g.T[:, None, :], self.um)[:, 0, :])  # sum over j >= s of column j of X_k (.) G
        out += 2.0 * np.einsum("ca,cab,cb->c", tu, v[self.start].reshape(-1, f, tm.shape[1]), tm)
        # sum over i, j >= s of X_k (.) G: each pair counted once, at the smaller of i and j
        q = suffix_sums(np.matmul(g[:, None, :], self.mm_upper)[:, 0, :]
                        + np.matmul(g.T[:, None, :], self.mm_lower_t)[:, 0, :])
        n_m = tm.shape[1]
        out += np.einsum("ca,cab,cb->c", tm, q[self.start].reshape(-1, n_m, n_m), tm)
        out += 2.0 * np.einsum("ck,ck->c", g[self.elem], self.cross) + self.own * g[self.elem, self.elem]
        return out


class WorkingBlocks:
    """Sums sum_i w_i I_i and inner products <G, I_i> of a working set given as
    :class:`~sensorplan.design.blocks.StructuredBlocks` (``blocks.subset(idx)``), computed in ``dtype``
    (single precision where a few digits are enough: the Hessian products of the Newton-CG steps)."""

    def __init__(self, blocks, *, dtype=np.float64):
        self.n = blocks.n_candidates
        self.p = blocks.n_params
        self.dtype = np.dtype(dtype)
        self.families = [_Family(fam, self.dtype) for fam in blocks.families]

    def weighted(self, w):
        """sum_i w_i I_i (symmetric)."""
        w = np.asarray(w, dtype=self.dtype)
        out = sum(fam.weighted(w[fam.index]) for fam in self.families)
        return 0.5 * (out + out.T)

    def dot(self, g):
        """<G, I_i> for every member."""
        g = np.asarray(g, dtype=self.dtype)
        g = 0.5 * (g + g.T)
        out = np.empty(self.n, dtype=self.dtype)
        for fam in self.families:
            out[fam.index] = fam.dot(g)
        return out

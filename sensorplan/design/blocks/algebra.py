"""Algebra of Fisher blocks that share a few fixed matrices: sums, inner products and congruences in O(P^2).

On a beam the actual moment diagram of a sensor's unit action at x is the
free-body atom at x (a step H(s - x) for a tiltmeter's unit couple, a ramp
-(s - x)_+ for a deflection gauge's unit force) plus a combination of the
support reactions' fixed unit diagrams, whose coefficients are the
sensor's own reactions.  The whitened Jacobian of candidate c is therefore

    J_c = sum_a t_ca Psi_a M_a(c) + g_c e_{j_c}^T

with a few fixed (whitened) readings x parameters matrices Psi_a: the
reactions' element integrals (M_a = I) and the integrals of the load
moment times 1 and s (M_a(c) keeps only the elements after j_c, the element
holding x); g_c is the integral over the part of element j_c after x.
Hence F_c = J_c^T J_c needs only the products X_ab = Psi_a^T Psi_b, the
coefficients t_c, r_c = (J_c - g_c e_j^T)^T g_c and g_c^T g_c: sums over
candidates become cumulative sums over the mask's first element, and
<G, F_c> for all c costs O(A^2 P^2 + C (A^2 + P)) instead of C P^2.

Owns: BlockFamily (one sensor kind's candidates; :mod:`.structured` holds all of them).  May import:
design.blocks.sums.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg.blas
import scipy.sparse

from .sums import sums_by_start, suffix_sums

__all__ = ["BlockFamily", "symmetrise_stack"]

# derived from the shared products only
_FROM_PRODUCTS = ("_pair_matrices", "_pair_matrices_single", "_free_flat", "_triangles", "_pair_stack",
                  "_mixed_stack")


def symmetrise_stack(a):
    """(A + A^T) / 2 of each matrix of a stack."""
    return 0.5 * (a + np.swapaxes(a, -1, -2))


@dataclass(frozen=True, eq=False)
class BlockFamily:
    """Candidates whose Jacobians share the fixed matrices (one sensor kind's whitening).

    ``products`` (A, P, A, P) holds X_ab = Psi_a^T Psi_b; the first
    ``n_free`` matrices act on all parameters, the others on the elements
    from ``start`` on; ``coef`` (k, A) the t_ca; ``elem`` (k,) j_c;
    ``cross`` (k, P) r_c; ``own`` (k,) g_c^T g_c; ``index`` (k,) the
    candidates' numbers in the problem; ``readings`` (n_free, L, P) the free
    Psi_a themselves (L whitened readings), if given (cheaper congruences).
    """

    index: np.ndarray
    products: np.ndarray
    n_free: int
    coef: np.ndarray
    elem: np.ndarray
    cross: np.ndarray
    own: np.ndarray
    readings: np.ndarray | None = None

    @property
    def start(self):
        return self.elem + 1

    @property
    def n_params(self):
        return self.products.shape[1]

    def subset(self, local, index):
        """The members at positions ``local`` renumbered as ``index`` (sharing what is derived from the products)."""
        out = BlockFamily(np.asarray(index), self.products, self.n_free, self.coef[local], self.elem[local],
                          self.cross[local], self.own[local], self.readings)
        for name in _FROM_PRODUCTS:
            if name in self.__dict__:
                out.__dict__[name] = self.__dict__[name]
        return out

    @cached_property
    def _pair_stack(self):
        """The free matrices X_ab for a <= b (the others are their transposes), contiguous (pairs, P, P)."""
        iu = np.triu_indices(self.n_free)
        return np.array([self.products[a, :, b, :] for a, b in zip(*iu)])

    @cached_property
    def _mixed_stack(self):
        """X_ab for a masked and b free, contiguous (m f, P, P)."""
        f = self.n_free
        return np.array([self.products[a, :, b, :] for a in range(f, self.products.shape[0]) for b in range(f)])

    def _free_congruences(self, v):
        """V^T X_ab V for the free a <= b (``np.triu_indices(n_free)`` order), (pairs, m m): from the pairs'
        products (pairs P^2 m flops) or, where that costs less, from Psi_a V (n_free L P m) and their Gram."""
        f, p, k = self.n_free, self.n_params, v.shape[1]
        iu = np.triu_indices(f)
        if self.readings is None or iu[0].size * p * p <= 1.2 * f * self.readings.shape[1] * (p + f * k):
            return np.matmul(v.T, np.matmul(self._pair_stack, v)).reshape(iu[0].size, k * k)
        y = np.matmul(self.readings, v)  # Psi_a V (f, L, m)
        flat = np.ascontiguousarray(y.transpose(1, 0, 2)).reshape(y.shape[1], f * k)
        gram = (flat.T @ flat).reshape(f, k, f, k)
        return gram[iu[0], :, iu[1], :].reshape(iu[0].size, k * k)

    @cached_property
    def _triangles(self):
        """triu(X_ab) and tril(X_ab, -1)^T of the masked matrices, (2, m, m, P, P) contiguous (for congruences)."""
        f, n_m = self.n_free, self.products.shape[0] - self.n_free
        x = self.products
        return np.array([[[np.triu(x[f + a, :, f + b, :]) for b in range(n_m)] for a in range(n_m)],
                         [[np.tril(x[f + a, :, f + b, :], -1).T for b in range(n_m)] for a in range(n_m)]])

    def _split(self):
        f = self.n_free
        x = self.products
        return x[:f, :, :f, :], x[:f, :, f:, :], x[f:, :, f:, :]

    @cached_property
    def _pair_matrices(self):
        """Contiguous (pairs, P * P) products for dense blocks: X_aa and X_ab + X_ba (a < b) of the free
        matrices, X_ab of free a and masked b, and the same symmetric pairs of the masked ones."""
        f, n_a = self.n_free, self.products.shape[0]
        x = self.products

        def symmetric(lo, hi):
            iu = np.triu_indices(hi - lo)
            mats = [x[lo + a, :, lo + b, :] + (x[lo + b, :, lo + a, :] if a != b else 0.0) for a, b in zip(*iu)]
            return iu, np.ascontiguousarray(np.array(mats).reshape(len(mats), -1))

        free = symmetric(0, f)
        masked = symmetric(f, n_a)
        cross = np.ascontiguousarray(x[:f, :, f:, :].transpose(0, 2, 1, 3).reshape(f * (n_a - f), -1))
        return free, cross, masked

    @cached_property
    def _free_flat(self):
        """X_ab of the free matrices as contiguous (f * f, P * P) rows (for inner products with a G)."""
        f, p = self.n_free, self.n_params
        return np.ascontiguousarray(self.products[:f, :, :f, :].transpose(0, 2, 1, 3)).reshape(f * f, p * p)

    @cached_property
    def _weighted_layout(self):
        """X_ab of free a and masked b, and of masked a and b, as contiguous (P, P, pairs) arrays (i, j first:
        the weighted sums reduce over the pairs element by element)."""
        _, um, mm = self._split()
        p = self.n_params
        return (np.ascontiguousarray(um.transpose(1, 3, 0, 2)).reshape(p, p, -1),
                np.ascontiguousarray(mm.transpose(1, 3, 0, 2)).reshape(p, p, -1))

    @cached_property
    def _pair_matrices_single(self):
        """:attr:`_pair_matrices` in single precision."""
        (iu_f, free), cross, (iu_m, masked) = self._pair_matrices
        return (iu_f, free.astype(np.float32)), cross.astype(np.float32), (iu_m, masked.astype(np.float32))

    def dense(self, local, *, symmetric=True, dtype=np.float64):
        """The blocks of the members at ``local``, shape (k, P, P); ``symmetric=False`` skips the final
        symmetrisation (the blocks are then symmetric up to round-off only: enough for a preconditioner), and
        ``dtype`` float32 forms them in single precision."""
        single = np.dtype(dtype) == np.float32
        (iu_f, free), cross, (iu_m, masked) = self._pair_matrices_single if single else self._pair_matrices
        f, p = self.n_free, self.n_params
        t = self.coef[local].astype(np.float32) if single else self.coef[local]
        tu, tm = t[:, :f], t[:, f:]
        k = len(t)
        out = (tu[:, iu_f[0]] * tu[:, iu_f[1]] @ free).reshape(k, p, p)
        y = ((tu[:, :, None] * tm[:, None, :]).reshape(k, -1) @ cross).reshape(k, p, p)
        z = (tm[:, iu_m[0]] * tm[:, iu_m[1]] @ masked).reshape(k, p, p)
        for n, s in enumerate(self.start[local]):  # the masked parts: rows or columns from the start on
            out[n, :s, s:] += y[n, :s, s:]
            out[n, s:, :s] += y[n, :s, s:].T
            out[n, s:, s:] += y[n, s:, s:] + y[n, s:, s:].T
            out[n, s:, s:] += z[n, s:, s:]
        rows = np.arange(len(t))
        e = self.elem[local]
        out[rows, e, :] += self.cross[local].astype(out.dtype)
        out[rows, :, e] += self.cross[local].astype(out.dtype)
        out[rows, e, e] += self.own[local].astype(out.dtype)
        return symmetrise_stack(out) if symmetric else out

    def weighted(self, w):
        """sum_c w_c F_c over the members (``w`` in member order; members without weight are skipped)."""
        f, p = self.n_free, self.n_params
        nz = np.flatnonzero(w)
        w, coef, elem = w[nz], self.coef[nz], self.elem[nz]
        wt = coef * w[:, None]
        pair = wt.T @ coef
        out = (pair[:f, :f].reshape(1, f * f) @ self._free_flat).reshape(p, p)  # sum_ab pair_ab X_ab
        mixed, masked = self._weighted_layout
        s = sums_by_start(wt[:, :f, None] * coef[:, None, f:], elem + 1, p).reshape(p, -1)  # (P, f m)
        y = np.einsum("ijk,jk->ij", mixed, s)  # sum_ab X_ab[i, j] s[j, a, b] (a free, b masked)
        out += y + y.T
        s2 = sums_by_start(wt[:, f:, None] * coef[:, None, f:], elem + 1, p).reshape(p, -1)  # (P, m m)
        low = np.minimum.outer(np.arange(p), np.arange(p))
        out += np.einsum("ijk,ijk->ij", masked, s2[low])
        # sum_c w_c (e_j r_c^T + r_c e_j^T): the rows r_c summed by element (a sparse (P, members) product)
        part = scipy.sparse.csr_matrix((w, (elem, np.arange(nz.size))), shape=(p, nz.size)) @ self.cross[nz]
        out += part + part.T
        np.add.at(out, (elem, elem), w * self.own[nz])
        return symmetrise_stack(out)

    def dot(self, g):
        """<G, F_c> for every member (``g`` symmetric)."""
        _, um, mm = self._split()
        f, p = self.n_free, self.n_params
        tu, tm = self.coef[:, :f], self.coef[:, f:]
        zu = np.dot(self._free_flat, g.reshape(p * p, 1)).reshape(f, f)  # tensordot(uu, g, ([1, 3], [0, 1]))
        out = np.einsum("ca,ab,cb->c", tu, zu, tu)
        v = suffix_sums(np.einsum("aibj,ij->jab", um, g))  # (P + 1, f, m): sum over j >= s of column sums
        out += 2.0 * np.einsum("ca,cab,cb->c", tu, v[self.start], tm)
        n_m = mm.shape[0]
        q = np.zeros((p + 1, n_m, n_m))  # q[s] = sum over i, j >= s of G (.) X_ab
        for a in range(n_m):
            for b in range(n_m):
                e = mm[a, :, b, :] * g
                q[:, a, b] = suffix_sums(np.triu(e).sum(axis=1) + np.tril(e, -1).sum(axis=0))
        out += np.einsum("ca,cab,cb->c", tm, q[self.start], tm)
        out += 2.0 * np.einsum("ck,ck->c", g[self.elem], self.cross) + self.own * g[self.elem, self.elem]
        return out

    def congruence(self, v):
        """V^T F_c V for every member, shape (k, m, m).

        The parts of F_c on the masked elements are sums over the elements
        from the member's ``start`` on; they are accumulated from the last
        element down, one group of members sharing a start at a time (tall
        products over the rows in between), so the memory is O(A^2 m^2), not
        O(P A^2 m^2), whatever m.  Each part enters once, unsymmetrised
        (V^T X V or its transpose: the whole is symmetrised at the end), and
        is added in place (BLAS gemm with beta = 1 on the rows of a group).
        """
        f, p = self.n_free, self.n_params
        n_m, k, n = self.products.shape[0] - f, v.shape[1], self.coef.shape[0]
        order, groups = self._start_groups
        coef, elem = (self.coef, self.elem) if order is None else (self.coef[order], self.elem[order])
        tu, tm = coef[:, :f], coef[:, f:]
        iu = np.triu_indices(f)
        z = self._free_congruences(v)  # V^T X_ab V, a <= b free (X_ba: the transposes)
        out = np.empty((n, k, k))
        flat_out = out.reshape(n, k * k)
        # rows j of triu(X_ab) V (a, b masked), of X_ba V (a free, b masked) and of tril(X_ab, -1)^T V: the
        # masked parts are V^T(sums from the start on of these rows (x) V[j]) (V^T triu(X) V enters transposed)
        upper = np.empty((p, n_m, n_m, k))
        lower = np.empty((p, n_m, n_m, k))
        triangles = self._triangles
        for a in range(n_m):
            for b in range(n_m):
                upper[:, a, b] = triangles[0, a, b] @ v
                lower[:, a, b] = triangles[1, a, b] @ v
        mixed = np.matmul(self._mixed_stack, v).reshape(n_m, f, p, k).transpose(2, 1, 0, 3).reshape(p, f * n_m * k)
        rows = np.concatenate([upper.reshape(p, -1), mixed, lower.reshape(p, -1)], axis=1)
        weights = np.concatenate([(tm[:, :, None] * tm[:, None, :]).reshape(n, -1),
                                  2.0 * (tu[:, :, None] * tm[:, None, :]).reshape(n, -1),  # X_ab V and X_ba V
                                  (tm[:, :, None] * tm[:, None, :]).reshape(n, -1)], axis=1)
        # r_c (x) v_j + v_j (x) r_c + own_c v_j (x) v_j (v_j = V[j_c], the same for a group) is twice the
        # symmetric part of (r_c + own_c v_j / 2) (x) v_j
        cross = self.cross if order is None else self.cross[order]
        own = self.own if order is None else self.own[order]
        half = 2.0 * (cross @ v) + own[:, None] * v[elem]
        sums = np.zeros((rows.shape[1], k))
        hi = p
        for g0, g1, lo in reversed(groups):  # by decreasing start: add the elements lo .. hi - 1 to the sums
            if lo < hi:
                sums += rows[lo:hi].T @ v[lo:hi]
                hi = lo
            np.matmul(weights[g0:g1], sums.reshape(-1, k * k), out=flat_out[g0:g1])
            _add_product(half[g0:g1].reshape(-1, 1), v[lo - 1][None, :], out[g0:g1].reshape(-1, k))
        # the free part: t_ca t_cb V^T X_ab V over a <= b, twice for a < b (V^T X_ba V is the transpose)
        _add_product(tu[:, iu[0]] * tu[:, iu[1]] * np.where(iu[0] == iu[1], 1.0, 2.0), z, flat_out)
        out = symmetrise_stack(out)
        if order is not None:
            out[order] = out.copy()
        return out

    @cached_property
    def _start_groups(self):
        """(order, groups): the members by increasing start (``order`` None when that is their order already, as
        for candidates by position), and the (first, stop, start) of each run of members sharing a start."""
        order = np.argsort(self.start, kind="stable")
        starts = self.start[order]
        edges = np.flatnonzero(np.diff(np.concatenate([[-1], starts, [-1]])))
        groups = [(int(g0), int(g1), int(starts[g0])) for g0, g1 in zip(edges[:-1], edges[1:])]
        return (None if np.array_equal(order, np.arange(order.size)) else order), groups


def _add_product(a, b, c):
    """C += A B in place (C (n, m) C-contiguous; BLAS gemm with beta = 1 on the transposes, no temporary)."""
    if c.size == 0:
        return
    scipy.linalg.blas.dgemm(1.0, b.T, a.T, beta=1.0, c=c.T, overwrite_c=True)

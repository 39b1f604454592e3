"""Low-rank roots of structured Fisher blocks without forming the blocks: a Nyström approximation from one sketch.

A member c of a :class:`~sensorplan.design.blocks.BlockFamily` has the block
F_c = sum_ab t_ca t_cb X_ab[c] + e r_c^T + r_c e^T + o_c e e^T, where the
fixed products X_ab (a, b over the family's matrices, the first ``n_free``
free, the others masked) enter whole when both are free, as Y M + M Y^T
(Y = X_ab) when one is masked and as M X_ab M when both are (M the
projection on the parameters from the member's start s_c on), and
e = e_{elem_c} (:meth:`BlockFamily.dense` forms the same sum).  For one
Gaussian sketch Omega (P, q), F_c Omega then costs O(A^2 P q) from the
products X_ab Omega, X_ab^T Omega and the suffix sums
X_ab[:, j >= s] Omega[j >= s] (for every start s), computed once per family,
instead of the P^2 A^2 of the formed block and the P^2 q of its sketch.
The root follows from the Nyström approximation
F ~ (F Omega)(Omega^T F Omega)^+ (F Omega)^T (Halko, Martinsson & Tropp,
SIAM Review 53 (2011), section 5.4), truncated to its ``rank`` leading
eigenpairs.

Owns: StructuredRoots.  May import: design.blocks.
"""

import numpy as np

__all__ = ["StructuredRoots"]


class _FamilySketch:
    """What one family's members need to sketch their blocks: X_ab Omega, X_ab^T Omega (a free, b masked) and the
    suffix sums of X_ab Omega over the masked pairs, in single precision."""

    def __init__(self, fam, omega):
        x, f = fam.products, fam.n_free
        p, q = omega.shape
        self.f, self.n_m = f, x.shape[0] - f
        self.coef, self.elem, self.cross, self.own = fam.coef, fam.elem, fam.cross, fam.own
        self.free = np.einsum("aibj,jq->abiq", x[:f, :, :f, :], omega).astype(np.float32)
        self.free_t = np.einsum("aibj,iq->abjq", x[:f, :, f:, :], omega).astype(np.float32)
        # suffix[pair][s] = X_ab[:, s:] Omega[s:] for the pairs with b masked (a free, then a masked), s = 0 .. P
        self.suffix = np.zeros((x.shape[0] * self.n_m, p + 1, p, q), dtype=np.float32)
        for a in range(x.shape[0]):
            for b in range(self.n_m):
                terms = x[a, :, f + b, :].T[:, :, None] * omega[:, None, :]  # (j, i, q): X_ab[i, j] Omega[j]
                self.suffix[a * self.n_m + b, :p] = np.cumsum(terms[::-1], axis=0)[::-1]

    def sketch(self, local, omega):
        """F_c Omega for the members at ``local``, (k, P, q) in single precision."""
        f, n_m = self.f, self.n_m
        t = self.coef[local].astype(np.float32)
        start, elem = self.elem[local] + 1, self.elem[local]
        k, p = t.shape[0], omega.shape[0]
        tt = t[:, :, None] * t[:, None, :]  # (k, A, A)
        out = np.einsum("kab,abiq->kiq", tt[:, :f, :f], self.free)
        rows = np.arange(p)[None, :] >= start[:, None]  # M: the parameters from the start on
        out += np.einsum("kab,abiq->kiq", tt[:, :f, f:], self.free_t) * rows[:, :, None]  # M Y^T Omega
        gathered = self.suffix[:, start]  # (pairs, k, P, q)
        coefs = tt[:, :, f:].reshape(k, -1)  # pairs (a, b masked) in the order of ``suffix``
        free_part = np.einsum("kn,nkiq->kiq", coefs[:, :f * n_m], gathered[:f * n_m])  # Y M Omega
        masked_part = np.einsum("kn,nkiq->kiq", coefs[:, f * n_m:], gathered[f * n_m:])  # M Z M Omega
        out += free_part + masked_part * rows[:, :, None]
        cross = self.cross[local].astype(np.float32)
        n = np.arange(k)
        out[n, elem, :] += cross @ omega + self.own[local, None].astype(np.float32) * omega[elem]  # e (r^T + o e^T) Omega
        out += cross[:, :, None] * omega[elem][:, None, :]  # r e^T Omega
        return out


class StructuredRoots:
    """R (k, P, r) with R_i R_i^T close to the blocks of candidates of a
    :class:`~sensorplan.design.blocks.StructuredBlocks` (module docstring), one sketch of ``rank`` +
    ``oversample`` Gaussian columns drawn from ``seed`` for all, in single precision."""

    def __init__(self, blocks, rank, *, oversample=8, seed=0):
        p = blocks.n_params
        self.rank = min(rank, p)
        omega = np.random.default_rng(seed).standard_normal((p, min(p, self.rank + oversample)))
        self.omega = omega.astype(np.float32)
        self.families = [_FamilySketch(fam, omega) for fam in blocks.families]
        self.owner = np.empty(blocks.n_candidates, dtype=int)
        self.local = np.empty(blocks.n_candidates, dtype=int)
        for k, fam in enumerate(blocks.families):
            self.owner[fam.index], self.local[fam.index] = k, np.arange(len(fam.index))

    def __call__(self, index):
        """The roots of the candidates ``index``."""
        return _nystrom(self.sketch(index).astype(float), self.omega.astype(float), self.rank)

    def sketch(self, index):
        """F_c Omega for the candidates ``index`` (k, P, q), ``omega`` (P, q) the sketch, in single precision."""
        index = np.asarray(index, dtype=int)
        y = np.empty((index.size, self.omega.shape[0], self.omega.shape[1]), dtype=np.float32)
        for k, fam in enumerate(self.families):
            hit = np.flatnonzero(self.owner[index] == k)
            if hit.size:
                y[hit] = fam.sketch(self.local[index[hit]], self.omega)
        return y


def _nystrom(y, omega, rank):
    """Roots (k, P, rank) of F ~ Y (Omega^T Y)^+ Y^T from the sketches ``y`` = F Omega (k, P, q): the pseudo-inverse
    from the eigenpairs of the small symmetric Omega^T Y above round-off, then the leading singular pairs."""
    core = np.matmul(omega.T[None], y)
    core = 0.5 * (core + np.swapaxes(core, 1, 2))
    mu, vec = np.linalg.eigh(core)
    keep = mu > 1e-6 * mu[:, -1:]  # round-off of the single-precision sketches
    scale = np.where(keep, 1.0 / np.sqrt(np.where(keep, mu, 1.0)), 0.0)
    e = np.matmul(y, vec * scale[:, None, :])  # F ~ E E^T
    u, s, _ = np.linalg.svd(e, full_matrices=False)
    return (u[:, :, :rank] * s[:, None, :rank]).astype(np.float32)

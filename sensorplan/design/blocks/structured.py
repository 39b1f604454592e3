"""The candidates' Fisher blocks of all sensor kinds as one stack that never forms them all.

Owns: StructuredBlocks, DENSE_CACHE_BYTES.  May import: _cache, design.blocks.algebra.
"""

import numpy as np

from ..._cache import Cache
from .algebra import symmetrise_stack

__all__ = ["StructuredBlocks", "DENSE_CACHE_BYTES"]

DENSE_CACHE_BYTES = 2**30  # dense blocks kept (greedy and exchange evaluate the same few candidates many times)


class StructuredBlocks:
    """The candidates' Fisher blocks as :class:`BlockFamily` members; indexing gives dense blocks.

    Stands in for the (C, P, P) array of a :class:`~sensorplan.design.problem.DesignProblem`:
    ``blocks[index]`` forms the dense blocks of a few candidates, while
    sums, inner products and congruences over all candidates never form them.
    """

    ndim = 3
    dtype = np.dtype(float)

    def __init__(self, families, n_candidates, *, origin=None, cache=None):
        self.families = tuple(families)
        self.n_candidates = int(n_candidates)
        # dense blocks kept by their number in the first (full) set, shared by its subsets
        self._origin = np.arange(self.n_candidates) if origin is None else np.asarray(origin)
        self._cache = cache if cache is not None else Cache(
            maxsize=max(1, DENSE_CACHE_BYTES // (8 * self.families[0].n_params ** 2)))
        self.n_params = self.families[0].n_params
        owner = np.full(self.n_candidates, -1)
        local = np.zeros(self.n_candidates, dtype=int)
        for k, fam in enumerate(self.families):
            owner[fam.index] = k
            local[fam.index] = np.arange(fam.index.size)
        if np.any(owner < 0):
            raise ValueError("every candidate must belong to one family")
        self._owner, self._local = owner, local

    @property
    def shape(self):
        return (self.n_candidates, self.n_params, self.n_params)

    def __len__(self):
        return self.n_candidates

    @property
    def nbytes(self):
        return sum(f.products.nbytes + f.cross.nbytes + f.coef.nbytes for f in self.families)

    def __getitem__(self, index):
        single = np.ndim(index) == 0
        index = np.atleast_1d(np.arange(self.n_candidates)[index])
        out = np.empty((index.size, self.n_params, self.n_params))
        missing = []
        for n, i in enumerate(index):
            found, block = self._cache.lookup((), key=int(self._origin[i]))
            if found:
                out[n] = block
            else:
                missing.append(n)
        missing = np.array(missing, dtype=int)
        for k, fam in enumerate(self.families):
            hit = missing[self._owner[index[missing]] == k]
            for s in range(0, hit.size, 64):
                part = hit[s:s + 64]
                out[part] = fam.dense(self._local[index[part]])
                for n in part:
                    self._cache.put((), out[n].copy(), key=int(self._origin[index[n]]))
        return out[0] if single else out

    def each(self, index):
        """The dense blocks of the candidates at ``index`` as a list of read-only arrays, those in the cache
        without a copy (``blocks[index]`` copies them into one new array)."""
        index = np.atleast_1d(np.arange(self.n_candidates)[index])
        out, missing = [], []
        for n, i in enumerate(index):
            found, block = self._cache.lookup((), key=int(self._origin[i]))
            out.append(block if found else None)
            if not found:
                missing.append(n)
        if missing:
            formed = self[index[missing]]  # forms and caches them
            for n, i in enumerate(missing):
                found, block = self._cache.lookup((), key=int(self._origin[index[i]]))
                out[i] = block if found else formed[n]
        for block in out:
            block.flags.writeable = False
        return out

    def unsymmetrised(self, index, *, dtype=np.float32):
        """The dense blocks of the candidates at ``index`` in ``dtype``, symmetric up to round-off only and
        not cached: what a preconditioner needs of many candidates seen once (a few digits, no transposed
        copy per block)."""
        index = np.asarray(index, dtype=int)
        out = np.empty((index.size, self.n_params, self.n_params), dtype=dtype)
        for k, fam in enumerate(self.families):
            hit = np.flatnonzero(self._owner[index] == k)
            for s in range(0, hit.size, 32):
                part = hit[s:s + 32]
                out[part] = fam.dense(self._local[index[part]], symmetric=False, dtype=dtype)
        return out

    def hold(self, index, *, first=1):
        """Form and keep the dense blocks of the candidates at ``index`` not in the cache (one pass over each
        family's shared products for all of them), if any of the ``first`` of them is not."""
        index = [int(i) for i in index]
        missing = [i for i in index if not self._cache.lookup((), key=int(self._origin[i]))[0]]
        if missing and any(i in missing for i in index[:first]):
            self[np.array(missing)]

    def held(self, index):
        """How many of the candidates at ``index`` have their dense block in the cache."""
        return sum(self._cache.lookup((), key=int(self._origin[i]))[0] for i in np.atleast_1d(index))

    def subset(self, index):
        """The candidates at ``index`` as structured blocks (renumbered 0 .. len(index) - 1)."""
        index = np.asarray(index, dtype=int)
        families = []
        for k, fam in enumerate(self.families):
            hit = np.flatnonzero(self._owner[index] == k)
            if hit.size:
                families.append(fam.subset(self._local[index[hit]], hit))
        return StructuredBlocks(families, index.size, origin=self._origin[index], cache=self._cache)

    def weighted(self, w):
        """sum_c w_c F_c."""
        w = np.asarray(w, dtype=float)
        return sum(fam.weighted(w[fam.index]) for fam in self.families)

    def dot(self, g, index=None):
        """<G, F_c> for every candidate (or those at ``index``)."""
        g = symmetrise_stack(np.asarray(g, dtype=float).reshape(self.n_params, self.n_params))
        out = np.empty(self.n_candidates)
        for fam in self.families:
            out[fam.index] = fam.dot(g)
        return out if index is None else out[np.asarray(index, dtype=int)]

    def congruence(self, v):
        """V^T F_c V for every candidate, shape (C, m, m)."""
        v = np.asarray(v, dtype=float)
        out = np.empty((self.n_candidates, v.shape[1], v.shape[1]))
        for fam in self.families:
            out[fam.index] = fam.congruence(v)
        return out

"""The Newton-CG preconditioner: the criterion's Hessian at an earlier iterate, from low-rank roots of the blocks.

The projected CG of :mod:`.newton_cg` is preconditioned by H~, the exact
Hessian of the criterion at an earlier iterate on the working set's core.
Its rows cost what the criterion's Hessian factors cost
(:meth:`Criterion.hessian_factors`: for D, the whitened block
L^-1 I_i L^-T, m P^3 on m candidates).  A preconditioner needs a few digits
only, and a candidate's Fisher block has a fast-decaying spectrum, so each
block enters by its rank-r root R_i (I_i ~ R_i R_i^T; structured blocks:
a Nyström approximation from their structure, :mod:`.structured_roots`;
dense blocks: a randomised range finder,
:func:`~sensorplan.design.blocks.low_rank_roots`), computed once per
candidate and kept for the whole relaxation.  At each new point the
criterion turns the roots into factors (:meth:`Criterion.hessian_factors_at`):
for D and A as :class:`~sensorplan.design.criteria.base.ProductRows`, rows
B_i = U_i^T V_i held as U_i (r, P) and V_i (r, P or nt), so that a row costs
r P numbers and an inner product <B_i, B_j> = <U_i U_j^T, V_i V_j^T>
about 2 r^2 P flops (for D, Z_i = L^-1 R_i: <Z_i Z_i^T, Z_j Z_j^T> =
||Z_i^T Z_j||^2, instead of P^2 / 2 for the packed whitened block).
Where the criterion weights the blocks by a matrix (A: H_ij = -2 tr(M I_i
Q^-1 I_j), M = N N^T), only the ``WEIGHT_RANK`` leading directions of M
enter: H~ is below the exact Hessian by what the tail of M carries, which
the CG iterations make up for (the products are exact).

Owns: StaleHessian.  May import: _cache, design.blocks, design.criteria.
"""

import numpy as np

from ..._cache import Cache
from ..blocks import low_rank_roots
from ..criteria.base import ProductRows
from .structured_roots import StructuredRoots

__all__ = ["StaleHessian", "ROOT_RANK", "WEIGHT_RANK"]

ROOT_RANK = 4  # rank of the blocks' roots (at the target, D, A and mixed take the CG iterations of rank 32)
# leading directions of the criterion's weighting kept in the rows (A: N N^T, N = Q^-1 C^T; H~ is then below H by
# what the weighting's tail carries)
WEIGHT_RANK = 64


class StaleHessian:
    """The Newton-CG preconditioner: the exact Hessian of an earlier iterate on the working set's core.

    The core is the members whose weight was above ``core_weight`` when the
    rows were computed; a member outside it enters the preconditioner
    through its diagonal only, estimated by -c g_i^2 (g_i the current
    gradient; for D exact with c = 1 when the whitened block
    Q^-1/2 I_i Q^-1/2 has rank one, and the candidates' blocks are dominated
    by one direction; c is the median ratio H_ii / -g_i^2 over the core).
    :meth:`refresh` recomputes the rows at a new iterate.  Where the
    criterion gives its Hessian as factors (:meth:`Criterion.hessian_factors`),
    the factors are kept with the point they were computed at, and
    :meth:`extend` adds the rows of members that joined the working set since
    (a new round of column generation) at that same point: one consistent
    Hessian, at the cost of the new members' factors only; members that
    left the working set are forgotten.  The blocks enter by their rank-``rank``
    roots (module docstring).  ``rows`` counts the block rows computed,
    ``refreshes`` the recomputations.
    """

    def __init__(self, problem, *, core_weight=1e-3, rank=ROOT_RANK, weight_rank=WEIGHT_RANK):
        self.problem = problem
        self.core_weight = core_weight
        self.rank = rank
        self.weight_rank = weight_rank
        self.members = np.zeros(0, dtype=int)  # in the order of the rows
        self.matrix = np.zeros((0, 0))
        self.rows = 0
        self.refreshes = 0
        self.scale = 1.0  # H_ii / -g_i^2 on the core (1 for D; the estimate is scaled for any criterion)
        self._roots = Cache()  # by candidate number, for this problem only (dropped with the preconditioner)
        self._sketch = None  # the structured blocks' sketches (StructuredRoots), made when first needed
        self._factors_at = None  # roots -> the criterion's Hessian factors at the rows' point
        self._store = None  # the rows' factors (None: the criterion has none)

    def refresh(self, idx, point, x, grad):
        """Recompute the rows of the members of ``idx`` whose weight ``x`` is above ``core_weight`` at
        ``point``; the preconditioner's Hessian on ``idx`` (gradient ``grad``)."""
        keep = x > self.core_weight
        core = idx[keep]
        self._factors_at = self.problem.criterion.hessian_factors_at(point.q, point.chol, rank=self.weight_rank)
        factors = self._factors_of(core)
        if factors is None:
            self._store = None
            h = self.problem.criterion.hessian(point.q, point.chol, _row_blocks(self.problem.blocks, core))
        else:
            self._store = _RowStore(factors)
            h = _gram(self._store.factors)
        self.members, self.matrix = core, 0.5 * (h + h.T)
        self.rows, self.refreshes = self.rows + core.size, self.refreshes + 1
        ratio = np.diag(self.matrix) / -np.maximum(grad[keep] ** 2, 1e-300)
        self.scale = float(np.median(ratio)) if ratio.size else 1.0
        return self.on(idx, grad)

    def extend(self, idx, x, grad):
        """Add the rows of the members of ``idx`` above ``core_weight`` that have none, at the point of the
        others (when the criterion gives factors; members that left ``idx`` are forgotten); the
        preconditioner's Hessian on ``idx``."""
        new = np.setdiff1d(idx[x > self.core_weight], self.members)
        if new.size and self._store is not None:
            stay = np.isin(self.members, idx)
            old = int(stay.sum())
            self._store.replace(stay, self._factors_of(new))
            cross = _gram(self._store.factors, rows=slice(old, None))  # (new, old + new)
            matrix = np.empty((old + new.size,) * 2)
            matrix[:old, :old] = self.matrix[np.ix_(stay, stay)]
            matrix[old:], matrix[:old, old:] = cross, cross[:, :old].T
            self.members, self.matrix = np.concatenate([self.members[stay], new]), matrix
            self.rows += new.size
        return self.on(idx, grad)

    def _factors_of(self, index):
        """The criterion's Hessian factors of the candidates ``index`` at the rows' point from the blocks'
        roots (computed once per candidate, in single precision); None where the criterion has none."""
        missing = np.array([i for i in index.tolist() if not self._roots.lookup((), key=i)[0]], dtype=int)
        if missing.size and self.problem.structured and self._sketch is None:
            self._sketch = StructuredRoots(self.problem.blocks, self.rank)
        for s in range(0, missing.size, 64):
            part = missing[s:s + 64]
            roots = self._sketch(part) if self.problem.structured else \
                low_rank_roots(_row_blocks(self.problem.blocks, part), self.rank)
            for i, root in zip(part.tolist(), roots):
                self._roots.put((), root, key=i)
        p = self.problem.n_params
        roots = np.stack([self._roots.lookup((), key=i)[1] for i in index.tolist()]) if index.size else \
            np.zeros((0, p, min(p, self.rank)), dtype=np.float32)
        return self._factors_at(roots)

    def on(self, idx, grad):
        """The preconditioner's Hessian on the sorted working set ``idx`` (gradient ``grad``)."""
        h = np.diag(-self.scale * grad**2)
        inside = np.isin(idx, self.members)
        if inside.any():
            order = np.argsort(self.members)
            pos = order[np.searchsorted(self.members, idx[inside], sorter=order)]
            where = np.flatnonzero(inside)
            h[np.ix_(where, where)] = self.matrix[np.ix_(pos, pos)]
        return h


class _RowStore:
    """The factors (N, M) of the rows (each None, rows (m, w) or :class:`ProductRows`), in buffers with room to
    grow: rows that stay are moved up in place and new rows appended, without a concatenated copy of the rows
    per extension."""

    def __init__(self, factors):
        self.templates = tuple(factors)
        self.buffers = [None if a is None else np.asarray(a) for a in _parts(factors)]
        self.count = len(factors[0])

    @property
    def factors(self):
        parts = [None if b is None else b[:self.count] for b in self.buffers]
        out = []
        for template in self.templates:
            if isinstance(template, ProductRows):
                out.append(ProductRows(parts.pop(0), parts.pop(0)))
            else:
                out.append(parts.pop(0))
        return tuple(out)

    def replace(self, stay, new):
        """Keep the rows where ``stay`` (in order), then append the rows of ``new`` (same form)."""
        kept = np.flatnonzero(stay)
        n = kept.size + len(new[0])
        for k, (buf, add) in enumerate(zip(self.buffers, _parts(new))):
            if buf is None:
                continue
            for dst, src in enumerate(kept.tolist()):  # dst <= src: moving forward in place is safe
                if dst != src:
                    buf[dst] = buf[src]
            if buf.shape[0] < n:
                grown = np.empty((n + n // 2,) + buf.shape[1:], dtype=buf.dtype)
                grown[:kept.size] = buf[:kept.size]
                buf = self.buffers[k] = grown
            buf[kept.size:n] = add
        self.count = n


def _parts(factors):
    """The arrays of ``factors`` in order (a :class:`ProductRows` gives its ``u`` and ``v``)."""
    out = []
    for f in factors:
        out.extend([f.u, f.v] if isinstance(f, ProductRows) else [f])
    return out


def _row_blocks(blocks, index):
    """The dense blocks at ``index`` in single precision for the preconditioner's rows (structured blocks:
    formed without the cache or a symmetrised copy)."""
    if isinstance(blocks, np.ndarray):
        return blocks[index].astype(np.float32)
    return blocks.unsymmetrised(index, dtype=np.float32)


def _gram(factors, *, rows=slice(None)):
    """M M^T - N N^T of ``factors`` = (N, M) (M may be None), for the rows ``rows`` only, in double precision."""
    negative, positive = factors
    h = -_inner(negative, rows)
    return h if positive is None else h + _inner(positive, rows)


def _inner(factor, rows):
    """The inner products of the rows ``rows`` of ``factor`` (rows or :class:`ProductRows`) with all its rows."""
    if isinstance(factor, ProductRows):
        return factor.gram(rows)
    return (factor[rows] @ factor.T).astype(float)

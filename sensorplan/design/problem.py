"""The sensor-placement problem: candidates, information blocks, constraints.

Weights w in [0, 1] on the candidates, sum w = R (new sensors), posterior
precision Q(w) = Q_0 + sum_i w_i I_i with Q_0 = prior precision + blocks of
fixed (existing) sensors.  Linear side constraints: a cost budget, minimum
and maximum counts per span, and a minimum spacing (for every candidate i,
the candidates in [x_i, x_i + spacing) carry at most one sensor: the maximal
cliques of the interval conflict graph, exact for integer layouts).

Owns: DesignProblem.  May import: errors.
"""

from dataclasses import KW_ONLY, dataclass
from functools import cached_property

import numpy as np
import scipy.optimize

from .._errors import ConfigError, SolverError

__all__ = ["DesignProblem", "CHUNK_BYTES"]

CHUNK_BYTES = 2**27  # blocks copied at a time when many are gathered (bounds the temporaries)
SMALL_LAYOUT = 64  # structured blocks: layouts up to this size are summed from their dense blocks


@dataclass(frozen=True, eq=False)
class DesignProblem:
    """A placement problem (internal; built by :func:`~sensorplan.design.recommend.build_problem`).

    The candidates' positions, spans and information blocks and the prior
    (plus existing sensors) ``q0`` are positional; everything else is a
    keyword.
    """

    positions: np.ndarray  # (C,) candidate positions [m]
    spans: np.ndarray  # (C,) span index of each candidate
    blocks: object  # (C, P, P) array, or StructuredBlocks: information of one sensor at each candidate
    q0: np.ndarray  # (P, P) prior + fixed sensors
    _: KW_ONLY
    criterion: object
    count: int
    costs: np.ndarray | None = None
    budget: float | None = None
    span_min: np.ndarray | None = None  # (n_spans,)
    span_max: np.ndarray | None = None
    min_spacing: float = 0.0
    n_spans: int = 1
    posterior_of: object = None  # index -> posterior precision of log EI, when blocks are not Fisher blocks
    kinds: tuple | None = None  # (C,) kind of each candidate (None: all of one kind)
    noise_std: np.ndarray | None = None  # (C,) noise std of each candidate [rad or m]
    fixed: object = None  # SensorLayout of the existing sensors

    def __post_init__(self):
        c = self.positions.size
        if not 1 <= self.count <= c:
            raise ConfigError(f"The 'count' parameter must be between 1 and the number of candidates ({c}). "
                              f"Got {self.count!r} instead.")

    @property
    def n_candidates(self):
        return self.positions.size

    @property
    def n_params(self):
        return self.q0.shape[0]

    @property
    def structured(self):
        """Whether the blocks are held as :class:`~sensorplan.design.blocks.StructuredBlocks` (never all dense)."""
        return not isinstance(self.blocks, np.ndarray)

    @cached_property
    def flat_blocks(self):
        return self.blocks.reshape(self.n_candidates, -1)

    def subset_blocks(self, index):
        """The blocks of the candidates at ``index`` in the same form (array or structured)."""
        return self.blocks.subset(index) if self.structured else self.blocks[index]

    def congruence(self, v, index=None):
        """V^T I_i V for every candidate (or those at ``index``), shape (C, k, k)."""
        if self.structured:
            return (self.blocks if index is None else self.blocks.subset(index)).congruence(v)
        if index is not None:
            return np.matmul(v.T, np.matmul(self.blocks[index], v))
        c, p = self.blocks.shape[:2]
        k = v.shape[1]
        bv = (self.blocks.reshape(c * p, p) @ v).reshape(c, p, k).transpose(0, 2, 1).reshape(c * k, p)
        return (bv @ v).reshape(c, k, k)

    def precision(self, w):
        """Q(w) for weights ``w`` (C,) (from the candidates with a weight only, when they are few)."""
        w = np.asarray(w, dtype=float)
        if self.structured:
            return self.q0 + self.blocks.weighted(w)
        nonzero = np.flatnonzero(w)
        if nonzero.size > w.size // 4:
            return self.q0 + (w @ self.flat_blocks).reshape(self.q0.shape)
        total = self.q0.copy()
        for start in range(0, nonzero.size, self._chunk):
            part = nonzero[start:start + self._chunk]
            total += (w[part] @ self.flat_blocks[part]).reshape(self.q0.shape)
        return total

    def layout_precision(self, index):
        index = list(index)
        if self.structured:
            # a few blocks from the cache (greedy and exchange keep a layout's there) cost less than the sum
            if len(index) <= SMALL_LAYOUT and len(index) - self.blocks.held(index) <= SMALL_LAYOUT // 8:
                blocks = self.blocks.each(index)
                return self.q0 + _summed(blocks) if blocks else self.q0.copy()
            return self.q0 + self.blocks.weighted(np.bincount(index, minlength=self.n_candidates).astype(float))
        step = self._chunk
        if len(index) <= step:
            return self.q0 + self.blocks[index].sum(axis=0)
        total = self.q0.copy()  # many blocks (a baseline's elimination): summed a chunk at a time
        for start in range(0, len(index), step):
            total += self.blocks[index[start:start + step]].sum(axis=0)
        return total

    def block_list(self, index):
        """The dense blocks of the candidates at ``index`` as a list of read-only arrays (structured blocks:
        those in their cache without a copy)."""
        if self.structured:
            return self.blocks.each(index)
        return [self.blocks[i] for i in np.atleast_1d(index)]

    @cached_property
    def _chunk(self):
        """Candidates' blocks gathered at a time (bounds the temporary copies to CHUNK_BYTES)."""
        return max(1, CHUNK_BYTES // max(1, self.flat_blocks.shape[1] * self.flat_blocks.itemsize))

    def block_dot(self, g, index=None):
        """<G, I_i> for every candidate (or those at ``index``), without copying all their blocks."""
        if self.structured:
            return self.blocks.dot(g, index)
        g = np.asarray(g, dtype=float).ravel()
        if index is None:
            return self.flat_blocks @ g
        index = np.asarray(index, dtype=int)
        step = self._chunk
        if index.size > self.n_candidates // 4:  # one pass over all blocks costs less than copying these
            return (self.flat_blocks @ g)[index]
        return np.concatenate([self.flat_blocks[index[s:s + step]] @ g for s in range(0, index.size, step)]
                              + [np.zeros(0)])

    def posterior_precision(self, index):
        """Posterior precision of the parameters for a layout (for reports)."""
        return self.layout_precision(index) if self.posterior_of is None else self.posterior_of(index)

    def utility_of(self, index):
        return self.criterion.utility(self.layout_precision(index))

    def value_of(self, index):
        return self.criterion.value(self.layout_precision(index))

    def gradient(self, w):
        """d utility / d w_i for all candidates."""
        return self.block_dot(self.criterion.gradient_matrix(self.precision(w)))

    # -- linear constraints ---------------------------------------------------------------
    @cached_property
    def inequalities(self):
        """(A_ub, b_ub) of the side constraints (without the box and the sum)."""
        rows, rhs = [], []
        c = self.n_candidates
        if self.budget is not None:
            rows.append(self.costs.copy())
            rhs.append(self.budget)
        for s in range(self.n_spans):
            member = (self.spans == s).astype(float)
            if self.span_max is not None and self.span_max[s] < self.count:
                rows.append(member)
                rhs.append(float(self.span_max[s]))
            if self.span_min is not None and self.span_min[s] > 0:
                rows.append(-member)
                rhs.append(-float(self.span_min[s]))
        for window in self.spacing_windows:
            row = np.zeros(c)
            row[window] = 1.0
            rows.append(row)
            rhs.append(1.0)
        if not rows:
            return np.zeros((0, c)), np.zeros(0)
        return np.array(rows), np.array(rhs)

    @cached_property
    def spacing_windows(self):
        """Maximal groups of candidates closer than the minimum spacing."""
        if self.min_spacing <= 0:
            return []
        order = np.argsort(self.positions)
        x = self.positions[order]
        windows, last_end = [], -1
        for i in range(x.size):
            end = np.searchsorted(x, x[i] + self.min_spacing - 1e-12, side="left")
            if end - i >= 2 and end > last_end:
                windows.append(order[i:end])
                last_end = end
        return windows

    def feasible(self, index):
        """Whether an integer layout (candidate indices) satisfies every constraint."""
        index = list(index)
        if len(index) != self.count or len(set(index)) != len(index):
            return False
        return self.partial_ok(index, final=True)

    def partial_ok(self, index, *, final=False):
        """Whether a partial layout can still be completed to a feasible one (heuristic for mins)."""
        index = list(index)
        if self.budget is not None:
            # the cheapest completion must still fit the budget
            left = self.count - len(index)
            rest = np.delete(self.costs, index)
            if self.costs[index].sum() + np.sort(rest)[:left].sum() > self.budget + 1e-9:
                return False
        counts = np.bincount(self.spans[index], minlength=self.n_spans)
        if self.span_max is not None and np.any(counts > self.span_max):
            return False
        if self.span_min is not None:
            missing = np.maximum(self.span_min - counts, 0).sum()
            if missing > self.count - len(index):
                return False
        if self.min_spacing > 0 and len(index) > 1:
            x = np.sort(self.positions[index])
            if np.any(np.diff(x) < self.min_spacing - 1e-9):
                return False
        return True

    # -- the linear oracle ---------------------------------------------------------------
    def linear_max(self, g):
        """max g^T w over the relaxed feasible set; returns (value, w)."""
        a_ub, b_ub = self.inequalities
        if a_ub.shape[0] == 0:
            top = np.argsort(g)[::-1][: self.count]
            w = np.zeros(self.n_candidates)
            w[top] = 1.0
            return float(g[top].sum()), w
        res = scipy.optimize.linprog(-g, A_ub=a_ub, b_ub=b_ub, A_eq=np.ones((1, self.n_candidates)),
                                     b_eq=[self.count], bounds=(0.0, 1.0), method="highs")
        if res.status != 0:
            raise SolverError(f"The placement constraints are infeasible or the LP failed ({res.message}). "
                              "Relax the budget, span counts or spacing.")
        return float(-res.fun), res.x

    def dual_bound(self, w):
        """Certified bound on the relaxation optimum of the utility from (near-optimal) weights ``w``."""
        return self.criterion.bound(self, w)


def _summed(blocks):
    """The sum of a list of arrays, added in order (the numbers of ``np.sum(stack, axis=0)``)."""
    total = blocks[0].copy()
    for block in blocks[1:]:
        total += block
    return total

"""Exact search for the detect criterion: does any layout of R candidates reach a worst-case d^2?

Branch and bound over the combinations of R candidates, one level (sensor)
at a time for all surviving partial layouts at once.  The candidates are
ordered from the ends of the bridge inwards and a layout takes them in that
order: the centres near the ends, which need a sensor close by, are then
settled by the first levels.  The bound is the monotonicity of d^2: for
every centre c,

    d^2_c(A) = min_x [1; -x]^T A_c [1; -x]

is non-decreasing when information is added (the minimum of a larger
quadratic form is larger), so a partial layout S whose remaining sensors
can only come from the candidates after its last one satisfies, for every
completion T,

    d^2_c(S + T) <= d^2_c(A_0 + A_S + sum of all the later candidates),

and is dropped as soon as that bound is below the threshold at one centre.
A complete layout is kept only if its exact d^2 (the design's
:func:`~sensorplan.design.criteria.detect_algebra.exact_d_squared`, which
equals ``detectability``'s to ~1e-8) reaches the threshold at every centre;
one factorisation of the common nuisance block per layout serves every
centre.  A minimum
spacing is checked on the way; the other side constraints (per-span counts,
budget) on the complete layouts.

The search is exhaustive (no layout is skipped) unless it stops at
``max_nodes`` partial and complete layouts generated, which bounds its
time (about 5-10 microseconds per layout on the embedded examples).
:func:`estimate_nodes` estimates that number beforehand by random dives
down the same tree (Knuth, Estimating the efficiency of backtrack
programs, Math. Comp. 29, 1975), so that a hopeless search is not started.

:func:`certify` turns the search into a certificate for a given layout:
it searches for a layout better than the given one (by a relative 1e-9,
or, when that search is estimated too large, better than value / 0.99,
0.95, ...), adopts any it finds, and when a search completes empty, the
threshold bounds every layout.

Owns: the exact search and the integer certificate.  May import: errors, design.criteria.
"""

from dataclasses import dataclass

import numpy as np

from .detect_algebra import NuisanceFactors

__all__ = ["ExactSearch", "ExactCertificate", "exact_search", "estimate_nodes", "certify", "MAX_NODES", "PROOF_LADDER"]

MAX_NODES = 3_000_000  # partial and complete layouts generated before the search gives up
_CHUNK = 8192  # layouts evaluated together


@dataclass(frozen=True)
class ExactSearch:
    """What :func:`exact_search` found.

    Attributes
    ----------
    layouts : tuple of tuple of int
        Feasible layouts (candidate indices) whose worst-case d^2 reaches the threshold, best first
        (at most ``max_found``).
    values : tuple of float
        Their worst-case d^2.
    complete : bool
        Whether every layout was covered: with no ``layouts``, a proof that none reaches the threshold.
    nodes : int
        Partial and complete layouts generated.
    """

    layouts: tuple
    values: tuple
    complete: bool
    nodes: int


class _Levels:
    """The candidates from the ends inwards, with their packed information (centre rows and nuisance
    blocks apart) and its suffix sums."""

    def __init__(self, problem, threshold, length):
        x = problem.positions
        self.order = np.lexsort((x, np.round(np.minimum(x, length - x), 9)))
        packing = problem.criterion.packing
        self.n = self.order.size
        self.rows, self.nn = (np.ascontiguousarray(f(problem.blocks[self.order]))
                              for f in (packing.rows, packing.nuisance))
        self.suffix_rows, self.suffix_nn = (np.concatenate([np.cumsum(a[::-1], axis=0)[::-1], np.zeros_like(a[:1])])
                                            for a in (self.rows, self.nn))
        self.q0_rows, self.q0_nn = packing.rows(problem.q0), packing.nuisance(problem.q0)
        self.x = problem.positions[self.order]
        self.min_spacing = float(problem.min_spacing)
        self.threshold = float(threshold)
        self.dropped = np.zeros(packing.n_centres)
        self.nodes = 0

    def counts(self, prefixes, left):
        """Last candidate of each partial layout and its number of children (``left`` sensors to add after)."""
        last = prefixes[:, -1] if prefixes.shape[1] else np.full(len(prefixes), -1)
        return last, np.maximum(self.n - left - (last + 1), 0)

    def children(self, prefixes, last, counts):
        """Every partial layout extended by one later candidate (those breaking the spacing dropped)."""
        rows = np.repeat(np.arange(len(prefixes)), counts)
        offset = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
        kids = np.concatenate([prefixes[rows], (offset + np.repeat(last + 1, counts))[:, None]], axis=1)
        self.nodes += len(kids)
        if self.min_spacing > 0 and kids.shape[1] >= 2:
            gaps = np.abs(self.x[kids[:, -1:]] - self.x[kids[:, :-1]])
            kids = kids[np.all(gaps >= self.min_spacing - 1e-9, axis=1)]
        return kids

    def _sum(self, blocks, q0, suffix, kids, left):
        total = q0 + blocks[kids[:, 0]]
        for j in range(1, kids.shape[1]):
            total += blocks[kids[:, j]]
        if left > 0:
            total += suffix[kids[:, -1] + 1]
        return total

    def survivors(self, kids, left):
        """Rows of ``kids`` whose bound (``left`` > 0) or exact d^2 (``left`` = 0) reaches the threshold
        at every centre; the centres that dropped most layouts so far are tried first."""
        alive = np.arange(len(kids))
        if alive.size == 0:
            return alive
        factors = NuisanceFactors.of(self._sum(self.nn, self.q0_nn, self.suffix_nn, kids, left))
        order = np.argsort(-self.dropped, kind="stable")
        for group in np.split(order, [2, 10]):
            if alive.size == 0 or group.size == 0:
                break
            rows = self._sum(self.rows[:, group], self.q0_rows[group], self.suffix_rows[:, group], kids[alive], left)
            part = NuisanceFactors(*(a[alive] for a in (factors.nn, factors.scale, factors.inverse, factors.bad)))
            low = part.d_squared(rows) < self.threshold
            self.dropped[group] += low.sum(axis=0)
            alive = alive[~low.any(axis=1)]
        return alive

    def level(self, prefixes, left):
        """Yield the surviving partial layouts one sensor longer, a chunk at a time."""
        last, counts = self.counts(prefixes, left)
        ends = np.cumsum(counts)
        start = 0
        while start < len(prefixes):
            stop = max(start + 1, int(np.searchsorted(ends, ends[start] - counts[start] + _CHUNK, side="right")))
            kids = self.children(prefixes[start:stop], last[start:stop], counts[start:stop])
            yield kids[self.survivors(kids, left)]
            start = stop


def exact_search(problem, threshold, *, length, max_nodes=MAX_NODES, max_found=8):
    """The feasible layouts of ``problem.count`` candidates whose worst-case d^2 (detect criterion, exact)
    is at least ``threshold``, by branch and bound (module docstring); an :class:`ExactSearch`.

    ``length`` is the bridge length [m] (the candidates are taken from both ends inwards).  Stops,
    incomplete, before a level would take the layouts generated above ``max_nodes``.
    """
    tree = _Levels(problem, threshold, length)
    prefixes = np.zeros((1, 0), dtype=int)
    for level in range(1, problem.count):
        left = problem.count - level
        _, counts = tree.counts(prefixes, left)
        if tree.nodes + int(counts.sum()) > max_nodes:
            return ExactSearch((), (), False, tree.nodes)
        prefixes = np.concatenate([np.zeros((0, level), dtype=int), *tree.level(prefixes, left)])
        if len(prefixes) == 0:
            return ExactSearch((), (), True, tree.nodes)
    _, counts = tree.counts(prefixes, 0)
    if tree.nodes + int(counts.sum()) > max_nodes:
        return ExactSearch((), (), False, tree.nodes)
    return _complete_layouts(problem, tree, prefixes, max_found)


def _complete_layouts(problem, tree, prefixes, max_found):
    """The last level: complete layouts that reach the threshold and meet every constraint, until
    ``max_found`` are found (the search is then incomplete unless it was the last chunk)."""
    found = []
    chunks = tree.level(prefixes, 0)
    for chunk in chunks:
        layouts = (tuple(sorted(int(i) for i in tree.order[row])) for row in chunk)
        found += [s for s in layouts if problem.feasible(s)]
        if len(found) >= max_found:
            break
    complete = next(chunks, None) is None
    values = [float(problem.value_of(s)) for s in found]
    best = np.argsort(values, kind="stable")[::-1][:max_found]
    return ExactSearch(tuple(found[i] for i in best), tuple(values[i] for i in best), complete, tree.nodes)


def estimate_nodes(problem, threshold, *, length, dives=32, seed=0):
    """Estimated number of layouts :func:`exact_search` would generate (Knuth's estimator).

    Each dive goes from the root to a leaf through one random surviving child per level; the
    product of the numbers of survivors along the way weights the children generated at each level.
    The mean over ``dives`` is unbiased; its spread is large, so it only tells feasible from hopeless.
    """
    tree = _Levels(problem, threshold, length)
    rng = np.random.default_rng(seed)
    total = 0.0
    for _ in range(dives):
        prefix, weight = np.zeros((1, 0), dtype=int), 1.0
        for level in range(1, problem.count + 1):
            left = problem.count - level
            last, counts = tree.counts(prefix, left)
            total += weight * float(counts[0])
            if left == 0:
                break
            kids = tree.children(prefix, last, counts)
            alive = tree.survivors(kids, left)
            if alive.size == 0:
                break
            weight *= alive.size
            prefix = kids[alive[rng.integers(alive.size)]][None]
    return total / dives


@dataclass(frozen=True)
class ExactCertificate:
    """What :func:`certify` proved.

    Attributes
    ----------
    layout : tuple of int
        The best layout found (the one given, or a better one the search met).
    value : float
        Its worst-case d^2.
    bound : float
        No feasible layout reaches it: a threshold the search proved unreachable, exhaustively.
    method : str
        How the bound was obtained, for the report.
    nodes : int
        Partial and complete layouts generated by all the searches.
    """

    layout: tuple
    value: float
    bound: float
    method: str
    nodes: int


PROOF_LADDER = (1.0, 0.99, 0.95, 0.9, 0.8)  # efficiencies tried, best first, when the search can afford them
STRICT = 1e-9  # "better" means better by this much, relatively (the value's own round-off is ~1e-15)


def certify(problem, layout, value, *, length, max_nodes=MAX_NODES):
    """An :class:`ExactCertificate` for ``layout`` of worst-case d^2 ``value``, or None.

    For the best efficiency e of :data:`PROOF_LADDER` whose search looks affordable
    (:func:`estimate_nodes` at most half of ``max_nodes`` still unused), the exhaustive search for a
    layout reaching value / e (value (1 + STRICT) for e = 1) runs: if it finds one, that layout is
    better, becomes the incumbent and the ladder starts again; if it completes without one, value / e
    bounds every layout.  None when no rung is affordable or the searches stop at ``max_nodes``.
    """
    best_layout, best, nodes = tuple(sorted(int(i) for i in layout)), float(value), 0
    while True:
        threshold = None
        for e in PROOF_LADDER:
            trial = best + STRICT * abs(best) if e == 1.0 else best / e
            trial = max(trial, 1e-300)
            if estimate_nodes(problem, trial, length=length) <= 0.5 * (max_nodes - nodes):
                threshold = trial
                break
        if threshold is None:
            return None
        found = exact_search(problem, threshold, length=length, max_nodes=max_nodes - nodes, max_found=1)
        nodes += found.nodes
        if found.layouts:
            best_layout, best = found.layouts[0], found.values[0]
            continue
        if not found.complete:
            return None
        share = best / threshold
        method = (f"exhaustive branch and bound over every layout: none reaches {threshold:.6g} "
                  f"({100 * share:.4g} % efficiency proven, {nodes} layouts generated)")
        return ExactCertificate(best_layout, best, threshold, method, nodes)

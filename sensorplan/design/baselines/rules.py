"""The built-in baselines: equal spacing, the rule of thumb, Effective Independence, the best random layout.

Owns: the built-in baselines.  May import: design.baselines.registry.
"""

import numpy as np
import scipy.linalg

from .registry import register_baseline

__all__ = ["snap", "equally_spaced", "rule_of_thumb", "effective_independence", "best_random"]


def snap(problem, targets):
    """Nearest feasible free candidate for each target position, in order (None if they do not make a layout)."""
    chosen = []
    for t in targets:
        order = np.argsort(np.abs(problem.positions - t))
        for i in order:
            i = int(i)
            if i not in chosen and problem.partial_ok(chosen + [i]):
                chosen.append(i)
                break
        if len(chosen) == problem.count:
            break
    return chosen if len(chosen) == problem.count else None


@register_baseline("equally_spaced")
def equally_spaced(problem, context):
    """Sensors at the centres of R equal stretches of the bridge."""
    length = context.length
    targets = length * (np.arange(problem.count) + 0.5) / problem.count
    return snap(problem, targets)


@register_baseline("rule_of_thumb")
def rule_of_thumb(problem, context):
    """The paper's rule: stations in (0, L/3) and (2L/3, L) of the spans, spans in turn."""
    support_positions = context.support_positions
    fractions = [1 / 6, 5 / 6, 1 / 12, 11 / 12, 1 / 4, 3 / 4, 1 / 24, 23 / 24, 5 / 24, 19 / 24]
    targets = []
    for f in fractions:
        for a, b in zip(support_positions[:-1], support_positions[1:]):
            targets.append(a + f * (b - a))
    return snap(problem, targets)


EXACT_BELOW = 300  # candidates left at or below which the elimination sums their blocks afresh (small problems: always)


@register_baseline("effective_independence")
def effective_independence(problem, context):
    """Kammer's Effective Independence (1991), by backward elimination.

    The effective independence of a candidate is its share of the
    information, E_i = tr(Q^{-1} I_i) with Q the precision of all remaining
    candidates (the sum over its rows of Kammer's E = diag(J Q^{-1} J^T));
    the candidate with the smallest share is removed, a few at a time when
    many remain, until R are left.
    """
    remaining = list(range(problem.n_candidates))
    q, dropped = None, []
    while len(remaining) > problem.count:
        own = getattr(problem.criterion, "information_share", None)
        if own is not None:  # a criterion with its own information layout (detect) says how to weigh it
            q = problem.layout_precision(remaining)
            share = problem.block_dot(own(q), remaining)
        else:
            # many candidates left: the precision updated by the dropped blocks (one pass over all blocks in all)
            q = problem.layout_precision(remaining) if q is None or len(remaining) <= EXACT_BELOW else \
                q - problem.layout_precision(dropped) + problem.q0
            inv = scipy.linalg.cho_solve((np.linalg.cholesky(q), True), np.eye(q.shape[0]))
            share = problem.block_dot(inv, remaining)
        n_drop = max(1, (len(remaining) - problem.count) // 10)
        drop = set(np.argsort(share)[:n_drop].tolist())
        dropped = [r for j, r in enumerate(remaining) if j in drop]
        remaining = [r for j, r in enumerate(remaining) if j not in drop]
    layout = [i for i in remaining]
    if not problem.feasible(layout):
        ranked = sorted(layout, key=lambda i: i)
        layout = snap(problem, problem.positions[ranked])
    return layout


@register_baseline("best_of_{n_random}_random")
def best_random(problem, context):
    """The best of ``n_random`` random feasible layouts."""
    n = context.n_random
    rng = np.random.default_rng(context.rng)
    best, best_u = None, -np.inf
    for _ in range(n):
        chosen = []
        for i in rng.permutation(problem.n_candidates):
            if problem.partial_ok(chosen + [int(i)]):
                chosen.append(int(i))
            if len(chosen) == problem.count:
                break
        if len(chosen) == problem.count:
            u = problem.utility_of(chosen)
            if u > best_u:
                best, best_u = chosen, u
    return best

"""The levels a design to a requirement tries: counts, or (count, total cost) pairs cheapest first.

Without a budget, or with one cost for every candidate, the levels are the
counts from the smallest allowed to the cap (the budget then caps the count).
With a few distinct costs (per kind), every split of a count among the cost
classes gives a total cost; the levels are the distinct (total cost, count)
pairs within the budget, cheapest first, each searched with that total as
its budget, so the first level that reaches the power is the cheapest.
With many distinct costs (one per candidate) the levels are the counts with
the given budget: the answer is then the smallest count within the budget.

Owns: the levels, and whether they are nested.  May import: design.
"""

import itertools

import numpy as np

__all__ = ["levels", "monotone", "MAX_COST_CLASSES"]

MAX_COST_CLASSES = 3  # distinct candidate costs up to which the levels enumerate total costs


def _cheapest(costs, count):
    return float(np.sort(costs)[:count].sum())


def levels(problem, r_min, cap):
    """The (count, budget) levels from ``r_min`` to ``cap`` sensors, in the order they are tried."""
    counts = range(r_min, cap + 1)
    budget, costs = problem.budget, problem.costs
    if budget is None:
        return [(r, None) for r in counts]
    values, sizes = np.unique(np.round(costs, 12), return_counts=True)
    if values.size == 1 or values.size > MAX_COST_CLASSES:
        return [(r, budget) for r in counts if _cheapest(costs, r) <= budget * (1 + 1e-12) + 1e-12]
    pairs = set()
    for split in itertools.product(*(range(min(int(s), cap) + 1) for s in sizes)):
        r = sum(split)
        total = float(np.dot(split, values))
        if r_min <= r <= cap and total <= budget * (1 + 1e-12) + 1e-12:
            pairs.add((round(total, 9), r))
    return [(r, total) for total, r in sorted(pairs)]


def monotone(problem):
    """Whether the levels are nested: every layout of a level plus one more candidate is a layout of the next
    (no minimum spacing, no per-span maximum, and no budget unless every candidate costs the same), so that
    the best worst-case power can only grow from one level to the next."""
    uniform = problem.budget is None or np.unique(np.round(problem.costs, 12)).size == 1
    return problem.min_spacing == 0 and problem.span_max is None and uniform

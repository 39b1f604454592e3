"""Column generation: a relaxation solved on a working set of candidates that grows until it is certified.

The restricted problem over the working set is solved (loosely in the early
rounds, which only locate the support); the certificate over *all*
candidates then gives the bound, and the candidates whose gradient beats
the multiplier of the count constraint (or that the certificate's linear
maximiser uses) join the working set, while candidates that look out
(small weight, gradient below the multiplier) leave it, each at most once
so that the rounds cannot cycle.  The rounds stop when the certified
relative gap is below the tolerance.  Used by the interior-point method of
smooth criteria (:mod:`.smooth`) and by the epigraph method of the detect
criterion (:mod:`.detect_epigraph`).

Owns: WorkingSet, Round, column_generation.  May import: design.relaxation.base.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["WorkingSet", "Round", "column_generation", "initial_size"]


def initial_size(n_candidates, count, divisor, *, cap=None):
    """Size of a first working set: a few times the count, at least 1/``divisor`` of the candidates (but
    not more than ``cap``, when given, unless a few times the count is)."""
    share = n_candidates // divisor if cap is None else min(n_candidates // divisor, cap)
    return min(n_candidates, max(4 * count + 20, share))


class WorkingSet:
    """The candidates a restricted problem is solved over, and those that already left it once."""

    def __init__(self, n_candidates, initial, *, start_layout=None, drop_below=1e-2, enter_share=0.5):
        self.n_candidates = n_candidates
        self.enter_share = enter_share  # at most this share of the set's size enters per round (or 2 R, or 20)
        self.drop_below = drop_below  # a member with a smaller weight (and a gradient below the threshold) leaves
        self.members = set(initial)
        if start_layout is not None:
            self.members |= {int(i) for i in start_layout}
        self.dropped = set()

    def __len__(self):
        return len(self.members)

    @property
    def complete(self):
        """Whether every candidate is in the set."""
        return len(self.members) == self.n_candidates

    def index(self):
        """The members as a sorted index array."""
        return np.array(sorted(self.members))

    def fill(self):
        """Put every candidate in (when the constraints need candidates outside the set); returns the index."""
        self.members = set(range(self.n_candidates))
        return np.arange(self.n_candidates)

    def entering(self, idx, grad, threshold, maximiser, count):
        """Candidates outside ``idx`` whose gradient beats ``threshold`` (the best first, a bounded
        number), plus those the certificate's ``maximiser`` uses."""
        outside = np.setdiff1d(np.arange(self.n_candidates), idx)
        enter = outside[grad[outside] > threshold]
        enter = enter[np.argsort(-grad[enter], kind="stable")][: max(2 * count, 20, int(self.enter_share * idx.size))]
        return np.union1d(enter, np.setdiff1d(np.nonzero(maximiser > 1e-9)[0], idx))

    def update(self, idx, x, grad, threshold, enter):
        """Drop the members that look out (weight ``x`` below ``drop_below``, gradient below ``threshold``;
        each at most once, so the rounds cannot cycle), then add ``enter``."""
        drop = [i for i in idx[(x < self.drop_below) & (grad[idx] < threshold)].tolist() if i not in self.dropped]
        self.dropped.update(drop)
        self.members -= set(drop)
        self.members |= set(enter.tolist())


@dataclass(frozen=True, kw_only=True)
class Round:
    """One restricted solve and its certificate over all candidates.

    ``idx`` the working set it was solved on and ``x`` its weights there;
    ``weights`` (C,) the repaired relaxed point; ``threshold`` the multiplier
    of sum(w) = R in the units of ``entry_gradient()``, the gradient over all
    candidates that decides who enters (computed only when needed);
    ``maximiser`` the certificate's linear maximiser.
    """

    idx: np.ndarray
    x: np.ndarray
    weights: np.ndarray
    utility: float
    bound: float
    gap: float
    threshold: float
    maximiser: np.ndarray
    iterations: int
    entry_gradient: Callable[[], np.ndarray]


def column_generation(problem, working, solve_round, *, tol, max_rounds, first_tol=1e-3):
    """Rounds of ``solve_round(working, idx, weights, inner_tol) -> Round`` until the certified relative
    gap is <= ``tol`` (or the set is complete and solved accurately, or nothing enters).  The first rounds
    are solved to the relative tolerance ``first_tol``, the later ones to a tenth of the last gap.

    Returns (last Round, rounds, total inner iterations).
    """
    weights, iterations, inner = None, 0, first_tol  # early rounds only locate the support: solve them loosely
    for rounds in range(1, max_rounds + 1):
        result = solve_round(working, working.index(), weights, inner)
        iterations += result.iterations
        weights = result.weights
        if result.gap <= tol or working.complete and inner <= 0.1 * tol:
            break
        grad = result.entry_gradient()
        enter = working.entering(result.idx, grad, result.threshold, result.maximiser, problem.count)
        if enter.size == 0:
            if inner <= 0.1 * tol:
                break
            inner = 0.1 * tol  # the support is found: solve accurately
            continue
        inner = max(0.1 * tol, min(inner, 0.1 * result.gap))
        working.update(result.idx, result.x, grad, result.threshold, enter)
    return result, rounds, iterations

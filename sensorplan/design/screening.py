"""The exact best candidate to add to a precision, most candidates settled by bounds refined on the survivors.

Greedy and exchange need argmax_i utility(Q + I_i) exactly.  On large
candidate grids the criterion's cheap bounds (the eigen-split with a few
eigenvectors) leave hundreds of candidates whose bound beats the best
value found, and each exact evaluation forms a dense block and factorises
it.  The criterion's ``subset_bounds`` with more eigenvectors (tighter for
a larger k) computed for those survivors only leave fewer, which are
evaluated exactly.  The answer is the one of evaluating every candidate
whose first bound beats the best value: the largest exact value, ties
going to the candidate first in the order of the first bounds.  (The
concavity bound at the best candidate evaluated, utility(Q + I_b) +
<G_b, I_i - I_b>, is not used: on a multi-span bridge it is looser than
the eigen-split even for the neighbours of b.)

Owns: best_candidate, slack, REFINE_K, BOUND_BYTES.  May import: nothing of the package.
"""

import numpy as np

__all__ = ["best_candidate", "slack", "REFINE_K"]

# (k, n): in turn, when more than n candidates survive, the eigen-split bounds for them with k eigenvectors (each
# costs about as much as n exact evaluations: a fixed part growing with k, then k^2 a candidate)
REFINE_K = ((16, 16), (32, 40), (64, 64), (128, 96))
BOUND_BYTES = 2**28  # size of one (n, k, k) array of eigen-split blocks computed at a time


def slack(u):
    """Round-off allowance on a bound (the bound and the exact value are computed differently)."""
    return 1e-9 * max(1.0, abs(u))


def best_candidate(problem, q, order, bound, evaluate, *, floor=-np.inf, usable=None, batch=8, refine=(),
                   shift=0.0, eig=None):
    """(index, value) of the candidate of ``order`` with the largest exact value above ``floor``, or (None, floor).

    ``order`` lists candidates by decreasing ``bound`` (an array over all
    candidates, bound[i] >= value of i, round-off allowance included);
    ``evaluate(list, v)`` gives the exact values (utility(Q + I_i) - ``shift``; any number not above the utility
    ``v`` to beat where it is not above) of a list, ``batch`` at a time; ``usable(i)`` whether a candidate may be
    taken (checked only for those a bound cannot exclude).  With ``refine``
    ((k, n) pairs, see ``REFINE_K``), in turn while more than n candidates
    survive, their bounds are lowered to the criterion's tighter
    ``subset_bounds`` with k eigenvectors (``eig``: Q's eigendecomposition,
    computed if needed), and the best few survivors are evaluated;
    ``bound`` is updated in place (still a valid bound).
    """
    rank = {int(i): n for n, i in enumerate(order)}
    best = [None, floor]
    seen = set()

    def take(group):
        seen.update(group)
        for i, u in zip(group, evaluate(group, best[1] + shift) if group else ()):
            if u > best[1] or (u == best[1] and best[0] is not None and rank[i] < rank[best[0]]):
                best[:] = [i, u]

    def survivors(candidates):
        return [i for i in candidates if i not in seen and bound[i] > best[1]]

    alive = [int(i) for i in order if bound[i] > floor]
    first = []
    for i in alive:  # the best few by the first bounds set the value to beat
        if len(first) == batch:
            break
        if usable is None or usable(i):
            first.append(i)
        else:
            seen.add(i)
    take(first)
    alive = [i for i in survivors(alive) if usable is None or usable(i)]
    for k, above in refine:
        if len(alive) <= above:
            continue
        tight = _tighter(problem, q, alive, k, eig)
        if tight is None:
            break
        eig = tight[1]
        bound[alive] = np.minimum(bound[alive], tight[0] - shift)
        alive = sorted(survivors(alive), key=lambda i: -bound[i])
        take(alive[:batch])
        alive = survivors(alive)
    pending = []
    for i in sorted(alive, key=lambda i: -bound[i]):
        if bound[i] <= best[1]:
            break
        pending.append(i)
        if len(pending) == batch:
            take(pending)
            pending = []
    take(pending)
    return best[0], best[1]


def _tighter(problem, q, index, k, eig):
    """(bounds on utility(Q + I_i) for ``index`` with the round-off allowance, Q's eigendecomposition), or None
    when the criterion has no eigen-split bounds."""
    method = getattr(problem.criterion, "subset_bounds", None)
    if method is None:
        return None
    if eig is None:
        eig = np.linalg.eigh(0.5 * (q + q.T))
    index = np.asarray(index, dtype=int)
    step = max(1, BOUND_BYTES // (8 * k * k))  # candidates a call: bounds the (n, k, k) temporaries
    parts = [method(problem, q, index[s:s + step], k=k, eig=eig) for s in range(0, index.size, step)]
    if any(part is None for part in parts):
        return None
    tight = np.concatenate([np.asarray(part, dtype=float) for part in parts])
    return tight + 1e-9 * np.maximum(1.0, np.abs(tight)), eig

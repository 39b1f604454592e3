"""The exact best candidate to add to a precision, most candidates settled by bounds refined on the survivors.

Greedy and exchange need argmax_i utility(Q + I_i) exactly.  On large
candidate grids the criterion's cheap bounds (the eigen-split with a few
eigenvectors) leave hundreds of candidates whose bound beats the best
value found, and each exact evaluation forms a dense block and factorises
it.  The criterion's ``subset_bounds`` with more eigenvectors (tighter for
a larger k) computed for those survivors only leave fewer, which are
evaluated exactly.  Criteria with ``split_bounds`` do better: the
survivors are close candidates whose whitened blocks L^-1 I_i L^-T share
a few directions, so a split of the whitened space along the leading
eigenvectors of their sum leaves almost nothing of them to the first-order
part of the bound.  The answer is the one of evaluating every candidate
whose first bound beats the best value: the largest exact value, ties
going to the candidate first in the order of the first bounds.  (The
concavity bound at the best candidate evaluated, utility(Q + I_b) +
<G_b, I_i - I_b>, is not used: on a multi-span bridge it is looser than
the eigen-split even for the neighbours of b.)

Owns: best_candidate, slack, REFINE_K, LOCAL_K, HALVES_ABOVE, BOUND_BYTES, PREFETCH.  May import: nothing of the package.
"""

import numpy as np
import scipy.linalg

__all__ = ["best_candidate", "slack", "REFINE_K", "LOCAL_K"]

# (k, n): in turn, when more than n candidates survive, the eigen-split bounds for them with k eigenvectors (each
# costs about as much as n exact evaluations: a fixed part growing with k, then k^2 a candidate)
REFINE_K = ((16, 16), (32, 40), (64, 64), (128, 96))
# k: in turn, while evaluating the survivors would cost more than one such level, the criterion's split bounds
# along the k leading eigenvectors of the whitened sum of the survivors' blocks (close candidates' blocks share
# a few directions); costs in factorisations of Q + I_i
LOCAL_K = (32, 64, 128)
LOCAL_COST = 60  # one level: the survivors' sum, its whitening and eigenvectors, congruences, inner products
FORM_COST = 2  # forming a candidate's dense block (when not held) on top of its factorisation
# candidates above which a level of split bounds takes each half (by position) along its own eigenvectors (on a
# six-span viaduct with stiff end springs A's greedy took 10.9 s instead of 19.3 s; within the noise elsewhere)
HALVES_ABOVE = 200
BOUND_BYTES = 2**28  # size of one (n, k, k) array of eigen-split blocks computed at a time
# candidates without a bound whose dense blocks are formed together when the next one to evaluate is not held (the
# pass over the family's shared products costs about as much as forming a few blocks)
PREFETCH = 8


def slack(u):
    """Round-off allowance on a bound or an array of bounds (the bound and the exact value are computed
    differently)."""
    return 1e-9 * np.maximum(1.0, np.abs(u))


def best_candidate(problem, q, order, bound, evaluate, *, floor=-np.inf, usable=None, batch=1, refine=(),
                   local=(), shift=0.0, eig=None):
    """(index, value) of the candidate of ``order`` with the largest exact value above ``floor``, or (None, floor).

    ``order`` lists candidates by decreasing ``bound`` (an array over all
    candidates, bound[i] >= value of i, round-off allowance included);
    ``evaluate(list, v)`` gives the exact values (utility(Q + I_i) - ``shift``; any number not above the utility
    ``v`` to beat where it is not above) of a list, ``batch`` at a time; ``usable(i)`` whether a candidate may be
    taken (checked only for those a bound cannot exclude).  With ``refine``
    ((k, n) pairs, see ``REFINE_K``), in turn while more than n candidates
    survive, their bounds are lowered to the criterion's ``subset_bounds``
    with k eigenvectors (``eig``: Q's eigendecomposition, computed if needed)
    and the best ``batch`` survivors are evaluated; then likewise with ``local`` (k
    in turn, see ``LOCAL_K``) to the criterion's ``split_bounds`` along the k
    leading eigenvectors of the survivors' whitened summed blocks, while
    evaluating them would cost more.  ``bound`` is updated in place.
    """
    # blocks formed ahead only where no split bounds follow (those settle most candidates without their blocks)
    hold = problem.blocks.hold if problem.structured and not local else None
    search = _Search(order, bound, evaluate, floor, batch, shift, hold)
    alive = [int(i) for i in order if bound[i] > floor]
    first = []
    for i in alive:  # the best ``batch`` by the first bounds set the value to beat
        if len(first) == batch:
            break
        if usable is None or usable(i):
            first.append(i)
        else:
            search.seen.add(i)
    search.take(first)
    alive = [i for i in search.survivors(alive) if usable is None or usable(i)]
    for k, above in refine:
        if len(alive) > above:
            tight = _tighter(problem, q, alive, k, eig)
            if tight is None:
                break
            eig = tight[1]
            alive = search.tighten(alive, tight[0])
    for k in local:
        tight = _split(problem, q, alive, k) if _worth_splitting(problem, alive) else None
        if tight is None:
            break
        alive = search.tighten(alive, tight)
    search.settle(alive)
    return search.best, search.value


class _Search:
    """The state of :func:`best_candidate`: the best exact value so far and the candidates evaluated."""

    def __init__(self, order, bound, evaluate, floor, batch, shift, hold=None):
        self.rank = {int(i): n for n, i in enumerate(order)}
        self.bound, self.evaluate, self.batch, self.shift = bound, evaluate, batch, shift
        self.best, self.value = None, floor
        self.seen = set()
        self.hold = hold

    def take(self, group, ahead=()):
        """Evaluate ``group``; ties go to the candidate first in ``order``.  With ``hold`` (structured blocks),
        a group whose dense blocks are not held has them formed together with those of the next candidates
        ``ahead`` that will be evaluated whatever the values (no bound; up to ``PREFETCH`` in all): one pass over
        the shared products instead of one per block."""
        if self.hold is not None and group:
            rest = [i for i in ahead if self.bound[i] == np.inf and i not in self.seen and i not in group]
            self.hold(list(group) + rest[:max(0, PREFETCH - len(group))], first=len(group))
        self.seen.update(group)
        for i, u in zip(group, self.evaluate(group, self.value + self.shift) if group else ()):
            if u > self.value or (u == self.value and self.best is not None and self.rank[i] < self.rank[self.best]):
                self.best, self.value = i, u

    def survivors(self, candidates):
        return [i for i in candidates if i not in self.seen and self.bound[i] > self.value]

    def tighten(self, alive, tight):
        """Lower the bounds of ``alive`` to ``tight``, evaluate the best ``batch``, return the survivors."""
        self.bound[alive] = np.minimum(self.bound[alive], tight - self.shift)
        alive = sorted(self.survivors(alive), key=lambda i: -self.bound[i])
        self.take(alive[:self.batch], alive)
        return self.survivors(alive)

    def settle(self, alive):
        """Evaluate ``alive`` by decreasing bound, ``batch`` at a time, until no bound beats the best value."""
        pending = []
        alive = sorted(alive, key=lambda i: -self.bound[i])
        for n, i in enumerate(alive):
            if self.bound[i] <= self.value:
                break
            pending.append(i)
            if len(pending) == self.batch:
                self.take(pending, alive[n + 1:n + PREFETCH])
                pending = []
        self.take(pending)


def _tighter(problem, q, index, k, eig):
    """(bounds on utility(Q + I_i) for ``index`` with the round-off allowance, Q's eigendecomposition), or None
    when the criterion has no eigen-split bounds."""
    method = getattr(problem.criterion, "subset_bounds", None)
    if method is None:
        return None
    if eig is None:
        eig = np.linalg.eigh(0.5 * (q + q.T))
    tight = _in_chunks(lambda part: method(problem, q, part, k=k, eig=eig), index, k)
    return None if tight is None else (tight, eig)


def _worth_splitting(problem, alive):
    """Whether evaluating the candidates ``alive`` exactly would cost more than a level of split bounds."""
    if len(alive) > LOCAL_COST:
        return True
    return len(alive) + FORM_COST * (len(alive) - problem.blocks.held(alive)) > LOCAL_COST


def _split(problem, q, index, k):
    """Bounds on utility(Q + I_i) for ``index`` with the round-off allowance from the criterion's split bounds
    along the k leading eigenvectors of L^-1 (sum of their blocks) L^-T (Q = L L^T), or None when the criterion
    has none.  More than ``HALVES_ABOVE`` candidates are split into two halves by position, each with the
    eigenvectors of its own sum: survivors spread along a long bridge share fewer directions than either half."""
    index = np.asarray(index, dtype=int)
    chol = np.linalg.cholesky(0.5 * (q + q.T))
    if index.size <= HALVES_ABOVE:
        return _split_along(problem, q, chol, index, k)
    order = np.argsort(problem.positions[index], kind="stable")
    out = np.empty(index.size)
    for half in (order[:index.size // 2], order[index.size // 2:]):
        part = _split_along(problem, q, chol, index[half], k)
        if part is None:
            return None
        out[half] = part
    return out


def _split_along(problem, q, chol, index, k):
    """:func:`_split` of ``index`` along the eigenvectors of its own sum (``chol``: Q's Cholesky factor)."""
    total = problem.layout_precision(index) - problem.q0  # the blocks held are summed, the others by structure
    white, info = scipy.linalg.lapack.dsygst(0.5 * (total + total.T), chol, itype=1, lower=1)  # L^-1 total L^-T
    if info != 0:
        return None
    white = np.tril(white) + np.tril(white, -1).T  # dsygst forms one triangle
    p = q.shape[0]
    k = min(k, p)
    if 2 * k <= p:  # a few eigenvectors cost less than all
        basis = scipy.linalg.eigh(white, subset_by_index=[p - k, p - 1], driver="evr", check_finite=False)[1]
    else:
        basis = scipy.linalg.eigh(white, driver="evd", check_finite=False)[1][:, p - k:]
    return _in_chunks(lambda part: problem.criterion.split_bounds(problem, q, part, basis=basis, chol=chol), index, k)


def _in_chunks(bounds, index, k):
    """``bounds(part)`` over ``index`` a part at a time (a part's (n, k, k) temporaries within ``BOUND_BYTES``),
    with the round-off allowance; None if the criterion gave none."""
    index = np.asarray(index, dtype=int)
    step = max(1, BOUND_BYTES // (8 * k * k))
    parts = [bounds(index[s:s + step]) for s in range(0, index.size, step)]
    if any(part is None for part in parts):
        return None
    tight = np.concatenate([np.asarray(part, dtype=float) for part in parts])
    return tight + slack(tight)

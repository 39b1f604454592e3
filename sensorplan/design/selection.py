"""Integer layouts: greedy (exact steps, pruned by upper bounds), exchange, rounding, baselines."""

import numpy as np
import scipy.linalg

from .._errors import SolverError

__all__ = ["iter_greedy", "greedy", "exchange", "round_weights", "baselines"]


def _upper_bounds(problem, q, k=16):
    """Upper bounds b_i >= utility(Q + I_i) for every candidate i.

    Split R^P into V, the k eigenvectors of Q with the smallest eigenvalues
    (where an added block matters most), and its complement W (eigenvalues
    Lambda_W).  Then, with S_i = V^T (Q + I_i) V = Lambda_V + V^T I_i V:

    * E (Cauchy interlacing): lambda_min(Q + I_i) <= lambda_min(S_i);
    * D (Fischer's inequality, then concavity of log det on W):
      log det(Q + I_i) <= log det S_i + log det Lambda_W + tr(Lambda_W^-1 W^T I_i W);
    * A with all parameters as targets (tr(M^-1) >= tr(V^T M V)^-1 + tr(W^T M W)^-1,
      then convexity of tr X^-1 on W):
      tr (Q + I_i)^-1 >= tr S_i^-1 + tr Lambda_W^-1 - tr(Lambda_W^-2 W^T I_i W);
    * otherwise concavity: utility(Q + I_i) <= utility(Q) + <G(Q), I_i>.

    Candidates can then be evaluated best bound first and a search stopped
    once no bound beats the best exact value found.
    """
    crit = problem.criterion
    p = q.shape[0]
    targets_all = crit.name == "A" and crit.targets.shape[0] == p and np.array_equal(crit.targets, np.eye(p))
    if crit.name not in ("E", "D") and not targets_all:
        u = crit.utility(q)
        return u, u + problem.flat_blocks @ crit.gradient_matrix(q).ravel()
    k = min(p, k)
    lam, vec = np.linalg.eigh(0.5 * (q + q.T))
    v, w = vec[:, :k], vec[:, k:]
    c = problem.n_candidates
    # V^T I_i V for all i as two tall products (one BLAS call each)
    bv = (problem.blocks.reshape(c * p, p) @ v).reshape(c, p, k).transpose(0, 2, 1).reshape(c * k, p)
    small = (bv @ v).reshape(c, k, k)
    small[:, np.arange(k), np.arange(k)] += lam[:k]
    if crit.name == "E":
        return float(lam[0]), np.linalg.eigvalsh(small)[:, 0]
    if crit.name == "D":
        logdet = 2.0 * np.log(np.diagonal(np.linalg.cholesky(small), axis1=1, axis2=2)).sum(axis=1)
        first = problem.flat_blocks @ ((w / lam[k:]) @ w.T).ravel()
        return float(np.sum(np.log(lam))), logdet + float(np.sum(np.log(lam[k:]))) + first
    trace = np.trace(np.linalg.inv(small), axis1=1, axis2=2)
    first = problem.flat_blocks @ ((w / lam[k:] ** 2) @ w.T).ravel()
    return -float(np.sum(1.0 / lam)), -(trace + float(np.sum(1.0 / lam[k:])) - first)


def _slack(u):
    """Round-off allowance on a bound (the bound and the exact value are computed differently)."""
    return 1e-9 * max(1.0, abs(u))


def iter_greedy(problem, *, start=()):
    """Yield ``(index, utility)`` as candidates are added greedily.

    For D lazy evaluations are used: the gains of D are submodular (they can
    only shrink as the layout grows), so a stale gain is an upper bound
    (the first step uses the bounds of :func:`_upper_bounds`).  Other
    criteria evaluate candidates in
    decreasing order of the upper bound of :func:`_upper_bounds` and
    stop when no remaining bound beats the best gain found: the result is
    the exact greedy step.
    """
    chosen = list(start)
    crit = problem.criterion
    lazy = crit.name == "D"
    bounds = None
    while len(chosen) < problem.count:
        q = problem.layout_precision(chosen)
        taken = set(chosen)
        ok = [i for i in range(problem.n_candidates)
              if i not in taken and problem.partial_ok(chosen + [i])]
        if not ok:
            raise SolverError("Greedy selection found no feasible candidate; relax the constraints.")
        if lazy:
            u_q = crit.utility(q)
            if bounds is None:  # first step: the bounds of _upper_bounds, as gains
                bounds = _upper_bounds(problem, q)[1] - u_q + _slack(u_q)
            order = sorted(ok, key=lambda i: -bounds[i])
            best, best_gain = None, -np.inf
            for i in order:
                if bounds[i] <= best_gain:
                    break
                gain = crit.utility(q + problem.blocks[i]) - u_q
                bounds[i] = gain + _slack(u_q)
                if gain > best_gain:
                    best, best_gain = i, gain
            chosen.append(best)
        else:
            _, ub = _upper_bounds(problem, q)
            ok = np.array(ok)
            best, best_u = None, -np.inf
            for i in ok[np.argsort(-ub[ok], kind="stable")]:
                if ub[i] + _slack(ub[i]) <= best_u:
                    break
                u = crit.utility(q + problem.blocks[i])
                if u > best_u:
                    best, best_u = int(i), u
            chosen.append(best)
        yield list(chosen), problem.utility_of(chosen)


def greedy(problem, *, start=()):
    """Greedy layout (indices) and its utility."""
    chosen, utility = list(start), None
    for chosen, utility in iter_greedy(problem, start=start):
        pass
    if utility is None:
        utility = problem.utility_of(chosen)
    return chosen, utility


def _subproblem(problem, index):
    """The placement problem restricted to the candidates ``index`` (sorted)."""
    from dataclasses import replace

    return replace(problem, positions=problem.positions[index], spans=problem.spans[index],
                   blocks=problem.blocks[index], costs=None if problem.costs is None else problem.costs[index])


COARSE_ABOVE = 300  # candidates above which exchange searches a coarse grid first


def exchange(problem, layout, *, max_sweeps=50, coarse_above=None, polish=True):
    """Swap local search from ``layout`` (see :func:`_exchange`), coarse to fine on large grids.

    With more than ``coarse_above`` candidates (default ``COARSE_ABOVE``), the search first runs on
    every k-th candidate (plus the start layout), k = C // (coarse_above / 2),
    then on all candidates from the coarse result: neighbouring candidates
    carry nearly the same information, so most swaps are settled on the
    coarse grid.  The polish first moves each sensor to the best of its k
    nearest candidates on either side (exact values, a few per sensor) until
    no such move improves, then runs the full search, which certifies
    that no swap with any candidate improves.  The result is a local
    optimum of the full problem either way, unless ``polish`` is false: then
    the coarse local optimum is returned (to polish only the best of several
    starts).
    """
    layout = [int(i) for i in layout]
    c = problem.n_candidates
    coarse_above = COARSE_ABOVE if coarse_above is None else coarse_above
    if c > coarse_above:
        step = max(2, c // (coarse_above // 2))
        index = np.union1d(np.arange(0, c, step), layout)
        local = {int(j): n for n, j in enumerate(index)}
        sub = _subproblem(problem, index)
        coarse, util = _exchange(sub, [local[i] for i in layout], max_sweeps=max_sweeps)
        layout = [int(index[n]) for n in coarse]
        if not polish:
            return layout, util
        layout = _local_moves(problem, layout, step, max_sweeps=max_sweeps)
    return _exchange(problem, layout, max_sweeps=max_sweeps)


def _local_moves(problem, layout, radius, *, max_sweeps=50):
    """Move sensors to better candidates among their ``radius`` neighbours on each side (by position)."""
    layout = list(layout)
    order = np.argsort(problem.positions, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    best = problem.utility_of(layout)
    for _ in range(max_sweeps):
        moved = False
        for pos in range(len(layout)):
            rest = layout[:pos] + layout[pos + 1:]
            r0 = rank[layout[pos]]
            cand_best = _best_replacement(problem, rest, problem.layout_precision(rest), set(layout), best,
                                          order[max(0, r0 - radius): r0 + radius + 1])
            if cand_best is not None:
                layout[pos] = cand_best
                best = problem.utility_of(layout)
                moved = True
        if not moved:
            break
    return layout


def _best_replacement(problem, rest, q_rest, taken, best, order, ub=None):
    """The candidate of ``order`` whose addition to ``rest`` beats ``best`` the most (None if none does).

    Utilities are exact; with upper bounds ``ub`` (``order`` by decreasing
    bound) the scan stops once no bound beats the best value found.
    """
    crit = problem.criterion
    cand_best, cand_util = None, best + 1e-12 * max(1.0, abs(best))
    for i in order:
        if ub is not None and ub[i] + _slack(ub[i]) <= cand_util:
            break
        i = int(i)
        if i in taken or not problem.partial_ok(rest + [i]):
            continue
        u = crit.utility(q_rest + problem.blocks[i])
        if u > cand_util:
            cand_best, cand_util = i, u
    return cand_best


def _exchange(problem, layout, *, max_sweeps=50):
    """Swap local search from ``layout``: best improving swap per removed sensor, until none.

    Sensors are visited in turn; the search stops when a whole round of
    sensors in a row has no improving swap (or after ``max_sweeps`` rounds).

    For each sensor in turn the best replacement is found exactly, but
    candidates are evaluated in decreasing order of the upper bound of
    :func:`_upper_bounds` on the layout without that sensor, stopping once
    no bound beats the best value found (most candidates are never
    evaluated).
    """
    layout = list(layout)
    best = problem.utility_of(layout)
    n = len(layout)
    quiet, pos, visited = 0, 0, 0  # positions in a row without an improving swap
    while quiet < n and visited < max_sweeps * n:
        rest = layout[:pos] + layout[pos + 1:]
        q_rest = problem.layout_precision(rest)
        _, ub = _upper_bounds(problem, q_rest)
        cand_best = _best_replacement(problem, rest, q_rest, set(layout), best, np.argsort(-ub, kind="stable"), ub)
        if cand_best is not None:
            layout = rest[:pos] + [cand_best] + rest[pos:]
            best = problem.utility_of(layout)
            quiet = 0
        else:
            quiet += 1
        pos = (pos + 1) % n
        visited += 1
    return layout, best


def round_weights(problem, weights):
    """Largest relaxed weights first, skipping candidates that break a constraint."""
    chosen = []
    for i in np.argsort(weights)[::-1]:
        if problem.partial_ok(chosen + [int(i)]):
            chosen.append(int(i))
        if len(chosen) == problem.count:
            return chosen
    raise SolverError("Rounding could not complete a feasible layout.")


def _snap(problem, targets):
    """Nearest feasible free candidate for each target position, in order."""
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


def equally_spaced(problem, length):
    targets = length * (np.arange(problem.count) + 0.5) / problem.count
    return _snap(problem, targets)


def rule_of_thumb(problem, support_positions):
    """The paper's rule: stations in (0, L/3) and (2L/3, L) of the spans, spans in turn."""
    fractions = [1 / 6, 5 / 6, 1 / 12, 11 / 12, 1 / 4, 3 / 4, 1 / 24, 23 / 24, 5 / 24, 19 / 24]
    targets = []
    for f in fractions:
        for a, b in zip(support_positions[:-1], support_positions[1:]):
            targets.append(a + f * (b - a))
    return _snap(problem, targets)


def effective_independence(problem):
    """Kammer's Effective Independence (1991), by backward elimination.

    The effective independence of a candidate is its share of the
    information, E_i = tr(Q^{-1} I_i) with Q the precision of all remaining
    candidates (the sum over its rows of Kammer's E = diag(J Q^{-1} J^T));
    the candidate with the smallest share is removed, a few at a time when
    many remain, until R are left.
    """
    remaining = list(range(problem.n_candidates))
    while len(remaining) > problem.count:
        q = problem.layout_precision(remaining)
        inv = scipy.linalg.cho_solve((np.linalg.cholesky(q), True), np.eye(q.shape[0]))
        share = problem.flat_blocks[remaining] @ inv.ravel()
        n_drop = max(1, (len(remaining) - problem.count) // 10)
        drop = set(np.argsort(share)[:n_drop].tolist())
        remaining = [r for j, r in enumerate(remaining) if j not in drop]
    layout = [i for i in remaining]
    if not problem.feasible(layout):
        ranked = sorted(layout, key=lambda i: i)
        layout = _snap(problem, problem.positions[ranked])
    return layout


def best_random(problem, n, rng):
    rng = np.random.default_rng(rng)
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


def baselines(problem, *, length, support_positions, n_random=100, rng=0):
    """Baseline layouts by name (None where a baseline cannot satisfy the constraints)."""
    return {
        "equally_spaced": equally_spaced(problem, length),
        "rule_of_thumb": rule_of_thumb(problem, support_positions),
        "effective_independence": effective_independence(problem),
        f"best_of_{n_random}_random": best_random(problem, n_random, rng),
    }

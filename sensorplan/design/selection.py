"""Integer layouts: greedy (exact steps, pruned by upper bounds), exchange, rounding, the best of several starts.

Everything here works through the criterion protocol (utility, upper
bounds, submodularity), so a registered criterion gets greedy and exchange
without changes here.

Owns: greedy, exchange, rounding, the best layout from several starts.
May import: errors, design.problem, design.feasibility, design.screening.
"""

import numpy as np

from .._errors import SolverError
from .feasibility import packing
from .screening import LOCAL_K, REFINE_K, best_candidate, slack

__all__ = ["iter_greedy", "greedy", "exchange", "round_weights", "sample_roundings", "best_layout"]


def _upper_bounds(problem, q):
    """(utility(Q), b) with b_i >= utility(Q + I_i) for every candidate (the criterion's bounds).

    Candidates can then be evaluated best bound first and a search stopped
    once no bound beats the best exact value found.
    """
    return problem.criterion.upper_bounds(problem, q)


def iter_greedy(problem, *, start=()):
    """Yield ``(index, utility)`` as candidates are added greedily.

    For submodular criteria (D) lazy evaluations are used: the gains can
    only shrink as the layout grows, so a stale gain is an upper bound
    (the first step uses the bounds of :func:`_upper_bounds`).  Other
    criteria evaluate candidates in
    decreasing order of the upper bound of :func:`_upper_bounds` and
    stop when no remaining bound beats the best gain found: the result is
    the exact greedy step.  On structured blocks the candidates a bound
    cannot exclude get tighter bounds first (:func:`~sensorplan.design.screening.best_candidate`).
    """
    chosen = list(start)
    crit = problem.criterion
    lazy = crit.submodular
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
                bounds = _upper_bounds(problem, q)[1] - u_q + slack(u_q)

            def gains(group, above, q=q, u_q=u_q):  # every gain exact: they are the bounds of later steps
                out = [u - u_q for u in crit.utilities(q, problem.block_list(group))]
                bounds[group] = np.asarray(out) + slack(u_q)  # gains only shrink: bounds for later steps
                return out

            best, _ = best_candidate(problem, q, sorted(ok, key=lambda i: -bounds[i]), bounds, gains,
                                     refine=_refinements(problem, _refine_levels(problem)),
                                     local=_local_levels(problem), shift=u_q)
        else:
            ub, eig = _first_bounds(problem, q)
            ok = np.array(ok)
            best, _ = best_candidate(problem, q, ok[np.argsort(-ub[ok], kind="stable")],
                                     ub + slack(ub),
                                     lambda group, above, q=q: crit.utilities_above(q, problem.block_list(group), above),
                                     refine=_after_first(problem), local=_local_levels(problem), eig=eig)
        chosen.append(int(best))
        yield list(chosen), problem.utility_of(chosen)


def _after_first(problem, *, split=True):
    """The eigen-split refinements of :func:`~sensorplan.design.screening.best_candidate` after the first bounds
    (:func:`_first_bounds`); none where the split bounds of :func:`_local_levels` are used (``split``)."""
    first = _refine_levels(problem)[0][0]
    return _refinements(problem, tuple(level for level in _refine_levels(problem) if level[0] > first), split=split)


def _refine_levels(problem):
    """The criterion's eigen-split levels (``refine_levels``, where its exact evaluations cost more than a
    factorisation), else ``REFINE_K``; the first level's k is that of every candidate's first bounds.  Levels
    only prune: a search's answer is the same with any."""
    return getattr(problem.criterion, "refine_levels", None) or REFINE_K


def _refinements(problem, levels, *, split=True):
    """The eigen-split ``levels`` on structured blocks (dense blocks cost less to evaluate than tighter bounds);
    with split bounds (:func:`_local_levels`, ``split``) only k <= 16, which the split bounds beat beyond."""
    if not problem.structured:
        return ()
    return tuple(level for level in levels if level[0] <= 16) if split and _local_levels(problem) else levels


def _local_levels(problem, *, split=True):
    """The split-bound levels of :func:`~sensorplan.design.screening.best_candidate`: on structured blocks for
    criteria with ``split_bounds``, unless not ``split``."""
    if not (split and problem.structured) or getattr(problem.criterion, "split_bounds", None) is None:
        return ()
    return LOCAL_K


def _first_bounds(problem, q):
    """(b, eig): the bounds of :func:`_upper_bounds` and Q's eigendecomposition when they came from it (so that
    tighter bounds on the survivors reuse it), else None."""
    method = getattr(problem.criterion, "subset_bounds", None)
    if problem.structured and method is not None:
        # a criterion whose bounds use only the k smallest eigenvectors computes those alone (no eig passed on)
        eig = None if problem.criterion.smallest_eigenvectors_only else np.linalg.eigh(0.5 * (q + q.T))
        ub = method(problem, q, k=_refine_levels(problem)[0][0], eig=eig)
        if ub is not None:
            return ub, eig
    return _upper_bounds(problem, q)[1], None


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
                   blocks=problem.subset_blocks(index), costs=None if problem.costs is None else problem.costs[index],
                   kinds=None if problem.kinds is None else tuple(problem.kinds[i] for i in index),
                   noise_std=None if problem.noise_std is None else problem.noise_std[index])


COARSE_ABOVE = 300  # candidates above which exchange searches a coarse grid first
LOCAL_STRIDE = 4  # the polish's local moves try every (k // LOCAL_STRIDE)-th of k neighbours, then the nearest


def exchange(problem, layout, *, max_sweeps=50, coarse_above=None, polish=True):
    """Swap local search from ``layout`` (see :func:`_exchange`), coarse to fine on large grids.

    With more than ``coarse_above`` candidates (default ``COARSE_ABOVE``), the search first runs on
    every k-th candidate (plus the start layout), k = C // (coarse_above / 2),
    then on all candidates from the coarse result: neighbouring candidates
    carry nearly the same information, so most swaps are settled on the
    coarse grid.  The polish first moves each sensor to the best of every
    s-th of its k nearest candidates on either side (s = k // LOCAL_STRIDE),
    then of its s nearest (exact values, a few per sensor), until no such
    move improves, then runs the full search.  After a swap the full search
    finds that moves a sensor beyond those k neighbours (its neighbours then
    often need small moves), the local moves run again; the full search that
    finds no swap certifies that no swap with any candidate improves.  The result is a local
    optimum of the full problem either way (a swap improves when it gains
    more than the criterion's ``swap_gain`` share of the utility, beyond
    round-off), unless ``polish`` is false: then
    the coarse local optimum is returned (to polish only the best of several
    starts).
    """
    layout, util, converged, step = _coarse(problem, layout, coarse_above, max_sweeps)
    if step is None or not polish:
        return layout, util
    return _polish(problem, layout, step, converged, max_sweeps)


def _coarse(problem, layout, coarse_above, max_sweeps):
    """(layout, utility, converged, k) of the coarse stage of :func:`exchange` (k None: no coarse grid, the
    full search was run)."""
    layout = [int(i) for i in layout]
    c = problem.n_candidates
    coarse_above = COARSE_ABOVE if coarse_above is None else coarse_above
    if c <= coarse_above:
        return *_exchange(problem, layout, max_sweeps=max_sweeps), None
    step = max(2, c // (coarse_above // 2))
    index = np.union1d(np.arange(0, c, step), layout)
    local = {int(j): n for n, j in enumerate(index)}
    # no split bounds on the coarse grid: its candidates lie too far apart to share a few directions, and their
    # dense blocks are held
    coarse, util, converged = _exchange(_subproblem(problem, index), [local[i] for i in layout],
                                        max_sweeps=max_sweeps, split=False)
    return [int(index[n]) for n in coarse], util, converged, step


def _polish(problem, layout, step, converged, max_sweeps):
    """The polish of :func:`exchange` from a coarse result.  A converged coarse result needs no second coarse
    search: its grid (every k-th candidate plus the layout) lies within the one it was optimal on."""
    if not converged:
        layout, _, converged, step = _coarse(problem, layout, None, max_sweeps)
    layout = _local_moves(problem, layout, step, max_sweeps=max_sweeps)
    _, rank = _by_position(problem)
    start = 0
    # a far swap of the full search is followed by the local moves its neighbours need (as many swaps at most as
    # the full search alone could make)
    for _ in range(max_sweeps * len(layout)):
        swapped, util, converged = _exchange(problem, layout, max_sweeps=max_sweeps, first_swap=True, start=start)
        moved = [n for n, (a, b) in enumerate(zip(layout, swapped)) if a != b]  # the sensor that moved
        if converged or not moved:  # (no swap and not converged: out of sweeps)
            return swapped, util
        pos = moved[0]
        far = abs(rank[swapped[pos]] - rank[layout[pos]]) > step
        layout = _local_moves(problem, swapped, step, max_sweeps=max_sweeps) if far else swapped
        # the full search resumes after that sensor unless the local moves changed the layout
        start = (pos + 1) % len(layout) if layout == swapped else 0
    return layout, problem.utility_of(layout)


def _local_moves(problem, layout, radius, *, max_sweeps=50):
    """Move sensors to better candidates among their ``radius`` neighbours on each side (by position): first
    to every s-th of them (s = radius // LOCAL_STRIDE), then among their s neighbours on each side."""
    order, rank = _by_position(problem)
    stride = max(1, radius // LOCAL_STRIDE)
    for reach, step in ((radius, stride), (stride, 1)) if stride > 1 else ((radius, 1),):
        def move(layout, pos, rest, best, reach=reach, step=step):
            r0 = rank[layout[pos]]
            below = min(reach, r0) // step * step  # the grid of every step-th neighbour holds the sensor
            return _best_replacement(problem, rest, problem.layout_precision(rest), set(layout), best,
                                     order[r0 - below: r0 + reach + 1: step])

        layout = _until_quiet(problem, layout, move, max_sweeps)[0]
    return layout


def _by_position(problem):
    """(order, rank): the candidates by position, and each candidate's place in that order."""
    order = np.argsort(problem.positions, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return order, rank


def _until_quiet(problem, layout, replace, max_sweeps, *, first_swap=False, start=0):
    """(layout, utility, converged): the sensors in turn get ``replace(layout, pos, rest, best)`` (a better
    candidate for the sensor at ``pos``, or None) until n sensors in a row get none (converged) or after
    ``max_sweeps`` rounds, or (``first_swap``) after the first improvement, starting at ``start``.  Stopping
    there is where sweeps until one without a change would stop too: the rest of that sweep could only repeat
    the searches of an unchanged layout."""
    layout = list(layout)
    _hold(problem, layout)
    best = problem.utility_of(layout)
    n = len(layout)
    quiet, pos, visited = 0, start, 0  # positions in a row without an improvement
    while quiet < n and visited < max_sweeps * n:
        rest = layout[:pos] + layout[pos + 1:]
        cand = replace(layout, pos, rest, best)
        if cand is not None:
            layout = rest[:pos] + [int(cand)] + rest[pos:]
            best = problem.utility_of(layout)
            quiet = 0
            if first_swap:
                break
        else:
            quiet += 1
        pos = (pos + 1) % n
        visited += 1
    return layout, best, quiet >= n


def _hold(problem, layout):
    """Form the dense blocks of ``layout`` once (structured blocks keep them): the precision of every layout
    without one sensor is then a sum of held blocks, not a pass over the structure."""
    if problem.structured:
        problem.blocks[list(layout)]


def _best_replacement(problem, rest, q_rest, taken, best, order, ub=None, eig=None, *, split=True):
    """The candidate of ``order`` whose addition to ``rest`` beats ``best`` the most (None if none does).

    Utilities are exact; with upper bounds ``ub`` (``order`` by decreasing
    bound) the candidates no bound can exclude are evaluated (on structured
    blocks after tighter bounds for the survivors, ``eig`` the
    eigendecomposition of ``q_rest`` if known), ties going to the first in ``order``; split bounds
    (:func:`_local_levels`) only if ``split``.
    """
    crit = problem.criterion
    # evaluated together, crit.batch_size at a time (cheaper per candidate for some criteria; one at a time
    # otherwise, so that each evaluation is against the best value found before it)
    batch = crit.batch_size
    bound = np.full(problem.n_candidates, np.inf) if ub is None else ub + slack(ub)
    cand, _ = best_candidate(problem, q_rest, [int(i) for i in order], bound,
                             lambda group, above: crit.utilities_above(q_rest, problem.block_list(group), above),
                             floor=_to_beat(problem, best),
                             usable=lambda i: i not in taken and problem.partial_ok(rest + [i]), batch=batch,
                             refine=_after_first(problem, split=split) if ub is not None else (),
                             local=_local_levels(problem, split=split), eig=eig)
    return cand


def _to_beat(problem, best):
    """The value a swap must exceed: ``best`` beyond round-off, and by the criterion's ``swap_gain`` share of it."""
    return best + max(1e-12 * max(1.0, abs(best)), problem.criterion.swap_gain * abs(best))


def _exchange(problem, layout, *, max_sweeps=50, split=True, first_swap=False, start=0):
    """(layout, utility, converged): swap local search from ``layout``, best improving swap per removed sensor,
    until none (converged) or ``max_sweeps`` rounds.

    Sensors are visited in turn; the search stops when a whole round of
    sensors in a row has no improving swap (or after ``max_sweeps`` rounds).

    For each sensor in turn the best replacement is found exactly, but
    candidates are evaluated in decreasing order of the upper bound of
    :func:`_upper_bounds` on the layout without that sensor, stopping once
    no bound beats the best value found (most candidates are never
    evaluated).
    """
    def swap(layout, pos, rest, best):
        q_rest = problem.layout_precision(rest)
        ub, eig = _first_bounds(problem, q_rest)
        return _best_replacement(problem, rest, q_rest, set(layout), best, np.argsort(-ub, kind="stable"), ub, eig,
                                 split=split)

    return _until_quiet(problem, layout, swap, max_sweeps, first_swap=first_swap, start=start)


def round_weights(problem, weights):
    """Largest relaxed weights first, skipping candidates that break a constraint."""
    chosen = []
    for i in np.argsort(weights)[::-1]:
        if problem.partial_ok(chosen + [int(i)]):
            chosen.append(int(i))
        if len(chosen) == problem.count:
            return chosen
    raise SolverError("Rounding could not complete a feasible layout.")


def sample_roundings(problem, weights, n, rng):
    """Up to ``n`` distinct randomised roundings: candidates in a random order favouring large weights
    (keys u^(1 / w), Efraimidis & Spirakis 2006), skipping those that break a constraint."""
    w = np.clip(np.asarray(weights, dtype=float), 0.0, None) + 1e-9
    out = []
    for _ in range(n):
        keys = rng.random(w.size) ** (1.0 / w)
        chosen = []
        for i in np.argsort(-keys):
            if problem.partial_ok(chosen + [int(i)]):
                chosen.append(int(i))
            if len(chosen) == problem.count:
                break
        if len(chosen) == problem.count and sorted(chosen) not in out:
            out.append(sorted(chosen))
    return out


def best_layout(problem, weights, starts, *, greedy_layout=None, rng=None):
    """(method, layout, utility): the best of exchange from the rounded relaxed ``weights``, the greedy
    layout (computed unless given), the best of the ``starts`` (candidate indices or None by name) and,
    for criteria that ask for them, randomised roundings of the weights (seeded by ``rng``).

    On large candidate grids each start is improved on a coarse grid and only
    the best result is polished on all candidates.  Exchange never makes a
    start worse, and a baseline still better than the
    result is used as a start too, so the result is never worse than any
    baseline.
    """
    tried, scored = _starts(problem, weights, starts, greedy_layout, rng)
    best = None

    def consider(method, start):
        # on large grids: the coarse-grid local optimum only; the best one is polished below
        nonlocal best
        layout, util, converged, step = _coarse(problem, start, None, 50)
        if best is None or util > best[2] + 1e-12 * max(1.0, abs(util)):
            best = (method, layout, util, converged, step)

    for method, start in tried:
        consider(method, start)
    for util, name, start in scored[1:]:  # a baseline still better than the result
        if util > best[2]:
            consider(f"exchange from {name}", start)
    method, layout, util, converged, step = best
    if step is not None:
        layout, util = _polish(problem, layout, step, converged, 50)
    elif not converged:  # a converged full search is already the local optimum
        layout, util = exchange(problem, layout)
    return method, layout, util


def _starts(problem, weights, starts, greedy_layout, rng):
    """The (method, layout) starts of :func:`best_layout`, and the feasible ``starts`` as
    (utility, name, layout), best first."""
    tried = []
    try:
        tried.append(("relaxation rounding + exchange", round_weights(problem, weights)))
    except SolverError:
        pass
    if greedy_layout is None:
        try:
            greedy_layout = greedy(problem)[0]
        except SolverError:
            greedy_layout = None
    if greedy_layout is not None:
        tried.append(("greedy + exchange", greedy_layout))
    scored = sorted(((problem.utility_of(s), name, s) for name, s in starts.items() if s is not None),
                    key=lambda t: -t[0])
    if scored:
        tried.append((f"exchange from {scored[0][1]}", scored[0][2]))
    if problem.criterion.random_starts:
        tried += [("randomised rounding + exchange", s) for s in
                  sample_roundings(problem, weights, problem.criterion.random_starts,
                                   np.random.default_rng(rng))]
    if not tried:  # the packing along the bridge (feasibility.packing) when every search failed
        packed = packing(problem.positions, problem.spans, problem.min_spacing, problem.span_max)[:problem.count]
        if problem.feasible(packed):
            tried.append(("packing + exchange", packed))
    if not tried:
        raise SolverError("No feasible layout was found; relax 'budget', 'span_min', 'span_max' or 'min_spacing'.")
    return tried, scored

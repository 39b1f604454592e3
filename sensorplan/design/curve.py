"""The criterion-versus-R curve of a placement problem, without a relaxation or exchange per count.

Owns: criterion_curve.  May import: errors, design.selection, design.relaxation, design.results.
"""

from dataclasses import replace

import numpy as np

from .._errors import SensorplanError
from .results import CurvePoint
from .relaxation import solve_relaxation
from .selection import exchange, greedy, iter_greedy

__all__ = ["criterion_curve", "SEARCH_PER_COUNT_ENTRIES"]

SEARCH_PER_COUNT_ENTRIES = 2_000_000  # C P^2 up to which each count gets its own exchange and relaxation


def criterion_curve(problem, count, curve_max=None, weights=None, layout=None, *, greedy_layout=None):
    """Criterion versus R, for R = 1 .. ``curve_max`` (default the requested count, or up to 3 more while
    that stays <= 12); a count whose constraints cannot be met is reported as failed, not dropped.

    The values are the better of greedy layouts (the prefixes of one greedy run where the side constraints
    allow, :func:`_curve_layouts`) and, given the recommended ``layout``, the layouts obtained from it by
    removing the least useful sensor one at a time or adding greedily (:func:`_around_layout`); the
    recommendation replaces the value at the requested count (:func:`design_result`).  The bounds are linearisations of the criterion (:meth:`Criterion.linearisation`)
    at the relaxed ``weights`` of the requested count scaled to each count and at each greedy layout: each
    is valid for every count, so without side constraints the bound curve is their lower envelope (concave
    in R); with side constraints (each count an LP) a count takes the relaxation's and its own layout's.
    On small problems (C P^2 <= ``SEARCH_PER_COUNT_ENTRIES``) each count also gets an exchange from its
    greedy layout and its own relaxation (the better value, the tighter bound); beyond, no relaxation is
    solved and no exchange is run per count.  ``greedy_layout``, the greedy layout of ``problem`` (in the
    order greedy chose it) when already computed, gives the greedy run's prefixes without running it again.
    """
    if curve_max == 0:
        return ()
    r_max = max(count, min(count + 3, 12)) if curve_max is None else int(curve_max)
    r_max = min(r_max, problem.n_candidates)
    layouts, failures = _curve_layouts(problem, count, r_max, greedy_layout)
    around = {} if layout is None else _around_layout(problem, list(layout), r_max)
    crit = problem.criterion
    scaled = {} if weights is None else {r: np.asarray(weights, dtype=float) * (r / count) for r in range(1, r_max + 1)}
    lines = {("relaxed", r): crit.linearisation(problem, w) for r, w in scaled.items()}
    for r, layout in layouts.items():
        lines[("greedy", r)] = crit.linearisation(problem, _indicator(problem, layout))
    envelope = problem.inequalities[0].shape[0] == 0  # every line at every count costs a sort, not an LP
    small = problem.n_candidates * problem.n_params**2 <= SEARCH_PER_COUNT_ENTRIES
    out = []
    sign = 1.0 if crit.maximise else -1.0
    for r in range(1, r_max + 1):
        if r not in layouts:
            out.append(CurvePoint(r, None, None, failures[r]))
            continue
        sub = replace(problem, count=r)
        util = max(sub.utility_of(layouts[r]), sub.utility_of(around[r]) if r in around else -np.inf)
        used = lines.values() if envelope else [v for k, v in lines.items() if k in (("relaxed", r), ("greedy", r))]
        try:
            bound = min(const + sub.linear_max(g)[0] for const, g in used)
            if small:  # a search and a relaxation per count cost little here: the tightest curve
                util = max(util, exchange(sub, layouts[r])[1])
                bound = min(bound, solve_relaxation(sub, "auto", start_layout=layouts[r]).bound)
        except SensorplanError as exc:
            out.append(CurvePoint(r, None, None, " ".join(str(exc).split())))
            continue
        out.append(CurvePoint(r, float(sign * util), float(sign * max(bound, util))))
    return tuple(out)


def _around_layout(problem, layout, r_max):
    """{count: layout} from ``layout``: the least useful sensor removed one at a time (while the subset stays
    feasible), and greedy additions up to ``r_max``."""
    out = {len(layout): list(layout)}
    current = list(layout)
    while len(current) > 1:
        subsets = [current[:j] + current[j + 1:] for j in range(len(current))]
        sub = replace(problem, count=len(current) - 1)
        feasible = [s for s in subsets if sub.feasible(s)]
        if not feasible:
            break
        current = max(feasible, key=sub.utility_of)
        out[len(current)] = current
    if r_max > len(layout):
        try:
            for chosen, _ in iter_greedy(replace(problem, count=r_max), start=layout):
                out[len(chosen)] = list(chosen)
        except SensorplanError:
            pass
    return out


def _indicator(problem, layout):
    w = np.zeros(problem.n_candidates)
    w[list(layout)] = 1.0
    return w


def _curve_layouts(problem, count, r_max, greedy_layout=None):
    """({count: greedy layout}, {count: reason it failed}).

    The prefixes of one greedy run are feasible for every smaller count unless a per-span minimum applies
    (a prefix may miss it); with a budget the run is for the requested count (a larger count may not fit
    the budget at all), and the counts beyond it get a greedy run each.  A given ``greedy_layout`` of
    ``problem`` (its count, in greedy order) is the run's start: greedy is deterministic, so its prefixes are
    the run's first layouts.
    """
    layouts, failures = {}, {}
    nested_to = 0
    if problem.span_min is None or not np.any(problem.span_min > 0):
        nested_to = count if problem.budget is not None else r_max
        start = [] if greedy_layout is None else list(greedy_layout)[:nested_to]
        if len(start) != min(nested_to, problem.count) or problem.count > nested_to:
            start = []
        layouts.update({r: start[:r] for r in range(1, len(start) + 1)})
        try:
            for chosen, _ in iter_greedy(replace(problem, count=nested_to), start=start):
                layouts[len(chosen)] = list(chosen)
        except SensorplanError as exc:
            reason = " ".join(str(exc).split())
            failures.update({r: reason for r in range(len(layouts) + 1, nested_to + 1)})
    need = 0 if problem.span_min is None else int(np.sum(problem.span_min))
    for r in range(nested_to + 1, r_max + 1):
        if r < need:  # no layout of r sensors meets the per-span minimum counts
            failures[r] = f"the per-span minimum counts need at least {need} sensors"
            continue
        try:
            layouts[r] = greedy(replace(problem, count=r))[0]
        except SensorplanError as exc:
            failures[r] = " ".join(str(exc).split())
    return layouts, failures

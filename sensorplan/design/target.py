"""Design to a requirement: the fewest sensors (the cheapest layout) whose worst-case detection power reaches P.

The worst-case power of a layout is the minimum over the damage centres
(inside ``region``) of the power that ``detectability`` reports for the
layout (and the existing sensors) with the same loss, nuisance, centre
step, false-alarm rate and crossings: exactly those numbers, so that
``sensorplan detectability`` confirms every power this module states.

Counts are tried from the smallest allowed up to the cap (with per-kind
costs and a budget: every (count, total cost) level, cheapest first); at
each, the detect-optimal layout is found as :func:`recommend` finds it.
The first count whose layout reaches P is the answer.  A power of P means
d >= T = z_(1-alpha) + z_P at every centre, i.e. the detect criterion
(worst-case d^2) at least T^2, so a count is *proven* too small when the
certified relaxation bound on the worst-case d^2 is below T^2, or when the
exact search (:mod:`.exact`) finds no layout reaching T^2.  Adding a sensor
never lowers d^2, so without a minimum spacing, per-span maxima or
unequal costs only the count just below the answer (or the cap) needs a
proof; otherwise every count tried does.

When no allowed count reaches P, the layout at the cap is returned with the
crossings that would reach P: d grows with the square root of the
crossings, n = ceil(n0 (T / d_min)^2), checked with ``detectability`` at n
(and raised while round-off leaves it short) and at n - 1.

Owns: :func:`design_for_target`, the per-count search and proofs, the crossings needed.
May import: model, detection, errors, design.
"""

import math
import time
from dataclasses import replace

import numpy as np
from scipy.special import ndtr, ndtri

from .._errors import ConfigError, SensorplanError
from .._threads import single_threaded
from ..detection.detectability import detectability
from .candidates import sensor_layout
from .detect_problem import DetectionTarget, centres_inside
from .exact import MAX_NODES, estimate_nodes, exact_search
from .feasibility import check_feasible, packing
from .recommend import Search, build_problem, design_result, search_layout
from .results import CurvePoint
from .target_levels import levels, monotone
from .target_results import CountTrial, TargetAnswer, TargetDesign

__all__ = ["design_for_target", "crossings_to_reach", "DEFAULT_MAX_COUNT"]

DEFAULT_MAX_COUNT = 12
_MICROSECONDS_PER_LAYOUT = (2.0, 1.0)  # exact search: 2 + 1 per sensor, measured on the embedded examples
_SKIP = 3.0  # an exact search estimated at more than this times its limit is not started
_ROUND_OFF = 1e-6  # relative: the design's d^2 and detectability's agree far better (~1e-8)


class _Requirement:
    """The required power and everything its worst case depends on; maps layouts to detectability."""

    def __init__(self, case, problem, power, target, n_crossings, region):
        self.case, self.power, self.target, self.n_crossings = case, float(power), target, int(n_crossings)
        self.region = region
        self.z_alarm = -float(ndtri(target.false_alarm))
        self.d_needed = self.z_alarm + float(ndtri(self.power))
        self.threshold = self.d_needed ** 2  # the worst-case d^2 (at n_crossings) that reaches the power
        self.problem = problem

    def power_of_d2(self, d2):
        return float(ndtr(math.sqrt(max(d2, 0.0)) - self.z_alarm))

    def map(self, index, n_crossings=None):
        """The detectability map of the candidates ``index`` plus the existing sensors."""
        p = self.problem
        index = sorted(int(i) for i in index)
        fixed = p.fixed
        positions = np.concatenate([p.positions[index], [] if fixed is None else fixed.positions])
        kinds = tuple(p.kinds[i] for i in index) + (() if fixed is None else tuple(fixed.kinds))
        stds = np.concatenate([p.noise_std[index], [] if fixed is None else fixed.noise_std])
        case = self.case.with_sensors(sensor_layout(positions, kinds, stds))
        t = self.target
        return detectability(case, severity=t.severity, length=t.length, false_alarm=t.false_alarm,
                             n_crossings=self.n_crossings if n_crossings is None else n_crossings,
                             nuisance=t.nuisance, step=t.step)

    def worst(self, dmap, values=None):
        """Minimum over the centres inside the region of ``values`` (default the map's power)."""
        values = dmap.power if values is None else values
        return float(np.min(values[centres_inside(dmap.centres_m, self.region)]))


@single_threaded
def design_for_target(case, *, power, max_count=None, target=None, n_crossings=1, region=None, grid=None,
                      constraints=None, kind="rotation", noise_std=None, solver="auto", n_random=100, rng=0,
                      max_nodes=MAX_NODES, progress=None):
    """The fewest new sensors (with per-kind costs and a budget: the cheapest layout) whose detect-optimal
    layout reaches a worst-case detection power of ``power``, or the best at the cap and the crossings needed.

    Parameters
    ----------
    case : Case
    power : float
        Required worst-case power P in (0, 1): the probability of detecting the loss of ``target``
        at its false-alarm rate, at the worst damage centre (inside ``region``).
    max_count : int, optional
        Largest count tried (default ``DEFAULT_MAX_COUNT`` = 12, and at most what fits the constraints).
    target : DetectionTarget, optional
        The loss (severity, length), nuisance, centre step and false-alarm rate (default: 25 % over 2 m,
        smooth nuisance, centres every 0.5 m, 5 %), as for ``detectability``.
    n_crossings : int
        Crossings of the campaign; the crossings needed are reported when no count suffices.
    region : (float, float), optional
        Damage centres in (start, stop) [m] only.
    grid, constraints, kind, noise_std, solver, n_random, rng :
        As for :func:`~sensorplan.design.recommend.recommend` (``constraints.budget`` with per-kind
        ``costs``: cheapest layout first).
    max_nodes : int
        Work limit of each exact search (partial and complete layouts, about 5-10 microseconds each).
    progress : callable, optional
        Called with one line of text per count tried (and before a long search).

    Returns
    -------
    TargetDesign
    """
    req, problem, level_list = _setup(case, power, max_count, target, n_crossings, region, grid, constraints,
                                      kind, noise_std)
    options = {"solver": solver, "n_random": n_random, "rng": rng}
    say = progress or (lambda message: None)
    nested = monotone(problem)
    trials, found = _climb(req, level_list, options, max_nodes, say, nested)
    answer_at, trials, found = _settle(req, trials, found, max_nodes, say, nested)
    return _result(req, level_list, (trials, found, answer_at, nested), grid)


def _setup(case, power, max_count, target, n_crossings, region, grid, constraints, kind, noise_std):
    """(requirement, the placement problem at the smallest count, the (count, budget) levels)."""
    if isinstance(power, bool) or not isinstance(power, (int, float)) or not 0.0 < power < 1.0:
        raise ConfigError(f"The 'power' parameter must be a probability in (0, 1), e.g. 0.8. Got {power!r} instead.")
    target = DetectionTarget() if target is None else target
    span_min = None if constraints is None else constraints.span_min
    r_min = max(1, int(np.sum(span_min)) if span_min is not None else 1)
    cap = DEFAULT_MAX_COUNT if max_count is None else max_count
    if isinstance(cap, bool) or not isinstance(cap, (int, np.integer)) or cap < r_min:
        raise ConfigError(f"The 'max_count' parameter must be a whole count of at least {r_min} (the smallest "
                          f"allowed count). Got {max_count!r} instead.")
    problem = build_problem(case, r_min, "detect", grid=grid, constraints=constraints, kind=kind,
                            noise_std=noise_std, n_crossings=n_crossings, region=region, target=target)
    fit = packing(problem.positions, problem.spans, problem.min_spacing, problem.span_max).size
    req = _Requirement(case, problem, power, target, n_crossings, problem.criterion.region)
    return req, problem, levels(problem, r_min, min(int(cap), fit))


def _climb(req, level_list, options, max_nodes, say, nested):
    """Try the levels in order until one reaches the power: (trials, {level index: (search, map)})."""
    trials, found = [], {}
    started = time.perf_counter()
    for k, (count, budget) in enumerate(level_list):
        t0 = time.perf_counter()
        trial, search, dmap = _try_level(req, count, budget, options)
        if trial.outcome == "pending" and not nested:
            trial, search, dmap = _prove(req, trial, search, dmap, max_nodes, say)
        trials.append(replace(trial, time_s=time.perf_counter() - t0))
        if search is not None:
            found[k] = (search, dmap)
        say(_progress_line(req, trials[-1], k, level_list, time.perf_counter() - started))
        if trial.outcome == "reached":
            break
    return trials, found


def _progress_line(req, trial, k, level_list, elapsed):
    """One progress line per level, with an estimate of the time left when it is long."""
    line = f"target power {req.power:g}: " + trial.line(req.power).strip()
    left = len(level_list) - k - 1
    if trial.outcome != "reached" and left > 0 and elapsed / (k + 1) * left > 10.0:
        line += f"; up to {left} more count(s), about {elapsed / (k + 1) * left:.0f} s at most"
    return line


def _level_problem(req, count, budget):
    return replace(req.problem, count=int(count), budget=budget)


def _try_level(req, count, budget, options):
    """The detect-optimal layout of one level and its worst-case power: (trial, search, map)."""
    problem = _level_problem(req, count, budget)
    try:
        check_feasible(problem.positions, problem.spans, count, min_spacing=problem.min_spacing,
                       span_min=problem.span_min, span_max=problem.span_max, costs=problem.costs, budget=budget)
        search = search_layout(problem, req.case, **options)
    except SensorplanError:
        return CountTrial(count, budget, (), None, None, "infeasible", "", 0.0), None, None
    dmap = req.map(search.layout)
    worst = req.worst(dmap)
    bound = float(search.relaxation.bound)
    outcome = ("reached" if worst >= req.power else
               "relaxation bound" if bound < req.threshold * (1.0 - _ROUND_OFF) else "pending")
    trial = CountTrial(count, budget, _positions(problem, search.layout), worst, req.power_of_d2(bound), outcome,
                       search.method, 0.0)
    return trial, search, dmap


def _positions(problem, index):
    return tuple(sorted(float(problem.positions[i]) for i in index))


def _prove(req, trial, search, dmap, max_nodes, say):
    """Exact search of a level the heuristic left short: a layout that reaches the power (then the trial is
    "reached" with it), or a proof that none does ("exhaustive"), or "not proven" (with a note when the
    search was not started because its estimated size is far above ``max_nodes``)."""
    problem = _level_problem(req, trial.count, trial.budget)
    threshold, length = req.threshold * (1.0 - _ROUND_OFF), req.case.bridge.length
    size = sum(math.comb(problem.n_candidates, r) for r in range(1, trial.count + 1))
    if size > max_nodes:
        size = int(estimate_nodes(problem, threshold, length=length))
    head = f"target power {req.power:g}: {trial.count} sensor(s): exact search over {problem.n_candidates} candidates"
    per_layout = 1e-6 * (_MICROSECONDS_PER_LAYOUT[0] + _MICROSECONDS_PER_LAYOUT[1] * trial.count)
    if size > _SKIP * max_nodes:
        note = (f"exact search not started: about {size:.2g} layouts, {_duration(size * per_layout)} "
                f"(limit {max_nodes:,})")
        say(f"{head}: {note}")
        return replace(trial, outcome="not proven", note=note), search, dmap
    if size * per_layout > 5.0:
        say(f"{head} (about {min(size, max_nodes):,} layouts, {_duration(min(size, max_nodes) * per_layout)} at "
            "most)")
    result = exact_search(problem, threshold, length=length, max_nodes=max_nodes)
    for layout, value in zip(result.layouts, result.values):
        candidate = req.map(layout)
        worst = req.worst(candidate)
        if worst >= req.power:
            better = Search(search.baselines, search.relaxation, "exhaustive search", list(layout), float(value))
            return (replace(trial, layout_m=_positions(problem, layout), worst_case_power=worst,
                            outcome="reached", method="exhaustive search"), better, candidate)
    proven = result.complete and len(result.layouts) < 8
    note = "" if proven else f"exact search stopped at {result.nodes:,} layouts"
    return replace(trial, outcome="exhaustive" if proven else "not proven", note=note), search, dmap


def _duration(seconds):
    """About how long, in words."""
    if seconds < 120:
        return f"about {seconds:.0f} s"
    if seconds < 7200:
        return f"about {seconds / 60:.0f} min"
    return f"about {seconds / 3600:.2g} h"


def _settle(req, trials, found, max_nodes, say, nested):
    """With nested levels, prove the level just below the answer (or the cap) by exact search, moving the
    answer down when that search finds a layout that reaches the power; the levels below are implied."""
    reached = [k for k, t in enumerate(trials) if t.outcome == "reached"]
    answer_at = reached[0] if reached else None
    if not nested:
        return answer_at, trials, found
    k = (answer_at if answer_at is not None else len(trials)) - 1
    while k >= 0 and trials[k].outcome == "pending":
        search, dmap = found[k]
        trials[k], search, dmap = _prove(req, trials[k], search, dmap, max_nodes, say)
        found[k] = (search, dmap)
        say(f"target power {req.power:g}: " + trials[k].line(req.power).strip())
        if trials[k].outcome != "reached":
            break
        answer_at, k = k, k - 1
    proven = k >= 0 and trials[k].outcome in ("exhaustive", "relaxation bound")
    label = "implied" if proven else "not proven"
    trials = [replace(t, outcome=label) if t.outcome == "pending" else t for t in trials]
    return answer_at, trials, found


def _minimality(trials, answer_at, nested):
    """How the claim about the levels below the answer (all levels when not met) was established."""
    below = trials[:answer_at] if answer_at is not None else trials
    if not below:
        return "trivial"
    outcomes = {t.outcome for t in below} - {"implied", "infeasible"}
    if nested:  # the proof of the highest level below the answer covers the rest
        proofs = [t.outcome for t in below if t.outcome not in ("implied", "infeasible")]
        outcomes = set(proofs[-1:])
    for name in ("not proven", "exhaustive", "relaxation bound"):
        if name in outcomes:
            return name
    return "trivial"  # every level below is infeasible


def _crossings_needed(req, search, dmap):
    """Smallest number of crossings with which the layout reaches the power (checked with detectability), or
    None when a centre sees nothing."""
    return crossings_to_reach(lambda n: req.worst(req.map(search.layout, n)), power=req.power,
                              n_crossings=req.n_crossings, d_min=req.worst(dmap, dmap.d), d_needed=req.d_needed)


def crossings_to_reach(worst_power, *, power, n_crossings, d_min, d_needed):
    """Fewest crossings above ``n_crossings`` with ``worst_power(n) >= power``, or None when ``d_min`` is 0.

    d grows with the square root of the crossings, so n = n0 (d_needed / d_min)^2 is the first guess
    (``d_min`` the worst-case d at ``n_crossings`` = n0, ``d_needed`` = z_(1 - alpha) + z_power); the exact
    ``worst_power`` (e.g. from detectability) then corrects it for round-off, up or down.
    """
    if not d_min > 0.0:
        return None
    n = max(n_crossings + 1, math.ceil(n_crossings * (d_needed / d_min) ** 2 - 1e-9))
    while worst_power(n) < power:  # round-off: one more
        n += 1
    while n - 1 > n_crossings and worst_power(n - 1) >= power:
        n -= 1
    return n


def _result(req, level_list, outcome, grid):
    """The TargetDesign: the answer's layout (or the cap's) as a DesignResult, the answer and the trials;
    ``outcome`` is (trials, {level: (search, map)}, index of the answer's level or None, nested)."""
    trials, found, answer_at, nested = outcome
    feasible = list(found)
    if not feasible:
        raise ConfigError("No allowed count has a layout that meets the constraints; relax 'budget', 'span_min', "
                          "'span_max' or 'min_spacing', or raise 'max_count'.")
    k = answer_at if answer_at is not None else max(feasible)
    search, dmap = found[k]
    count, budget = level_list[k]
    problem = _level_problem(req, count, budget)
    curve = tuple(CurvePoint(t.count, float(found[j][0].utility), float(found[j][0].relaxation.bound))
                  for j, t in enumerate(trials) if j in found)
    design = design_result(req.case, problem, search, _best_per_count(curve), n_crossings=req.n_crossings,
                           support_margin=0.0 if grid is None else float(grid.support_margin))
    met = answer_at is not None
    answer = TargetAnswer(req.power, met, int(count), req.worst(dmap), None if met else
                          _crossings_needed(req, search, dmap), _minimality(trials, answer_at, nested),
                          design.cost)
    return TargetDesign(design, answer, tuple(trials), dmap, req.region)


def _best_per_count(curve):
    """One CurvePoint per count (the best value and the largest bound over its budget levels)."""
    best = {}
    for p in curve:
        q = best.get(p.count)
        best[p.count] = p if q is None else CurvePoint(p.count, max(p.value, q.value), max(p.bound, q.bound))
    return tuple(best[c] for c in sorted(best))

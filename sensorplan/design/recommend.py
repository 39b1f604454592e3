"""Recommend a layout: assemble the placement problem, solve, certify, compare with baselines.

Owns: option groups (CandidateGrid, Constraints), problem assembly,
:func:`recommend`.  May import: model, errors, design.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError, SolverError
from .._threads import single_threaded
from ..model.fisher import fisher_blocks
from ..model.prior import GMRFPrior
from .baselines import baselines as make_baselines
from .blocks import DENSE_CACHE_BYTES, candidate_information
from .candidates import (
    as_kinds,
    candidate_set,
    fixed_layout,
    kind_costs,
    kind_noise,
    sensor_layout,
)
from .criteria import criterion_class, make_criterion
from .curve import criterion_curve
from .detect_problem import DetectionTarget, detection_information
from .feasibility import check_feasible
from .problem import DesignProblem
from .relaxation import Relaxation, solve_relaxation
from .resources import check_resources, estimate_resources
from .results import Baseline, DesignResult, SolverStats
from .selection import best_layout, greedy
from .supports import keep_off_supports, support_notes

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["recommend", "build_problem", "candidate_positions", "search_layout", "design_result", "Search",
           "CandidateGrid", "Constraints", "DetectionTarget"]


@dataclass(frozen=True)
class CandidateGrid:
    """Where new sensors may go.

    Parameters
    ----------
    spacing : float
        Grid spacing [m] from the left end.
    exclude : sequence of (float, float)
        Exclusion zones [m] (bearings, joints, anchorages).
    positions : sequence of float, optional
        Explicit candidate positions [m] instead of the grid.
    kinds : sequence of str, optional
        Sensor kinds offered at every position (e.g. ``("rotation", "deflection")``);
        default: the ``kind`` of :func:`recommend`.
    support_margin : float
        Smallest distance [m] of a new sensor from every support (default 0: none);
        applies to explicit ``positions`` too.
    """

    spacing: float = 0.5
    exclude: tuple = ()
    positions: tuple | None = None
    kinds: tuple | None = None
    support_margin: float = 0.0

    def candidates(self, bridge):
        """Candidate positions [m] on ``bridge``."""
        if self.positions is not None:
            x = np.asarray(self.positions, dtype=float)
        else:
            x = candidate_positions(bridge, self.spacing, self.exclude)
        bridge.check_on_bridge(x, "candidates", "recommend")
        return keep_off_supports(x, bridge.support_positions, self.support_margin)


@dataclass(frozen=True)
class Constraints:
    """Engineering constraints on a layout.

    Parameters
    ----------
    fixed : sequence of float or SensorLayout
        Existing sensors (their information is in Q_0): positions [m] of
        sensors of the first candidate kind with its noise, or a SensorLayout
        (its kinds; its noise std if set, else the case's noise for the case's
        own layout, else the median noise of the case's sensors of its kind).
    min_spacing : float
        Minimum distance between sensors [m] (new and existing, whatever their kinds).
    span_min, span_max : sequence of int, optional
        Minimum / maximum count of new sensors per span.
    costs : float, sequence of float or mapping, optional
        Cost of a sensor at each candidate, or per kind as ``{"rotation": 1, "deflection": 3}``
        (default 1 each); used with ``budget``.
    budget : float, optional
        Total cost of the new sensors.
    """

    fixed: tuple = ()
    min_spacing: float = 0.0
    span_min: tuple | None = None
    span_max: tuple | None = None
    costs: object = None
    budget: float | None = None

    def __post_init__(self):
        if not (np.isfinite(self.min_spacing) and self.min_spacing >= 0):
            raise ConfigError(f"The 'min_spacing' parameter must be a non-negative distance in m. "
                              f"Got {self.min_spacing!r} instead.")
        if self.budget is not None and not (np.isfinite(self.budget) and self.budget > 0):
            raise ConfigError(f"The 'budget' parameter must be positive. Got {self.budget!r} instead.")


def candidate_positions(bridge, spacing, exclude=()):
    """Grid of candidate positions [m] with ``spacing`` minus the exclusion zones."""
    if not spacing > 0:
        raise ConfigError(f"The 'spacing' parameter must be positive. Got {spacing!r} instead.")
    n = int(math.floor(bridge.length / spacing + 1e-9))
    x = np.minimum(np.round(np.arange(n + 1) * spacing, 9), bridge.length)
    keep = np.ones(x.size, dtype=bool)
    for a, b in exclude:
        if not b > a:
            raise ConfigError(f"An 'exclude' zone must be start:stop with stop > start. Got {a:g}:{b:g}.")
        keep &= ~((x >= a) & (x <= b))
    if not keep.any():
        raise ConfigError("The 'exclude' zones remove every candidate position; narrow 'exclude'.")
    return x[keep]


def build_problem(case, count, criterion="D", *, grid=None, constraints=None, kind="rotation", noise_std=None,
                  n_crossings=1, prior=None, springs=False, region=None, functionals=None, target=None):
    """Assemble the placement problem (see :func:`recommend` for the parameters)."""
    prior = GMRFPrior() if prior is None else prior
    detection = criterion_class(criterion).information == "detection"
    if target is not None and not detection:
        raise ConfigError(f"A detection target (severity, length, nuisance, step, false alarm) applies to the "
                          f"detect criterion only, not to {criterion}.")
    grid = CandidateGrid() if grid is None else grid
    constraints = Constraints() if constraints is None else constraints
    bridge = case.bridge
    kinds = as_kinds(kind if grid.kinds is None else grid.kinds)
    noise = kind_noise(case, kinds, noise_std)
    fixed = fixed_layout(case, constraints.fixed, kinds[0], noise)
    if fixed is not None:
        bridge.check_on_bridge(fixed.positions, "fixed", "recommend")
    cands = candidate_set(case, grid.candidates(bridge), kinds, noise, fixed, constraints.min_spacing)
    positions = cands.positions
    c_arr = None
    if constraints.budget is not None:
        c_arr = kind_costs(constraints.costs, cands.kinds, kinds)
    span_min, span_max = (_span_counts(v, name, bridge.n_spans, int(count))
                          for v, name in ((constraints.span_min, "span_min"), (constraints.span_max, "span_max")))
    if span_min is not None and span_max is not None and np.any(span_min > span_max):
        raise ConfigError(f"The 'span_min' counts ({span_min.tolist()}) exceed the 'span_max' counts "
                          f"({span_max.tolist()}) in some span; lower 'span_min' or raise 'span_max'.")
    check_feasible(positions, bridge.span_of(positions), int(count), min_spacing=float(constraints.min_spacing),
                   span_min=span_min, span_max=span_max, n_fixed=0 if fixed is None else fixed.n_sensors,
                   costs=c_arr, budget=constraints.budget)
    n_params = case.n_elements + (len(bridge.spring_parameters) if springs else 0)
    check_resources(estimate_resources(cands.n_candidates, n_params, int(count), n_loads=case.sweep.n_loads,
                                       detection=detection, n_kinds=len(kinds)), what=f"{cands.n_candidates} candidates",
                    fits="use fewer candidates (a larger grid spacing) or fewer elements")
    blocks, q0, crit, posterior_of = _information(case, cands, criterion, detection, n_crossings=n_crossings,
                                                  prior=prior, springs=springs, region=region,
                                                  functionals=functionals, target=target)
    return DesignProblem(positions, bridge.span_of(positions), _candidate_blocks(blocks, positions.size), q0,
                         criterion=crit, count=int(count), costs=c_arr, budget=constraints.budget,
                         span_min=span_min, span_max=span_max, min_spacing=float(constraints.min_spacing),
                         n_spans=bridge.n_spans, posterior_of=posterior_of, kinds=cands.kinds,
                         noise_std=cands.noise_std, fixed=fixed)


def _candidate_blocks(blocks, n):
    """The first ``n`` blocks (the candidates'; detect stacks hold the existing sensors' after them)."""
    if isinstance(blocks, np.ndarray):
        return np.ascontiguousarray(blocks[:n])
    return blocks


# parameters from which the structured blocks are used even where dense ones fit: their Hessian products and
# screening bounds beat the dense exact Hessians and evaluations there (D at N = 400, C = 400: 61.5 s against
# 98.9 s CPU; N = 240, C = 800: 22.5 s against 29.2 s; at N = 120 even; at N <= 40 the dense path is 2x faster)
STRUCTURED_FROM_PARAMS = 160


def _information(case, cands, criterion, detection, *, n_crossings, prior, springs, region, functionals, target):
    """(blocks of the candidates then the existing sensors, q0, criterion, posterior_of): detection Gram
    stacks (:mod:`.detect_problem`) or Fisher blocks in log EI (and spring log-stiffnesses)."""
    if detection:
        return detection_information(case, cands, n_crossings=n_crossings, region=region, target=target,
                                     prior=prior, springs=springs, functionals=functionals)
    n_springs = len(case.bridge.spring_parameters) if springs else 0
    n_params = case.n_elements + n_springs
    if n_params < STRUCTURED_FROM_PARAMS and 8.0 * cands.n_candidates * n_params**2 <= DENSE_CACHE_BYTES:
        # few parameters and dense blocks that fit the memory the structured ones would cache: faster directly
        blocks = fisher_blocks(case, sensors=cands.layout(), parameterisation="log_ei", springs=springs,
                               n_crossings=n_crossings).blocks
        fixed = blocks[cands.n_candidates:].sum(axis=0)
    else:
        blocks, fixed = candidate_information(case, cands, n_crossings=n_crossings, springs=springs)
    q0 = prior.precision(case.n_elements, n_springs) + fixed
    crit = make_criterion(criterion, q0.shape[0], n_elements=case.n_elements, edges=case.mesh.edges,
                          region=region, functionals=functionals)
    return blocks, q0, crit, None


def _span_counts(values, name, n_spans, count):
    """Per-span counts as an int array (None stays None), checked against the spans and the count."""
    if values is None:
        return None
    arr = np.asarray(values, dtype=float).ravel()
    if arr.size != n_spans or not np.all((arr >= 0) & (arr == np.round(arr))):
        raise ConfigError(f"The '{name}' parameter must give a non-negative whole count for each of the {n_spans} "
                          f"span(s). Got {list(np.atleast_1d(values))!r} instead.")
    if name == "span_min" and arr.sum() > count:
        raise ConfigError(f"The 'span_min' counts add up to {int(arr.sum())}, more than 'count' {count}; lower "
                          "'span_min' or raise 'count'.")
    if name == "span_max" and arr.sum() < count:
        raise ConfigError(f"The 'span_max' counts add up to {int(arr.sum())}, fewer than 'count' {count}; raise "
                          "'span_max' or lower 'count'.")
    return arr.astype(int)


@single_threaded
def recommend(case: "Case", count: int, criterion: str = "D", *, grid: CandidateGrid | None = None,
              constraints: Constraints | None = None, kind: "str | Sequence[str]" = "rotation",
              noise_std: "float | Mapping[str, float] | None" = None, n_crossings: int = 1,
              prior: GMRFPrior | None = None, springs: bool = False,
              region: tuple[float, float] | None = None, functionals: "np.ndarray | None" = None,
              solver: str = "auto", n_random: int = 100, rng: "int | np.random.Generator" = 0,
              curve_max: int | None = None, target: DetectionTarget | None = None) -> DesignResult:
    """Recommend where to put ``count`` new sensors.

    Parameters
    ----------
    case : Case
        Bridge, nominal EI, vehicle, load sweep and noise.
    count : int
        Number of new sensors R.
    criterion : str
        A registered criterion: "D", "A", "E", "Ds", "detect" (see :mod:`sensorplan.design.criteria`;
        detect: the worst case over damage centres of the detectability d^2, :mod:`.criteria.detect`).
    grid : CandidateGrid, optional
        Candidate positions (default: every 0.5 m).
    constraints : Constraints, optional
        Existing sensors, minimum spacing, per-span counts, costs and budget.
    kind : {"rotation", "deflection"} or sequence of them
        Kind(s) of the new sensors; with several kinds every candidate
        position is offered once per kind (``grid.kinds`` overrides it).
    noise_std : float or mapping kind -> float, optional
        Noise std of the new sensors [rad or m], one per kind when several
        (default: :meth:`Case.noise_std_for` for each kind).
    n_crossings : int
    prior : GMRFPrior
    springs : bool
        Spring log-stiffnesses as nuisance parameters.
    region, functionals : targeted A criterion (see :class:`ACriterion`); for detect, ``region``
        (start, stop) [m] restricts the damage centres.
    solver : {"auto", "fast", "cvxpy"}
    n_random : int
        Random layouts tried by the random baseline.
    rng : seed or Generator for the random baseline.
    curve_max : int, optional
        Largest R of the criterion-versus-R curve (default ``count``, or ``count + 3`` while that is
        <= 12); 0 disables it.
    target : DetectionTarget, optional
        The loss the detect criterion must see (default 25 % over 2 m, smooth nuisance, centres every
        0.5 m, power reported at a 5 % false-alarm rate); detect only.

    Returns
    -------
    DesignResult
    """
    problem = build_problem(case, count, criterion, grid=grid, constraints=constraints, kind=kind,
                            noise_std=noise_std, n_crossings=n_crossings, prior=prior, springs=springs,
                            region=region, functionals=functionals, target=target)
    search = search_layout(problem, case, solver=solver, n_random=n_random, rng=rng)
    margin = 0.0 if grid is None else float(grid.support_margin)
    curve = criterion_curve(problem, count, curve_max, search.relaxation.weights, search.layout,
                            greedy_layout=search.greedy_layout)
    return design_result(case, problem, search, curve, n_crossings=n_crossings, support_margin=margin)


@dataclass(frozen=True, eq=False)
class Search:
    """What the search found: the baselines (candidate indices or None by name), the relaxation, and the
    best layout (candidate indices) with its utility and the start it came from (``method``)."""

    baselines: dict
    relaxation: Relaxation
    method: str
    layout: list
    utility: float
    bound: float | None = None  # a bound on the integer layouts tighter than the relaxation's, if proven
    bound_method: str = "relaxation"
    greedy_layout: list | None = None  # the greedy layout, in the order greedy chose it (None if it failed)


def search_layout(problem, case, *, solver, n_random, rng):
    """The :class:`Search` of ``problem``: baselines, the greedy start, the relaxation and the best layout
    from every start (what :func:`recommend` returns, before the result is assembled)."""
    base = make_baselines(problem, length=case.bridge.length,
                          support_positions=case.bridge.support_positions, n_random=n_random, rng=rng)
    try:
        g_start, _ = greedy(problem)
    except SolverError:
        g_start = None
    relaxation = solve_relaxation(problem, solver, start_layout=g_start)
    method, layout, utility = best_layout(problem, relaxation.weights, base, greedy_layout=g_start, rng=rng)
    proof = problem.criterion.integer_bound(problem, layout, utility, length=case.bridge.length)
    if proof is None or proof.bound >= relaxation.bound:
        return Search(base, relaxation, method, layout, utility, greedy_layout=g_start)
    if proof.value > utility:
        method, layout, utility = "exact search (branch and bound)", list(proof.layout), proof.value
    return Search(base, relaxation, method, layout, utility, proof.bound, proof.method, greedy_layout=g_start)


def design_result(case, problem, search, curve, *, n_crossings, support_margin=0.0):
    """The DesignResult of a :class:`Search`: values and certificate, baselines, ``curve`` (CurvePoints),
    posterior std, details, and the notes on sensors that sit on a support."""
    crit = problem.criterion
    sign = 1.0 if crit.maximise else -1.0
    value = sign * search.utility
    bound = sign * (search.relaxation.bound if search.bound is None else search.bound)
    count = problem.count
    curve = tuple(_at_count(c, value, bound, sign) if c.count == count and not c.failed else c for c in curve)
    order = _sorted_index(problem, search.layout)
    details, detail_line = crit.describe(problem.layout_precision(order))
    layout_m = tuple(float(problem.positions[i]) for i in order)
    layout_kind = tuple(problem.kinds[i] for i in order)
    kinds = tuple(dict.fromkeys(problem.kinds))
    fixed = problem.fixed
    fixed_m, fixed_kind, fixed_std = ((), (), ()) if fixed is None else (
        tuple(float(x) for x in fixed.positions), fixed.kinds, tuple(fixed.noise_std))
    informativeness = fisher_blocks(case, sensors=sensor_layout(layout_m, layout_kind, problem.noise_std[order]),
                                    parameterisation="ei", n_crossings=n_crossings)
    return DesignResult(criterion=crit.name, description=crit.description, maximise=crit.maximise,
                        count=int(count), n_params=crit.n_effective, layout_m=layout_m, value=float(value),
                        bound=float(bound), efficiency=crit.efficiency(value, bound), method=search.method,
                        baselines=_baseline_results(problem, search.baselines, value),
                        solver=_solver_stats(search.relaxation, search.bound_method), candidates_m=problem.positions,
                        weights=search.relaxation.weights, fixed_m=fixed_m, curve=curve, kind="+".join(kinds),
                        layout_index=tuple(order), edges=case.mesh.edges.copy(),
                        supports_m=tuple(float(x) for x in case.bridge.support_positions),
                        posterior_std=_posterior_stds(problem, order, search.baselines, case.n_elements),
                        details=details, detail_line=detail_line, params_label=crit.params_label,
                        informativeness=informativeness, layout_kind=layout_kind, fixed_kind=fixed_kind,
                        fixed_noise_std=fixed_std,
                        noise_std={k: float(problem.noise_std[problem.kinds.index(k)]) for k in kinds},
                        cost=_cost(problem, order), budget=problem.budget,
                        support_notes=support_notes(case.bridge, layout_m, layout_kind),
                        support_margin_m=float(support_margin))


def _at_count(point, value, bound, sign):
    """The curve's point at the requested count with the recommendation's value and bound where better."""
    return replace(point, value=float(value) if sign * point.value < sign * value else point.value,
                   bound=float(bound) if sign * point.bound > sign * bound else point.bound)


def _baseline_results(problem, base, value):
    """Each baseline's positions, kinds, value, cost and efficiency relative to the layout's ``value``."""
    crit = problem.criterion
    out = []
    for name, idx in base.items():
        if idx is None:
            out.append(Baseline(name, None, None))
            continue
        b_value = float(problem.value_of(idx))
        b_order = _sorted_index(problem, idx)
        out.append(Baseline(name, tuple(float(problem.positions[i]) for i in b_order), b_value,
                            float(crit.relative(b_value, value)), tuple(problem.kinds[i] for i in b_order),
                            _cost(problem, b_order)))
    return tuple(out)


def _solver_stats(relaxation, bound_method="relaxation"):
    """SolverStats of a relaxation: solver, status, certified gap, time, and the other counters as details
    (with how the layout's bound was proven)."""
    stats = {**relaxation.stats, "bound_method": bound_method}
    return SolverStats(str(stats.pop("solver", "?")), str(stats.pop("status", "?")), float(relaxation.relative_gap),
                       float(stats.pop("time_s", 0.0)), relaxation.method, stats)


def _posterior_stds(problem, order, base, n_elements):
    """Posterior std of log EI per element for the recommended layout and each feasible baseline."""
    out = {"recommended": _posterior_std(problem, order, n_elements)}
    for name, idx in base.items():
        if idx is not None:
            out[name] = _posterior_std(problem, idx, n_elements)
    return out


def _sorted_index(problem, index):
    """Candidate indices by position, then in the order the kinds are offered."""
    return sorted((int(i) for i in index), key=lambda i: (problem.positions[i], i))


def _cost(problem, index):
    return None if problem.costs is None else float(problem.costs[list(index)].sum())


def _posterior_std(problem, index, n_elements):
    """Posterior standard deviation of log EI per element (~ relative std of EI)."""
    q = problem.posterior_precision(index)
    return np.sqrt(np.diag(np.linalg.inv(q))[:n_elements])

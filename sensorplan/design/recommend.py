"""Optimal sensor placement: recommend a layout, certify it, compare it with baselines."""

import math
from dataclasses import dataclass, field

import numpy as np

from .criteria import make_criterion
from .problem import DesignProblem
from .._errors import ConfigError, SolverError
from ..model.fisher import fisher_blocks
from ..model.prior import GMRFPrior
from .relaxation import solve_relaxation_cvxpy, solve_relaxation_fast
from .selection import baselines as make_baselines
from .selection import exchange, greedy, round_weights
from ..model.sensors import SensorLayout
from .._threads import single_threaded

__all__ = ["DesignResult", "recommend", "build_problem", "candidate_positions"]


@dataclass(frozen=True, eq=False)
class DesignResult:
    """A recommended layout with its certificate and the baselines.

    Attributes
    ----------
    criterion : str
    count : int
        Number of new sensors.
    n_params : int
    layout_m : tuple of float
        Sorted positions of the recommended sensors [m].
    value : float
        Criterion value of the layout (D, Ds: log det; A: trace; E: lambda_min).
    bound : float
        Relaxation bound on the criterion of every feasible layout (upper for
        D, Ds and E, lower for A), certified by a dual bound.
    efficiency : float
        Certified lower bound on the layout's efficiency against the best
        possible layout.
    method : str
        How the layout was found.
    baselines : dict
        ``{name: {"layout_m": [...], "value": float}}``.
    solver : dict
        Relaxation solver statistics.
    curve : tuple of dict
        Criterion versus number of sensors: ``{"count", "value", "bound"}``.
    """

    criterion: str
    count: int
    n_params: int
    layout_m: tuple
    value: float
    bound: float
    efficiency: float
    method: str
    baselines: dict
    solver: dict
    candidates_m: np.ndarray
    weights: np.ndarray
    fixed_m: tuple = ()
    curve: tuple = ()
    kind: str = "rotation"
    layout_index: tuple = field(default=(), repr=False)
    edges: np.ndarray = None
    supports_m: tuple = ()
    posterior_std: dict = field(default_factory=dict)

    def summary(self):
        unit = {"D": "log det of the posterior precision",
                "Ds": "log det of the posterior precision of log EI, springs marginalised",
                "A": "trace of the posterior covariance",
                "E": "smallest eigenvalue of the posterior precision"}[self.criterion]
        lines = [f"Recommended {self.count} {self.kind} sensor(s), {self.criterion}-optimal "
                 f"({unit}, {self.n_params} parameters)",
                 "  positions [m]: " + ", ".join(f"{x:.2f}" for x in self.layout_m)]
        if self.fixed_m:
            lines.append("  existing sensors [m]: " + ", ".join(f"{x:.2f}" for x in self.fixed_m))
        gap = self.value - self.bound
        lines.append(f"  criterion {self.value:.6g}; relaxation bound {self.bound:.6g}; gap {gap:.3g}; "
                     f"certified efficiency >= {100 * self.efficiency:.2f} %  (method: {self.method})")
        status = self.solver.get("status", "?")
        lines.append(f"  relaxation: {self.solver.get('solver', '?')}, status {status}, relative duality gap "
                     f"{self.solver.get('relative_gap', float('nan')):.1e}, {self.solver.get('time_s', 0.0):.2f} s"
                     + ("" if status == "optimal" else "  <- NOT optimal: treat the bound with care"))
        lines.append(f"  {'baseline':28s} {'criterion':>12s} {'vs layout':>10s}  positions [m]")
        for name, b in self.baselines.items():
            if b is None:
                lines.append(f"  {name:28s} {'infeasible':>12s}")
                continue
            rel = _relative(self.criterion, b["value"], self.value, self.n_params)
            lines.append(f"  {name:28s} {b['value']:12.6g} {100 * rel:9.1f}%  "
                         + ", ".join(f"{x:.2f}" for x in b["layout_m"]))
        return "\n".join(lines)

    def best_baseline(self):
        """Name of the best feasible baseline."""
        sign = -1.0 if self.criterion == "A" else 1.0
        feasible = {k: v for k, v in self.baselines.items() if v is not None}
        return max(feasible, key=lambda k: sign * feasible[k]["value"]) if feasible else None

    def to_dict(self):
        return {
            "criterion": self.criterion,
            "count": self.count,
            "n_params": self.n_params,
            "layout_m": list(self.layout_m),
            "value": self.value,
            "bound": self.bound,
            "efficiency": self.efficiency,
            "method": self.method,
            "baselines": self.baselines,
            "fixed_m": list(self.fixed_m),
            "kind": self.kind,
            "solver": {k: v for k, v in self.solver.items() if _jsonable(v)},
            "curve": list(self.curve),
        }


def _jsonable(v):
    return isinstance(v, (str, int, float, bool, type(None)))


def _relative(criterion, value, reference, n_params):
    """Efficiency of ``value`` relative to ``reference`` (1 = as good)."""
    if criterion in ("D", "Ds"):
        return math.exp((value - reference) / n_params)
    if criterion == "A":
        return reference / value
    return value / reference


def candidate_positions(bridge, spacing, exclude=()):
    """Grid of candidate positions [m] with ``spacing`` minus the exclusion zones."""
    if not spacing > 0:
        raise ConfigError(f"The 'spacing' parameter must be positive. Got {spacing!r} instead.")
    n = int(math.floor(bridge.length / spacing + 1e-9))
    x = np.minimum(np.round(np.arange(n + 1) * spacing, 9), bridge.length)
    keep = np.ones(x.size, dtype=bool)
    for a, b in exclude:
        if not b > a:
            raise ConfigError(f"An exclusion zone must be start:stop with stop > start. Got {a}:{b}.")
        keep &= ~((x >= a) & (x <= b))
    if not keep.any():
        raise ConfigError("The exclusion zones remove every candidate position.")
    return x[keep]


def build_problem(case, count, criterion="D", *, spacing=0.5, exclude=(), fixed=(), kind="rotation",
                  noise_std=None, n_crossings=1, prior=None, springs=False, costs=None, budget=None,
                  span_min=None, span_max=None, min_spacing=0.0, region=None, functionals=None,
                  candidates=None):
    """Assemble the placement problem (see :func:`recommend` for the parameters)."""
    prior = GMRFPrior() if prior is None else prior
    bridge = case.bridge
    positions = candidate_positions(bridge, spacing, exclude) if candidates is None else np.asarray(candidates, float)
    bridge.check_on_bridge(positions, "candidates", "recommend")
    fixed = np.asarray(list(fixed), dtype=float)
    if fixed.size:
        bridge.check_on_bridge(fixed, "fixed", "recommend")
        far = np.all(np.abs(positions[:, None] - fixed[None, :]) >= max(min_spacing, 1e-9), axis=1)
        positions = positions[far]
    if noise_std is None:
        same = ([s for k, s in zip(case.sensors.kinds, case.noise.std) if k == kind]
                if case.noise is not None else [])
        if not same:
            unit = "rad" if kind == "rotation" else "m"
            raise ConfigError(f"The case has no {kind} sensor to take the noise level from; give noise_std "
                              f"(in {unit}) for the new sensors.")
        noise_std = float(np.median(same))
    all_pos = np.concatenate([positions, fixed])
    layout = SensorLayout.candidates(all_pos, kind, noise_std=[noise_std] * all_pos.size)
    blocks = fisher_blocks(case, sensors=layout, parameterisation="log_ei", springs=springs,
                           n_crossings=n_crossings).blocks
    n_springs = len(case.bridge.spring_parameters) if springs else 0
    q0 = prior.precision(case.n_elements, n_springs) + blocks[positions.size:].sum(axis=0)
    crit = make_criterion(criterion, q0.shape[0], n_elements=case.n_elements, edges=case.mesh.edges,
                          region=region, functionals=functionals)
    n_spans = bridge.n_spans
    c_arr = None
    if budget is not None:
        c_arr = np.broadcast_to(np.asarray(1.0 if costs is None else costs, dtype=float), positions.shape).copy()
    return DesignProblem(positions, bridge.span_of(positions), np.ascontiguousarray(blocks[:positions.size]),
                         q0, crit, int(count), c_arr, budget,
                         None if span_min is None else np.asarray(span_min, int),
                         None if span_max is None else np.asarray(span_max, int), float(min_spacing), n_spans)


def solve_relaxation(problem, solver="auto", start_layout=None):
    if solver == "auto":
        # the fast path agrees with cvxpy + Clarabel to the certified gap and was
        # faster for D, A and E at both sizes of studies/benchmarks/bench_design.py
        solver = "fast"
    if solver == "cvxpy":
        return solve_relaxation_cvxpy(problem)
    if solver == "fast":
        return solve_relaxation_fast(problem, start_layout=start_layout)
    raise ConfigError(f"The 'solver' parameter must be 'auto', 'cvxpy' or 'fast'. Got {solver!r} instead.")


def _best_layout(problem, relaxation, starts, greedy_layout=None):
    """Best of exchange from: the rounded relaxation, the greedy layout, the best baseline.

    On large candidate grids each start is improved on a coarse grid and only
    the best result is polished on all candidates.  Exchange never makes a
    start worse, and a baseline still better than the
    result is used as a start too, so the result is never worse than any
    baseline.
    """
    tried = []
    try:
        tried.append(("relaxation rounding + exchange", round_weights(problem, relaxation.weights)))
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
    if not tried:
        raise SolverError("No feasible layout was found; relax the budget, span counts or spacing.")
    best = None

    def consider(method, start):
        # on large grids: the coarse-grid local optimum only; the best one is polished below
        nonlocal best
        layout, util = exchange(problem, start, polish=False)
        if best is None or util > best[2] + 1e-12 * max(1.0, abs(util)):
            best = (method, layout, util)

    for method, start in tried:
        consider(method, start)
    for util, name, start in scored[1:]:  # a baseline still better than the result
        if util > best[2]:
            consider(f"exchange from {name}", start)
    layout, util = exchange(problem, best[1])
    return best[0], layout, util


@single_threaded
def recommend(case, count, criterion="D", *, spacing=0.5, exclude=(), fixed=(), kind="rotation",
              noise_std=None, n_crossings=1, prior=None, springs=False, costs=None, budget=None,
              span_min=None, span_max=None, min_spacing=0.0, region=None, functionals=None,
              solver="auto", n_random=100, rng=0, curve_max=None, candidates=None):
    """Recommend where to put ``count`` new sensors.

    Parameters
    ----------
    case : Case
        Bridge, nominal EI, vehicle, load sweep and noise (median noise std
        of the case's sensors of the same ``kind`` unless ``noise_std`` is given).
    count : int
        Number of new sensors R.
    criterion : {"D", "A", "E", "Ds"}
    spacing : float
        Candidate grid spacing [m].
    exclude : sequence of (float, float)
        Exclusion zones [m] (bearings, joints, anchorages).
    fixed : sequence of float
        Positions of existing sensors [m] (their information is in Q_0).
    kind : {"rotation", "deflection"}
    n_crossings : int
    prior : GMRFPrior
    springs : bool
        Spring log-stiffnesses as nuisance parameters.
    costs, budget : per-candidate costs and a total budget.
    span_min, span_max : per-span minimum / maximum counts.
    min_spacing : float
        Minimum distance between chosen sensors [m].
    region, functionals : targeted A criterion (see :func:`make_criterion`).
    solver : {"auto", "cvxpy", "fast"}
    n_random : int
        Random layouts tried by the random baseline.
    rng : seed or Generator for the random baseline.
    curve_max : int, optional
        Largest R of the criterion-versus-R curve (default min(count + 3, 12)); 0 disables it.

    Returns
    -------
    DesignResult
    """
    problem = build_problem(case, count, criterion, spacing=spacing, exclude=exclude, fixed=fixed, kind=kind,
                            noise_std=noise_std, n_crossings=n_crossings, prior=prior, springs=springs,
                            costs=costs, budget=budget, span_min=span_min, span_max=span_max,
                            min_spacing=min_spacing, region=region, functionals=functionals,
                            candidates=candidates)
    base = make_baselines(problem, length=case.bridge.length,
                          support_positions=case.bridge.support_positions, n_random=n_random, rng=rng)
    try:
        g_start, _ = greedy(problem)
    except SolverError:
        g_start = None
    relaxation = solve_relaxation(problem, solver, start_layout=g_start)
    method, layout, utility = _best_layout(problem, relaxation, base, g_start)
    crit = problem.criterion
    sign = 1.0 if crit.maximise else -1.0
    value = sign * utility
    bound = sign * relaxation.bound
    efficiency = crit.efficiency(value, bound)
    base_out = {name: (None if idx is None else {
        "layout_m": sorted(float(x) for x in problem.positions[idx]),
        "value": float(problem.value_of(idx))}) for name, idx in base.items()}
    curve = tuple(dict(c, value=float(value)) if c["count"] == count and sign * c["value"] < sign * value
                  else c for c in _curve(problem, count, curve_max, solver))
    order = sorted(layout, key=lambda i: problem.positions[i])
    n_el = case.n_elements
    post_std = {"recommended": _posterior_std(problem, order, n_el)}
    for name, idx in base.items():
        if idx is not None:
            post_std[name] = _posterior_std(problem, idx, n_el)
    return DesignResult(criterion=crit.name, count=int(count), n_params=crit.n_effective,
                        layout_m=tuple(float(problem.positions[i]) for i in order), value=float(value),
                        bound=float(bound), efficiency=efficiency, method=method, baselines=base_out,
                        solver=dict(relaxation.stats, relaxation_method=relaxation.method,
                                    relative_gap=relaxation.relative_gap),
                        candidates_m=problem.positions, weights=relaxation.weights,
                        fixed_m=tuple(float(x) for x in fixed), curve=curve, kind=kind,
                        layout_index=tuple(order), edges=case.mesh.edges.copy(),
                        supports_m=tuple(float(x) for x in case.bridge.support_positions),
                        posterior_std=post_std)


def _posterior_std(problem, index, n_elements):
    """Posterior standard deviation of log EI per element (~ relative std of EI)."""
    q = problem.layout_precision(index)
    return np.sqrt(np.diag(np.linalg.inv(q))[:n_elements])


def _curve(problem, count, curve_max, solver):
    from dataclasses import replace

    if curve_max == 0:
        return ()
    r_max = min(count + 3, 12) if curve_max is None else int(curve_max)
    r_max = min(r_max, problem.n_candidates)
    out = []
    sign = 1.0 if problem.criterion.maximise else -1.0
    for r in range(1, r_max + 1):
        sub = replace(problem, count=r)
        try:
            g, _ = greedy(sub)
            layout, util = exchange(sub, g)
            rel = solve_relaxation(sub, solver, start_layout=layout)
        except Exception:  # an R for which the constraints cannot be met
            continue
        out.append({"count": r, "value": float(sign * util), "bound": float(sign * rel.bound)})
    return tuple(out)

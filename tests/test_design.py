"""Placement: brute force on small problems, certificates, constraints, symmetry, baselines."""

import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sensorplan as sp
from sensorplan import CandidateGrid, Case, ConfigError, Constraints, example_case, recommend
from sensorplan.design.recommend import build_problem
from sensorplan.design.relaxation import solve_relaxation
from sensorplan.design.selection import exchange, greedy


def small_case(spans=(20.0,), n_elements=8, rot=None):
    bridge = sp.Bridge(spans, rotational_springs=rot)
    length = bridge.length
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), 1e10, sp.Vehicle((0.0, 2.0), (5e4, 5e4)),
                sp.SensorLayout([length / 2], noise_std=2e-6),
                sweep=sp.LoadSweep.from_range(0.0, length + 2.0, 0.5))


def brute_force(problem):
    best, best_u, count = None, -np.inf, 0
    for subset in itertools.combinations(range(problem.n_candidates), problem.count):
        if not problem.feasible(subset):
            continue
        count += 1
        u = problem.utility_of(subset)
        if u > best_u:
            best, best_u = subset, u
    return best, best_u, count


# -- references straight from the definitions (numpy on dense matrices, no package code) --

MAXIMISE = {"D": True, "Ds": True, "E": True, "A": False}


def criterion_value(criterion, q, n_springs=0):
    """D = log det Q; Ds = log det of the Schur complement of the spring block; A = tr Q^-1; E = lambda_min."""
    if criterion == "D":
        return np.linalg.slogdet(q)[1]
    if criterion == "Ds":
        n = q.shape[0] - n_springs
        schur = q[:n, :n] - q[:n, n:] @ np.linalg.solve(q[n:, n:], q[n:, :n])
        return np.linalg.slogdet(schur)[1]
    if criterion == "A":
        return np.trace(np.linalg.inv(q))
    return np.linalg.eigvalsh(q)[0]


def true_efficiency(criterion, q, q_opt, n_springs=0):
    """Efficiency of precision q against the optimal layout's q_opt, from its definition:
    (det ratio)^(1/n) for D and Ds (n = dimension of the determinant), the ratio of summed
    variances for A, the ratio of smallest eigenvalues for E."""
    if criterion in ("D", "Ds"):
        n = q.shape[0] - (n_springs if criterion == "Ds" else 0)
        return np.exp((criterion_value(criterion, q, n_springs) - criterion_value(criterion, q_opt, n_springs)) / n)
    if criterion == "A":
        return np.trace(np.linalg.inv(q_opt)) / np.trace(np.linalg.inv(q))
    return np.linalg.eigvalsh(q)[0] / np.linalg.eigvalsh(q_opt)[0]


def reference_prior(n_elements, n_springs, tau=100.0, marginal_std=0.5, spring_std=1.0, level_std=1.0):
    """The default GMRF prior precision, tau D^T D + (marginal_std^2 I + level_std^2 1 1^T)^-1 (first
    differences; the proper part is the covariance of independent elements plus a common level, inverted
    densely here), springs 1/spring_std^2."""
    d = np.diff(np.eye(n_elements), axis=0)
    q = np.zeros((n_elements + n_springs,) * 2)
    proper = np.linalg.inv(marginal_std**2 * np.eye(n_elements) + level_std**2 * np.ones((n_elements, n_elements)))
    q[:n_elements, :n_elements] = tau * d.T @ d + proper
    q[n_elements:, n_elements:] = np.eye(n_springs) / spring_std**2
    return q


def reference_feasible(positions, supports, subset, *, min_spacing=0.0, costs=None, budget=None, span_min=None,
                       span_max=None):
    """The constraints checked directly (a support belongs to the span on its right)."""
    x = positions[list(subset)]
    if min_spacing and np.any(np.diff(np.sort(x)) < min_spacing - 1e-9):
        return False
    if budget is not None and np.sum(np.asarray(costs)[list(subset)]) > budget + 1e-9:
        return False
    counts = np.bincount(np.searchsorted(supports[1:-1], x, side="right"), minlength=len(supports) - 1)
    if span_min is not None and np.any(counts < span_min):
        return False
    return span_max is None or not np.any(counts > span_max)


@pytest.mark.parametrize("criterion", ["D", "A", "E", "Ds"])
@pytest.mark.parametrize("constraints", [
    {},
    {"min_spacing": 3.5},
    {"costs": "ramp", "budget": 5.0},
    {"span_min": [1, 1], "span_max": [2, 2]},
])
def test_brute_force_bounds_and_certificates(criterion, constraints):
    # Two-span bridge with springs (so Ds has nuisance parameters), 13
    # candidates, R = 3: every feasible layout is enumerated and scored with
    # the criterion's definition (criterion_value), not with the package's
    # criterion code; feasibility is checked directly from the constraints.
    case = small_case((12.0, 12.0), 8, rot=(2e9, 0.0, 2e9))
    kwargs = dict(constraints)
    if kwargs.get("costs") == "ramp":
        kwargs["costs"] = 1.0 + np.arange(13) / 6.0
    springs = criterion == "Ds"
    n_springs = len(case.bridge.spring_parameters) if springs else 0
    result = recommend(case, 3, criterion, springs=springs, curve_max=0, n_random=20,
                       grid=CandidateGrid(spacing=2.0), constraints=Constraints(**kwargs))
    problem = build_problem(case, 3, criterion, springs=springs, grid=CandidateGrid(spacing=2.0),
                            constraints=Constraints(**kwargs))
    np.testing.assert_allclose(problem.positions, np.arange(13) * 2.0)
    np.testing.assert_allclose(problem.q0, reference_prior(case.n_elements, n_springs), rtol=1e-12)
    supports = case.bridge.support_positions
    values = {}
    for subset in itertools.combinations(range(problem.n_candidates), 3):
        ok = reference_feasible(problem.positions, supports, subset, **kwargs)
        assert problem.feasible(subset) == ok, subset
        if ok:
            q = problem.q0 + problem.blocks[list(subset)].sum(axis=0)
            values[subset] = criterion_value(criterion, q, n_springs)
    assert values
    sign = 1.0 if MAXIMISE[criterion] else -1.0
    best = max(values, key=lambda k: sign * values[k])
    optimum = values[best]
    tol = 1e-9 * max(1.0, abs(optimum))
    # the reported value is the criterion of the reported layout
    layout = sorted(result.layout_index)
    q_layout = problem.q0 + problem.blocks[layout].sum(axis=0)
    assert result.value == pytest.approx(criterion_value(criterion, q_layout, n_springs), rel=1e-9, abs=1e-12)
    # every constraint respected, positions reported sorted
    assert tuple(layout) in values
    np.testing.assert_allclose(problem.positions[layout], result.layout_m)
    # the relaxation bound is never beaten by the brute-force optimum
    assert sign * (result.bound - optimum) >= -tol
    # the brute-force optimum is never beaten by the reported layout
    assert sign * (optimum - result.value) >= -tol
    # the certified efficiency never exceeds the true efficiency against the optimum
    q_opt = problem.q0 + problem.blocks[list(best)].sum(axis=0)
    assert result.efficiency <= true_efficiency(criterion, q_layout, q_opt, n_springs) + 1e-9
    # never worse than a baseline it reports, and a baseline's value is that of its layout
    for b in result.baselines:
        if b.feasible:
            index = tuple(sorted(int(np.argmin(np.abs(problem.positions - x))) for x in b.layout_m))
            assert b.value == pytest.approx(values[index], rel=1e-9, abs=1e-12), b.name
            assert sign * (result.value - b.value) >= -tol, b.name


@settings(max_examples=12)
@given(st.integers(1, 4), st.sampled_from(["D", "A", "E"]), st.integers(0, 3))
def test_greedy_exchange_bound_ordering(count, criterion, seed):
    rng = np.random.default_rng(seed)
    case = small_case((rng.uniform(10, 25),), int(rng.integers(4, 10)))
    problem = build_problem(case, count, criterion, grid=CandidateGrid(spacing=case.bridge.length / 12))
    g, g_u = greedy(problem)
    e, e_u = exchange(problem, g)
    rel = solve_relaxation(problem, "fast")
    assert g_u <= e_u + 1e-12 * max(1.0, abs(e_u))
    assert e_u <= rel.bound + 1e-9 * max(1.0, abs(rel.bound))


@pytest.mark.parametrize("criterion", ["D", "A", "E", "Ds"])
@pytest.mark.parametrize("constraints", [
    {},
    {"min_spacing": 2.0},
    {"costs": "ramp", "budget": 6.0},
    {"span_min": [1, 1], "span_max": [2, 2]},
])
def test_fast_path_equals_cvxpy_clarabel(criterion, constraints):
    case = small_case((12.0, 12.0), 10, rot=(2e9, 0.0, 2e9))
    kwargs = dict(constraints)
    if kwargs.get("costs") == "ramp":
        kwargs["costs"] = 1.0 + np.arange(17) / 8.0
    problem = build_problem(case, 3, criterion, springs=criterion == 'Ds', grid=CandidateGrid(spacing=1.5), constraints=Constraints(**kwargs))
    fast = solve_relaxation(problem, "fast")
    ref = solve_relaxation(problem, "cvxpy")
    scale = max(1.0, abs(ref.bound))
    # same relaxed optimum; the fast path's certificate is as tight, up to the criterion's stopping tolerance
    # (its default relative gap: 1e-7, E 1e-6)
    assert abs(fast.utility - ref.utility) <= 1e-6 * scale
    tol = problem.criterion.relaxation_tol
    assert ref.utility - 1e-9 * scale <= fast.bound <= ref.bound + (tol + 1e-9) * scale
    # the generic reference's own certificate at Clarabel's default tolerances: ~1e-5 (1.07e-5 measured on Ds with
    # the prior's common level, whose constant direction is weakly informed)
    assert fast.relative_gap <= 1e-6 and ref.relative_gap <= 2e-5


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("side", [False, True])
@pytest.mark.parametrize("warm", [False, True])
def test_small_lmi_interior_point_matches_clarabel(seed, side, warm):
    # The E subspace SDP solver (lmi_interior_point) against cvxpy + Clarabel on random
    # problems: same optimum, a trace-one PSD multiplier, feasible weights; also from a warm start
    # (the E relaxation's rounds start from the last round's weights: here random ones, off the sum)
    import cvxpy as cp

    from sensorplan.design.relaxation.lmi import lmi_interior_point

    rng = np.random.default_rng(seed)
    k, m, count = 7, 30, 5
    f = rng.normal(size=(m, k, 3))
    bmat = np.einsum("mpr,mqr->mpq", f, f) * rng.uniform(0.5, 5.0, m)[:, None, None]
    a0 = rng.normal(size=(k, k))
    b0 = a0 @ a0.T * 0.05 + 0.2 * np.eye(k)
    rows, rhs = np.zeros((0, m)), np.zeros(0)
    if side:  # a budget, at most 2 of the first 12, at least 1 of the last 6
        rows = np.vstack([rng.uniform(0.5, 2.0, m), (np.arange(m) < 12) * 1.0, -1.0 * (np.arange(m) >= 24)])
        rhs = np.array([1.3 * count, 2.0, -1.0])
    start = (rng.uniform(0.0, 1.0, m), 0.1) if warm else None
    value, w, x, nu, status, _, mult = lmi_interior_point(b0, bmat, rows, rhs, count, tol=1e-9, start=start)
    wv, t = cp.Variable(m), cp.Variable()
    mat = b0 + cp.reshape(bmat.reshape(m, -1).T @ wv, (k, k), order="C")
    cons = [wv >= 0, wv <= 1, cp.sum(wv) == count, 0.5 * (mat + mat.T) - t * np.eye(k) >> 0]
    if side:
        cons.append(rows @ wv <= rhs)
    ref = cp.Problem(cp.Maximize(t), cons)
    ref.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    if status != "optimal":  # the caller falls back to Clarabel; the value is still close
        assert abs(value - ref.value) <= 1e-6 * max(1.0, abs(ref.value))
        return
    assert abs(value - ref.value) <= 1e-8 * max(1.0, abs(ref.value))
    assert abs(nu - cons[2].dual_value) <= 1e-5 * max(1.0, abs(nu))
    assert np.linalg.eigvalsh(x)[0] >= -1e-9 and abs(np.trace(x) - 1.0) <= 1e-8
    assert w.min() >= -1e-9 and w.max() <= 1 + 1e-9 and abs(w.sum() - count) <= 1e-8
    if side:  # the rows hold, and their multipliers are Clarabel's duals (the candidates' prices)
        assert np.all(rows @ w <= rhs + 1e-8)
        assert mult.shape == (3,) and np.all(mult >= 0)
        np.testing.assert_allclose(mult, cons[4].dual_value, atol=1e-5 * max(1.0, abs(nu)))
    # the multiplier certifies: lambda_min(S(w')) <= <X, S(w')> for every w', so
    # the LP over the feasible set with X's gradient bounds the optimum
    s_w = b0 + (w @ bmat.reshape(m, -1)).reshape(k, k)
    assert np.linalg.eigvalsh(s_w)[0] >= value - 1e-7 * max(1.0, abs(value))


def test_small_e_sdp_falls_back_to_clarabel(monkeypatch):
    from sensorplan.design.relaxation import lmi

    case = small_case((12.0, 12.0), 10, rot=(2e9, 0.0, 2e9))
    problem = build_problem(case, 3, 'E', grid=CandidateGrid(spacing=1.5))
    reference = solve_relaxation(problem, "fast")
    assert reference.stats["clarabel_fallbacks"] == 0

    def failing(*args, **kwargs):
        return 0.0, None, None, 0.0, "numerical problems", 1, None

    monkeypatch.setattr(lmi, "lmi_interior_point", failing)
    fallback = solve_relaxation(problem, "fast")
    assert fallback.stats["clarabel_fallbacks"] == fallback.stats["rounds"]
    assert abs(fallback.bound - reference.bound) <= 1e-6 * max(1.0, abs(reference.bound))
    assert fallback.relative_gap <= 1e-6


@pytest.mark.parametrize("criterion", ["D", "A", "E"])
def test_coarse_to_fine_recommendation_keeps_its_guarantees(criterion, monkeypatch):
    # Force the large-grid path (coarse exchange per start, best one polished)
    # on a problem small enough to enumerate.
    from sensorplan.design import selection

    monkeypatch.setattr(selection, "COARSE_ABOVE", 6)
    case = small_case((12.0, 12.0), 8, rot=(2e9, 0.0, 2e9))
    result = recommend(case, 3, criterion, curve_max=0, n_random=20, grid=CandidateGrid(spacing=2.0))
    problem = build_problem(case, 3, criterion, grid=CandidateGrid(spacing=2.0))
    _, best_u, _ = brute_force(problem)
    sign = 1.0 if problem.criterion.maximise else -1.0
    tol = 1e-9 * max(1.0, abs(best_u))
    assert sign * result.value <= best_u + tol
    assert sign * result.value <= sign * result.bound + tol
    assert problem.feasible(list(result.layout_index))
    for b in result.baselines:
        if b.feasible:
            assert sign * (result.value - b.value) >= -tol, b.name
    # the polished layout is a local optimum of the full problem
    layout = list(result.layout_index)
    util = problem.utility_of(layout)
    for pos in range(3):
        for i in range(problem.n_candidates):
            if i not in layout:
                trial = layout[:pos] + [i] + layout[pos + 1:]
                assert problem.utility_of(trial) <= util + tol


@settings(max_examples=12)
@given(st.integers(2, 4), st.sampled_from(["D", "A", "E", "Ds"]), st.integers(0, 5), st.booleans())
def test_exchange_ends_at_a_local_optimum(count, criterion, seed, coarse):
    # The pruned search (concavity bounds) must find every improving swap:
    # check the result against all single swaps, evaluated directly.
    rng = np.random.default_rng(seed)
    case = small_case((rng.uniform(10, 25), rng.uniform(10, 25)), int(rng.integers(6, 12)), rot=(1e9, 0.0, 1e9))
    problem = build_problem(case, count, criterion, springs=criterion == 'Ds', grid=CandidateGrid(spacing=case.bridge.length / 14))
    start = list(rng.choice(problem.n_candidates, count, replace=False))
    # coarse: the coarse-to-fine path (a coarse grid first), forced on this small grid
    layout, util = exchange(problem, start, coarse_above=8 if coarse else 300)
    assert util >= problem.utility_of(start) - 1e-12 * max(1.0, abs(util))
    assert util == pytest.approx(problem.utility_of(layout), rel=1e-12)
    for pos in range(count):
        for i in range(problem.n_candidates):
            if i in layout:
                continue
            trial = layout[:pos] + [i] + layout[pos + 1:]
            # a swap is taken when it gains more than the criterion's swap_gain share (E: 1e-6)
            assert problem.utility_of(trial) <= util + max(1e-9 * max(1.0, abs(util)),
                                                           problem.criterion.swap_gain * abs(util))


def assert_no_swap_improves(problem, layout, util):
    """Reference: every single swap of ``layout``, evaluated directly (brute force); a swap is taken when it
    gains more than the criterion's ``swap_gain`` share (E: 1e-6), beyond round-off."""
    share = max(problem.criterion.swap_gain * abs(util), 1e-9 * max(1.0, abs(util)))
    for pos in range(len(layout)):
        for i in range(problem.n_candidates):
            if i not in layout:
                assert problem.utility_of(layout[:pos] + [i] + layout[pos + 1:]) <= util + share


@pytest.mark.parametrize("criterion", ["D", "E"])
def test_two_level_local_moves_of_the_polish_end_at_a_local_optimum(criterion):
    # 97 candidates with a coarse grid from 10 on: every 19th candidate, local moves first to every 4th of the 19
    # neighbours on each side, then among the 4 nearest.  Reference: every single swap, evaluated directly.
    case = small_case((14.0, 18.0), 10, rot=(1e9, 0.0, 1e9))
    problem = build_problem(case, 3, criterion, grid=CandidateGrid(spacing=case.bridge.length / 96))
    assert problem.n_candidates // (10 // 2) // 4 > 1  # the two levels are used
    layout, util = exchange(problem, [0, 1, 2], coarse_above=10)
    assert util == pytest.approx(problem.utility_of(layout), rel=1e-12)
    assert_no_swap_improves(problem, layout, util)


@pytest.mark.parametrize("criterion", ["E", "A"])
def test_exchange_takes_only_swaps_that_gain_the_criterions_share(monkeypatch, criterion):
    # Reference: every single swap of the start, evaluated directly (brute force).
    case = small_case((14.0, 18.0), 10, rot=(1e9, 0.0, 1e9))
    problem = build_problem(case, 3, criterion, grid=CandidateGrid(spacing=case.bridge.length / 16))
    start = [0, 1, 2]
    u0 = problem.utility_of(start)
    gains = [(problem.utility_of(start[:pos] + [i] + start[pos + 1:]) - u0) / abs(u0)
             for pos in range(3) for i in range(problem.n_candidates) if i not in start]
    best_gain = max(gains)
    assert best_gain > 1e-3  # the start is far from a local optimum
    # a share above every swap's gain: the start is a local optimum at that share
    monkeypatch.setattr(type(problem.criterion), "swap_gain", 1.01 * best_gain)
    assert exchange(problem, start)[0] == start
    # a share just below the best swap's gain: that swap (at least) is taken, and the result is a local optimum
    # at that share
    share = 0.99 * best_gain
    monkeypatch.setattr(type(problem.criterion), "swap_gain", share)
    layout, util = exchange(problem, start)
    assert util >= u0 + share * abs(u0)
    for pos in range(3):
        for i in range(problem.n_candidates):
            if i not in layout:
                trial = layout[:pos] + [i] + layout[pos + 1:]
                assert problem.utility_of(trial) <= util + share * abs(util) + 1e-9 * abs(util)


@settings(max_examples=10)
@given(st.integers(1, 4), st.sampled_from(["D", "A", "E", "Ds"]), st.integers(0, 5))
def test_pruned_greedy_equals_plain_greedy(count, criterion, seed):
    # Reference: the plain greedy step, every candidate evaluated.
    rng = np.random.default_rng(seed)
    case = small_case((rng.uniform(10, 25), rng.uniform(10, 25)), int(rng.integers(6, 12)), rot=(1e9, 0.0, 1e9))
    problem = build_problem(case, count, criterion, springs=criterion == 'Ds', grid=CandidateGrid(spacing=case.bridge.length / 14))
    chosen = []
    for _ in range(count):
        values = [(problem.utility_of(chosen + [i]), -i) for i in range(problem.n_candidates) if i not in chosen]
        chosen.append(-max(values)[1])
    layout, util = greedy(problem)
    assert util == pytest.approx(problem.utility_of(chosen), rel=1e-10)


@pytest.mark.parametrize("criterion", ["D", "A", "E"])
def test_mirror_symmetric_bridge_scores_mirrored_layouts_equally(criterion):
    # Symmetric two-span bridge; a symmetric (point-load) sweep over the bridge.
    bridge = sp.Bridge((15.0, 15.0), rotational_springs=(1e9, 0.0, 1e9))
    case = Case(bridge, sp.Mesh.uniform(bridge, 10), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([5.0], noise_std=2e-6), sweep=sp.LoadSweep.from_range(0.0, 30.0, 0.5))
    problem = build_problem(case, 2, criterion, grid=CandidateGrid(spacing=1.0))
    x = problem.positions
    rng = np.random.default_rng(1)
    for _ in range(5):
        layout = rng.choice(x.size, 2, replace=False)
        mirrored = [int(np.argmin(np.abs(x - (30.0 - x[i])))) for i in layout]
        a, b = problem.value_of(layout), problem.value_of(mirrored)
        assert a == pytest.approx(b, rel=1e-9)


def test_fixed_sensors_and_exclusions():
    case = example_case("openlab-like")
    result = recommend(case, 2, 'D', curve_max=0, n_random=10, grid=CandidateGrid(spacing=1.0, exclude=[(14.0, 16.0)]), constraints=Constraints(fixed=[11.0], min_spacing=2.0))
    x = np.array(result.layout_m)
    assert not np.any((x >= 14.0) & (x <= 16.0))
    assert np.all(np.abs(x - 11.0) >= 2.0)
    assert result.fixed_m == (11.0,)
    assert np.all(np.diff(x) >= 2.0)


def test_infeasible_constraints_are_reported():
    case = small_case()
    with pytest.raises(ConfigError, match="'count' 3 with 'min_spacing' 15 m: at most 2 sensor"):
        recommend(case, 3, 'D', curve_max=0, n_random=5, grid=CandidateGrid(spacing=2.0), constraints=Constraints(min_spacing=15.0))


def test_design_result_json_values_and_curve():
    case = example_case("simply-supported")
    result = recommend(case, 2, 'D', n_random=10, curve_max=4, grid=CandidateGrid(spacing=1.0))
    d = json.loads(json.dumps(result.to_dict()))  # what `sensorplan recommend` writes
    # the JSON carries the result's numbers
    assert (d["criterion"], d["count"], d["n_params"], d["method"], d["kind"]) == (
        "D", 2, case.n_elements, result.method, "rotation")
    assert d["layout_m"] == list(result.layout_m) == sorted(d["layout_m"])
    assert (d["value"], d["bound"], d["efficiency"]) == (result.value, result.bound, result.efficiency)
    for b in result.baselines:
        entry = d["baselines"][b.name]
        assert entry is None if not b.feasible else (entry["layout_m"], entry["value"]) == (list(b.layout_m), b.value)
    # reference: log det of the posterior precision of the layout, formed densely from the prior
    # and the Fisher blocks of two tiltmeters at the recommended positions (the case's noise)
    sensors = sp.SensorLayout.candidates(result.layout_m, noise_std=case.noise.std[:1].repeat(2))
    q = reference_prior(case.n_elements, 0) + sp.fisher_blocks(case, sensors=sensors).total()
    assert d["value"] == pytest.approx(np.linalg.slogdet(q)[1], rel=1e-10)
    assert d["value"] <= d["bound"] and 0.0 < d["efficiency"] <= 1.0
    values = [c.value for c in result.curve]
    bounds = [c.bound for c in result.curve]
    assert [c.count for c in result.curve] == [1, 2, 3, 4]
    assert [c["count"] for c in d["curve"]] == [1, 2, 3, 4]
    assert [c["value"] for c in d["curve"]] == values and [c["bound"] for c in d["curve"]] == bounds
    assert values[1] == result.value  # the curve's entry for the requested R is the recommended layout
    assert np.all(np.diff(values) > 0) and np.all(np.array(values) <= np.array(bounds) + 1e-9)
    # diminishing returns of log det (submodularity of the bound curve is not guaranteed, the gains are)
    assert np.all(np.diff(np.diff(bounds)) <= 1e-9)


def test_the_curve_reports_counts_below_the_span_minimums_as_one_run():
    # Per-span minimum counts of 2 and 1 on two spans: no layout of fewer than 3 sensors meets them (every
    # such layout checked by enumeration), so R = 1-2 fail with that reason and R = 3-4 get values; the
    # summary names the failed counts once, as a run.
    case = example_case("openlab-like")
    result = recommend(case, 3, "D", n_random=5, curve_max=4, grid=CandidateGrid(spacing=1.0),
                       constraints=Constraints(span_min=(2, 1)))
    problem = build_problem(case, 3, "D", grid=CandidateGrid(spacing=1.0), constraints=Constraints(span_min=(2, 1)))
    for r in (1, 2):
        assert not any(problem.feasible(s) for s in itertools.combinations(range(problem.n_candidates), r))
    assert [c.count for c in result.curve if c.failed] == [1, 2]
    assert all("at least 3 sensors" in c.reason for c in result.curve if c.failed)
    assert all(c.value is not None for c in result.curve if c.count >= 3)
    assert "criterion vs R failed for R = 1-2 (the per-span minimum counts need at least 3 sensors)" in result.summary()


@pytest.mark.parametrize("criterion", ["D", "A", "E"])
def test_the_polish_returns_to_the_local_moves_after_a_swap_of_the_full_search(criterion, monkeypatch):
    # Local moves of one neighbour from the three leftmost candidates leave swaps to the full search; after each,
    # the local moves run again, and the last full search finds none.  Reference: every single swap, evaluated
    # directly (brute force).
    from sensorplan.design import selection

    case = small_case((14.0, 18.0), 10, rot=(1e9, 0.0, 1e9))
    problem = build_problem(case, 3, criterion, grid=CandidateGrid(spacing=case.bridge.length / 48))
    converged, full = [], selection._exchange

    def spy(*args, **kwargs):
        out = full(*args, **kwargs)
        converged.append(out[2])
        return out

    monkeypatch.setattr(selection, "_exchange", spy)
    layout, util = selection._polish(problem, [0, 1, 2], 1, True, 50)
    assert False in converged and converged[-1]  # a swap sent it back to the local moves; the last search certified
    assert util == pytest.approx(problem.utility_of(layout), rel=1e-12)
    assert_no_swap_improves(problem, layout, util)

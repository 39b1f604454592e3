"""Design at scale: the criterion-versus-R curve, the resource estimate, the block products.

References are independent of the code they check: exhaustive search over
every layout (the curve's bounds), dense products formed with numpy from
the definition (block products, whitened blocks), and the CLI's own
refusal message re-run with the spacing it suggests.
"""

import itertools

import numpy as np
import pytest
import scipy.linalg

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.design.criteria.linalg import whitened_blocks
from sensorplan.design.curve import criterion_curve
from sensorplan.design.recommend import CandidateGrid, Constraints, build_problem
from sensorplan.design.relaxation import solve_relaxation
from sensorplan.design.resources import (
    RESOURCES,
    check_resources,
    estimate_resources,
    largest_fitting,
    spacing_for,
)
from sensorplan.io.config import example_case


def _exhaustive(problem, r):
    """Best utility over every feasible layout of r candidates (brute force)."""
    from dataclasses import replace

    sub = replace(problem, count=r)
    return max(sub.utility_of(list(c)) for c in itertools.combinations(range(problem.n_candidates), r)
               if sub.feasible(list(c)))


@pytest.mark.parametrize("criterion", ["D", "A", "E"])
def test_curve_bounds_hold_against_exhaustive_search(criterion):
    case = example_case("simply-supported")
    problem = build_problem(case, 3, criterion, grid=CandidateGrid(spacing=2.0))
    rel = solve_relaxation(problem)
    curve = criterion_curve(problem, 3, 5, rel.weights)
    assert [p.count for p in curve] == [1, 2, 3, 4, 5]
    sign = 1.0 if problem.criterion.maximise else -1.0
    for point in curve:
        best = _exhaustive(problem, point.count)
        # the value is a layout's (never above the optimum) and the bound is above the optimum
        assert sign * point.value <= best + 1e-9 * max(1.0, abs(best))
        assert sign * point.bound >= best - 1e-9 * max(1.0, abs(best))


def test_curve_reaches_the_requested_count_and_keeps_the_recommendation():
    case = example_case("openlab-like")
    result = sp.recommend(case, 14, "D", grid=CandidateGrid(spacing=1.0), n_random=5)
    assert [p.count for p in result.curve] == list(range(1, 15))  # not cut at 12
    at_r = result.curve[-1]
    # the point at R takes the recommendation's value and the tighter of the two bounds (the curve's own
    # linearisations may be tighter than the relaxation's by round-off)
    assert at_r.value == result.value and at_r.bound == pytest.approx(result.bound, rel=1e-12)
    assert at_r.bound <= result.bound


def test_curve_with_a_budget_uses_feasible_layouts():
    case = example_case("openlab-like")
    problem = build_problem(case, 3, "D", grid=CandidateGrid(spacing=2.0, kinds=("rotation", "deflection")),
                            constraints=Constraints(costs={"rotation": 1.0, "deflection": 3.0}, budget=6.0),
                            noise_std={"rotation": 5e-6, "deflection": 1e-4})
    curve = criterion_curve(problem, 3, 4)
    for point in curve:
        if not point.failed:
            assert point.value <= _exhaustive(problem, point.count) + 1e-9
            assert point.bound >= _exhaustive(problem, point.count) - 1e-9
    assert curve[3].failed or curve[3].value is not None  # 4 sensors: at most 4 rotations of cost 1 fit 6


def test_block_products_match_dense_sums():
    case = example_case("three-span")
    problem = build_problem(case, 2, "D", grid=CandidateGrid(spacing=0.5))
    rng = np.random.default_rng(3)
    g = rng.standard_normal((problem.n_params, problem.n_params))
    g = g + g.T
    index = rng.choice(problem.n_candidates, 40, replace=False)
    dense = np.array([np.sum(problem.blocks[i] * g) for i in index])  # <G, I_i> from the definition
    np.testing.assert_allclose(problem.block_dot(g, index), dense, rtol=1e-10, atol=1e-12 * np.abs(dense).max())
    many = list(range(problem.n_candidates))
    reference = problem.q0 + sum(problem.blocks[i] for i in many)
    # structured sums (cumulative over candidates) and dense blocks round differently: to 1e-12 of the largest entry
    np.testing.assert_allclose(problem.layout_precision(many), reference, rtol=1e-10,
                               atol=1e-12 * np.abs(reference).max())


def test_whitened_blocks_match_the_definition():
    rng = np.random.default_rng(0)
    p, m = 12, 5
    roots = rng.standard_normal((m, p, 4))
    blocks = np.matmul(roots, roots.transpose(0, 2, 1))
    q = np.eye(p) * 3.0 + np.cov(rng.standard_normal((p, 3 * p)))
    chol = np.linalg.cholesky(q)
    li = scipy.linalg.inv(chol)
    for a, b in zip(whitened_blocks(chol, blocks), blocks):
        np.testing.assert_allclose(a, li @ b @ li.T, rtol=1e-10, atol=1e-12)


def test_resource_estimate_grows_and_states_a_fitting_count():
    small = estimate_resources(200, 60, 6, n_loads=300)
    large = estimate_resources(3000, 400, 20, n_loads=741)
    assert large.memory_bytes > small.memory_bytes and large.cpu_seconds > small.cpu_seconds
    # the relaxation's working set (at least 4 R + 20 candidates, 16 P^2 bytes each) is a floor of the estimate
    assert large.memory_bytes >= 16 * (4 * 20 + 20) * 400**2
    # structured blocks: far below the 8 C P^2 bytes of dense blocks at 30,000 candidates
    assert estimate_resources(30000, 400, 20, n_loads=741).memory_bytes < 8 * 30000 * 400**2 / 5
    memory = 2 * 2**30

    def estimate(c):
        return estimate_resources(c, 400, 20, n_loads=741)

    fitting = largest_fitting(estimate, memory=memory)
    assert 0 < fitting < 3000
    check_resources(estimate(fitting), what="fits", memory=memory)  # no error at the largest fitting count
    with pytest.raises(sp.ConfigError, match=r"GiB .* of CPU .*use --spacing >= 1"):
        check_resources(estimate(fitting + 1), what="too many", fits="use --spacing >= 1", memory=memory)
    assert RESOURCES.memory_fraction < 1.0


def test_spacing_for_gives_at_most_the_count():
    for length, n in ((180.0, 1200), (30.0, 61), (45.0, 7)):
        s = spacing_for(length, n)
        assert int(np.floor(length / s + 1e-9)) + 1 <= n


def test_cli_refuses_a_grid_beyond_the_estimate_and_accepts_its_suggestion(capsys, tmp_path):
    argv = ["recommend", "--example", "openlab-like", "--count", "2", "--criterion", "D", "--spacing", "1e-7",
            "--out", str(tmp_path / "a")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "GiB" in err and "of CPU" in err and "--spacing >=" in err
    suggested = float(err.rsplit("--spacing >= ", 1)[1].rstrip("."))
    # the suggestion passes the same check (no refusal naming --spacing), though it is too fine to run here
    from sensorplan.cli._common import check_design_resources

    class Args:
        spacing, kind, springs, count, criterion = suggested, None, False, 2, "D"

    check_design_resources(example_case("openlab-like"), Args)


def test_auto_does_not_fall_back_to_cvxpy_beyond_its_size(monkeypatch):
    from sensorplan.design.relaxation import dispatch

    case = example_case("simply-supported")
    # every candidate chosen: the relaxed set is one point, the fast path has no interior and fails
    problem = build_problem(case, 6, "D", grid=CandidateGrid(spacing=4.0))
    assert problem.count == problem.n_candidates
    assert solve_relaxation(problem).stats.get("fallback")  # small: cvxpy solves it
    monkeypatch.setattr(dispatch, "CVXPY_FALLBACK_ENTRIES", 0)
    with pytest.raises(sp.SolverError, match="cvxpy fallback is not tried") as info:
        solve_relaxation(problem)
    assert "\n" not in str(info.value)

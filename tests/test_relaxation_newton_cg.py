"""Hessian products of the smooth criteria and the Newton-CG interior point on structured blocks.

References: the criteria's exact Hessians (``Criterion.hessian``, their own
closed forms, checked against finite differences in tests/test_conformance.py),
central differences of the gradient in the weights (independent of both),
and the exact-Hessian interior point on dense blocks (a different Newton
system solver: one Cholesky factorisation per step, no conjugate gradients).
"""

import dataclasses
import pathlib
import sys

import numpy as np
import pytest
import scipy.linalg

import sensorplan as sp
from sensorplan.design.recommend import build_problem

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from criterion_checks import LogDiagonal  # noqa: E402  (the shared toy criterion)


def small_case():
    # two spans with an elastic end spring (so Ds has a nuisance parameter), 8 elements
    bridge = sp.Bridge((12.0, 12.0), rotational_springs=(2e9, 0.0, 2e9))
    return sp.Case(bridge, sp.Mesh.uniform(bridge, 8), 1e10, sp.Vehicle((0.0, 2.0), (5e4, 5e4)),
                   sp.SensorLayout([6.0], noise_std=2e-6), sweep=sp.LoadSweep.from_range(0.0, 26.0, 0.5))


def problem_for(criterion, **options):
    """The small problem for ``criterion`` ("A-region": A on the elements of 3 to 9 m)."""
    if criterion == "A-region":
        criterion, options = "A", {"region": (3.0, 9.0), **options}
    return build_problem(small_case(), 3, criterion, grid=sp.CandidateGrid(spacing=2.0),
                         springs=criterion == "Ds", **options)


def point(problem, seed):
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.1, 0.4, problem.n_candidates)
    q = problem.precision(w)
    q = 0.5 * (q + q.T)
    return rng, w, q


@pytest.mark.parametrize("criterion", ["D", "Ds", "A", "A-region"])
def test_hessian_product_equals_the_exact_hessian_times_v(criterion):
    problem = problem_for(criterion)
    crit = problem.criterion
    rng, w, q = point(problem, 0)
    chol = np.linalg.cholesky(q)
    h = crit.hessian(q, chol, problem.blocks)
    for _ in range(3):
        v = rng.standard_normal(problem.n_candidates)
        g = crit.hessian_product(q, chol, np.einsum("c,cij->ij", v, problem.blocks))
        np.testing.assert_allclose(g, g.T, rtol=0, atol=1e-12 * np.abs(g).max())
        hv = problem.block_dot(g)
        np.testing.assert_allclose(hv, h @ v, rtol=1e-8, atol=1e-10 * np.abs(h @ v).max())
        # the same product in single precision (a few digits: what a Newton direction needs)
        g32 = crit.hessian_operator(q, chol, dtype=np.float32)(np.einsum("c,cij->ij", v, problem.blocks))
        assert g32.dtype == np.float32
        np.testing.assert_allclose(g32, g, rtol=0, atol=1e-4 * np.abs(g).max())


@pytest.mark.parametrize("criterion", ["D", "Ds", "A", "logdiag"])
def test_hessian_product_equals_finite_differences_of_the_gradient(criterion):
    if criterion == "logdiag":  # the protocol's default (central differences of gradient_matrix) on a toy criterion
        problem = problem_for("D")
        problem = dataclasses.replace(problem, criterion=LogDiagonal(problem.n_params))
    else:
        problem = problem_for(criterion)
    rng, w, q = point(problem, 1)
    chol = np.linalg.cholesky(q)
    v = rng.standard_normal(problem.n_candidates)
    hv = problem.block_dot(problem.criterion.hessian_product(q, chol, np.einsum("c,cij->ij", v, problem.blocks)))
    step = 1e-6
    fd = (problem.gradient(w + step * v) - problem.gradient(w - step * v)) / (2 * step)
    np.testing.assert_allclose(hv, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def structured_problem(monkeypatch, criterion, example="three-span", **options):
    from sensorplan.design import recommend as module
    from sensorplan.io.config import example_case

    monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)  # structured blocks even where dense ones fit
    problem = build_problem(example_case(example), 4, criterion, grid=sp.CandidateGrid(spacing=1.0), **options)
    assert problem.structured
    return problem, dataclasses.replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])


def test_projected_pcg_solves_the_bordered_system():
    # reference: the bordered system [K 1; 1^T 0] solved directly; the preconditioner a perturbed K
    from sensorplan.design.relaxation.newton_cg import projected_pcg

    rng = np.random.default_rng(3)
    a = rng.standard_normal((30, 30))
    k = a @ a.T + 30 * np.eye(30)
    stale = k + 0.3 * np.diag(np.diag(k)) * rng.uniform(-1, 1, 30)
    rhs = rng.standard_normal(30)
    kkt = np.block([[k, np.ones((30, 1))], [np.ones((1, 30)), np.zeros((1, 1))]])
    ref = np.linalg.solve(kkt, np.concatenate([rhs, [0.7]]))
    dx, dnu, it = projected_pcg(scipy.linalg.cho_factor(stale), lambda v: k @ v, rhs, 0.7, rtol=1e-10, max_iter=100)
    assert 0 < it <= 30
    np.testing.assert_allclose(dx, ref[:30], rtol=1e-7, atol=1e-9)
    assert dnu == pytest.approx(ref[30], rel=1e-7)
    # the exact preconditioner: no iteration
    dx, dnu, it = projected_pcg(scipy.linalg.cho_factor(k), lambda v: k @ v, rhs, 0.7, rtol=1e-10, max_iter=100)
    assert it == 0 and dnu == pytest.approx(ref[30], rel=1e-9)


@pytest.mark.parametrize("criterion", ["D", "A", "Ds"])
def test_newton_cg_relaxation_equals_the_exact_hessian_relaxation(monkeypatch, criterion):
    # reference: the same problem on dense blocks, solved with exact Hessians and direct Newton systems
    from sensorplan.design.relaxation import solve_relaxation

    if criterion == "Ds":  # a nuisance parameter: the elastic end spring of the two-span case
        from sensorplan.design import recommend as module

        monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)
        problem = build_problem(small_case(), 3, "Ds", grid=sp.CandidateGrid(spacing=1.0), springs=True)
        assert problem.structured and problem.criterion.n_keep < problem.n_params
        dense = dataclasses.replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])
    else:
        problem, dense = structured_problem(monkeypatch, criterion)
    cg = solve_relaxation(problem, "fast")
    exact = solve_relaxation(dense, "fast")
    assert "newton-cg" in cg.stats["solver"] and "newton-cg" not in exact.stats["solver"]
    assert cg.relative_gap <= 1e-7 and exact.relative_gap <= 1e-7
    # both certified: each bound is above the other's feasible utility
    assert cg.bound >= exact.utility - 1e-9 * abs(exact.utility)
    assert exact.bound >= cg.utility - 1e-9 * abs(cg.utility)
    assert cg.utility == pytest.approx(exact.utility, rel=2e-7)
    # the optimal weights need not be unique (neighbouring candidates carry nearly the same information), the
    # optimal precision is (log det and trace of the inverse are strictly concave / convex in Q)
    q_cg, q_exact = dense.precision(cg.weights), dense.precision(exact.weights)
    np.testing.assert_allclose(q_cg, q_exact, rtol=0, atol=1e-3 * np.abs(q_exact).max())


def test_newton_cg_relaxation_with_a_truncated_preconditioner_reaches_the_same_certified_optimum(monkeypatch):
    # A's preconditioner rows with 2 directions of N N^T only (H~ far below H): the Newton-CG steps still use the
    # exact Hessian products, so the relaxation reaches the optimum of the exact-Hessian relaxation on dense
    # blocks (reference: direct Newton systems, no preconditioner)
    from sensorplan.design.relaxation import smooth, solve_relaxation
    from sensorplan.design.relaxation.preconditioner import StaleHessian

    made = []

    class Narrow(StaleHessian):
        def __init__(self, problem):
            super().__init__(problem, weight_rank=2)
            made.append(self)

    problem, dense = structured_problem(monkeypatch, "A")
    assert problem.n_params > 2
    monkeypatch.setattr(smooth, "StaleHessian", Narrow)
    cg = solve_relaxation(problem, "fast")
    exact = solve_relaxation(dense, "fast")
    assert made and made[0].rows > 0
    assert cg.relative_gap <= 1e-7 and exact.relative_gap <= 1e-7
    assert cg.bound >= exact.utility - 1e-9 * abs(exact.utility)
    assert exact.bound >= cg.utility - 1e-9 * abs(cg.utility)
    assert cg.utility == pytest.approx(exact.utility, rel=2e-7)


@pytest.mark.parametrize("criterion", ["D", "A", "Ds"])
def test_stale_hessian_extended_equals_the_exact_hessian_of_the_union(monkeypatch, criterion):
    # reference: the criterion's exact Hessian (closed form, checked against differences above) of the new working
    # set at the point where the first rows were computed; members that left the set are forgotten
    from sensorplan.design.relaxation.newton_cg import Point, StaleHessian

    if criterion == "Ds":
        from sensorplan.design import recommend as module

        monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)
        problem = build_problem(small_case(), 3, "Ds", grid=sp.CandidateGrid(spacing=1.0), springs=True)
        assert problem.criterion.n_keep < problem.n_params
    else:
        problem, _ = structured_problem(monkeypatch, criterion)
    _, w, q = point(problem, 4)
    chol = np.linalg.cholesky(q)
    c = problem.n_candidates
    first, second = np.arange(0, c // 2), np.arange(c // 4, 3 * c // 4)
    grad = problem.gradient(w)
    stale = StaleHessian(problem, rank=32)  # roots accurate to this test's tolerance (the default is coarser)
    stale.refresh(first, Point(q, chol), np.ones(first.size), grad[first])
    h = stale.extend(second, np.ones(second.size), grad[second])
    ref = problem.criterion.hessian(q, chol, problem.blocks[second])
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-4 * np.abs(ref).max())
    np.testing.assert_array_equal(stale.members, second)
    assert stale.refreshes == 1 and stale.rows == first.size + (second.size - (first.size - c // 4))


def test_working_blocks_sums_and_inner_products_equal_the_dense_blocks(monkeypatch):
    # reference: the dense blocks (BlockFamily.dense, formed element by element) summed and contracted directly
    from sensorplan.design.relaxation.working_blocks import WorkingBlocks

    problem, dense = structured_problem(monkeypatch, "D")
    rng = np.random.default_rng(5)
    idx = np.sort(rng.choice(problem.n_candidates, problem.n_candidates // 2, replace=False))
    blocks = dense.blocks[idx]
    working = WorkingBlocks(problem.blocks.subset(idx))
    w = rng.uniform(0.0, 1.0, idx.size)
    ref = np.einsum("c,cij->ij", w, blocks)
    np.testing.assert_allclose(working.weighted(w), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    g = rng.standard_normal((problem.n_params, problem.n_params))
    ref = np.einsum("cij,ij->c", blocks, 0.5 * (g + g.T))
    np.testing.assert_allclose(working.dot(g), ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_structured_restricted_products_single_then_double_precision(monkeypatch):
    # reference: the criterion's exact Hessian (closed form) on the dense blocks of the working set times v
    from sensorplan.design.relaxation.newton_cg import StructuredRestricted

    problem, dense = structured_problem(monkeypatch, "A")
    rng = np.random.default_rng(8)
    idx = np.sort(rng.choice(problem.n_candidates, problem.n_candidates // 2, replace=False))
    smooth = StructuredRestricted(problem, idx)
    x = rng.uniform(0.1, 0.5, idx.size)
    u, g, pt = smooth.derivatives(x)
    q = dense.q0 + np.einsum("c,cij->ij", x, dense.blocks[idx])
    h = problem.criterion.hessian(q, np.linalg.cholesky(q), dense.blocks[idx])
    v = rng.standard_normal(idx.size)
    ref = h @ v
    assert u == pytest.approx(problem.criterion.utility(q), rel=1e-12)
    single = smooth.hessian_operator(pt)(v)
    assert single.dtype == np.float32
    np.testing.assert_allclose(single, ref, rtol=0, atol=1e-4 * np.abs(ref).max())
    smooth.use_double_products()
    u, g, pt = smooth.derivatives(x)
    double = smooth.hessian_operator(pt)(v)
    assert double.dtype == np.float64
    np.testing.assert_allclose(double, ref, rtol=0, atol=1e-10 * np.abs(ref).max())


def test_restricted_newton_cg_resumed_on_the_same_working_set_reaches_the_direct_solution(monkeypatch):
    # reference: the same restricted problem solved directly to the tight tolerance (from its own start)
    from sensorplan.design.relaxation.newton_cg import StaleHessian, restricted_newton_cg

    problem, _ = structured_problem(monkeypatch, "A")
    idx = np.arange(0, problem.n_candidates, 2)
    direct = restricted_newton_cg(problem, idx, None, tol=1e-9, stale=StaleHessian(problem))
    stale = StaleHessian(problem)
    loose = restricted_newton_cg(problem, idx, None, tol=1e-3, stale=stale)
    resumed = restricted_newton_cg(problem, idx, loose[0], tol=1e-9, stale=stale, resume=loose[4])
    assert resumed[2] < direct[2]  # fewer Newton steps: continued, not restarted
    u = problem.criterion.utility
    full = np.zeros(problem.n_candidates)
    full[idx] = direct[0]
    ref = u(problem.precision(full))
    full[idx] = resumed[0]
    assert u(problem.precision(full)) == pytest.approx(ref, rel=1e-8)
    assert resumed[1] == pytest.approx(direct[1], rel=1e-5)  # the multiplier of sum(w) = R


@pytest.mark.slow
@pytest.mark.parametrize("criterion", ["D", "A"])
def test_structured_newton_cg_relaxation_equals_cvxpy_clarabel(monkeypatch, criterion):
    # reference: cvxpy + Clarabel on the same problem's dense blocks (a generic conic solver, no code shared with
    # the Newton-CG path: structured products, product-row preconditioner from structured roots, resumed rounds)
    from sensorplan.design.relaxation import solve_relaxation

    problem, dense = structured_problem(monkeypatch, criterion)
    fast = solve_relaxation(problem, "fast")
    ref = solve_relaxation(dense, "cvxpy")
    assert "newton-cg" in fast.stats["solver"]
    scale = max(1.0, abs(ref.bound))
    assert abs(fast.utility - ref.utility) <= 1e-6 * scale
    assert ref.utility - 1e-9 * scale <= fast.bound <= ref.bound + (problem.criterion.relaxation_tol + 1e-9) * scale
    assert fast.relative_gap <= 1e-7 and ref.relative_gap <= 2e-5

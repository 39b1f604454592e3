"""The whitened split bounds of the D and A criteria (``split_bounds``) and the searches that use them.

References: exact values computed here with numpy's slogdet or inverse of Q + I_i (not the criteria's code), brute force
over every candidate (greedy steps, swaps).
"""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.design.criteria import make_criterion
from sensorplan.design.problem import DesignProblem

sys.path.insert(0, str(Path(__file__).resolve().parent))
from design_problems import structured_three_span  # noqa: E402


def _random_problem(seed, *, c=30, p=10, rank=3):
    rng = np.random.default_rng(seed)
    jac = rng.standard_normal((c, rank, p)) * rng.uniform(0.2, 3.0, (c, 1, 1))
    a = rng.standard_normal((p, p))
    return DesignProblem(np.sort(rng.uniform(0.0, 50.0, c)), np.zeros(c, dtype=int),
                         np.einsum("cri,crj->cij", jac, jac), a @ a.T / p + 0.1 * np.eye(p),
                         criterion=make_criterion("D", p), count=3)


def _exact(problem, q):
    return np.array([np.linalg.slogdet(q + b)[1] for b in problem.blocks])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 10))
def test_split_bounds_hold_for_any_basis_and_are_exact_for_a_full_one(seed, k):
    problem = _random_problem(seed)
    rng = np.random.default_rng(seed + 1)
    q = problem.layout_precision(rng.choice(problem.n_candidates, 2, replace=False))
    exact = _exact(problem, q)
    basis = np.linalg.qr(rng.standard_normal((problem.n_params, problem.n_params)))[0][:, :k]
    index = np.sort(rng.choice(problem.n_candidates, 12, replace=False))
    b = problem.criterion.split_bounds(problem, q, index, basis=basis, chol=np.linalg.cholesky(q))
    assert np.all(b >= exact[index] - 1e-9 * np.maximum(1.0, np.abs(exact[index])))
    if k == problem.n_params:  # nothing left to bound: the exact values
        assert b == pytest.approx(exact[index], rel=1e-10, abs=1e-10)


def test_split_bounds_are_exact_when_the_basis_spans_the_whitened_block():
    problem = _random_problem(3)
    q = problem.layout_precision([0, 5])
    chol = np.linalg.cholesky(q)
    l_inv = np.linalg.inv(chol)
    white = l_inv @ problem.blocks[7] @ l_inv.T  # rank 3
    basis = np.linalg.eigh(white)[1][:, -3:]
    b = problem.criterion.split_bounds(problem, q, [7, 8], basis=basis, chol=chol)
    exact = _exact(problem, q)
    assert b[0] == pytest.approx(exact[7], abs=1e-10)
    assert b[1] > exact[8] + 1e-6  # another candidate's block is not spanned: a bound, not the value


@pytest.mark.parametrize("seed", range(3))
def test_ds_bounds_hold_with_springs_marginalised(seed):
    # Reference: Ds(Q + I_i) = log det(Q + I_i) - log det((Q + I_i)_22) by numpy's slogdet of dense matrices,
    # for every candidate; the bounds (first-order, eigen-split, whitened split) must lie above it, and the
    # split bound with every direction is the value
    problem = replace(_random_problem(seed), criterion=make_criterion("Ds", 10, n_elements=8))  # 2 marginalised
    crit = problem.criterion
    q = problem.layout_precision([1, 4])
    exact = np.array([np.linalg.slogdet(q + b)[1] - np.linalg.slogdet((q + b)[8:, 8:])[1] for b in problem.blocks])
    value, upper = crit.upper_bounds(problem, q)
    assert value == pytest.approx(np.linalg.slogdet(q)[1] - np.linalg.slogdet(q[8:, 8:])[1], rel=1e-12)
    assert np.all(upper >= exact - 1e-9)
    assert np.all(crit.subset_bounds(problem, q, k=4) >= exact - 1e-9)
    chol = np.linalg.cholesky(q)
    index = np.arange(problem.n_candidates)
    assert np.all(crit.split_bounds(problem, q, index, basis=np.eye(10)[:, :3], chol=chol) >= exact - 1e-9)
    np.testing.assert_allclose(crit.split_bounds(problem, q, index, basis=np.eye(10), chol=chol), exact,
                               rtol=1e-10, atol=1e-10)


def test_ds_without_parameters_to_marginalise_is_d():
    # log det Q - log det Q_22 with nothing in Q_22 is log det Q: D's values, bounds and paths, under Ds's name
    from sensorplan.design import selection

    problem = _random_problem(1)
    d, ds = make_criterion("D", 10), make_criterion("Ds", 10, n_elements=10)
    assert ds.name == "Ds" and ds.n_keep == 10 and ds.submodular
    q = problem.layout_precision([1, 4])
    reference = make_criterion("Ds", 10, n_elements=8)  # the general difference of log determinants ...
    reference.n_keep = 10  # ... with nothing marginalised (the value written out, not D's code)
    assert ds.value(q) == pytest.approx(reference.value(q), rel=1e-14) == d.value(q)
    blocks = [problem.blocks[i] for i in range(problem.n_candidates)]
    assert ds.utilities(q, blocks) == pytest.approx(d.utilities(q, blocks), rel=1e-14)
    assert selection._local_levels(replace(problem, criterion=ds)) == selection._local_levels(
        replace(problem, criterion=d))


@pytest.fixture(scope="module")
def structured_problem():
    return structured_three_span()


def test_split_bounds_on_structured_blocks_hold_and_are_exact_with_every_direction(structured_problem):
    problem = structured_problem
    rng = np.random.default_rng(2)
    q = problem.layout_precision([3, 30, 60])
    index = np.sort(rng.choice(problem.n_candidates, 25, replace=False))
    dense = problem.blocks[index]
    exact = np.array([np.linalg.slogdet(q + b)[1] for b in dense])
    chol = np.linalg.cholesky(q)
    for k in (4, 16, problem.n_params):
        basis = np.linalg.qr(rng.standard_normal((problem.n_params, k)))[0]
        b = problem.criterion.split_bounds(problem, q, index, basis=basis, chol=chol)
        assert np.all(b >= exact - 1e-9 * np.abs(exact))
    assert b == pytest.approx(exact, rel=1e-11)


EXACT = {"D": lambda m: np.linalg.slogdet(m)[1], "A": lambda m: -np.trace(np.linalg.inv(m)),
         "A region": lambda m: -np.trace(np.linalg.inv(m)[: m.shape[0] // 2, : m.shape[0] // 2])}


def _criterion(name, p):
    from sensorplan.design.criteria.covariance import ACriterion

    return ACriterion(p, targets=np.eye(p)[: p // 2]) if name == "A region" else make_criterion(name, p)


@pytest.mark.parametrize("name", ["D", "A", "A region"])
@pytest.mark.parametrize("coarse_above, halves_above", [(None, None), (40, None), (None, 1), (40, 1)])
def test_greedy_and_exchange_with_split_bounds_at_every_step_equal_brute_force(monkeypatch, structured_problem,
                                                                                coarse_above, halves_above, name):
    # halves_above 1: every level of split bounds takes each half of two or more survivors (by position) along its
    # own eigenvectors (the default does so above 200 survivors, more than this problem has)
    from sensorplan.design import screening, selection

    monkeypatch.setattr(screening, "LOCAL_COST", 0)  # a level of split bounds whenever anything survives
    monkeypatch.setattr(screening, "LOCAL_K", (4, 8, 16))
    monkeypatch.setattr(selection, "LOCAL_K", (4, 8, 16))
    calls, along = {"expected": 0, "along": 0, "halved": 0}, screening._split_along
    if halves_above is not None:
        monkeypatch.setattr(screening, "HALVES_ABOVE", halves_above)

    def counted(*args, **kwargs):
        calls["along"] += 1
        return along(*args, **kwargs)

    monkeypatch.setattr(screening, "_split_along", counted)
    problem = replace(structured_problem, criterion=_criterion(name, structured_problem.n_params))
    dense = replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])
    exact = EXACT[name]
    chosen = []  # brute-force greedy
    while len(chosen) < problem.count:
        q = dense.q0 + dense.blocks[chosen].sum(axis=0)
        values = [(exact(q + dense.blocks[i]), -i) for i in range(problem.n_candidates) if i not in chosen]
        chosen.append(-max(values)[1])
    split = screening._split

    def counted_split(problem, q, index, k):
        calls["expected"] += 2 if len(index) > screening.HALVES_ABOVE else 1
        calls["halved"] += len(index) > screening.HALVES_ABOVE
        return split(problem, q, index, k)

    monkeypatch.setattr(screening, "_split", counted_split)
    layout, _ = selection.greedy(problem)
    assert layout == chosen
    assert calls["expected"] > 0 and calls["along"] == calls["expected"]
    assert (calls["halved"] > 0) == (halves_above is not None)
    start = np.random.default_rng(5).choice(problem.n_candidates, 5, replace=False).tolist()
    swapped, value = selection.exchange(problem, start, coarse_above=coarse_above)
    for pos in range(len(swapped)):  # a local optimum: no swap with any candidate improves (brute force)
        rest = swapped[:pos] + swapped[pos + 1:]
        q = dense.q0 + dense.blocks[rest].sum(axis=0)
        best_swap = max(exact(q + dense.blocks[i]) for i in range(problem.n_candidates) if i not in swapped)
        assert best_swap <= value + max(1e-9 * max(1.0, abs(value)), problem.criterion.swap_gain * abs(value))


def _a_criterion(seed, kind):
    """A on all parameters, on a region (the first four), or on random functionals."""
    from sensorplan.design.criteria.covariance import ACriterion

    if kind == "all":
        return ACriterion(10)
    if kind == "region":
        return ACriterion(10, targets=np.eye(10)[:4])
    return ACriterion(10, targets=np.random.default_rng(seed + 7).standard_normal((3, 10)))


def _exact_a(criterion, q, blocks):
    """-trace(C (Q + I_i)^-1 C^T) with numpy's inverse."""
    c = criterion.targets
    return np.array([-np.trace(c @ np.linalg.inv(q + b) @ c.T) for b in blocks])


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 10), kind=st.sampled_from(["all", "region", "functionals"]))
def test_a_split_bounds_hold_for_any_basis_and_are_exact_for_a_full_one(seed, k, kind):
    # reference: -trace of C times numpy's inverse of Q + I_i times C^T
    problem = replace(_random_problem(seed), criterion=_a_criterion(seed, kind))
    rng = np.random.default_rng(seed + 3)
    q = problem.layout_precision(rng.choice(problem.n_candidates, 2, replace=False))
    exact = _exact_a(problem.criterion, q, problem.blocks)
    basis = np.linalg.qr(rng.standard_normal((problem.n_params, problem.n_params)))[0][:, :k]
    b = problem.criterion.split_bounds(problem, q, np.arange(problem.n_candidates), basis=basis,
                                       chol=np.linalg.cholesky(q))
    assert np.all(b >= exact - 1e-9 * np.maximum(1.0, np.abs(exact)))
    if k == problem.n_params:
        assert b == pytest.approx(exact, rel=1e-9)


@pytest.mark.parametrize("kind", ["all", "region", "functionals"])
def test_a_split_bounds_are_exact_when_the_basis_spans_the_whitened_block(kind):
    problem = replace(_random_problem(4), criterion=_a_criterion(4, kind))
    q = problem.layout_precision([1, 2])
    chol = np.linalg.cholesky(q)
    l_inv = np.linalg.inv(chol)
    basis = np.linalg.eigh(l_inv @ problem.blocks[9] @ l_inv.T)[1][:, -3:]
    b = problem.criterion.split_bounds(problem, q, [9], basis=basis, chol=chol)
    assert b[0] == pytest.approx(_exact_a(problem.criterion, q, problem.blocks[9:10])[0], rel=1e-10)


def test_search_utilities_equal_numpy_values():
    # reference: numpy's slogdet and inverse of Q + I_i (the searches' exact evaluations use LAPACK's dpotrf)
    problem = _random_problem(8)
    q = problem.layout_precision([0, 3])
    for name, exact in EXACT.items():
        crit = _criterion(name, problem.n_params)
        assert crit.utilities(q, problem.blocks) == pytest.approx([exact(q + b) for b in problem.blocks], rel=1e-12)

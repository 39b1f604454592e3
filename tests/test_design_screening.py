"""Tighter bounds on the survivors (sensorplan.design.screening) and the searches that use them.

References: exact values computed here with numpy's slogdet / inv / eigvalsh of Q + I_i (not the criteria's
code), brute force over every candidate (argmax, greedy step, swap), and the dense blocks of
:func:`sensorplan.model.fisher.fisher_blocks` for the structured congruences.
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
from sensorplan.design.screening import best_candidate

sys.path.insert(0, str(Path(__file__).resolve().parent))
from design_problems import structured_three_span  # noqa: E402

EXACT = {"D": lambda m: np.linalg.slogdet(m)[1], "A": lambda m: -np.trace(np.linalg.inv(m)),
         "E": lambda m: np.linalg.eigvalsh(m)[0]}


def _random_problem(seed, criterion, *, c=40, p=12, rank=3, count=4):
    """Blocks of random rank-``rank`` Jacobians, a random positive definite prior (dense blocks)."""
    rng = np.random.default_rng(seed)
    jac = rng.standard_normal((c, rank, p)) * rng.uniform(0.2, 3.0, (c, 1, 1))
    blocks = np.einsum("cri,crj->cij", jac, jac)
    a = rng.standard_normal((p, p))
    q0 = a @ a.T / p + 0.1 * np.eye(p)
    return DesignProblem(np.sort(rng.uniform(0.0, 50.0, c)), np.zeros(c, dtype=int), blocks, q0,
                         criterion=make_criterion(criterion, p), count=count)


def _exact(problem, q, name):
    return np.array([EXACT[name](q + b) for b in problem.blocks])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), name=st.sampled_from(["D", "A", "E"]), k=st.integers(1, 12))
def test_subset_bounds_hold_for_every_k(seed, name, k):
    problem = _random_problem(seed, name)
    rng = np.random.default_rng(seed + 1)
    q = problem.layout_precision(rng.choice(problem.n_candidates, 3, replace=False))
    exact = _exact(problem, q, name)
    index = np.sort(rng.choice(problem.n_candidates, 15, replace=False))
    b = problem.criterion.subset_bounds(problem, q, index, k=k)
    assert np.all(b >= exact[index] - 1e-9 * np.maximum(1.0, np.abs(exact[index])))
    full = problem.criterion.subset_bounds(problem, q, k=k)
    assert full[index] == pytest.approx(b, rel=1e-12, abs=1e-12)
    if k == problem.n_params:  # nothing left to bound: the exact values
        assert b == pytest.approx(exact[index], rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("name", ["D", "A", "E"])
def test_subset_bounds_tighten_with_k_and_upper_bounds_unchanged(name):
    problem = _random_problem(5, name, p=20, rank=2)
    q = problem.layout_precision([1, 7, 20])
    exact = _exact(problem, q, name)
    slack = [float(np.median(problem.criterion.subset_bounds(problem, q, k=k) - exact)) for k in (2, 8, 20)]
    assert slack[0] > slack[1] > slack[2] and slack[2] == pytest.approx(0.0, abs=1e-9)
    _, ub = problem.criterion.upper_bounds(problem, q)
    assert ub == pytest.approx(problem.criterion.subset_bounds(problem, q, k=16), rel=1e-13)
    assert np.all(ub >= exact - 1e-9 * np.maximum(1.0, np.abs(exact)))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), name=st.sampled_from(["D", "A", "E"]), floor_shift=st.sampled_from([None, 0.0]))
def test_best_candidate_equals_brute_force(seed, name, floor_shift):
    problem = _random_problem(seed, name, c=60)
    rng = np.random.default_rng(seed + 2)
    q = problem.layout_precision(rng.choice(problem.n_candidates, 2, replace=False))
    exact = _exact(problem, q, name)
    _, ub = problem.criterion.upper_bounds(problem, q)
    bound = ub + 1e-9 * np.maximum(1.0, np.abs(ub))
    banned = set(rng.choice(problem.n_candidates, 10, replace=False).tolist())
    allowed = [i for i in range(problem.n_candidates) if i not in banned]
    floor = -np.inf if floor_shift is None else float(np.median(exact[allowed]))
    order = np.argsort(-ub, kind="stable")
    evaluated = []

    def evaluate(group, above):  # like ECriterion.utilities_above: values that cannot win come back as -inf
        evaluated.extend(group)
        values = [EXACT[name](q + problem.blocks[i]) for i in group]
        return [v if v > above else -np.inf for v in values]

    best, value = best_candidate(problem, q, order, bound.copy(), evaluate, floor=floor,
                                 usable=lambda i: i not in banned, batch=3,
                                 refine=((2, 0), (4, 0), (8, 2)))
    above = [i for i in allowed if exact[i] > floor]
    reference = max(above, key=lambda i: exact[i])  # brute force (no ties in random data)
    assert best == reference and value == exact[reference]
    assert not banned & set(evaluated)


def _brute_greedy(problem):
    chosen = []
    name = problem.criterion.name
    while len(chosen) < problem.count:
        q = problem.q0 + problem.blocks[chosen].sum(axis=0)
        values = [(EXACT[name](q + problem.blocks[i]), -i) for i in range(problem.n_candidates) if i not in chosen]
        chosen.append(-max(values)[1])
    return chosen


@pytest.fixture(scope="module")
def structured_problem():
    return structured_three_span()


@pytest.mark.parametrize("name", ["D", "A", "E"])
def test_greedy_and_exchange_with_refined_bounds_equal_brute_force(monkeypatch, structured_problem, name):
    from sensorplan.design import screening, selection

    monkeypatch.setattr(selection, "REFINE_K", ((4, 0), (8, 0), (16, 0), (32, 0)))  # refine whenever anything survives
    monkeypatch.setattr(screening, "BOUND_BYTES", 8 * 32 * 32 * 5)  # the tighter bounds 5 candidates a call at k = 32
    problem = replace(structured_problem, criterion=make_criterion(name, structured_problem.n_params))
    monkeypatch.setattr(problem.criterion, "refine_levels", None, raising=False)  # the levels above, for A too
    dense = replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])
    layout, _ = selection.greedy(problem)
    assert layout == _brute_greedy(dense)
    rng = np.random.default_rng(7)
    starts = [list(range(0, problem.n_candidates, problem.n_candidates // 5))[:5]]
    starts += [rng.choice(problem.n_candidates, 5, replace=False).tolist() for _ in range(3)]
    # plain, and coarse grid first + local moves + the full search
    for start, coarse_above in [(starts[0], None)] + [(s, c) for s in starts for c in (40, 20)]:
        swapped, value = selection.exchange(problem, start, coarse_above=coarse_above)
        assert value == pytest.approx(problem.utility_of(swapped), rel=1e-12)
        for pos in range(len(swapped)):  # a local optimum: no swap with any candidate improves (brute force)
            rest = swapped[:pos] + swapped[pos + 1:]
            q = dense.q0 + dense.blocks[rest].sum(axis=0)
            best_swap = max(EXACT[name](q + dense.blocks[i]) for i in range(problem.n_candidates) if i not in swapped)
            assert best_swap <= value + max(1e-9 * max(1.0, abs(value)), problem.criterion.swap_gain * abs(value))


@pytest.mark.parametrize("name", ["D", "A"])
def test_the_criteria_own_refine_levels_give_brute_force_greedy_and_local_optima(monkeypatch, structured_problem,
                                                                                   name):
    # the criterion's levels (first bounds at their first k, then the rest), scaled to the small problem so that
    # every level is used
    from sensorplan.design import selection

    problem = replace(structured_problem, criterion=make_criterion(name, structured_problem.n_params))
    monkeypatch.setattr(problem.criterion, "refine_levels", ((8, 0), (12, 0), (16, 0)), raising=False)
    dense = replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])
    assert selection.greedy(problem)[0] == _brute_greedy(dense)
    swapped, value = selection.exchange(problem, list(range(0, problem.n_candidates, 9))[:5], coarse_above=20)
    for pos in range(len(swapped)):  # a local optimum: no swap with any candidate improves (brute force)
        rest = swapped[:pos] + swapped[pos + 1:]
        q = dense.q0 + dense.blocks[rest].sum(axis=0)
        best_swap = max(EXACT[name](q + dense.blocks[i]) for i in range(problem.n_candidates) if i not in swapped)
        assert best_swap <= value + max(1e-9 * max(1.0, abs(value)), problem.criterion.swap_gain * abs(value))


def test_layout_precision_of_a_small_structured_layout_equals_the_weighted_sum(structured_problem):
    problem = structured_problem
    layout = [3, 40, 41, 77]
    w = np.bincount(layout, minlength=problem.n_candidates).astype(float)
    reference = problem.q0 + problem.blocks.weighted(w)
    assert np.abs(problem.layout_precision(layout) - reference).max() <= 1e-12 * np.abs(reference).max()


def test_congruence_with_many_eigenvectors_and_shared_elements_equals_dense(structured_problem):
    # several candidates per element share the start of their masked part (the suffix sums are grouped)
    problem = structured_problem
    rng = np.random.default_rng(4)
    dense = problem.blocks[np.arange(problem.n_candidates)]
    for k in (1, 17, problem.n_params):
        v = np.linalg.qr(rng.standard_normal((problem.n_params, k)))[0]
        index = np.sort(rng.choice(problem.n_candidates, 30, replace=False))
        ref = np.einsum("ip,cij,jq->cpq", v, dense[index], v)
        assert np.abs(problem.congruence(v, index) - ref).max() <= 1e-10 * np.abs(ref).max()
        assert np.abs(problem.congruence(v)[index] - ref).max() <= 1e-10 * np.abs(ref).max()

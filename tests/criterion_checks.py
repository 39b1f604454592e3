"""The common checks every design criterion passes, as functions of a placement problem.

scikit-learn's common-checks style: tests/test_conformance.py runs them over
every registered criterion (the built-in ones and a toy one), and a
criterion defined anywhere else runs them on its own problems
(tests/test_toy_criterion.py).  References are independent of the code
under test: finite differences for gradients and Hessians, brute-force
enumeration for optima, bounds and efficiencies.
"""

import itertools

import numpy as np
import pytest

from sensorplan.design.criteria import Criterion
from sensorplan.design.relaxation import solve_relaxation
from sensorplan.design.selection import exchange, greedy


class LogDiagonal(Criterion):
    """A toy criterion: sum of log of the precision's diagonal (concave in the weights)."""

    name = "logdiag"
    description = "sum of log diagonal of the posterior precision"

    def value(self, q):
        return float(np.sum(np.log(np.diag(q))))

    def gradient_matrix(self, q):
        return np.diag(1.0 / np.diag(q))

    def cvxpy_objective(self, cp, q, constraints):
        return cp.Maximize(cp.sum(cp.log(cp.diag(q)))), None


def brute_force(problem):
    """Best feasible layout by enumeration (the reference optimum) and its utility."""
    best, best_u = None, -np.inf
    for subset in itertools.combinations(range(problem.n_candidates), problem.count):
        if problem.feasible(subset):
            u = problem.utility_of(subset)
            if u > best_u:
                best, best_u = list(subset), u
    return best, best_u


def check_gradient(problem, seed=0):
    """The gradient in the weights against central differences of the utility."""
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.1, 0.4, problem.n_candidates)
    grad = problem.gradient(w)
    for i in rng.choice(problem.n_candidates, 4, replace=False):
        h = 1e-5
        up, down = w.copy(), w.copy()
        up[i] += h
        down[i] -= h
        utility = problem.criterion.utility
        fd = (utility(problem.precision(up)) - utility(problem.precision(down))) / (2 * h)
        assert grad[i] == pytest.approx(fd, rel=1e-5, abs=1e-7 * max(1.0, abs(fd)))


def check_hessian(problem, seed=1):
    """The Hessian in the weights of a working set against central differences of the gradient."""
    crit = problem.criterion
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.1, 0.4, problem.n_candidates)
    idx = rng.choice(problem.n_candidates, 5, replace=False)
    q = 0.5 * (problem.precision(w) + problem.precision(w).T)
    h = crit.hessian(q, np.linalg.cholesky(q), problem.blocks[idx])
    step = 1e-6
    for a, j in enumerate(idx):
        up, down = w.copy(), w.copy()
        up[j] += step
        down[j] -= step
        fd = (problem.gradient(up)[idx] - problem.gradient(down)[idx]) / (2 * step)
        np.testing.assert_allclose(h[:, a], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def check_upper_bounds(problem, layouts=((), (0, 5), (1, 3, 8))):
    """``upper_bounds`` returns the utility and bounds at least the exact utility of adding each candidate."""
    crit = problem.criterion
    for layout in layouts:
        q = problem.layout_precision(list(layout))
        u, ub = crit.upper_bounds(problem, q)
        assert u == pytest.approx(crit.utility(q), rel=1e-9)
        exact = np.array([crit.utility(q + problem.blocks[i]) for i in range(problem.n_candidates)])
        assert np.all(ub >= exact - 1e-9 * np.maximum(1.0, np.abs(exact)))


def check_relaxation_certificate(problem, solver, best_u=None):
    """The relaxation's certified bound bounds the brute-force optimum; its weights are feasible; the
    certified efficiency of the greedy layout never exceeds its true efficiency."""
    if best_u is None:
        _, best_u = brute_force(problem)
    rel = solve_relaxation(problem, solver)
    tol = 1e-9 * max(1.0, abs(best_u))
    assert rel.bound >= best_u - tol
    assert rel.bound >= rel.utility - tol
    w = rel.weights
    assert w.min() >= -1e-9 and w.max() <= 1 + 1e-9 and abs(w.sum() - problem.count) <= 1e-6
    crit = problem.criterion
    sign = 1.0 if crit.maximise else -1.0
    _, greedy_u = greedy(problem)
    certified = crit.efficiency(sign * greedy_u, sign * rel.bound)
    true = crit.efficiency(sign * greedy_u, sign * best_u)
    assert 0.0 <= certified <= true + 1e-12 and true <= 1.0
    assert crit.efficiency(sign * best_u, sign * best_u) == pytest.approx(1.0, rel=1e-12)


def check_greedy_exchange(problem, best_u=None):
    """Greedy <= exchange <= the brute-force optimum, both feasible."""
    if best_u is None:
        _, best_u = brute_force(problem)
    g, g_u = greedy(problem)
    x, x_u = exchange(problem, g)
    tol = 1e-9 * max(1.0, abs(best_u))
    assert problem.feasible(g) and problem.feasible(x)
    assert g_u <= x_u + tol <= best_u + 2 * tol


def check_recommendation(result, problem, best_u):
    """A recommendation's value is at most the optimum and its certified bound at least the optimum."""
    sign = 1.0 if problem.criterion.maximise else -1.0
    tol = 1e-9 * max(1.0, abs(best_u))
    assert sign * result.value <= best_u + tol
    assert sign * result.bound >= best_u - tol
    assert 0.0 <= result.efficiency <= 1.0

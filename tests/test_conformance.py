"""Every member of each plug-in family through the same checks (scikit-learn's common-checks style).

Families: design criteria (the built-in ones and a toy criterion defined
here in a few lines), relaxation solvers and baselines.  The criterion
checks live in tests/criterion_checks.py, so that a criterion defined
elsewhere runs them too; references are independent of the code under
test: finite differences for gradients and Hessians, brute-force
enumeration for optima, bounds and efficiencies.
"""

import dataclasses
import pathlib
import sys

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.design.baselines import BASELINES, BaselineContext
from sensorplan.design.recommend import build_problem
from sensorplan.design.relaxation import RELAXATION_SOLVERS

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from criterion_checks import (  # noqa: E402
    LogDiagonal,
    brute_force,
    check_gradient,
    check_greedy_exchange,
    check_hessian,
    check_recommendation,
    check_relaxation_certificate,
    check_upper_bounds,
)


@pytest.fixture(scope="module", autouse=True)
def toy_criterion():
    sp.register_criterion(LogDiagonal)
    yield
    sp.CRITERIA.pop(LogDiagonal.name)


CRITERIA = ["D", "Ds", "A", "E", "logdiag", "detect"]


def small_case():
    # two spans with an elastic end spring (so Ds has a nuisance parameter), 8 elements
    bridge = sp.Bridge((12.0, 12.0), rotational_springs=(2e9, 0.0, 2e9))
    return sp.Case(bridge, sp.Mesh.uniform(bridge, 8), 1e10, sp.Vehicle((0.0, 2.0), (5e4, 5e4)),
                   sp.SensorLayout([6.0], noise_std=2e-6), sweep=sp.LoadSweep.from_range(0.0, 26.0, 0.5))


def problem_for(criterion, count=3, **constraints):
    return build_problem(small_case(), count, criterion, grid=sp.CandidateGrid(spacing=2.0),
                         springs=criterion == "Ds", constraints=sp.Constraints(**constraints))


@pytest.mark.parametrize("criterion", CRITERIA)
def test_gradient_matches_finite_differences(criterion):
    check_gradient(problem_for(criterion))


# E and detect are minima (not smooth): their relaxations do not use Criterion.hessian (detect's
# epigraph solver has its own per-centre Hessians, checked in tests/test_detect_criterion.py)
@pytest.mark.parametrize("criterion", [c for c in CRITERIA if c not in ("E", "detect")])
def test_hessian_matches_finite_differences_of_the_gradient(criterion):
    check_hessian(problem_for(criterion))


@pytest.mark.parametrize("criterion", CRITERIA)
def test_upper_bounds_are_upper_bounds(criterion):
    check_upper_bounds(problem_for(criterion))


@pytest.mark.parametrize("solver", sorted(RELAXATION_SOLVERS))
@pytest.mark.parametrize("criterion", CRITERIA)
@pytest.mark.parametrize("constraints", [{}, {"min_spacing": 5.0}, {"costs": 1.0, "budget": 3.0, "span_max": [2, 2]}])
def test_relaxation_certificate_bounds_the_brute_force_optimum(criterion, solver, constraints):
    check_relaxation_certificate(problem_for(criterion, **constraints), solver)


@pytest.mark.parametrize("criterion", CRITERIA)
def test_greedy_exchange_recommend_against_brute_force(criterion):
    problem = problem_for(criterion)
    _, best_u = brute_force(problem)
    check_greedy_exchange(problem, best_u)
    result = sp.recommend(small_case(), 3, criterion, grid=sp.CandidateGrid(spacing=2.0), springs=criterion == "Ds",
                          curve_max=2, n_random=10)
    check_recommendation(result, problem, best_u)
    assert result.criterion == criterion and [c.count for c in result.curve] == [1, 2]
    # the toy criterion runs end to end on the command line too
    assert criterion in sp.CRITERIA


@pytest.mark.parametrize("name", sorted(BASELINES))
def test_baselines_are_feasible_or_none(name):
    problem = problem_for("D", min_spacing=5.0)
    ctx = BaselineContext(24.0, (0.0, 12.0, 24.0), n_random=10, rng=0)
    layout = BASELINES[name](problem, ctx)
    assert layout is None or problem.feasible(layout)
    # 3 sensors 13 m apart do not fit on 24 m: build_problem refuses it up front (feasibility.check_feasible),
    # so the baseline meets the impossible problem built directly
    with pytest.raises(sp.ConfigError, match="at most 2 sensor"):
        problem_for("D", min_spacing=13.0)
    impossible = dataclasses.replace(problem, min_spacing=13.0)
    layout = BASELINES[name](impossible, ctx)
    assert layout is None or impossible.feasible(layout)


def test_toy_criterion_on_the_command_line(tmp_path, capsys):
    from sensorplan.cli import main

    code = main(["recommend", "--example", "simply-supported", "--count", "2", "--criterion", "logdiag",
                 "--spacing", "2", "--out", str(tmp_path)])
    assert code == 0
    assert "logdiag-optimal" in capsys.readouterr().out

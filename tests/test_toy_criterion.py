"""A criterion defined here, in one class, works end to end without editing the package.

``RegionD`` is D-optimality on a block of the Fisher information: the log
determinant of the posterior precision block of the log EI of the elements
that overlap a region of interest,

    value(Q) = log det Q_SS,  S = the log-EI parameters of those elements,

i.e. the information about EI there if every other parameter were known
(concave in the weights: Q_SS is linear in them).  It is registered through
the public registry (``sp.register_criterion``), passes the common criterion
checks (tests/criterion_checks.py), and through ``recommend`` and
``sensorplan recommend --criterion`` finds the brute-force optimum of a small
problem, which beats every random layout on the criterion computed here
from independent Fisher blocks.
"""

import json
import math
import pathlib
import sys

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.design.recommend import build_problem
from sensorplan.design.relaxation import RELAXATION_SOLVERS

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from criterion_checks import (  # noqa: E402
    brute_force,
    check_gradient,
    check_greedy_exchange,
    check_hessian,
    check_recommendation,
    check_relaxation_certificate,
    check_upper_bounds,
)

REGION = (4.0, 14.0)  # m: elements 2..4 of 8 on the 24 m bridge below (edges every 3 m)


class RegionD(sp.Criterion):
    """log det of the posterior precision block of the log EI of the elements overlapping ``region``."""

    name = "Dregion"
    description = "log det of the precision block of log EI in the region"

    def __init__(self, n_params, *, index=None):
        super().__init__(n_params)
        self.index = np.arange(self.n_params) if index is None else np.asarray(index)

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        if functionals is not None:
            raise sp.ConfigError("Functionals apply to the A criterion only, not to Dregion.")
        if region is None:
            return cls(n_params, index=np.arange(n_params if n_elements is None else n_elements))
        inside = (edges[1:] > region[0]) & (edges[:-1] < region[1])
        return cls(n_params, index=np.nonzero(inside)[0])

    @property
    def n_effective(self):
        return self.index.size

    def _block(self, q):
        return q[np.ix_(self.index, self.index)]

    def value(self, q):
        sign, logdet = np.linalg.slogdet(self._block(q))
        return float(logdet) if sign > 0 else -math.inf

    def gradient_matrix(self, q):
        g = np.zeros_like(q)
        inv = np.linalg.inv(self._block(q))
        g[np.ix_(self.index, self.index)] = 0.5 * (inv + inv.T)
        return g

    def cvxpy_objective(self, cp, q, constraints):
        a, b = int(self.index[0]), int(self.index[-1]) + 1  # a contiguous block of elements
        return cp.Maximize(cp.log_det(q[a:b, a:b])), None

    def efficiency(self, value, bound):
        return float(math.exp(min(0.0, (value - bound) / self.n_effective)))

    def relative(self, value, reference):
        return math.exp((value - reference) / self.n_effective)


@pytest.fixture(scope="module", autouse=True)
def registered():
    sp.register_criterion(RegionD)
    yield
    sp.CRITERIA.pop(RegionD.name)


def small_case():
    # two 12 m spans with elastic end springs, 8 elements of 3 m, one tiltmeter of 2 urad
    bridge = sp.Bridge((12.0, 12.0), rotational_springs=(2e9, 0.0, 2e9))
    return sp.Case(bridge, sp.Mesh.uniform(bridge, 8), 1e10, sp.Vehicle((0.0, 2.0), (5e4, 5e4)),
                   sp.SensorLayout([6.0], noise_std=2e-6), sweep=sp.LoadSweep.from_range(0.0, 26.0, 0.5))


def problem_for(count=3, **constraints):
    return build_problem(small_case(), count, "Dregion", grid=sp.CandidateGrid(spacing=2.0), region=REGION,
                         constraints=sp.Constraints(**constraints))


def independent_value(case, positions):
    """The criterion of a layout from Fisher blocks of its own sensors and the prior (no design code)."""
    layout = sp.SensorLayout(list(positions), noise_std=case.noise_std_for("rotation"))
    info = sp.fisher_blocks(case, sensors=layout, parameterisation="log_ei").blocks.sum(axis=0)
    q = sp.GMRFPrior().precision(case.n_elements) + info
    inside = (case.mesh.edges[1:] > REGION[0]) & (case.mesh.edges[:-1] < REGION[1])
    return float(np.linalg.slogdet(q[np.ix_(inside, inside)])[1])


def test_the_toy_is_registered_and_built_with_its_region():
    assert "Dregion" in sp.CRITERIA
    crit = problem_for().criterion
    assert isinstance(crit, RegionD) and crit.index.tolist() == [1, 2, 3, 4]


def test_the_toy_passes_the_common_criterion_checks():
    problem = problem_for()
    check_gradient(problem)
    check_hessian(problem)
    check_upper_bounds(problem)
    _, best_u = brute_force(problem)
    check_greedy_exchange(problem, best_u)
    for solver in sorted(RELAXATION_SOLVERS):
        check_relaxation_certificate(problem, solver, best_u)


@pytest.mark.parametrize("constraints", [{"min_spacing": 5.0}, {"costs": 1.0, "budget": 3.0, "span_max": [2, 2]}])
def test_the_toy_relaxation_is_certified_under_constraints(constraints):
    problem = problem_for(**constraints)
    for solver in sorted(RELAXATION_SOLVERS):
        check_relaxation_certificate(problem, solver)


def test_recommend_finds_the_brute_force_optimum_and_beats_random_layouts():
    case = small_case()
    result = sp.recommend(case, 3, "Dregion", grid=sp.CandidateGrid(spacing=2.0), region=REGION, curve_max=3,
                          n_random=20)
    problem = problem_for()
    best, best_u = brute_force(problem)
    check_recommendation(result, problem, best_u)
    assert result.criterion == "Dregion" and result.n_params == 4 and [c.count for c in result.curve] == [1, 2, 3]
    assert result.value == pytest.approx(best_u, rel=1e-12)
    assert sorted(result.layout_m) == sorted(float(problem.positions[i]) for i in best)
    # the reported value is the criterion of the layout, computed independently
    assert independent_value(case, result.layout_m) == pytest.approx(result.value, rel=1e-9)
    rng = np.random.default_rng(7)
    for _ in range(20):
        random_layout = rng.choice(problem.positions, 3, replace=False)
        assert independent_value(case, random_layout) <= result.value + 1e-9 * abs(result.value)
    # the criterion targets the region: the region's posterior std is smaller than under D's layout
    d_result = sp.recommend(case, 3, "D", grid=sp.CandidateGrid(spacing=2.0), curve_max=0, n_random=20)
    inside = np.arange(1, 5)
    assert result.posterior_std["recommended"][inside].mean() <= d_result.posterior_std["recommended"][inside].mean()


def test_the_toy_on_the_command_line(tmp_path, capsys):
    code = main(["recommend", "--example", "simply-supported", "--count", "2", "--criterion", "Dregion",
                 "--region", "5:15", "--spacing", "2", "--json", str(tmp_path / "design.json"),
                 "--out", str(tmp_path)])
    assert code == 0
    assert "Dregion-optimal" in capsys.readouterr().out
    payload = json.loads((tmp_path / "design.json").read_text())
    api = sp.recommend(sp.example_case("simply-supported"), 2, "Dregion", grid=sp.CandidateGrid(spacing=2.0),
                       region=(5.0, 15.0))
    assert payload["criterion"] == "Dregion"
    assert payload["layout_m"] == list(api.layout_m) and payload["value"] == pytest.approx(api.value, rel=1e-12)

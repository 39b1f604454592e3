"""Mixed sensor kinds, per-kind noise and cost, budgets and existing sensors: brute force on small problems.

The reference Fisher information is built independently of sensorplan: the
readings come from the finite-element solver of tests/fe_reference.py, the
Jacobian with respect to log EI (and the spring log-stiffnesses) from
central finite differences of those readings, and the AR(1) noise is
whitened with the dense correlation matrix exp(-|x_i - x_j| / l) and each
sensor's own noise std (per kind).  The criteria are computed from their
definitions (tests/test_design.py: numpy on dense matrices) and every
feasible layout is enumerated, with the constraints checked directly.
"""

import itertools
import math
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from fe_reference import fe_response  # noqa: E402
from test_design import MAXIMISE, criterion_value, reference_prior, true_efficiency  # noqa: E402

import sensorplan as sp
from sensorplan import CandidateGrid, Case, Constraints, recommend
from sensorplan.design.recommend import build_problem

SPANS = (10.0, 10.0)
ROT = (2e9, 0.0, 2e9)  # elastic end restraints: two spring parameters (rotational_0, rotational_2)
AXLES = ((0.0, 2.0), (5e4, 5e4))
LOADS = np.arange(0.0, 22.01, 1.0)
CORRELATION = 0.8  # m
NOISE = {"rotation": 2e-6, "deflection": 5e-6}  # the case's sensors: rad, m


def mixed_case():
    bridge = sp.Bridge(SPANS, rotational_springs=ROT)
    sensors = sp.SensorLayout([3.0, 15.0], kinds=["rotation", "deflection"], names=["T", "D"])
    noise = sp.NoiseModel([NOISE["rotation"], NOISE["deflection"]], CORRELATION)
    return Case(bridge, sp.Mesh.uniform(bridge, 8), 1e10, sp.Vehicle(*AXLES), sensors, noise=noise,
                sweep=sp.LoadSweep.from_range(0.0, 22.0, 1.0))


def readings(log_ei, log_k, sensors):
    """FE readings (n_sensors, n_loads) for per-element log EI and spring log-stiffnesses."""
    edges = np.linspace(0.0, 20.0, 9)
    rot = [math.exp(log_k[0]), 0.0, math.exp(log_k[1])]
    out = np.empty((len(sensors), LOADS.size))
    for j, z in enumerate(LOADS):
        loads = [(z - d, p) for d, p in zip(*AXLES) if 0.0 <= z - d <= 20.0]
        out[:, j] = fe_response(list(SPANS), edges, np.exp(log_ei), rot, [math.inf] * 3, loads, sensors) \
            if loads else 0.0
    return out


def reference_blocks(sensors, stds, springs):
    """Fisher block of each sensor: J^T Gamma^-1 J / std^2 with dense Gamma and a finite-difference J."""
    theta = np.concatenate([np.full(8, math.log(1e10)), np.log([ROT[0], ROT[2]])])
    n = 10 if springs else 8
    h = 1e-4
    jac = np.empty((len(sensors), LOADS.size, n))
    for p in range(n):
        up, down = theta.copy(), theta.copy()
        up[p] += h
        down[p] -= h
        jac[:, :, p] = (readings(up[:8], up[8:], sensors) - readings(down[:8], down[8:], sensors)) / (2 * h)
    gamma = np.exp(-np.abs(LOADS[:, None] - LOADS[None, :]) / CORRELATION)
    return np.array([jac[i].T @ np.linalg.solve(gamma, jac[i]) / stds[i] ** 2 for i in range(len(sensors))])


def feasible(xs, kinds, costs, budget, min_spacing, span_max):
    """The constraints checked directly: budget of the per-kind costs, spacing whatever the kinds, span counts."""
    if sum(costs[k] for k in kinds) > budget + 1e-9:
        return False
    x = np.sort(xs)
    if min_spacing and np.any(np.diff(x) < min_spacing - 1e-9):
        return False
    if span_max is not None:
        counts = np.bincount((np.asarray(xs) >= 10.0).astype(int), minlength=2)
        if np.any(counts > span_max):
            return False
    return True


CASES = [  # (count, costs, budget, min_spacing, span_max, noise_std, keep the case's sensors)
    # the budget binds for every criterion here (checked below)
    (4, {"rotation": 1.0, "deflection": 2.5}, 6.5, 0.0, None, None, False),
    # existing sensors of both kinds with the case's noise, new deflection sensors quieter than the case's
    (3, {"rotation": 3.0, "deflection": 1.0}, 5.0, 1.5, [2, 2], {"deflection": 2e-6}, True),
]


@pytest.mark.parametrize("criterion", ["D", "A", "E", "Ds"])
@pytest.mark.parametrize("count, costs, budget, min_spacing, span_max, noise_std, keep", CASES)
def test_mixed_kinds_with_a_budget_brute_force(criterion, count, costs, budget, min_spacing, span_max, noise_std,
                                               keep):
    case = mixed_case()
    springs = criterion == "Ds"
    n_springs = 2 if springs else 0
    grid = CandidateGrid(spacing=2.0, kinds=("rotation", "deflection"))  # 11 positions x 2 kinds = 22 candidates
    constraints = Constraints(fixed=case.sensors if keep else (), min_spacing=min_spacing, costs=costs,
                              budget=budget, span_max=span_max)
    kwargs = dict(grid=grid, constraints=constraints, noise_std=noise_std, springs=springs)
    result = recommend(case, count, criterion, curve_max=0, n_random=20, **kwargs)
    problem = build_problem(case, count, criterion, **kwargs)
    noise = dict(NOISE, **(noise_std or {}))
    cand = [(float(x), str(k)) for k in ("rotation", "deflection") for x in np.arange(0.0, 20.01, 2.0)
            if not (keep and (float(x), str(k)) in ((3.0, "rotation"), (15.0, "deflection")))
            and not (keep and min_spacing and min(abs(x - 3.0), abs(x - 15.0)) < min_spacing)]
    assert len(cand) <= 25 and count <= 4
    assert [(float(x), str(k)) for x, k in zip(problem.positions, problem.kinds)] == cand
    blocks = reference_blocks(cand, [noise[k] for _, k in cand], springs)
    scale = np.abs(blocks).max()
    np.testing.assert_allclose(problem.blocks, blocks, rtol=0, atol=1e-6 * scale)
    q0 = reference_prior(8, n_springs)
    if keep:  # the case's own sensors, with their own kinds and noise
        q0 = q0 + reference_blocks([(3.0, "rotation"), (15.0, "deflection")], [2e-6, 5e-6], springs).sum(axis=0)
    values = {}
    for subset in itertools.combinations(range(len(cand)), count):
        xs, kinds = [cand[i][0] for i in subset], [cand[i][1] for i in subset]
        ok = feasible(xs, kinds, costs, budget, min_spacing, span_max)
        assert problem.feasible(subset) == ok, subset
        if ok:
            values[subset] = criterion_value(criterion, q0 + blocks[list(subset)].sum(axis=0), n_springs)
    sign = 1.0 if MAXIMISE[criterion] else -1.0
    best = max(values, key=lambda s: sign * values[s])
    optimum = values[best]
    tol = 1e-5 * max(1.0, abs(optimum))
    chosen = tuple(sorted(cand.index(pair) for pair in zip(result.layout_m, result.layout_kind)))
    assert chosen in values  # feasible: budget, spacing whatever the kinds, span counts
    q_layout = q0 + blocks[list(chosen)].sum(axis=0)
    assert result.value == pytest.approx(criterion_value(criterion, q_layout, n_springs), rel=1e-5, abs=1e-9)
    assert sign * (result.bound - optimum) >= -tol  # the bound is never beaten
    assert sign * (optimum - result.value) >= -tol
    q_opt = q0 + blocks[list(best)].sum(axis=0)
    assert result.efficiency <= true_efficiency(criterion, q_layout, q_opt, n_springs) + 1e-5
    assert result.cost == pytest.approx(sum(costs[k] for k in result.layout_kind)) and result.cost <= budget
    if keep:
        return
    # the budget binds: the best layout without it costs more than the budget allows
    free = max(itertools.combinations(range(len(cand)), count),
               key=lambda s: sign * criterion_value(criterion, q0 + blocks[list(s)].sum(axis=0), n_springs)
               if feasible([cand[i][0] for i in s], [cand[i][1] for i in s], costs, math.inf, min_spacing,
                           span_max) else -np.inf)
    assert sum(costs[cand[i][1]] for i in free) > budget


def test_single_kind_is_unchanged_by_the_kinds_option():
    # the same problem posed through CandidateGrid(kinds=...) and through kind=...: identical layout and numbers
    case = mixed_case()
    a = recommend(case, 3, "D", grid=CandidateGrid(spacing=2.0), kind="deflection", curve_max=0, n_random=5)
    b = recommend(case, 3, "D", grid=CandidateGrid(spacing=2.0, kinds=("deflection",)), curve_max=0, n_random=5)
    assert a.layout_m == b.layout_m and a.value == b.value and a.layout_kind == ("deflection",) * 3
    assert a.to_dict()["layout_kind"] == ["deflection"] * 3 and a.kind == "deflection"

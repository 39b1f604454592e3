"""The detect design criterion against references that share no code with it.

* Brute force over every layout of small problems (<= 19 candidates, R = 3
  and 4), with the worst-case d^2 of each layout computed from an
  independent finite-element computation: the Hermite beam elements of
  tests/fe_reference.py for the damaged and undamaged readings, nuisance
  columns by central differences, dense AR(1) whitening (the reference of
  tests/test_detectability.py), and the Schur complement by a
  pseudo-inverse of the normal equations written here.
* Finite differences for the gradient and the Hessian of the ridged d^2.
* The generic cvxpy + Clarabel formulation for the fast solver.
* ``sensorplan detectability`` (itself checked against the FE reference in
  tests/test_detectability.py) for the integer values and the acceptance
  check, with an independent search (exhaustive on a coarse grid, then
  coordinate moves on the fine grid) that uses neither the relaxation nor
  greedy / exchange.
"""

import itertools
import json
import pathlib
import sys

import numpy as np
import pytest
from scipy import stats as scipy_stats

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_detectability import _case, _fe_difference, _FEReference, _whiten, _whiten_restricted

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.design.criteria.detect import RIDGE
from sensorplan.design.criteria.detect_algebra import HessianFactors, gradients, ridged_parts
from sensorplan.design.recommend import DetectionTarget, build_problem
from sensorplan.design.relaxation import solve_relaxation
from sensorplan.design.selection import exchange, greedy
from sensorplan.detection.detectability import detectability
from sensorplan.detection.signatures import whitened_signatures
from sensorplan.io.config import example_case

INF = float("inf")
GRID = np.arange(0.0, 18.5, 1.0)  # candidate positions [m] of the FE problem (19)
# two spans 10 + 8 m, an elastic rotational spring at the left end and a vertical spring at the pier
SPEC = dict(spans=[10.0, 8.0], rot=[5.0e8, 0.0, 0.0], vert=[INF, 1.0e9, INF], elements=9,
            ei=[1.8e9] * 5 + [2.4e9] * 4, axles=[(0.0, 30.0e3), (2.0, 30.0e3)],
            positions=np.arange(0.0, 20.25, 0.5), sensors=[(x, "rotation", 2.0e-6) for x in GRID],
            correlation=0.6, length=1.5, step=1.85, severity=0.25, crossings=4)
TARGET = DetectionTarget(severity=SPEC["severity"], length=SPEC["length"], step=SPEC["step"])


def fe_schur(total):
    """d^2 per row of ``total`` (..., m, m) = a_ss - b^T pinv(A_NN) b (normal equations, pseudo-inverse)."""
    pinv = np.linalg.pinv(total[..., 1:, 1:], rcond=1e-12, hermitian=True)
    b = total[..., 1:, 0]
    return total[..., 0, 0] - np.einsum("...n,...nm,...m->...", b, pinv, b)


# the same problem under the noise model in time (white + 3 s Ornstein-Uhlenbeck + wander at 1.2 m/s); the FE
# reference whitens with the dense covariance of its definition and treats the wander's level as a nuisance column
SPEC_TIME = dict(SPEC, correlation=0.0,
                 time=dict(relative_correlated=0.5, correlation_time_s=3.0, relative_walk=0.15, speed=1.2))


def fe_grams(spec):
    """Per-sensor Gram matrices of the FE reference at every grid position, and the case."""
    # in time, the wander's level is projected out per sensor (columns of ones for all 19 candidates would make
    # the normal equations too ill-conditioned for the pseudo-inverse of fe_schur)
    timed = "time" in spec
    ref = _FEReference(spec, offsets=not timed)
    whiten = _whiten_restricted if timed else _whiten
    n_s, k = len(GRID), len(spec["positions"])
    columns = ref.columns.reshape(n_s, k, -1)
    total = sum(spec["spans"])
    centres = spec["length"] / 2 + spec["step"] * np.arange(int((total - spec["length"]) / spec["step"]) + 1)
    grams = np.empty((n_s, centres.size, 1 + columns.shape[2], 1 + columns.shape[2]))
    for c, centre in enumerate(centres):
        signal = whiten(spec, _fe_difference(spec, centre, ref.undamaged))
        stacked = np.concatenate([signal[:, :, None], columns], axis=2)
        grams[:, c] = np.einsum("ska,skb->sab", stacked, stacked)
    return _case(spec), grams * spec["crossings"], centres


@pytest.fixture(scope="module")
def fe():
    return fe_grams(SPEC)


def fe_brute_force(problem, grams, fixed_index=()):
    """Worst-case d^2 of every feasible layout, by the FE Gram matrices; (best layout, best value, values)."""
    index = [int(np.argmin(np.abs(GRID - x))) for x in problem.positions]
    assert np.allclose(GRID[index], problem.positions)
    base = grams[list(fixed_index)].sum(axis=0)
    layouts = [s for s in itertools.combinations(range(problem.n_candidates), problem.count) if problem.feasible(s)]
    values = np.array([fe_schur(base + grams[[index[i] for i in s]].sum(axis=0)).min() for s in layouts])
    best = int(np.argmax(values))
    return layouts[best], float(values[best]), dict(zip(layouts, values))


CONSTRAINTS = {
    "none": ({}, ()),
    "fixed": ({"fixed": (12.0,)}, ()),
    "exclusion": ({}, ((8.5, 9.5),)),
    "min_spacing": ({"min_spacing": 4.0}, ()),
    "span_counts": ({"span_min": (1, 1), "span_max": (2, 2)}, ()),
    "budget": ({"costs": 1.0 + 0.1 * GRID, "budget": 3.6}, ()),
}


@pytest.mark.parametrize("name", sorted(CONSTRAINTS))
def test_bound_and_efficiency_against_fe_brute_force(fe, name):
    case, grams, centres = fe
    options, exclude = CONSTRAINTS[name]
    grid = sp.CandidateGrid(spacing=1.0, exclude=exclude)
    problem = build_problem(case, 3, "detect", grid=grid, constraints=sp.Constraints(**options),
                            n_crossings=SPEC["crossings"], target=TARGET)
    np.testing.assert_allclose(problem.criterion.centres, centres, rtol=0, atol=1e-12)
    fixed = [int(np.argmin(np.abs(GRID - x))) for x in options.get("fixed", ())]
    best, best_value, values = fe_brute_force(problem, grams, fixed)
    # the integer values are the FE ones (the signatures agree with FE to ~1e-8, see test_detectability)
    for layout in list(values)[:: max(1, len(values) // 40)] + [best]:
        assert problem.value_of(layout) == pytest.approx(values[layout], rel=1e-6)
    crit = problem.criterion
    tol = 1e-9 * best_value
    for solver in ("fast", "cvxpy"):
        rel = solve_relaxation(problem, solver)
        assert rel.bound >= best_value - tol, solver
        w = rel.weights
        assert w.min() >= -1e-9 and w.max() <= 1 + 1e-9 and abs(w.sum() - 3) <= 1e-6
    g_layout, g_value = greedy(problem)
    x_layout, x_value = exchange(problem, g_layout)
    assert problem.feasible(x_layout) and g_value <= x_value + tol <= best_value + 2 * tol
    result = sp.recommend(case, 3, "detect", grid=grid, constraints=sp.Constraints(**options),
                          n_crossings=SPEC["crossings"], target=TARGET, curve_max=0, n_random=10)
    assert result.value <= best_value + tol and result.bound >= best_value - tol
    # the claimed efficiency never exceeds the true one, and the optimum is (near) 100 % efficient
    assert result.efficiency <= result.value / best_value + 1e-12
    assert crit.efficiency(best_value, best_value) == pytest.approx(1.0)


def test_detect_criterion_under_the_noise_model_in_time_against_fe_brute_force():
    case, grams, centres = fe_grams(SPEC_TIME)
    assert case.noise.in_time
    problem = build_problem(case, 3, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=SPEC["crossings"],
                            target=TARGET)
    np.testing.assert_allclose(problem.criterion.centres, centres, rtol=0, atol=1e-12)
    best, best_value, values = fe_brute_force(problem, grams)
    for layout in list(values)[:: max(1, len(values) // 40)] + [best]:
        assert problem.value_of(layout) == pytest.approx(values[layout], rel=1e-6)
    result = sp.recommend(case, 3, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=SPEC["crossings"],
                          target=TARGET, curve_max=0, n_random=10)
    assert result.bound >= best_value * (1 - 1e-9)
    # the worst-case power of the recommended layout: the design's own against the FE reference's
    layout = tuple(int(np.argmin(np.abs(GRID - x))) for x in result.layout_m)
    z = scipy_stats.norm.ppf(1 - 0.05)
    fe_power = scipy_stats.norm.cdf(np.sqrt(values[tuple(sorted(layout))]) - z)
    assert scipy_stats.norm.cdf(np.sqrt(result.value) - z) == pytest.approx(fe_power, abs=0.02)


def test_four_sensors_against_fe_brute_force(fe):
    case, grams, _ = fe
    problem = build_problem(case, 4, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=SPEC["crossings"],
                            target=TARGET)
    _, best_value, _ = fe_brute_force(problem, grams)
    for solver in ("fast", "cvxpy"):
        assert solve_relaxation(problem, solver).bound >= best_value * (1 - 1e-9)
    result = sp.recommend(case, 4, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=SPEC["crossings"],
                          target=TARGET, curve_max=0, n_random=10)
    assert result.value <= best_value * (1 + 1e-9) and result.efficiency <= result.value / best_value + 1e-12
    # on this problem greedy + exchange finds the optimum itself
    assert result.value == pytest.approx(best_value, rel=1e-6)


def test_ridged_gradient_and_hessian_match_finite_differences(fe):
    case, _, _ = fe
    problem = build_problem(case, 3, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=SPEC["crossings"],
                            target=TARGET)
    ridge = problem.criterion.ridge
    rng = np.random.default_rng(3)
    w = rng.uniform(0.05, 0.3, problem.n_candidates)
    packing = problem.criterion.packing
    _, x, chol = ridged_parts(packing, problem.precision(w), ridge)
    grad = gradients(packing, problem.blocks, x)
    roots = HessianFactors.of(packing, problem.blocks).roots(x, chol)
    hess = -2.0 * np.einsum("nci,ncj->cij", roots, roots)
    for i in rng.choice(problem.n_candidates, 4, replace=False):
        h = 1e-5
        up, down = w.copy(), w.copy()
        up[i] += h
        down[i] -= h
        f_up, x_up, _ = ridged_parts(packing, problem.precision(up), ridge)
        f_down, x_down, _ = ridged_parts(packing, problem.precision(down), ridge)
        np.testing.assert_allclose(grad[i], (f_up - f_down) / (2 * h), rtol=1e-6, atol=1e-9 * np.abs(grad).max())
        fd = (gradients(packing, problem.blocks, x_up) - gradients(packing, problem.blocks, x_down)) / (2 * h)
        np.testing.assert_allclose(hess[:, :, i].T, fd, rtol=1e-5, atol=1e-8 * np.abs(fd).max())


@pytest.mark.parametrize("example,spacing", [("openlab-like", 1.0), ("simply-supported", 1.0)])
def test_fast_solver_agrees_with_cvxpy(example, spacing):
    problem = build_problem(example_case(example), 4, "detect", grid=sp.CandidateGrid(spacing=spacing),
                            n_crossings=10)
    fast = solve_relaxation(problem, "fast")
    ref = solve_relaxation(problem, "cvxpy")
    assert fast.relative_gap <= 1e-6 and fast.stats["status"] == "optimal"
    assert fast.utility == pytest.approx(ref.utility, rel=1e-6)
    # each certificate bounds the other solver's relaxed point
    assert fast.bound >= ref.utility * (1 - 1e-9) and ref.bound >= fast.utility * (1 - 1e-9)


def test_integer_value_is_what_detectability_computes():
    case = example_case("openlab-like")
    result = sp.recommend(case, 4, "detect", n_crossings=10, curve_max=0, n_random=10)
    reference = detectability(case, layout=list(result.layout_m), n_crossings=10)
    worst = int(np.argmin(reference.d))
    details = result.details["detection"]
    assert result.value == pytest.approx(reference.d[worst] ** 2, rel=1e-8)
    assert details["worst_centre_m"] == reference.centres_m[worst]
    assert details["power"] == pytest.approx(reference.power[worst], rel=1e-8)
    for b in result.baselines:
        if b.feasible:
            assert b.value == pytest.approx((detectability(case, layout=list(b.layout_m), n_crossings=10).d ** 2)
                                            .min(), rel=1e-8)
    # the ridge of the relaxation changes the layout's d^2 by far less than the certified gap tolerance
    problem = build_problem(case, 4, "detect", n_crossings=10)
    w = np.zeros(problem.n_candidates)
    w[list(result.layout_index)] = 1.0
    ridged = problem.criterion.relaxed_utility(problem, w)
    assert result.value <= ridged <= result.value * (1 + 1e-8)
    assert RIDGE == 1e-10


def test_region_restricts_the_centres():
    case = example_case("openlab-like")
    result = sp.recommend(case, 2, "detect", region=(0.0, 15.0), n_crossings=10, curve_max=0, n_random=5)
    details = result.details["detection"]
    assert details["region_m"] == [0.0, 15.0] and details["worst_centre_m"] <= 15.0
    assert result.n_params == 29  # centres 1.0, 1.5, ..., 15.0 (inclusive)
    reference = detectability(case, layout=list(result.layout_m), n_crossings=10)
    inside = reference.centres_m <= 15.0
    assert result.value == pytest.approx((reference.d[inside] ** 2).min(), rel=1e-8)
    with pytest.raises(sp.ConfigError, match="region"):
        sp.recommend(case, 2, "detect", region=(14.9, 14.95), curve_max=0)


# ----------------------------------------------------------------------------------------------
# acceptance: detect beats D-optimal and evenly spaced, and reaches 0.9 x an independent search


def _worst_d2(grams, layouts, chunk=1500):
    """Worst-case d^2 of each layout (rows of sensor indices), by the normal equations."""
    out = []
    for start in range(0, len(layouts), chunk):
        part = np.asarray(layouts[start:start + chunk])
        out.append(fe_schur(grams[part].sum(axis=1)).min(axis=1))
    return np.concatenate(out)


def _independent_search(case, count, coarse_step):
    """Exhaustive search on a coarse grid, then single-sensor moves on the 0.5 m grid (the best 10 starts)."""
    fine = np.arange(0.0, case.bridge.length + 1e-9, 0.5)
    sensors = sp.SensorLayout.candidates(fine, "rotation", noise_std=[case.noise_std_for("rotation")] * fine.size)
    noise = sp.NoiseModel(np.full(fine.size, case.noise_std_for("rotation")), case.noise.correlation_length)
    from sensorplan.detection.signatures import centre_grid

    centres = centre_grid(case.bridge.length, 2.0, 0.5)
    grams = whitened_signatures(case, sensors, noise, centres, severity=0.25, length=2.0).grams() * 10
    coarse = np.nonzero(np.isclose(np.mod(fine, coarse_step), 0.0) | np.isclose(fine, case.bridge.length))[0]
    layouts = list(itertools.combinations(coarse.tolist(), count))
    values = _worst_d2(grams, layouts)
    best_layout, best_value = None, -np.inf
    for start in np.argsort(-values)[:10]:
        layout, value = list(layouts[start]), values[start]
        improved = True
        while improved:
            improved = False
            for pos in range(count):
                trials = [layout[:pos] + [j] + layout[pos + 1:] for j in range(fine.size) if j not in layout]
                trial_values = _worst_d2(grams, trials)
                if trial_values.max() > value * (1 + 1e-12):
                    layout, value, improved = trials[int(np.argmax(trial_values))], trial_values.max(), True
        if value > best_value:
            best_layout, best_value = layout, value
    return [float(fine[i]) for i in best_layout]


@pytest.mark.slow
@pytest.mark.parametrize("example,coarse_step", [("openlab-like", 1.0), ("three-span", 2.0)])
def test_acceptance_worst_case_power(example, coarse_step):
    case = example_case(example)
    detect = sp.recommend(case, 4, "detect", n_crossings=10, curve_max=0)
    d_opt = sp.recommend(case, 4, "D", n_crossings=10, curve_max=0)
    length = case.bridge.length
    even = [length * (k + 0.5) / 4 for k in range(4)]
    searched = _independent_search(case, 4, coarse_step)

    def worst_power(layout):
        return float(detectability(case, layout=list(layout), n_crossings=10).power.min())

    p_detect, p_search = worst_power(detect.layout_m), worst_power(searched)
    # measured (2026-11-24, worst-case power): openlab-like detect 0.196 = search 0.196 (the same layout),
    # D 0.130, even 0.075; three-span detect 0.171 (d^2 0.481), search 0.176 (d^2 0.510: exchange stops
    # in a local optimum), D 0.133, even 0.077
    assert p_detect >= 0.9 * p_search
    assert p_detect >= worst_power(d_opt.layout_m) and p_detect >= worst_power(even)


# ----------------------------------------------------------------------------------------------
# command line

def test_cli_detect_summary_and_json(tmp_path, capsys):
    code = main(["recommend", "--example", "simply-supported", "--count", "2", "--criterion", "detect",
                 "--crossings", "10", "--spacing", "1", "--step", "1", "--severity", "0.3", "--region", "2:18",
                 "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "detect-optimal" in out and "worst case over" in out and "power" in out
    data = json.loads((tmp_path / "design.json").read_text())
    for key in ("value", "bound", "efficiency", "layout_m", "baselines", "solver"):
        assert key in data
    assert data["detection"]["severity"] == 0.3 and data["detection"]["region_m"] == [2.0, 18.0]
    assert data["value"] == pytest.approx(data["detection"]["d2"])


@pytest.mark.parametrize("argv,needle", [
    (["--criterion", "D", "--severity", "0.3"], "--severity apply to --criterion detect only"),
    (["--criterion", "detect", "--severity", "1.5"], "severity"),
    (["--criterion", "detect", "--region", "30:40"], "region"),
    (["--criterion", "detect", "--springs"], "springs"),
])
def test_cli_detect_errors_are_one_line(tmp_path, capsys, argv, needle):
    code = main(["recommend", "--example", "simply-supported", "--count", "2", "--spacing", "2",
                 "--out", str(tmp_path)] + argv)
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and needle in err, err
    assert not (tmp_path / "design.json").exists()


@pytest.mark.parametrize("example", ["openlab-like", "three-span"])
def test_zone_response_change_equals_two_full_forward_solves(example):
    # the damage signatures (and so every Gram matrix above) use the zone-only formula of
    # response_change; the reference is the difference of two complete forward solves
    from sensorplan.model.forward import influence_lines, response_change

    case = example_case(example)
    mesh = sp.Mesh(np.union1d(case.mesh.edges, [5.2, 7.2]))
    ei = case.ei_at(mesh.midpoints)
    damaged = ei * np.where((mesh.midpoints > 5.2) & (mesh.midpoints < 7.2), 0.7, 1.0)
    sensors = sp.SensorLayout([0.0, 6.0, 14.0, 21.5], ("rotation", "deflection", "rotation", "deflection"), None,
                              (1e-6,) * 4)
    full = (influence_lines(case.bridge, mesh, damaged, sensors, case.vehicle, case.sweep.positions).predictions
            - influence_lines(case.bridge, mesh, ei, sensors, case.vehicle, case.sweep.positions).predictions)
    change = response_change(case.bridge, mesh, ei, damaged, sensors, case.vehicle, case.sweep.positions)
    np.testing.assert_allclose(change, full, rtol=0, atol=1e-11 * np.abs(full).max())

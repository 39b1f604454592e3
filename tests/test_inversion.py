"""Bayesian identification: exact linear case, calibration, damage recovery, robustness."""

import json
import math

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import (Case, Crossing, Crossings, GMRFPrior, SensorplanWarning, example_case, invert,
                        simulate_crossings)
from sensorplan.inference.screening import screen_crossings

L = 20.0


def simple(n_elements, positions=(4.0, 10.0, 16.0), std=2e-6, step=0.25, corr=0.0):
    bridge = sp.Bridge((L,))
    noise = sp.NoiseModel(np.full(len(positions), std), corr) if corr else None
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout(list(positions), noise_std=std), noise=noise,
                sweep=sp.LoadSweep.from_range(0.0, L, step))


def dense_gamma(positions, corr):
    return np.exp(-np.abs(positions[:, None] - positions[None, :]) / corr)


@pytest.mark.parametrize("corr", [0.0, 0.6])
def test_linear_case_equals_closed_form_posterior(corr):
    # Determinate bridge, compliance parameters, Gaussian prior: the posterior
    # is Gaussian with Q = A^T Gamma^-1 A / sigma^2 + Q0 (paper eq. qpost),
    # computed here with a dense Gamma, independently of the package.
    case = simple(8, corr=corr)
    truth = 1.0 / np.linspace(0.8e10, 1.2e10, 8)
    data = simulate_crossings(case, 2, noise=True, rng=3, ei=1.0 / truth)
    prior = GMRFPrior(order=2, smoothness_std=0.2, marginal_std=0.4)
    tau = prior.tau
    res = invert(case, data, prior=prior, parameterisation="compliance", hyper="fixed", tau=tau)
    v0 = np.full(8, 1e-10)
    d = np.diff(np.eye(8), n=2, axis=0)  # second differences
    # log EI = level + field: covariance 0.4^2 I + level_std^2 1 1^T of the tau-free part, inverted directly
    fixed = np.linalg.inv(0.4**2 * np.eye(8) + prior.level_std**2 * np.ones((8, 8)))
    q0 = (tau * d.T @ d + fixed) / np.outer(v0, v0)
    # the forward map is linear in the compliance on a determinate bridge, so a central
    # difference with a large step is exact up to round-off: A = dy/dv
    kernel = np.empty((3, case.sweep.n_loads, 8))
    for j in range(8):
        up, down = v0.copy(), v0.copy()
        up[j] *= 1.5
        down[j] *= 0.5
        kernel[:, :, j] = (case.influence_lines(1.0 / up).predictions
                           - case.influence_lines(1.0 / down).predictions) / v0[j]
    pos = case.sweep.positions
    g_inv = np.linalg.inv(dense_gamma(pos, corr)) if corr else np.eye(pos.size)
    precision = q0.copy()
    rhs = q0 @ v0
    for c in data:
        for i in range(3):
            a = kernel[i]
            precision += a.T @ g_inv @ a / 2e-6**2
            rhs += a.T @ g_inv @ c.values[i] / 2e-6**2
    mean = np.linalg.solve(precision, rhs)
    cov = np.linalg.inv(precision)
    np.testing.assert_allclose(res.theta, mean, rtol=1e-10)
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-10, atol=1e-10 * np.abs(cov).max())
    # MAP = Tikhonov normal equations with lambda = sigma^2 tau:
    # (A^T G^-1 A + lambda L^T L) v = A^T G^-1 y + lambda L^T L v0,
    # L^T L = (D^T D + I / (tau marginal^2)) / v0^2.
    lam = 2e-6**2 * tau
    ltl = q0 / tau
    lhs = (precision - q0) * 2e-6**2 + lam * ltl
    right = (rhs - q0 @ v0) * 2e-6**2 + lam * ltl @ v0
    np.testing.assert_allclose(np.linalg.solve(lhs, right), res.theta, rtol=1e-10)
    # Laplace evidence = exact Gaussian marginal likelihood when linear:
    # y ~ N(A v0, sigma^2 Gamma + A Q0^-1 A^T) over all stacked data.
    a_all = np.vstack([kernel[i] for c in data for i in range(3)])
    y_all = np.concatenate([c.values[i] for c in data for i in range(3)])
    noise_cov = scipy_block_diag([2e-6**2 * (dense_gamma(pos, corr) if corr else np.eye(pos.size))] * 6)
    marg = noise_cov + a_all @ np.linalg.inv(q0) @ a_all.T
    sign, logdet = np.linalg.slogdet(marg)
    resid = y_all - a_all @ v0
    exact = -0.5 * resid @ np.linalg.solve(marg, resid) - 0.5 * logdet - 0.5 * y_all.size * math.log(2 * math.pi)
    assert res.log_evidence == pytest.approx(exact, rel=1e-9, abs=1e-6)


def scipy_block_diag(blocks):
    import scipy.linalg

    return scipy.linalg.block_diag(*blocks)


def test_laplace_equals_exact_when_linear_with_evidence():
    # With hyperparameters by evidence the compliance model stays linear: the
    # Laplace evidence is exact, so the reported evidence is the maximum of
    # the closed form over (sigma, tau) -- nudging either lowers it.
    case = simple(8)
    ei = 1e10 * (1.0 + 0.2 * np.sin(np.linspace(0.0, 3.0, 8)))
    data = simulate_crossings(case, 3, noise=True, rng=5, ei=ei)
    prior = GMRFPrior(order=1)
    res = invert(case, data, prior=prior, parameterisation="compliance", hyper="evidence")
    assert res.converged and 1.0 < res.tau < 1e8  # an interior optimum
    for factor_noise, factor_tau in [(1.05, 1.0), (0.95, 1.0), (1.0, 1.5), (1.0, 0.67)]:
        other = invert(case, data, prior=prior, parameterisation="compliance", hyper="fixed",
                       noise_scale=res.noise_scale * factor_noise, tau=res.tau * factor_tau)
        assert other.log_evidence < res.log_evidence + 1e-9 * abs(res.log_evidence)


def test_calibration_well_specified():
    # Truth drawn from the prior on the inversion mesh, represented on a 4x
    # finer mesh for the data; 95 % intervals cover 90-99 % of the elements
    # over many seeds and the evidence recovers sigma within 20 %.
    prior = GMRFPrior(order=1, smoothness_std=0.1, marginal_std=0.3)
    coarse = simple(10, positions=(3.0, 10.0, 17.0))
    fine = coarse.with_mesh(sp.Mesh.uniform(coarse.bridge, 40))
    cov = np.linalg.inv(prior.precision(10))
    covered, scales = [], []
    for seed in range(30):
        rng = np.random.default_rng(seed)
        eta = math.log(1e10) + rng.multivariate_normal(np.zeros(10), cov)
        data = simulate_crossings(fine, 5, noise=True, rng=rng, ei=np.exp(np.repeat(eta, 4)))
        res = invert(coarse, data, prior=prior)
        ci = res.credible_interval(0.95)
        truth = np.exp(eta)
        covered.append(np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1])))
        scales.append(res.noise_scale)
    assert 0.90 <= np.mean(covered) <= 0.99
    assert np.all(np.abs(np.array(scales) - 1.0) < 0.2)


def test_damage_recovery():
    # 25 % EI loss over 2 m at mid-span of a 20 m span, 3 tiltmeters,
    # sigma = 2 urad, 10 crossings, truth on a 4x finer mesh.
    case = simple(40, positions=(4.0, 10.0, 16.0), step=0.1)
    fine = case.with_mesh(sp.Mesh.uniform(case.bridge, 160))
    ei_fine = np.where(np.abs(fine.mesh.midpoints - 10.0) < 1.0, 0.75e10, 1e10)
    data = simulate_crossings(fine, 10, noise=True, rng=2024, ei=ei_fine)
    res = invert(case, data)
    assert res.converged
    # element truth: the element-average compliance (paper eq. v_avg)
    truth = 1.0 / np.mean((1.0 / ei_fine).reshape(40, 4), axis=1)
    centre = case.mesh.midpoints[np.argmin(res.ei_mean)]
    assert abs(centre - 10.0) <= 1.5
    ci = res.credible_interval(0.95)
    assert np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1])) >= 0.90
    # the damage is visible: posterior mean at the centre clearly below nominal
    assert res.ei_mean[case.mesh.element_of(10.0)] < 0.9e10


def test_openlab_like_converges_from_nominal_and_recovers_springs():
    case = example_case("openlab-like")
    fine = case.with_mesh(sp.Mesh.uniform(case.bridge, 90))
    truth_bridge = case.bridge.with_spring_stiffness([3.0e9, 0.6e9])
    data = simulate_crossings(fine, 10, noise=True, rng=7, bridge=truth_bridge,
                              ei=fine.ei * 0.95)
    res = invert(case, data)
    assert res.converged and res.n_iter < 100
    springs = res.springs(level=0.99)
    # both springs move from the nominal (2e9, 1e9) towards the truth (3e9, 0.6e9)
    assert springs["rotational_0"]["map"] > 2.0e9 and springs["rotational_2"]["map"] < 1.0e9
    assert springs["rotational_0"]["low"] < 3.0e9 < springs["rotational_0"]["high"]
    assert springs["rotational_2"]["low"] < 0.6e9 < springs["rotational_2"]["high"]
    # the JSON form (posterior.json) carries the result's numbers
    d = json.loads(json.dumps(res.to_dict()))
    np.testing.assert_array_equal(d["edges_m"], case.mesh.edges)
    np.testing.assert_array_equal(d["ei_mean"], res.ei_mean)
    np.testing.assert_array_equal(d["ei_nominal"], case.ei)
    np.testing.assert_array_equal(d["ei_ci95"], res.credible_interval(0.95))
    np.testing.assert_array_equal(d["ei_ci75"], res.credible_interval(0.75))
    assert d["springs"] == {name: {k: float(v) for k, v in s.items()} for name, s in res.springs(0.95).items()}
    assert d["noise_std"] == dict(zip(case.sensors.names, res.noise_std.tolist()))
    assert (d["noise_scale"], d["tau"], d["log_evidence"], d["n_iter"]) == (
        res.noise_scale, res.tau, res.log_evidence, res.n_iter)
    assert d["converged"] is True and d["excluded_crossings"] == []


def test_non_convergence_is_reported():
    case = example_case("openlab-like")
    data = simulate_crossings(case, 2, noise=True, rng=1, ei=case.ei * 0.5)
    with pytest.warns(SensorplanWarning, match="did not converge"):
        res = invert(case, data, max_iter=1, max_outer=1)
    assert res.converged is False and res.to_dict()["converged"] is False


def test_outlier_crossing_is_excluded_with_a_warning():
    case = example_case("openlab-like")
    data = simulate_crossings(case, 5, noise=True, rng=11)
    bad = data.crossings[2]
    flipped = Crossing(bad.label, bad.positions, bad.values[::-1].copy(), bad.load_factor)
    data = Crossings(data.sensor_names, data.crossings[:2] + (flipped,) + data.crossings[3:])
    with pytest.warns(SensorplanWarning, match="crossing '3' excluded"):
        res = invert(case, data)
    assert res.excluded_crossings == ("3",)


def test_load_factor_scales_the_model():
    case = example_case("simply-supported")
    data = simulate_crossings(case, 1)
    c = data.crossings[0]
    factor = np.full(c.n_loads, 2.0)
    doubled = Crossings(data.sensor_names, (Crossing("1", c.positions, 2.0 * c.values, factor),))
    # without the local-loss hypotheses: their one-sided step prior moves the posterior mean slightly
    # below the nominal even on noise-free data, which is not what this test is about
    res = invert(case, doubled, hyper="fixed", noise_scale=1.0, detect=False)
    np.testing.assert_allclose(res.ei_map, case.ei, rtol=1e-6)


def test_interval_methods_agree_for_small_uncertainty():
    # One Gaussian (point estimates of the hyperparameters): the three methods agree.
    case = example_case("simply-supported")
    data = simulate_crossings(case, 10, noise=True, rng=4)
    res = invert(case, data, hyper="evidence", detect=False)
    logn = res.credible_interval(0.95)
    delta = res.credible_interval(0.95, method="delta")
    samp = res.credible_interval(0.95, method="sampling", rng=1)
    width = logn[:, 1] - logn[:, 0]
    np.testing.assert_allclose(samp, logn, atol=0.05 * width.max())
    np.testing.assert_allclose(delta, logn, atol=0.1 * width.max())
    narrow = res.credible_interval(0.75)
    assert np.all(narrow[:, 0] > logn[:, 0]) and np.all(narrow[:, 1] < logn[:, 1])


@pytest.mark.parametrize("method", ["quasi-optimality", "gcv"])
def test_comparison_criteria_run_and_give_sensible_tau(method):
    case = example_case("simply-supported")
    data = simulate_crossings(case, 5, noise=True, rng=2)
    res = invert(case, data, hyper=method)
    assert res.hyper_method == method and 1e-4 <= res.tau <= 1e10
    assert 0.7 < res.noise_scale < 1.3


def test_screening_keeps_ordinary_crossings():
    # AR(1) noise, ten crossings, several seeds: nothing is excluded.
    case = example_case("three-span")
    for seed in range(5):
        data = simulate_crossings(case, 10, noise=True, rng=seed)
        kept, excluded, _ = screen_crossings(data)
        assert excluded == () and len(kept) == 10


def test_engine_normal_equations_equal_the_stacked_problem():
    # The engine forms r.r, J^T J and J^T r from groups of crossings (equal positions and load factors share
    # one whitened Jacobian); reference: the same sums over the stacked rows of every crossing, here the
    # detector's null model, whose stacked residual and Jacobian are formed crossing by crossing.
    from sensorplan.inference.detector import NullProblem

    case = example_case("three-span")
    data = simulate_crossings(case, 3, noise=True, rng=8)
    c = data.crossings[0]
    doubled = Crossing("4", c.positions, 2.0 * c.values, np.full(c.n_loads, 2.0))
    data = Crossings(data.sensor_names, data.crossings + (doubled,))
    problem = NullProblem(case, data, nuisance="smooth")
    assert [g.members for g in problem.groups] == [(0, 1, 2), (3,)]
    eta = np.linspace(-0.05, 0.05, problem.n_params)
    lin, stacked = problem.evaluate(eta), problem.stacked(eta)
    np.testing.assert_allclose(lin.rr, stacked.residual @ stacked.residual, rtol=1e-12)
    np.testing.assert_allclose(lin.jtr, stacked.jacobian.T @ stacked.residual, rtol=1e-10,
                               atol=1e-12 * np.abs(lin.jtr).max())
    np.testing.assert_allclose(lin.jtj, stacked.jacobian.T @ stacked.jacobian, rtol=1e-12)
    # one cache, keyed by the value of theta, emptied by one call
    assert problem.evaluate(eta.copy()) is lin and problem.evaluate(eta, jacobian=False) is lin
    problem.clear_cache()
    assert len(problem.cache) == 0 and problem.evaluate(eta) is not lin

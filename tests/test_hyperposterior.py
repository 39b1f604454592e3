"""Hyperparameters integrated out: hyperprior, mixture, quadrature over log tau, fit warnings."""

import math

import numpy as np
import pytest
from scipy import special

import sensorplan as sp
from sensorplan import SensorplanWarning
from sensorplan.inference.checks import residual_p_values
from sensorplan.inference.inversion import invert
from sensorplan.inference.mixture import GaussianMixture, mixture_quantile
from sensorplan.io.config import example_case
from sensorplan.model.case import Case
from sensorplan.model.crossings import Crossing, Crossings
from sensorplan.model.prior import GMRFPrior, HyperPrior, difference_operator
from sensorplan.model.simulate import simulate_crossings

L = 20.0
STD = 2e-6


def simple(n_elements=8, positions=(4.0, 10.0, 16.0)):
    bridge = sp.Bridge((L,))
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout(list(positions), noise_std=STD), sweep=sp.LoadSweep.from_range(0.0, L, 0.25))


@pytest.mark.parametrize("family", ["lognormal", "pc"])
def test_hyperprior_is_normalised_and_tied_to_the_smoothness_std(family):
    hyper = HyperPrior(family=family).for_prior(GMRFPrior(smoothness_std=0.2))
    assert hyper.smoothness_scale == 0.2
    u = np.linspace(-40.0, 80.0, 200001)
    density = np.exp(hyper.log_density_log_tau(u))
    assert np.trapezoid(density, u) == pytest.approx(1.0, abs=1e-8)
    # median of sigma = smoothness_std: half of the mass at tau > 1 / 0.2^2 (the cut falls between grid
    # points 6e-4 apart, where the log-normal density peaks at 0.4: up to 2.4e-4 of truncation)
    assert np.trapezoid(density[u > math.log(25.0)], u[u > math.log(25.0)]) == pytest.approx(0.5, abs=3e-4)
    # the draws follow the density (reference: the quadrature above; 20000 draws, 5 binomial se)
    draws = hyper.sample_smoothness(np.random.default_rng(4), 20000)
    for q in (0.1, 1.0, 3.0):  # P(sigma > q U) = P(log tau < log(1 / (q U)^2))
        cut = u < -2.0 * math.log(q * 0.2)
        expected = np.trapezoid(density * cut, u)
        assert abs(np.mean(draws > q * 0.2) - expected) < 5 * math.sqrt(expected * (1 - expected) / draws.size)
    v = np.linspace(-10, 10, 20001)
    assert np.trapezoid(np.exp(hyper.log_density_log_noise(v)), v) == pytest.approx(1.0, abs=1e-10)


def test_hyperprior_families_and_parameters():
    pc = HyperPrior(family="pc").for_prior(GMRFPrior(smoothness_std=0.2))
    assert pc.rate == pytest.approx(math.log(2.0) / 0.2)
    u = np.linspace(-40.0, 80.0, 200001)
    tail = HyperPrior(smoothness_scale=0.5, smoothness_tail=0.01, family="pc")
    sigma = np.exp(-u / 2)
    assert np.trapezoid(np.exp(tail.log_density_log_tau(u)) * (sigma > 0.5), u) == pytest.approx(0.01, abs=1e-4)
    # log-normal: log sigma ~ N(log U, s^2), so P(sigma > U e^s) = 1 - Phi(1) (reference: scipy.stats.norm)
    ln = HyperPrior(smoothness_scale=0.5, smoothness_log_std=0.8)
    density = np.exp(ln.log_density_log_tau(u))
    assert np.trapezoid(density * (sigma > 0.5 * math.exp(0.8)), u) == pytest.approx(0.15865525393145707, abs=1e-6)
    with pytest.raises(sp.ConfigError, match="smoothness_tail"):
        HyperPrior(smoothness_tail=1.0)
    with pytest.raises(sp.ConfigError, match="family"):
        HyperPrior(family="gamma")
    with pytest.raises(sp.ConfigError, match="smoothness_log_std"):
        HyperPrior(smoothness_log_std=0.0)


def test_mixture_quantile_solves_the_mixture_cdf():
    rng = np.random.default_rng(0)
    k, n = 7, 40
    weights = rng.dirichlet(np.ones(k))
    means = rng.normal(0.0, 2.0, (k, n))
    stds = np.exp(rng.normal(-1.0, 1.5, (k, n)))
    for p in (1e-4, 0.025, 0.3, 0.5, 0.875, 0.975):
        x = mixture_quantile(weights, means, stds, p)
        cdf = weights @ special.ndtr((x[None] - means) / stds)
        np.testing.assert_allclose(cdf, p, rtol=1e-10, atol=1e-13)
    # one component: the Gaussian quantile
    np.testing.assert_allclose(mixture_quantile(np.ones(1), means[:1], stds[:1], 0.975),
                               means[0] + 1.959963984540054 * stds[0], rtol=1e-13)


def test_mixture_moments_and_sampling():
    rng = np.random.default_rng(1)
    k, n = 4, 3
    thetas = rng.normal(size=(k, n))
    factors = rng.normal(size=(k, n, n))
    covs = factors @ factors.transpose(0, 2, 1) + 0.1 * np.eye(n)
    mix = GaussianMixture(np.array([0.1, 0.2, 0.3, 0.4]), thetas, covs, np.ones(k), np.ones(k))
    draws = mix.sample(2, 400000)
    np.testing.assert_allclose(draws.mean(axis=0), mix.mean, atol=0.01)
    np.testing.assert_allclose(np.cov(draws.T), mix.covariance, atol=0.03)
    np.testing.assert_allclose(np.quantile(draws, 0.9, axis=0), mix.quantile(0.9), atol=0.02)
    a = np.array([0.3, -0.2, 0.5])
    assert mix.linear_cdf(a, 0.4) == pytest.approx(np.mean(draws @ a <= 0.4), abs=3e-3)


def _brute_force(case, data, prior, hyper, u_grid, v_grid):
    """Posterior of the compliances by direct summation over (log tau, log alpha) of exact Gaussians.

    Independent of the package: stacked dense kernel, dense Cholesky per grid
    point, the hyperpriors (PC or log-normal on sigma, log-normal on alpha) written out here.
    """
    n = case.n_elements
    lines = case.influence_lines()
    a_mat = np.vstack([lines.kernel[i] for _ in data for i in range(3)]) / STD
    y = np.concatenate([c.values[i] for c in data for i in range(3)]) / STD
    v0 = 1.0 / case.ei
    scale = np.outer(case.ei, case.ei)  # d log EI = -dv / v0
    d = difference_operator(n, prior.order).toarray()
    # the tau-free part: marginal_std^2 I + level_std^2 1 1^T (the overall level), inverted directly
    f_mat = np.linalg.inv(prior.marginal_std**2 * np.eye(n) + prior.level_std**2 * np.ones((n, n))) * scale
    s_mat = d.T @ d * scale
    lam = -math.log(hyper.smoothness_tail) / prior.smoothness_std
    yc = y - a_mat @ v0
    ata, aty, yy, m = a_mat.T @ a_mat, a_mat.T @ yc, yc @ yc, y.size
    alpha2 = np.exp(2.0 * v_grid)[:, None, None]
    logw, means, variances = [], [], []
    for u in u_grid:
        q = math.exp(u) * s_mat + f_mat
        logdet_q = np.linalg.slogdet(q)[1]
        precision = ata[None] / alpha2 + q[None]
        chol = np.linalg.cholesky(precision)
        rhs = (aty[None] / alpha2[:, :, 0])[..., None]
        mean = np.linalg.solve(precision, rhs)[..., 0]
        logdet_p = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
        quad = yy / alpha2[:, 0, 0] - np.einsum("ki,ki->k", rhs[..., 0], mean)
        loglik = -0.5 * m * np.log(2 * math.pi * alpha2[:, 0, 0]) - 0.5 * logdet_p + 0.5 * logdet_q - 0.5 * quad
        s_v = hyper.noise_log_std
        if hyper.family == "pc":  # p(sigma) = lam exp(-lam sigma), sigma = e^{-u/2}, |d sigma / du| = sigma / 2
            log_tau_prior = math.log(lam / 2) - u / 2 - lam * math.exp(-u / 2)
        else:  # log sigma = -u/2 ~ N(log U, s^2), |d log sigma / du| = 1/2
            z = (-u / 2 - math.log(prior.smoothness_std)) / hyper.smoothness_log_std
            log_tau_prior = -0.5 * z * z - math.log(2 * hyper.smoothness_log_std * math.sqrt(2 * math.pi))
        logprior = log_tau_prior - 0.5 * (v_grid / s_v) ** 2 - math.log(s_v * math.sqrt(2 * math.pi))
        logw.append(loglik + logprior)
        means.append(v0 + mean)
        variances.append(np.diagonal(np.linalg.inv(precision), axis1=1, axis2=2))
    logw = np.concatenate(logw)
    weights = np.exp(logw - logw.max())
    log_z = logw.max() + math.log(weights.sum() * (u_grid[1] - u_grid[0]) * (v_grid[1] - v_grid[0]))
    weights /= weights.sum()
    return weights, np.concatenate(means), np.sqrt(np.concatenate(variances)), log_z - m * math.log(STD)


@pytest.mark.parametrize("family", ["lognormal", "pc"])
def test_integrated_linear_case_equals_brute_force_integration(family):
    # Compliance parameters of a determinate beam: given (tau, alpha) the posterior is an exact
    # Gaussian, so the mixture must equal the direct numerical integration of those Gaussians over
    # log tau and log alpha under the hyperprior (here only the Laplace step in alpha and the
    # quadrature in log tau separate the two).
    case = simple()
    ei = 1e10 * (1.0 + 0.15 * np.sin(np.linspace(0.0, 3.0, 8)))
    data = simulate_crossings(case, 2, noise=True, rng=5, ei=ei)
    prior, hyper = GMRFPrior(order=1), HyperPrior(family=family)
    res = invert(case, data, prior=prior, parameterisation="compliance", hyperprior=hyper)
    mix = res.mixture
    assert res.hyper_method == "integrated" and mix.n_components >= 8 and not res.tau_at_bound
    assert max(mix.weights[0], mix.weights[-1]) < 1e-3 * mix.weights.max()  # the ends are negligible
    u_grid = np.arange(-4.0, 36.0, 0.1)
    v_grid = np.arange(-0.5, 0.5, 0.004)
    weights, means, sds, log_z = _brute_force(case, data, prior, hyper.for_prior(prior), u_grid, v_grid)
    mean_ref = weights @ means
    sd_ref = np.sqrt(weights @ (sds**2 + means**2) - mean_ref**2)
    np.testing.assert_allclose((res.theta - mean_ref) / sd_ref, 0.0, atol=3e-3)
    np.testing.assert_allclose(res.std / sd_ref, 1.0, atol=3e-3)
    for p in (0.025, 0.125, 0.875, 0.975):
        q = mix.quantile(p)
        cdf = np.array([weights @ special.ndtr((q[j] - means[:, j]) / sds[:, j]) for j in range(case.n_elements)])
        np.testing.assert_allclose(cdf, p, atol=2e-3)
    # the intervals of EI are those quantiles mapped through EI = 1 / v
    ci = res.credible_interval(0.95)
    np.testing.assert_allclose(ci, np.sort(1.0 / np.stack([mix.quantile(0.025), mix.quantile(0.975)], 1), 1))
    # hyper-posterior of log tau and the log marginal likelihood
    w_u = weights.reshape(u_grid.size, -1).sum(axis=1)
    mean_u = w_u @ u_grid
    sd_u = math.sqrt(w_u @ (u_grid - mean_u) ** 2)
    assert mix.weights @ mix.log_tau == pytest.approx(mean_u, abs=3e-3 * sd_u)
    assert math.sqrt(mix.weights @ (mix.log_tau - mean_u) ** 2) == pytest.approx(sd_u, rel=3e-3)
    assert res.log_evidence == pytest.approx(log_z, abs=2e-2)


def test_posterior_result_reports_the_mixture():
    case = example_case("openlab-like")
    data = simulate_crossings(case, 3, noise=True, rng=8, ei=case.ei * 0.9)
    res = invert(case, data)
    mix = res.mixture
    n = res.n_elements
    assert mix.weights.sum() == pytest.approx(1.0) and mix.n_components > 3
    np.testing.assert_allclose(res.theta, mix.mean)
    np.testing.assert_allclose(res.std, np.sqrt(np.diag(mix.covariance)))
    lognormal_means = np.exp(mix.thetas[:, :n] + 0.5 * mix.component_stds[:, :n] ** 2)
    np.testing.assert_allclose(res.ei_mean, mix.weights @ lognormal_means)
    np.testing.assert_allclose(res.credible_interval(0.75), np.exp(np.stack(
        [mix.quantile(0.125, slice(0, n)), mix.quantile(0.875, slice(0, n))], axis=1)))
    springs = res.springs(0.95)["rotational_0"]
    assert springs["low"] == pytest.approx(math.exp(mix.quantile(0.025, slice(n, n + 1))[0]))
    d = res.to_dict()
    hp = d["hyper_posterior"]
    assert len(hp["log_tau"]) == len(hp["weights"]) == res.hyper_nodes.n_components and hp["at_bound"] is False
    assert d["warnings"] == [] and d["hyperparameters"] == "integrated"
    assert d["ei_ci95"] == res.credible_interval(0.95).tolist()
    assert "tau integrated over" in res.summary()
    # the mixture is wider than its most probable component
    top = int(np.argmax(mix.weights))
    assert np.all(res.std[:n] >= mix.component_stds[top, :n] * (1 - 1e-9))


def test_integrated_does_not_run_away_to_a_flat_field():
    # Low signal (one crossing, 10 urad): the evidence maximum is a flat field with
    # very narrow bands that miss the truth; integrating over tau does not.
    case = example_case("openlab-like")
    case = case.with_sensors(case.sensors, sp.NoiseModel(np.full(2, 10e-6)))
    fine = case.with_mesh(sp.Mesh.uniform(case.bridge, 90))
    ei_fine = fine.ei * np.exp(0.15 * np.sin(2 * np.pi * fine.mesh.midpoints / 12.0))
    truth = 1.0 / np.mean((1.0 / ei_fine).reshape(30, 3), axis=1)
    flat_level = GMRFPrior(level_std=0.0)
    found = False
    for seed in range(40):
        data = simulate_crossings(fine, 1, noise=True, rng=seed, ei=ei_fine)
        # the hyperparameter treatment alone (no local-loss hypotheses in either)
        # the hyperparameter treatment alone: no overall level of log EI (it widens both kinds of band)
        evidence = invert(case, data, hyper="evidence", detect=False, prior=flat_level)
        if evidence.tau < 1e8:
            continue
        found = True
        res = invert(case, data, detect=False, prior=flat_level)
        ci_ev, ci = evidence.credible_interval(0.95), res.credible_interval(0.95)
        cover_ev = np.mean((truth >= ci_ev[:, 0]) & (truth <= ci_ev[:, 1]))
        cover = np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1]))
        assert not res.tau_at_bound and res.tau < 1e6
        assert cover >= 0.9 > cover_ev
        break
    assert found, "no seed gave a run-away evidence maximum"


def test_noise_scale_far_from_one_is_reported():
    case = example_case("openlab-like")
    clean = simulate_crossings(case, 3)
    rng = np.random.default_rng(3)
    noisy = Crossings(clean.sensor_names, tuple(
        Crossing(c.label, c.positions, c.values + 4 * 5e-6 * rng.standard_normal(c.values.shape), c.load_factor)
        for c in clean))
    expected = r"estimated noise is [34]\.\d+ times the configured noise_std.*sensorplan diagnose"
    with pytest.warns(SensorplanWarning, match=expected):
        res = invert(case, noisy)
    assert len(res.warnings) == 1 and "wrong unit" in res.warnings[0]
    assert "WARNING: the estimated noise" in res.summary()


def test_systematic_residual_is_reported_for_the_sensor_that_has_it():
    case = example_case("openlab-like")
    data = simulate_crossings(case, 5, noise=True, rng=12)
    drift = 4e-6 * np.sin(2 * np.pi * data.crossings[0].positions / 16.0)  # a slow drift on PE2 only
    bad = Crossings(data.sensor_names, tuple(
        Crossing(c.label, c.positions, c.values + np.stack([0 * drift, drift]), c.load_factor) for c in data))
    with pytest.warns(SensorplanWarning, match=r"systematic residuals at PE2 \(p = "):
        res = invert(case, bad)
    assert not any("PE1" in w for w in res.warnings)
    p = residual_p_values(case.noise, invert(case, data).fits, 1.0)
    assert np.all(p > 1e-3)


def test_tau_mass_at_the_bound_is_flagged():
    # A hyperprior that puts the smoothness std at 1e-8 pushes the mass of tau to the upper
    # end of its range: the result says so, and warns.
    case = example_case("simply-supported")
    data = simulate_crossings(case, 2, noise=True, rng=1)
    with pytest.warns(SensorplanWarning, match="reaches the end of its range: the data favour an ever flatter"):
        res = invert(case, data, hyperprior=HyperPrior(smoothness_scale=1e-9, smoothness_tail=0.5, family="pc"))
    assert res.tau_at_bound and res.to_dict()["hyper_posterior"]["at_bound"] is True


def test_gauss_newton_failure_sends_the_other_nodes_straight_to_the_fallback(monkeypatch):
    # Nodes differ only in tau: after Gauss-Newton fails once, the rest of the grid is solved by the
    # Levenberg-Marquardt fallback alone, and the mixture is the one Gauss-Newton finds (both solve
    # every node to a Newton decrement of ~1e-2, so the means agree to a small fraction of a std).
    import sensorplan.inference.hyperposterior as hp

    case = example_case("openlab-like")
    data = simulate_crossings(case, 3, noise=True, rng=4, ei=case.ei * 0.9)
    plain = invert(case, data, detect=False)
    calls = []

    def failing(ctx, x, lin, log_tau, v, max_iter):
        calls.append(log_tau)
        return None, 1, x

    monkeypatch.setattr(hp, "_gauss_newton", failing)
    fallback = invert(case, data, detect=False)
    assert len(calls) == 1  # the start node only
    assert fallback.mixture.n_components == plain.mixture.n_components
    np.testing.assert_allclose((fallback.theta - plain.theta) / plain.std, 0.0, atol=0.05)
    np.testing.assert_allclose(fallback.std / plain.std, 1.0, atol=0.05)
    assert fallback.log_evidence == pytest.approx(plain.log_evidence, abs=0.1)

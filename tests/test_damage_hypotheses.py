"""Local-loss hypotheses in the EI posterior (sensorplan.inference.damage).

Reference: a linear-Gaussian model y = J theta + e, where the evidence and
the posterior of "theta = eta + s v, eta ~ N(theta0, Q^-1), -s half-normal"
are computed by brute force: the Gaussian marginal likelihood
N(y; J (theta0 + s v), J Q^-1 J^T + I) of each s on a fine grid (trapezoid
rule), and the conditional posterior mean and covariance of theta given s
from the Gaussian conditioning formulas in data space (no precision
downdates, no truncated-normal moments).
"""

import numpy as np
import pytest
from scipy import stats

import sensorplan as sp
from sensorplan.inference.damage import damage_hypotheses, step_evidence, zone_fractions


def _toy(seed=3, n=12, m=9):
    rng = np.random.default_rng(seed)
    prior = sp.GMRFPrior(order=1, smoothness_std=0.2, marginal_std=0.5)
    q = prior.precision(n, 0, tau=prior.tau)
    jac = rng.standard_normal((m, n)) * np.linspace(0.2, 3.0, n)
    theta0 = np.log(np.full(n, 2.0))
    truth = theta0.copy()
    truth[4:7] -= 0.4  # a loss over elements 4-6
    y = jac @ truth + rng.standard_normal(m)
    return prior, q, jac, theta0, y


def _brute_force(q, jac, theta0, y, v, sigma):
    """Evidence ratio, posterior mean and covariance of theta under the step hypothesis, by quadrature over s."""
    cov_prior = np.linalg.inv(q)
    s_data = jac @ cov_prior @ jac.T + np.eye(y.size)
    gain = cov_prior @ jac.T @ np.linalg.inv(s_data)
    post_cov = cov_prior - gain @ jac @ cov_prior
    grid = np.linspace(-8 * sigma, 0.0, 40001)
    log_like = np.array([stats.multivariate_normal.logpdf(y, jac @ (theta0 + s * v), s_data) for s in grid[::100]])
    # the likelihood is Gaussian in s: interpolate its log (a quadratic) exactly through three points
    coef = np.polyfit(grid[::100], log_like, 2)
    dens = np.exp(np.polyval(coef, grid) - stats.multivariate_normal.logpdf(y, jac @ theta0, s_data))
    dens *= 2 * stats.norm.pdf(grid, scale=sigma)
    bf = np.trapezoid(dens, grid)
    p = dens / bf
    means = np.array([theta0 + s * v + gain @ (y - jac @ (theta0 + s * v)) for s in grid])
    mean = np.trapezoid(p[:, None] * means, grid, axis=0)
    dev = means - mean
    cov = post_cov + np.trapezoid(p[:, None, None] * dev[:, :, None] * dev[:, None, :], grid, axis=0)
    return bf, mean, cov


@pytest.mark.parametrize("zone", [(4.0, 7.0), (0.5, 2.5), (8.2, 11.0)])
def test_step_hypothesis_equals_brute_force_integration(zone):
    prior, q, jac, theta0, y = _toy()
    info = jac.T @ jac
    h = info + q
    theta_k = np.linalg.solve(h, jac.T @ y + q @ theta0)
    edges = np.arange(13.0)
    v = zone_fractions(edges, [zone])[0]
    sigma = 0.5
    log_bf, x, e_s, var_s, _ = step_evidence(info, q, theta_k, theta0, v[None], sigma)
    bf, mean, cov = _brute_force(q, jac, theta0, y, v, sigma)
    assert log_bf[0] == pytest.approx(np.log(bf), abs=1e-6)
    np.testing.assert_allclose(theta_k + e_s[0] * x[:, 0], mean, atol=1e-7)
    np.testing.assert_allclose(np.linalg.inv(h) + var_s[0] * np.outer(x[:, 0], x[:, 0]), cov, atol=1e-7)


def test_mixture_weights_are_the_prior_times_the_evidence():
    prior, q, jac, theta0, y = _toy()
    info = jac.T @ jac
    theta_k = np.linalg.solve(info + q, jac.T @ y + q @ theta0)
    cov_k = np.linalg.inv(info + q)
    edges = np.arange(13.0)
    zones = np.array([(4.0, 7.0), (0.5, 2.5), (8.2, 11.0)])
    w, thetas, covs, comp, zone, p_damage = damage_hypotheses(
        np.ones(1), theta_k[None], cov_k[None], np.array([prior.tau]), np.ones(1), theta0, info, prior=prior,
        n_elements=12, edges=edges, zones=zones, prior_damage=0.3, loss_log_std=0.5, min_information=0.0, keep=1.0)
    bfs = [_brute_force(q, jac, theta0, y, zone_fractions(edges, [z])[0], 0.5)[0] for z in zones]
    expected = np.array([0.7] + [0.3 / 3 * b for b in bfs])
    expected /= expected.sum()
    np.testing.assert_allclose(w[np.argsort(zone)], expected, rtol=1e-6)
    assert p_damage == pytest.approx(expected[1:].sum(), rel=1e-6)
    # every hypothesis component is the moment-matched posterior of its zone
    for i in np.flatnonzero(zone >= 0):
        _, mean, cov = _brute_force(q, jac, theta0, y, zone_fractions(edges, [zones[zone[i]]])[0], 0.5)
        np.testing.assert_allclose(thetas[i], mean, atol=1e-7)
        np.testing.assert_allclose(covs[i], cov, atol=1e-7)

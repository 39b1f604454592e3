"""The residual test of ``invert`` with an estimated noise scale (issue 36): the right degrees of freedom.

References: the F and chi-square distributions drawn by numpy's generator (a Monte Carlo of the test's null
law, no quadrature), and the nominal false-rejection rate of a calibrated test (binomial standard errors) on
null data simulated on a finer mesh (80 elements against the inversion's 20: no inverse crime).
"""

import warnings

import numpy as np
import pytest
from scipy import special, stats

import sensorplan as sp
from sensorplan.inference.checks import residual_dof, residual_p_values
from sensorplan.inference.ei_problem import EIProblem, prior_matrices


def test_tail_of_the_sum_matches_a_simulation():
    # P(m F(m, nu) + chi2(k) > t) by quadrature against 400 000 draws of F and chi-square from numpy
    from sensorplan.inference.checks import _sum_sf

    rng = np.random.default_rng(5)
    n = 400_000
    for m, nu, k in ((1.0, 4.0, 2), (2.7, 11.3, 4), (3.0, 40.0, 0)):
        draws = m * rng.f(m, nu, n) + (rng.chisquare(k, n) if k else 0.0)
        for t in np.quantile(draws, [0.5, 0.9, 0.99, 0.999]):
            simulated = float(np.mean(draws > t))
            se = np.sqrt(simulated * (1 - simulated) / n)
            assert abs(_sum_sf(float(t), m, nu, k) - simulated) <= 4 * se + 1e-12, (m, nu, k, t)
    # known noise scale: the chi-square test it replaces (nu -> infinity)
    assert _sum_sf(9.0, 2.0, 1e9, 3) == pytest.approx(special.chdtrc(5, 9.0), rel=1e-5)


def _static_case(n_sensors=5):
    case = sp.example_case("simply-supported")
    layout = sp.SensorLayout(np.linspace(2.0, 18.0, n_sensors), kinds="rotation", noise_std=2e-6)
    return case.with_sensors(layout, sp.NoiseModel([2e-6] * n_sensors))


def test_short_static_record_rejects_at_the_nominal_rate():
    # Five tiltmeters, four static load positions (one reading per sensor and crossing), 20 elements: the noise
    # scale rests on about 15.7 residual degrees of freedom.  Before issue 36 such crossings (fewer than 20
    # positions) were not tested at all (rate 0); with the mean term against F(m_eff, nu - m_eff) the share of
    # sensors rejected at level q is q within its binomial band.  Measured with 300 replicates (rates over the
    # tested sensors): 0.108 at 0.1, 0.047 at 0.05, 0.007 at 0.01; the known-variance chi-square test of the same
    # statistic gave 0.081, 0.023 and 0.000.
    case = _static_case()
    fine = case.with_mesh(sp.Mesh.uniform(case.bridge, 80))
    clean = [sp.simulate_crossings(fine, 1, positions=[x]).crossings[0] for x in (3.0, 7.7, 12.3, 17.0)]
    rng = np.random.default_rng(0)
    replicates = 150
    p_values, dofs = [], []
    for _ in range(replicates):
        data = sp.Crossings(case.sensors.names, tuple(
            sp.Crossing(c.label + str(j), c.positions, c.values + case.noise.sample(c.positions, rng)[0],
                        c.load_factor) for j, c in enumerate(clean)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sp.SensorplanWarning)
            result = sp.invert(case, data, detect=False)
        problem = EIProblem(case, data, estimate_springs=False, parameterisation="log_ei")
        dof = residual_dof(problem.n_data, result.hyper_nodes, *prior_matrices(problem, sp.GMRFPrior()))
        dofs.append(dof)
        p_values.append(residual_p_values(case.noise, result.fits, result.noise_scale, dof=dof))
    p = np.concatenate(p_values)
    assert 12.0 < np.mean(dofs) < 20.0 - 2.0  # the prior holds most of the 20 elements' parameters
    assert np.mean(np.isfinite(p)) > 0.7  # tested (a sensor whose residuals are far below the noise is not)
    for level in (0.1, 0.05):
        rate = float(np.mean(np.nan_to_num(p, nan=1.0) < level))
        # band: 3 standard errors with the replicates (not the 750 sensors, which share a noise scale) as count
        assert abs(rate - level) <= 3 * np.sqrt(level * (1 - level) / replicates), (level, rate)


def test_many_readings_give_the_known_variance_test():
    # two crossings of 81 positions and two sensors: nu is about 320 and F(m, nu - m) is the chi-square of a
    # known noise scale; the p-values of the two agree (different laws only in the far tail)
    case = _static_case(2)
    data = sp.simulate_crossings(case, 2, noise=True, rng=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sp.SensorplanWarning)
        result = sp.invert(case, data, detect=False)
    problem = EIProblem(case, data, estimate_springs=False, parameterisation="log_ei")
    dof = residual_dof(problem.n_data, result.hyper_nodes, *prior_matrices(problem, sp.GMRFPrior()))
    assert 300 < dof < problem.n_data
    known = residual_p_values(case.noise, result.fits, result.noise_scale)
    estimated = residual_p_values(case.noise, result.fits, result.noise_scale, dof=dof)
    assert np.all((known > 1e-3) & (known <= 1.0))
    np.testing.assert_allclose(estimated, known, atol=0.03)


@pytest.mark.slow
def test_time_model_residual_p_values_are_uniform():
    # The real inclinometer's noise in time (white, a 3 s Ornstein-Uhlenbeck part and wander whose offset is
    # marginalised; issue 36, scaled to 5 urad white) on one crawl crossing, four tiltmeters.  The offset
    # projection takes a share of each crossing's mean and one reading's worth of information: counted with the
    # noise model, the p-values are uniform.  Before (n mean^2 taken as chi-square(1), Ljung-Box with every
    # reading), 300 replicates gave KS p = 5e-6 with 0.078 below 0.1 and 0.036 below 0.05 (too few rejections);
    # now KS p = 0.79, 0.102 and 0.053.
    case = sp.example_case("openlab-like")
    time_model = dict(correlated_std=5e-6 * 9 / 21, correlation_time_s=3.0, random_walk=5e-6 * 2.5 / 21, speed=1.0)
    case = case.with_sensors(sp.SensorLayout([4.0, 11.0, 19.0, 26.0], noise_std=5e-6),
                             sp.NoiseModel([5e-6] * 4, **time_model))
    clean = sp.simulate_crossings(case.with_mesh(sp.Mesh.uniform(case.bridge, 120)), 1).crossings[0]
    rng = np.random.default_rng(0)
    p_values = []
    for _ in range(300):
        data = sp.Crossings(case.sensors.names, (sp.Crossing(
            "c", clean.positions, clean.values + case.noise.sample(clean.positions, rng)[0], clean.load_factor),))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sp.SensorplanWarning)
            result = sp.invert(case, data, detect=False)
        problem = EIProblem(case, data, estimate_springs=True, parameterisation="log_ei")
        dof = residual_dof(problem.n_data, result.hyper_nodes, *prior_matrices(problem, sp.GMRFPrior()))
        p_values.append(residual_p_values(case.noise, result.fits, result.noise_scale, dof=dof))
    p = np.concatenate(p_values)
    assert np.all(np.isfinite(p))
    assert stats.kstest(p, "uniform").pvalue > 0.01
    for level in (0.1, 0.05):
        assert abs(float(np.mean(p < level)) - level) <= 3 * np.sqrt(level * (1 - level) / 300), level

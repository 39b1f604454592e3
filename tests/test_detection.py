"""The damage detector: its false-alarm rate, its power against the physical limit, its estimates.

References: the nominal false-alarm rate (binomial standard errors over
replicates), the known-location power of ``sensorplan.detectability``
(checked against an independent finite-element computation in
test_detectability.py), and the true zone and loss of the simulated damage.
Truths are simulated on the finer, differently aligned truth mesh of the
verification (no inverse crime).
"""

import math

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.verification.scenarios import Scenario, truth_mesh


# The real Munich inclinometer's noise in time (issue 36: 21 urad white, about 9 urad over 3 s, wander),
# scaled to 5 urad white, at a crawl of 1 m/s.
TIME = dict(correlated_std=5e-6 * 9 / 21, correlation_time_s=3.0, random_walk=5e-6 * 2.5 / 21, speed=1.0)


def two_span(correlation=0.0, time=None):
    case = sp.example_case("openlab-like")
    layout = sp.SensorLayout([4.0, 11.0, 19.0, 26.0], noise_std=5e-6)
    return case.with_sensors(layout, sp.NoiseModel([5e-6] * 4, correlation, **(time or {})))


def simulate(case, scenario, seed, *, ei_variation=0.0, n_crossings=10):
    mesh = truth_mesh(case)
    fine = case.with_mesh(mesh)
    truth = scenario.truth(mesh, fine.ei) * np.exp(ei_variation * np.sin(np.pi * mesh.midpoints / 15.0 + 0.3))
    bridge = case.bridge.with_spring_stiffness(case.bridge.spring_stiffness() * np.array([2.0, 0.5]))
    return sp.simulate_crossings(fine, n_crossings, noise=True, rng=seed, ei=truth, bridge=bridge)


@pytest.mark.slow
@pytest.mark.parametrize(("correlation", "variation", "time"), [(0.0, 0.0, None), (0.5, 0.15, None),
                                                                (0.0, 0.15, TIME)])
def test_false_alarm_rate_is_nominal(correlation, variation, time):
    # undamaged bridges (springs off nominal, optionally a smooth +-15 % EI variation, AR(1) noise or
    # the noise model in time with its wander)
    case = two_span(correlation, time)
    n = 120
    alarms = [sp.detect_damage(case, simulate(case, Scenario("control"), 100 + k, ei_variation=variation),
                               rng=k, n_null=4000).detected for k in range(n)]
    rate = float(np.mean(alarms))
    # nominal 0.05; the binomial standard error with 120 replicates is 0.02
    assert abs(rate - 0.05) <= 0.05, rate


def test_strong_loss_is_found_and_estimated():
    case = two_span()
    # zones whose known-location power under the smooth nuisance is >= 0.95 (from the detectability map)
    limit = sp.detectability(case, severity=0.3, length=2.0, n_crossings=10, step=1.0)
    strong = [c for c, p in zip(limit.centres_m, limit.power) if p >= 0.95]
    assert len(strong) >= 5
    centres = strong[:: max(1, len(strong) // 5)][:5]
    found, covered = 0, 0
    for k, c in enumerate(centres):
        scenario = Scenario("local", c - 1.0, c + 1.0, 0.3)
        d = sp.detect_damage(case, simulate(case, scenario, 7 + k), rng=k, n_null=4000)
        if d.detected:
            found += 1
            assert abs(d.centre_m - c) <= 1.5, (c, d.centre_m)
            covered += d.loss_ci95[0] <= 0.3 <= d.loss_ci95[1]
    assert found >= 4
    assert covered >= math.ceil(0.8 * found) - 1


def test_noise_free_data_give_a_finite_verdict():
    case = two_span()
    data = sp.simulate_crossings(case, 2, noise=False)
    d = sp.detect_damage(case, data, n_null=2000)
    assert np.isfinite(d.statistic) and not d.detected
    assert set(d.to_dict()) >= {"detected", "false_alarm_rate", "statistic", "threshold", "centre_m", "length_m",
                                "loss", "loss_ci95"}


def test_bad_false_alarm_rate_is_refused():
    case = two_span()
    with pytest.raises(sp.ConfigError, match="false_alarm"):
        sp.detect_damage(case, sp.simulate_crossings(case, 1), false_alarm=0.7)


def test_pruned_zones_carry_negligible_weight():
    # Reference: the zone posteriors computed on every zone (no pruning); the zones _plausible drops must
    # have a relative weight below e^-40 there, and the kept ones give the same weights renormalised.
    from sensorplan.detection.scan import _log_prior, _plausible, _zone_posteriors

    rng = np.random.default_rng(3)
    starts = rng.uniform(0.0, 28.0, 600)
    zones = np.column_stack([starts, starts + rng.choice([0.5, 1.0, 2.0], 600)])
    norms = rng.uniform(0.5, 40.0, 600)
    norms[17] = 40.0  # a clear loss in zone 17 (r = 0.5, a third of EI lost)
    proj = rng.normal(0.0, 1.0, 600) * norms + np.where(np.arange(600) == 17, 0.5 * norms**2, 0.0)
    log_prior = _log_prior(zones)
    keep = _plausible(proj, norms, 1.3, log_prior, 1.0)
    weights, _, _ = _zone_posteriors(proj, norms, 1.3, zones, 1.0)
    assert 0 < keep.sum() < keep.size  # the check is not vacuous
    assert weights[~keep].max() < math.exp(-40.0) * weights.max()
    sub, _, _ = _zone_posteriors(proj[keep], norms[keep], 1.3, zones[keep], 1.0, log_prior[keep])
    np.testing.assert_allclose(sub, weights[keep] / weights[keep].sum(), rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("seed", range(6))
def test_the_screened_threshold_is_that_of_all_draws_in_double_precision(seed):
    # Reference: the null maxima of every draw in double precision, written out here as the scan's module
    # docstring defines them (a factor of the projected Gram matrix, r normals, the estimated scale with its
    # chi^2 part), then numpy's quantile and the p-value's count.  The screened calibration computes single-
    # precision maxima with an error bound and only the unsettled draws in double precision.
    from sensorplan.detection import scan

    gen = np.random.default_rng(100 + seed)
    n_el, n_zones, n = int(gen.integers(5, 30)), int(gen.integers(1, 200)), int(gen.choice([1, 2, 7, 500, 20000]))
    basis = gen.standard_normal((n_el, int(gen.integers(1, n_el + 1))))
    gram = basis @ basis.T  # rank-deficient like a projected Gram matrix
    weights = np.abs(gen.standard_normal((n_zones, n_el))) * (gen.random((n_zones, n_el)) < 0.3)
    weights /= np.sqrt(np.clip(np.einsum("he,ef,hf->h", weights, gram, weights), 1e-300, None))[:, None]
    dof = int(gen.integers(1, 3000))
    vals, vecs = np.linalg.eigh(gram)
    keep = vals > 1e-12 * vals.max()
    factor = weights @ (vecs[:, keep] * np.sqrt(vals[keep]))
    draws = np.random.default_rng(seed)
    maxima, square = np.empty(n), np.empty(n)
    for start in range(0, n, 2000):
        g = draws.standard_normal((min(2000, n - start), factor.shape[1]))
        maxima[start:start + g.shape[0]] = (g @ factor.T).max(axis=1)
        square[start:start + g.shape[0]] = np.sum(g * g, axis=1)
    if dof > factor.shape[1]:
        square += draws.chisquare(dof - factor.shape[1], size=n)
    maxima /= np.maximum(np.sqrt(square / dof), 0.5)

    null = scan._NullMaxima(weights, gram, n, np.random.default_rng(seed), dof=dof)
    assert np.all(null.low <= maxima) and np.all(maxima <= null.high)
    for level in (0.5, 0.95, 0.999):
        for statistic in (float(np.quantile(maxima, level)) + 1e-9, 3.0, float(maxima.max()) + 1.0):
            threshold, p_value = scan._calibration(null, level, statistic)
            assert threshold == pytest.approx(float(np.quantile(maxima, level)), rel=1e-13, abs=1e-13)
            assert p_value == (1 + np.sum(maxima >= statistic)) / (1 + n)

"""The noise model in time: white + Ornstein-Uhlenbeck + random walk, mapped through the crossing speed.

References (no sensorplan code): the dense covariance written from the
definitions, Sigma_ij = white^2 delta_ij + c^2 exp(-|t_i - t_j| / tau)
+ q^2 min(t_i - t_1, t_j - t_1), inverted by numpy; the offset of the walk
marginalised under a flat prior by the restricted quadratic form
Sigma^-1 - Sigma^-1 1 1^T Sigma^-1 / (1^T Sigma^-1 1) (Harville 1974,
Biometrika 61, 383).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan._errors import ConfigError
from sensorplan.model.noise import NoiseModel


def dense_covariance(t, white, correlated, tau, walk):
    dt = np.abs(t[:, None] - t[None, :])
    cov = white**2 * np.eye(t.size) + walk**2 * np.minimum(t[:, None] - t[0], t[None, :] - t[0])
    if correlated > 0.0:
        cov += correlated**2 * np.exp(-dt / tau)
    return cov


def restricted_precision(cov, offset):
    inv = np.linalg.inv(cov)
    if offset:
        v = inv @ np.ones(cov.shape[0])
        inv = inv - np.outer(v, v) / v.sum()
    return inv


@settings(max_examples=30, deadline=None)
@given(white=st.floats(1e-6, 5e-5), correlated=st.sampled_from([0.0, 1e-5, 4e-5]),
       tau=st.floats(0.2, 10.0), walk=st.sampled_from([0.0, 1e-6, 1e-5]), speed=st.floats(0.3, 20.0),
       seed=st.integers(0, 2**16))
def test_whitening_gives_the_dense_quadratic_form(white, correlated, tau, walk, speed, seed):
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.0, 30.0, 25))
    noise = NoiseModel([white, 2 * white], correlated_std=correlated, correlation_time_s=tau,
                       random_walk=walk, speed=speed)
    y = rng.standard_normal((2, x.size, 3)) * 1e-5
    w = noise.whiten(y, x)
    log_det = 0.0
    for s, scale in enumerate((1.0, 2.0)):
        cov = dense_covariance(x / speed, white * scale, correlated, tau, walk)
        prec = restricted_precision(cov, walk > 0.0)
        np.testing.assert_allclose(w[s].T @ w[s], y[s].T @ prec @ y[s], rtol=1e-8, atol=1e-12)
        log_det += np.linalg.slogdet(cov)[1]
        if walk > 0.0:
            log_det += np.log(np.ones(x.size) @ np.linalg.solve(cov, np.ones(x.size)))
    np.testing.assert_allclose(noise.log_det(x), log_det, rtol=1e-9)


def test_without_a_time_part_the_model_is_the_position_ar1_model():
    x = np.linspace(0.0, 10.0, 40)
    old = NoiseModel([1e-6, 3e-6], 0.7)
    assert not old.in_time
    y = np.random.default_rng(0).standard_normal((2, 40))
    # AR(1) in x: the bidiagonal inverse Cholesky factor (Box & Jenkins), written here from its definition
    rho = np.exp(-np.diff(x) / 0.7)
    ref = y.copy()
    ref[:, 1:] = (y[:, 1:] - rho * y[:, :-1]) / np.sqrt(1 - rho**2)
    ref /= np.array([1e-6, 3e-6])[:, None]
    np.testing.assert_allclose(old.whiten(y, x), ref, rtol=1e-12)
    assert old.log_det(x) == pytest.approx(2 * np.log1p(-rho**2).sum() + 2 * 40 * np.log([1e-6, 3e-6]).sum())


def test_samples_have_the_dense_covariance():
    x = np.linspace(0.0, 12.0, 13)
    noise = NoiseModel([2e-5], correlated_std=1e-5, correlation_time_s=3.0, random_walk=4e-6, speed=1.5)
    draws = noise.sample(x, np.random.default_rng(5), n_crossings=40_000)[:, 0, :]
    cov = dense_covariance(x / 1.5, 2e-5, 1e-5, 3.0, 4e-6)
    emp = draws.T @ draws / draws.shape[0]
    # 40,000 draws: relative standard error of a covariance entry about sqrt(2 / 40000) = 0.7 %
    assert np.max(np.abs(emp - cov)) < 0.04 * np.max(cov)


def test_speed_maps_positions_to_times():
    x = np.linspace(0.0, 6.0, 30)
    slow = NoiseModel([1e-5], correlated_std=1e-5, correlation_time_s=2.0, speed=1.0)
    fast = slow.at_speed(3.0)
    y = np.ones((1, 30))
    # at three times the speed the same positions are three times closer in time: more correlated
    assert fast.speed == 3.0 and slow.at_speed(None) is slow
    assert np.sum(fast.whiten(y, x)**2) < np.sum(slow.whiten(y, x)**2)
    assert fast.subset([0]).speed == 3.0
    np.testing.assert_allclose(fast.whiten(y, x), NoiseModel(
        [1e-5], correlated_std=1e-5, correlation_time_s=2.0, speed=1.0).whiten(y, x / 3.0))


def test_degrees_of_freedom_spend_one_reading_per_wandering_sensor():
    noise = NoiseModel([1e-5, 1e-5], random_walk=[1e-6, 0.0], speed=1.0)
    assert noise.dof(50) == 99
    assert NoiseModel([1e-5, 1e-5]).dof(50) == 100


@pytest.mark.parametrize("kwargs, field", [
    (dict(correlated_std=1e-5), "correlation_time_s"),
    (dict(random_walk=1e-6, speed=1.0, correlation_length=0.5), "correlation_length"),
    (dict(random_walk=[1e-6, 1e-6, 1e-6], speed=1.0), "random_walk"),
    (dict(correlated_std=-1.0, correlation_time_s=1.0, speed=1.0), "correlated_std"),
])
def test_bad_time_models_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        NoiseModel([1e-5, 1e-5], **kwargs)


def test_readings_by_load_position_need_the_speed():
    # a logger channel's noise is read in time and needs no speed; readings at load positions do
    noise = NoiseModel([1e-5, 1e-5], random_walk=1e-6)
    x = np.linspace(0.0, 10.0, 20)
    with pytest.raises(ConfigError, match="speed"):
        noise.whiten(np.ones((2, x.size)), x)
    np.testing.assert_allclose(noise.whiten(np.ones((2, x.size)), x, times=x / 2.0),
                               noise.at_speed(2.0).whiten(np.ones((2, x.size)), x))


def test_a_reading_stands_for_the_mean_of_the_logger_samples_between_readings():
    x = np.linspace(0.0, 10.0, 21)  # a reading every 0.5 m: 0.5 s at 1 m/s, 50 samples at 100 Hz
    one = NoiseModel([2e-5], correlated_std=1e-5, correlation_time_s=3.0, speed=1.0)
    mean = NoiseModel([2e-5], correlated_std=1e-5, correlation_time_s=3.0, speed=1.0, sample_rate=100.0)
    ref = dense_covariance(x, 2e-5 / np.sqrt(50.0), 1e-5, 3.0, 0.0)
    y = np.random.default_rng(2).standard_normal((1, 21)) * 1e-5
    w = mean.whiten(y, x)[0]
    np.testing.assert_allclose(w @ w, y[0] @ np.linalg.solve(ref, y[0]), rtol=1e-10)
    # slower crossings average more samples: more information, capped by the correlated part (what the
    # information would be without white noise) and always above the one-sample readings
    speeds = (4.0, 1.0, 0.25, 0.05)
    ones = np.ones((1, 21))
    info = [float(np.sum(mean.at_speed(v).whiten(ones, x)**2)) for v in speeds]
    cap = NoiseModel([1e-12], correlated_std=1e-5, correlation_time_s=3.0, speed=1.0)
    assert all(a < b for a, b in zip(info, info[1:]))
    for v, i in zip(speeds, info):
        assert float(np.sum(one.at_speed(v).whiten(ones, x)**2)) < i < float(np.sum(cap.at_speed(v).whiten(ones, x)**2))


def test_crossings_at_their_own_speeds_are_whitened_at_their_own_times(tmp_path):
    import dataclasses

    import sensorplan as sp
    from sensorplan.inference.ei_problem import EIProblem
    from sensorplan.io.csvio import read_crossings, write_crossings

    base = sp.example_case("openlab-like")
    noise = NoiseModel(base.noise.std, correlated_std=2e-6, correlation_time_s=3.0, random_walk=5e-7, speed=1.0)
    case = dataclasses.replace(base, noise=noise)
    data = sp.simulate_crossings(case, 2, noise=True, rng=3)
    speeds = (0.8, 2.5)
    timed = sp.Crossings(data.sensor_names, tuple(
        dataclasses.replace(c, times=100.0 * k + c.positions / v) for k, (c, v) in enumerate(zip(data, speeds))))
    write_crossings(tmp_path / "timed.csv", timed)
    back = read_crossings(tmp_path / "timed.csv", case.sensors)
    np.testing.assert_allclose(back[1].times, timed[1].times)
    problem = EIProblem(case, back, estimate_springs=False, parameterisation="log_ei")
    for c, (crossing, v) in enumerate(zip(data, speeds)):
        # reference: the same readings whitened by a model at that crossing's speed
        want = noise.at_speed(v).whiten(crossing.values, crossing.positions)
        np.testing.assert_allclose(problem.white_data[c], want, rtol=1e-6, atol=1e-9)
    assert len(problem.groups) == 2  # equal positions, different times: whitened apart
    pred, _ = problem.whitened_model(problem.theta0, jacobian=False)[1]
    np.testing.assert_allclose(pred, noise.at_speed(2.5).whiten(
        case.influence_lines().predictions, case.sweep.positions), rtol=1e-6, atol=1e-9)

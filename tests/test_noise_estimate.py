"""The noise estimator: its likelihood against the Kalman filter of model/statespace.py, the Allan variance
against brute-force sums, the quiet mask, and the parameters of records from the independent simulator."""

import math
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from logger_sim import MUNICH_LIKE, Bridge, Channel, Crossing, record  # noqa: E402
from sensorplan.acquisition.noise import (  # noqa: E402
    allan_variance_data,
    allan_variance_model,
    estimate_noise,
    quiet_parts,
)
from sensorplan.acquisition.noise.likelihood import restricted_loglik  # noqa: E402
from sensorplan.model.statespace import innovation_filter  # noqa: E402
from sensorplan.model.timeseries import TimeSeries  # noqa: E402


def _reference_loglik(params, segments, dt):
    """Restricted log-likelihood by the lead's InnovationFilter (a different implementation of the filter)."""
    white, correlated, tau, walk = params
    total = 0.0
    for y in segments:
        f = innovation_filter(np.arange(y.size) * dt, white=white, correlated=correlated, correlation_time=tau,
                              random_walk=walk)
        w = f.whiten(y)
        total += -0.5 * (f.log_det() + w @ w + (y.size - 1) * math.log(2.0 * math.pi))
    return total


@pytest.mark.parametrize("params", [(1.0, 0.43, 3.0, 0.12), (1.0, 2.0, 0.5, 0.5), (0.7, 0.3, 0.05, 0.02)])
def test_fast_likelihood_equals_the_kalman_filter(params):
    # segments long enough for the steady-state (lfilter) part to run, and one shorter than the transient
    rng = np.random.default_rng(3)
    segments = [rng.standard_normal(n).cumsum() * 0.05 + rng.standard_normal(n) for n in (9000, 2500, 40)]
    fast = restricted_loglik(params, segments, [0.01] * 3)
    assert fast == pytest.approx(_reference_loglik(params, segments, 0.01), abs=1e-5)


@pytest.mark.parametrize("m", [1, 2, 5, 64])
def test_model_allan_variance_equals_the_covariance_sum(m):
    # Allan variance = w' C w / 2 with w = (-1/m ... , +1/m ...) over two adjacent blocks of m samples
    dt = 0.01
    t = (np.arange(2 * m) + 1) * dt
    w = np.where(np.arange(2 * m) < m, -1.0 / m, 1.0 / m)
    covs = {"white": (dict(white=2.0), 4.0 * np.eye(2 * m)),
            "ou": (dict(white=0.0, correlated=3.0, correlation_time=0.07),
                   9.0 * np.exp(-np.abs(t[:, None] - t[None, :]) / 0.07)),
            "walk": (dict(white=0.0, random_walk=1.5), 1.5**2 * np.minimum(t[:, None], t[None, :]))}
    for kwargs, cov in covs.values():
        assert allan_variance_model([m], dt, **kwargs)[0] == pytest.approx(0.5 * w @ cov @ w, rel=1e-9)


def test_data_allan_variance_is_the_overlapping_estimator():
    rng = np.random.default_rng(0)
    segments = [rng.standard_normal(50), rng.standard_normal(31)]
    avar, counts = allan_variance_data(segments, [1, 3, 20])
    for i, m in enumerate((1, 3, 20)):  # the overlapping estimator (Riley, NIST SP 1065), written out
        terms = [(y[j + m:j + 2 * m].mean() - y[j:j + m].mean())**2
                 for y in segments for j in range(y.size - 2 * m + 1)]
        assert counts[i] == len(terms) and avar[i] == pytest.approx(0.5 * np.mean(terms))


def test_quiet_parts_leave_out_a_vehicle_and_bursts():
    channel = Channel("INC", 5.0, burst_rate=1.0 / 60.0)
    bridge = Bridge(spans=[20.0], ei=2e9)
    time, values, signal = record(400.0, 50.0, [channel], bridge=bridge, crossings=[Crossing(200.0, 2.0)],
                                  axle_loads=(2e5,), rng=7)
    quiet = quiet_parts(time, values, min_segment_s=30.0)
    vehicle = np.abs(signal[0]) > 3 * MUNICH_LIKE["white"]
    assert vehicle.any() and not (quiet.mask & vehicle).any()
    burst = np.abs(values[0] - signal[0]) > 2e-4  # the simulator's bursts are above 2.4e-4 rad
    assert burst.any() and not (quiet.mask & burst).any()
    assert 0.5 < quiet.fraction < 1.0


TRUTH = {"white_std": MUNICH_LIKE["white"], "correlated_std": MUNICH_LIKE["correlated"],
         "correlation_time_s": MUNICH_LIKE["tau"]}


def _check_estimates(seed, rate):
    """A one-hour record with the measured Munich statistics and a burst every 10 minutes: the three
    parameters of the acceptance within 30 %, the walk within 50 %, the model's Allan deviation on the data's."""
    channel = Channel("INC", 5.0, burst_rate=1.0 / 600.0)
    time, values, _ = record(3600.0, rate, [channel], rng=seed)
    result = estimate_noise(TimeSeries(time, ("INC",), values))
    c = result.channels[0]
    assert result.quiet_fraction > 0.9
    for name, value in TRUTH.items():
        est = getattr(c, name)
        assert abs(est.value / value - 1.0) < 0.3, (seed, name, est.value, value)
        assert 0.0 < est.std_error < 0.3 * est.value
    assert abs(c.random_walk.value / MUNICH_LIKE["walk"] - 1.0) < 0.5
    short = c.allan.tau_s <= 60.0  # longer averages have few terms and scatter
    assert np.allclose(c.allan.model[short], c.allan.data[short], rtol=0.15)
    assert c.allan.misfit()[0] < 0.15 and "note:" not in result.summary()
    # the floor between 1 and 30 s, data and model, near the simulator's (closed form at the true parameters)
    factors = np.round(c.allan.tau_s / c.allan.tau_s[0]).astype(int)
    inside = (c.allan.tau_s >= 1.0) & (c.allan.tau_s <= 30.0)
    true = np.sqrt(allan_variance_model(factors[inside], 1.0 / rate, white=MUNICH_LIKE["white"],
                                        correlated=MUNICH_LIKE["correlated"], correlation_time=MUNICH_LIKE["tau"],
                                        random_walk=MUNICH_LIKE["walk"])).min()
    assert c.allan.floor() == pytest.approx(true, rel=0.15)
    assert c.allan.floor(model=True) == pytest.approx(true, rel=0.15)
    return result


def test_estimates_within_30_percent_at_20_hz():
    result = _check_estimates(21, 20.0)
    model = result.noise_model(speed=1.5)  # what the other layers compute under
    c = result.channels[0]
    assert model.std[0] == c.white_std.value and model.correlation_time_s[0] == c.correlation_time_s.value
    assert model.random_walk[0] == c.random_walk.value and model.speed == 1.5 and model.in_time


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12, 13])
def test_estimates_within_30_percent_of_the_simulator(seed):
    # the acceptance: records at the logger's 100 Hz
    _check_estimates(seed, 100.0)


def test_a_vibration_the_model_lacks_is_noted():
    # white + OU + a 7 Hz oscillation (a bridge mode): the fit cannot follow the oscillation and says so
    channel = Channel("INC", 5.0, walk=0.0)
    time, values, _ = record(600.0, 100.0, [channel], rng=4)
    values = values + 20e-6 * np.sin(2 * np.pi * 7.0 * time)
    result = estimate_noise(TimeSeries(time, ("INC",), values))
    worst, at = result.channels[0].allan.misfit()
    assert worst > 0.2 and at < 1.0 and "(--rate)" in result.summary()


def test_coarsely_quantised_readings_are_fitted():
    # a logger resolution of 1e-4 rad, five times the noise: most differences are 0 (the robust scale is 0)
    time, values, _ = record(300.0, 20.0, [Channel("INC", 5.0, walk=0.0)], rng=2)
    coarse = np.round((values + 3e-4 * np.sin(2 * np.pi * time / 200.0)) / 1e-4) * 1e-4
    c = estimate_noise(TimeSeries(time, ("INC",), coarse)).channels[0]
    # quantisation noise of a uniform rounding error is 1e-4 / sqrt(12) = 29 urad; white + OU together near it
    total = math.hypot(c.white_std.value, c.correlated_std.value)
    assert 1e-5 < total < 1e-4


def test_a_record_without_quiet_part_is_refused():
    from sensorplan._errors import DataError

    channel = Channel("INC", 5.0, burst_rate=0.5)
    time, values, _ = record(120.0, 50.0, [channel], rng=1)
    with pytest.raises(DataError, match="no quiet part of at least 60 s"):
        estimate_noise(TimeSeries(time, ("INC",), values))

"""Estimate a logger channel's noise (white + OU + random walk) from the quiet parts of its record.

Per channel: the quiet segments (:mod:`.quiet`), a start from the Allan
deviation (the model's closed form fitted to the data's, in log scale), then
the maximum of the exact restricted likelihood of the state-space model
(:mod:`.likelihood`: Kalman filter, the walk's level marginalised per
segment) over the log-parameters, and standard errors from the observed
information (the numerical Hessian of the log-likelihood there).  The
readings are scaled by their robust sample-to-sample noise first, so the
search works on numbers of order one whatever the unit.
"""

import math
import time as clock

import numpy as np
from scipy.optimize import least_squares, minimize

from ..._errors import DataError
from .allan import allan_variance_data, allan_variance_model, octave_factors
from .likelihood import restricted_loglik
from .quiet import quiet_parts
from .results import AllanDeviation, ChannelEstimate, Estimate, NoiseEstimate

__all__ = ["estimate_noise", "fit_channel"]

HESSIAN_STEP = 1e-3  # in log-parameter


def _bounds(dt, longest_s):
    """Search ranges of the log-parameters (values in units of the robust per-sample noise)."""
    walk_low = 1e-4 / math.sqrt(dt)  # below it the walk's filter needs > 1e4 steps to settle and is invisible
    low = np.log([1e-3, 1e-3, 2.0 * dt, walk_low])
    high = np.log([1e2, 1e4, max(longest_s / 2.0, 4.0 * dt), 1e4])
    return low, high


def _allan_start(factors, avar, counts, dt, low, high):
    """Log-parameters whose model Allan variance best matches the data's (weighted, in log scale)."""
    ok = np.isfinite(avar) & (avar > 0)
    weight = np.sqrt(counts[ok] / factors[ok])  # about the square root of the independent terms

    def residual(theta):
        p = np.exp(theta)
        model = allan_variance_model(factors[ok], dt, white=p[0], correlated=p[1], correlation_time=p[2],
                                     random_walk=p[3])
        return weight * (np.log(model) - np.log(avar[ok]))

    start = np.clip(np.log([1.0, 0.5, 100.0 * dt, 10.0 * math.exp(low[3])]), low + 1e-6, high - 1e-6)
    fit = least_squares(residual, start, bounds=(low, high))
    return np.clip(fit.x, low + 1e-3, high - 1e-3)


def _hessian(f, x, h=HESSIAN_STEP):
    """Central-difference Hessian of ``f`` at ``x``."""
    n = x.size
    out = np.empty((n, n))
    f0 = f(x)
    eye = np.eye(n) * h
    for i in range(n):
        out[i, i] = (f(x + eye[i]) - 2.0 * f0 + f(x - eye[i])) / h**2
        for j in range(i):
            out[i, j] = out[j, i] = (f(x + eye[i] + eye[j]) - f(x + eye[i] - eye[j]) - f(x - eye[i] + eye[j])
                                     + f(x - eye[i] - eye[j])) / (4.0 * h**2)
    return out


def _errors(neg_loglik, theta, low, high):
    """Standard errors of the log-parameters (nan where the information is singular or at a bound)."""
    at_bound = (theta <= low + 1e-2) | (theta >= high - 1e-2)
    free = ~at_bound
    se = np.full(theta.size, math.nan)
    if free.any():
        def sub(x):
            full = theta.copy()
            full[free] = x
            return neg_loglik(full)

        info = _hessian(sub, theta[free])
        try:
            cov = np.linalg.inv(info)
            var = np.diag(cov)
            se[free] = np.where(var > 0, np.sqrt(np.abs(var)), math.nan)
        except np.linalg.LinAlgError:
            pass
    return se, at_bound


def fit_channel(segments, dt, *, name="", kind="rotation"):
    """The :class:`ChannelEstimate` of one channel's quiet ``segments`` (arrays evenly sampled every ``dt`` s)."""
    start_cpu = clock.process_time()
    segments = [np.asarray(y, dtype=float) for y in segments]
    pooled = np.concatenate([np.diff(y) for y in segments])
    scale = float(1.4826 * np.median(np.abs(pooled - np.median(pooled))) / math.sqrt(2.0))
    if not scale > 0.0:  # coarsely quantised readings: most differences are 0
        scale = float(np.std(pooled) / math.sqrt(2.0))
    if not scale > 0.0:
        raise DataError(f"channel '{name}' does not vary in its quiet parts (constant readings); no noise to "
                        "estimate.")
    scaled = [y / scale for y in segments]
    longest = max(y.size for y in segments) * dt
    low, high = _bounds(dt, longest)
    factors = octave_factors(max(y.size for y in segments))
    avar, counts = allan_variance_data(scaled, factors)
    theta0 = _allan_start(factors, avar, counts, dt, low, high)
    dts = [dt] * len(scaled)

    def neg_loglik(theta):
        return -restricted_loglik(np.exp(theta), scaled, dts)

    fit = minimize(neg_loglik, theta0, method="L-BFGS-B", bounds=list(zip(low, high)),
                   options={"eps": 1e-6, "ftol": 1e-12, "gtol": 1e-6, "maxiter": 200})
    theta = np.clip(fit.x, low, high)
    se, at_bound = _errors(neg_loglik, theta, low, high)
    values = np.exp(theta) * np.array([scale, scale, 1.0, scale])
    estimates = [Estimate(float(v), float(v * s), float(s), bool(b)) for v, s, b in zip(values, se, at_bound)]
    model = allan_variance_model(factors, dt, white=values[0], correlated=values[1], correlation_time=values[2],
                                 random_walk=values[3])
    allan = AllanDeviation(factors * dt, np.sqrt(avar) * scale, np.sqrt(model), counts)
    return ChannelEstimate(name, kind, *estimates, allan=allan, log_likelihood=float(-fit.fun) - sum(
        y.size for y in segments) * math.log(scale), converged=bool(fit.success),
        cpu_s=clock.process_time() - start_cpu)


def _even_segments(series, quiet):
    """Per segment its sample slice, and one common step when the segments share the logger's rate."""
    steps = [(series.time[b - 1] - series.time[a]) / (b - a - 1) for a, b in quiet.segments]
    dt = float(np.median(steps))
    if any(abs(s / dt - 1.0) > 0.02 for s in steps):
        raise DataError("the quiet segments of the record are sampled at different rates (more than 2 % apart); "
                        "give a record at one sample rate.")
    return dt


def estimate_noise(series, kinds=None, *, max_rate=None, min_segment_s=60.0, margin_s=2.0, baseline_s=60.0,
                   burst_k=7.0, activity_k=5.0):
    """Estimate the noise of every channel of ``series`` (a :class:`~sensorplan.model.timeseries.TimeSeries`).

    ``kinds`` gives each channel's kind ("rotation" or "deflection"; default
    rotation).  The quiet parts are found once for all channels (see
    :func:`.quiet.quiet_parts` for the thresholds); each channel is fitted on
    them (:func:`fit_channel`).  Timestamps that jitter by rounding (a 100 Hz
    logger stamped to the millisecond) are taken as the even grid they
    round.  ``max_rate`` [Hz] fits every k-th sample only, the smallest k
    that brings the rate to at most ``max_rate`` (None: every sample): faster
    and exact for the model (a sub-sampled white + OU + walk is one again),
    and what a record with fast structure the model lacks needs (vibration,
    a filter's ringing: folded into the white part).
    """
    kinds = tuple(kinds) if kinds is not None else ("rotation",) * len(series.names)
    quiet = quiet_parts(series.time, series.values, min_segment_s=min_segment_s, margin_s=margin_s,
                        baseline_s=baseline_s, burst_k=burst_k, activity_k=activity_k)
    if not quiet.segments:
        raise DataError(f"the record has no quiet part of at least {min_segment_s:g} s (no vehicle, no burst, no "
                        f"gap; {quiet.bursts} burst and {quiet.active} activity samples flagged); give a longer "
                        "record or a shorter minimum segment.")
    dt = _even_segments(series, quiet)
    every = 1 if max_rate is None else max(int(math.ceil(1.0 / (dt * max_rate) - 1e-9)), 1)
    channels = []
    for row, name, kind in zip(series.values, series.names, kinds):
        segments = [row[a:b:every] for a, b in quiet.segments]
        channels.append(fit_channel(segments, dt * every, name=name, kind=kind))
    spans = tuple((float(series.time[a]), float(series.time[b - 1])) for a, b in quiet.segments)
    return NoiseEstimate(tuple(channels), quiet.fraction, spans, dt * every, series.duration, quiet.bursts,
                         quiet.active)

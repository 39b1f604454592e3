"""Before the vehicle test: bursts masked out, and a robust noise model when the case has none.

*Bursts.*  Real tiltmeters log rare bursts (spikes, short ringing) of up to
0.28 deg, hundreds of times the noise: the vehicle test would see one as a
vehicle-sized misfit of the noise model.  A burst is sharp at the sampling
scale, a vehicle is not: the influence line of a moving axle changes little
between two samples (its second difference is a fraction of a micro-radian
at crawl speed, a few at 40 m/s), while white noise of std s has a second
difference of std s sqrt 6.  Samples whose second difference exceeds
``BURST_SIGMA`` robust standard deviations (median absolute deviation) are
burst samples; they and ``BURST_PAD`` seconds around them are replaced by a
straight line between the medians of the good samples on either side
(the test then sees no information there).  What slips through (a slow,
small burst) leaves a misfit the test's goodness-of-fit check rejects.

*Noise without a model.*  When the case gives no noise model in time, each
channel's white, Ornstein-Uhlenbeck and random-walk parts are fitted to the
record's robust variogram: for a lag L, half the variance of y(t + L) - y(t)
(from the median absolute deviation, burst samples left out) is

    gamma(L) = w^2 + s^2 (1 - exp(-L / tau)) + q^2 L / 2,

fitted in log over lags from one sample to two minutes.  The median makes it
robust to vehicles occupying a minority of the record; vehicles occupying
much of it inflate the estimate, which makes the vehicle test stricter, not
looser.  ``sensorplan noise`` on a quiet stretch gives the better model.
"""

import numpy as np

from ..model.noise import NoiseModel

__all__ = ["screen_bursts", "estimate_noise", "BURST_SIGMA", "BURST_PAD"]

_MAD_TO_STD = 1.482602218505602  # 1 / Phi^-1(3/4): MAD of a normal sample to its std
BURST_SIGMA = 8.0  # second differences beyond 8 robust std: P < 1e-15 per sample for Gaussian noise
BURST_PAD = 0.5  # s masked either side of a burst sample (a burst rings for up to about 0.5 s)
MAX_LAG = 120.0  # s, the longest variogram lag


def _robust_std(x):
    return _MAD_TO_STD * float(np.median(np.abs(x - np.median(x))))


def _runs(mask):
    """(start, stop) index pairs of the True runs of ``mask`` (stop exclusive)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _impute(y, mask):
    """``y`` with each masked run replaced by a line between the medians of up to 10 good samples around it."""
    out = y.copy()
    for a, b in _runs(mask):
        left = y[max(0, a - 10):a]
        right = y[b:b + 10]
        lo = float(np.median(left)) if left.size else float(np.median(right)) if right.size else 0.0
        hi = float(np.median(right)) if right.size else lo
        out[a:b] = np.linspace(lo, hi, b - a + 2)[1:-1]
    return out


def screen_bursts(values, dt):
    """Burst samples masked and imputed, per channel.

    Returns ``(mask, imputed)``: ``mask`` (n_channels, n_samples) True where
    a sample was replaced, ``imputed`` the record with those samples on the line.
    """
    values = np.asarray(values, dtype=float)
    pad = max(1, int(round(BURST_PAD / dt)))
    mask = np.zeros(values.shape, bool)
    imputed = values.copy()
    for c, y in enumerate(values):
        d2 = y[2:] - 2.0 * y[1:-1] + y[:-2]
        scale = _robust_std(d2)
        if scale <= 0.0:
            continue
        hits = np.flatnonzero(np.abs(d2) > BURST_SIGMA * scale) + 1
        if hits.size == 0:
            continue
        flagged = np.zeros(y.size, bool)
        flagged[hits] = True
        mask[c] = np.convolve(flagged, np.ones(2 * pad + 1), mode="same") > 0
        imputed[c] = _impute(y, mask[c])
    return mask, imputed


def _variogram(y, mask, lags):
    """Half the robust variance of the lag-L differences, burst samples left out."""
    out = np.empty(lags.size)
    for i, lag in enumerate(lags):
        good = ~(mask[lag:] | mask[:-lag])
        d = (y[lag:] - y[:-lag])[good]
        out[i] = 0.5 * _robust_std(d) ** 2 if d.size > 10 else np.nan
    return out


def _fit_variogram(lags_s, gamma):
    """(w, s, tau, q) of gamma(L) = w^2 + s^2 (1 - exp(-L / tau)) + q^2 L / 2, least squares in log."""
    from scipy.optimize import least_squares

    ok = np.isfinite(gamma) & (gamma > 0.0)
    lags_s, gamma = lags_s[ok], gamma[ok]
    g0 = float(gamma[0])

    def model(p):
        w2, s2, tau, q2 = np.exp(p)
        return w2 + s2 * -np.expm1(-lags_s / tau) + 0.5 * q2 * lags_s

    def residual(p):
        return np.log(model(p)) - np.log(gamma)

    start = np.log([g0, max(g0 * 0.2, 1e-300), 3.0, max(g0 * 1e-3, 1e-300)])
    p = least_squares(residual, start, bounds=(start - 40.0, start + 40.0)).x
    w2, s2, tau, q2 = np.exp(p)
    # parts below a thousandth of the white variance at their own scale carry no information: drop them
    s = float(np.sqrt(s2)) if s2 > 1e-3 * w2 else 0.0
    q = float(np.sqrt(q2)) if 0.5 * q2 * lags_s[-1] > 1e-3 * w2 else 0.0
    return float(np.sqrt(w2)), s, (float(tau) if s > 0.0 else 0.0), q


def estimate_noise(values, mask, dt):
    """The :class:`~sensorplan.model.noise.NoiseModel` of the channels from the record's robust variogram."""
    values = np.asarray(values, dtype=float)
    n = values.shape[1]
    top = max(2, min(n // 4, int(MAX_LAG / dt)))
    lags = np.unique(np.round(np.geomspace(1, top, 30)).astype(int))
    w, s, tau, q = np.array([_fit_variogram(lags * dt, _variogram(y, m, lags)) for y, m in zip(values, mask)]).T
    return NoiseModel(w, correlated_std=s, correlation_time_s=tau, random_walk=q)

"""Allan deviation: of a record (overlapping estimator) and of the noise model (closed form).

The Allan variance at averaging time tau = m tau0 is half the mean square
difference of adjacent m-sample means (Riley, *Handbook of Frequency
Stability Analysis*, NIST SP 1065 (2008), with the overlapping
estimator; IEEE Std 952-1997, Annex C).  White noise falls as 1/tau, a
random walk rises as tau, a correlated (OU) part peaks near its correlation
time: the curve shows where averaging stops helping.

The model's Allan variance of m-sample means of readings every tau0, derived
here by summing the covariance of two adjacent blocks of m samples (exact for
the sampled process):

* white, per-sample std s: s^2 / m  (IEEE 952 Annex C: N^2 / tau with N^2 = s^2 tau0);
* OU, std c, correlation time T, phi = exp(-tau0 / T) (AR(1) samples):
  c^2 / m^2 [m (1 + phi) / (1 - phi) - 2 phi (1 - phi^m) / (1 - phi)^2 - phi (1 - phi^m)^2 / (1 - phi)^2];
  its limit tau0 -> 0 is c^2 T^2 / tau^2 (2 x - 3 + 4 e^-x - e^-2x), x = tau / T, the first-order
  Gauss-Markov result of El-Sheimy, Hou & Niu, IEEE Trans. Instrum. Meas. 57 (2008) 140;
* random walk, q per sqrt(s): q^2 tau0 (2 m^2 + 1) / (6 m); its limit q^2 tau / 3 is IEEE 952's rate
  random walk K^2 tau / 3.

tests/test_noise_estimate.py checks each against the brute-force double sum of the covariance.
"""

import math

import numpy as np

__all__ = ["octave_factors", "allan_variance_data", "allan_variance_model"]


def octave_factors(n_samples, *, min_terms=4):
    """Averaging factors m = 1, 2, 4, ... with at least ``min_terms`` non-overlapping pairs in ``n_samples``."""
    out, m = [], 1
    while 2 * m * min_terms <= n_samples:
        out.append(m)
        m *= 2
    return np.array(out, dtype=int)


def allan_variance_data(segments, factors):
    """Overlapping Allan variance pooled over ``segments`` for each factor m, and its number of terms.

    Each segment (evenly sampled) contributes its N - 2m + 1 overlapping
    differences of adjacent m-sample means (Riley's overlapping estimator);
    segments shorter than 2m contribute none.  Returns (avar, n_terms), nan
    where no term.
    """
    factors = np.asarray(factors, dtype=int)
    sums = np.zeros(factors.size)
    counts = np.zeros(factors.size, dtype=int)
    for y in segments:
        y = np.asarray(y, dtype=float)
        y = y - y.mean()
        cum = np.concatenate([[0.0], np.cumsum(y)])
        for i, m in enumerate(factors):
            if y.size < 2 * m:
                continue
            # (sum of block 2 - sum of block 1) / m for every start j
            d = (cum[2 * m:] - 2.0 * cum[m:-m] + cum[:-2 * m]) / m
            sums[i] += float(d @ d)
            counts[i] += d.size
    with np.errstate(invalid="ignore", divide="ignore"):
        avar = np.where(counts > 0, 0.5 * sums / np.maximum(counts, 1), np.nan)
    return avar, counts


def allan_variance_model(factors, dt, *, white, correlated=0.0, correlation_time=0.0, random_walk=0.0):
    """The Allan variance of m-sample means (m in ``factors``) under the noise model (module docstring)."""
    m = np.asarray(factors, dtype=float)
    avar = white**2 / m
    if correlated > 0.0 and correlation_time > 0.0:
        phi = math.exp(-dt / correlation_time)
        one = -math.expm1(-dt / correlation_time)  # 1 - phi without cancellation
        tail = -np.expm1(m * math.log(phi)) if phi > 0.0 else np.ones_like(m)  # 1 - phi^m
        var = m * (1.0 + phi) / one - 2.0 * phi * tail / one**2
        cov = phi * tail**2 / one**2
        avar = avar + correlated**2 * (var - cov) / m**2
    if random_walk > 0.0:
        avar = avar + random_walk**2 * dt * (2.0 * m**2 + 1.0) / (6.0 * m)
    return avar

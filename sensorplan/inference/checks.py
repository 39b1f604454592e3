"""Say when a fit is not to be trusted.

Three checks on a finished inversion, each a message that names the likely
causes and points at ``sensorplan diagnose``:

* the noise scale alpha (estimated / configured noise) outside
  [0.5, 2]: the configured noise or its units are wrong, or the model
  misses something;
* hyper-posterior mass of tau at a hard end of its grid (or a point
  estimate of tau on its optimiser's bound);
* a systematic residual: per sensor, the whitened residuals r / alpha are
  tested for a non-zero mean and for autocorrelation.  Per crossing, with
  n readings of which n' inform (``NoiseModel.dof``: one fewer where the
  time model marginalises the wander's offset), the mean term is
  n mean^2 / v (v = 1 - (1^T u)^2 / n, u the unit whitened constant the
  offset projection removed; 1 without it); it carries 1 - h / v degrees
  of freedom, h the readings' mean leverage (the fit absorbs that share of
  the mean; :func:`_leverages`).  Crossings of at least ``MIN_LOADS``
  positions add the Ljung-Box term n' (n' + 2) sum_k rho_k^2 / (n' - k)
  over the sample autocorrelations rho_k, lags 1..h' with
  h' = max(1, min(5, n // 10)) (with more lags the chi-square tail is too
  light at a hundred positions, simulated).  Summed over a sensor's
  crossings: M (mean terms, m degrees of freedom) + B (Ljung-Box terms,
  k = the sum of the h').

  With alpha known (``dof`` None, e.g. ``hyper="fixed"``) only crossings
  of at least ``MIN_LOADS`` positions are tested: M + B ~ chi-square(m + k).
  With alpha estimated from the fit's residual degrees of freedom nu
  (:func:`residual_dof`), the mean terms are an F statistic, the sensor's
  own mean-square against the rest of the residual sum of squares S (all
  readings, in units of alpha): F = (M / m) / ((S - M) / (nu - m)) ~
  F(m, nu - m), the extra-sum-of-squares test of one offset per crossing,
  which compares a sensor with the others and so also tests the mean of
  short crossings (static readings) when nu - m >= 1.  B does not depend
  on alpha.  The p-value is P(m F(m, nu - m) + chi-square(k) > m F + B), the
  two parts independent (for Gaussian noise the sample mean and the
  autocorrelations of the centred residuals are), by one quadrature; for
  nu -> infinity it is the chi-square test of known alpha.  A sensor is
  flagged when p < 1e-3 / n_sensors (Bonferroni) and its residuals are not
  negligible (mean square of r / alpha at least 0.25: the structure of a
  residual far below the noise, e.g. of noise-free data, does not matter).

Owns: fit_warnings.  May import: model, errors.
"""

import numpy as np
from scipy import integrate, special

__all__ = ["fit_warnings", "residual_p_values", "residual_dof", "NOISE_SCALE_RANGE", "RESIDUAL_LEVEL"]

NOISE_SCALE_RANGE = (0.5, 2.0)
RESIDUAL_LEVEL = 1e-3  # family-wise level of the residual test over the sensors
MIN_LOADS = 20  # shorter crossings: no Ljung-Box term, and untested when alpha is known
MIN_MEAN_VARIANCE = 0.05  # a crossing whose mean the offset projection (nearly) removes has no mean term
DIAGNOSE = "run `sensorplan diagnose` to test these explanations against the data"


def residual_dof(n_data, mixture, rough, fixed):
    """Residual degrees of freedom nu = n_data - gamma of a fit (the noise scale's estimate rests on them).

    gamma = sum_k w_k (P - tr(Q_k Sigma_k)) is the effective number of
    parameters (MacKay 1992, Neural Comput. 4(3), eq. 4.9: gamma =
    tr(J^T J / alpha^2 H^{-1}) with H = J^T J / alpha^2 + Q, the same as
    P - tr(Q H^{-1})), averaged over the mixture's nodes (``weights``,
    ``taus``, ``covariances``); Q_k = tau_k ``rough`` + ``fixed``.
    """
    n_params = rough.shape[0]
    gamma = 0.0
    for w, tau, cov in zip(mixture.weights, mixture.taus, mixture.covariances):
        gamma += float(w) * (n_params - float(np.sum((tau * rough + fixed) * cov)))
    return float(n_data) - gamma


def _mean_variances(noise, fit, n_loads):
    """Per sensor, the variance of sqrt(n) mean(r) under the model (v of the module docstring)."""
    v = np.ones(noise.n_sensors)
    if not noise.in_time:
        return v
    for i in range(noise.n_sensors):
        flt = noise.filter(i, fit.positions, fit.times)
        if flt.offset:
            u = flt.innovations(np.ones(n_loads))
            v[i] = 1.0 - float(np.sum(u)) ** 2 / (n_loads * float(u @ u))
    return v


def _leverages(noise, fit, noise_scale):
    """Per sensor, the mean leverage of the crossing's readings: (model std / marginal noise std)^2.

    Exact for one white-noise reading (the fit's hat matrix diagonal, model_std^2 being the posterior
    variance of the prediction).  For longer crossings it is the average leverage of single readings,
    usually below that of their mean (smooth predictions move together), so the mean term keeps more
    degrees of freedom than it has: the test errs on the conservative side.  Measured calibrations:
    tests/test_residual_calibration.py.
    """
    marginal = noise_scale * np.sqrt(noise.std**2 + np.asarray(noise.correlated_std) ** 2)
    return np.mean((fit.model_std / marginal[:, None]) ** 2, axis=1)


def _residual_terms(noise, fits, noise_scale, short):
    """Per sensor: mean terms M, Ljung-Box terms B, their counts (m, m h), mean square; and S over all readings.

    ``short``: whether crossings with fewer than ``MIN_LOADS`` positions give mean terms.
    """
    n_sensors = noise.n_sensors
    informs = np.array([noise.subset([i]).dof(1) for i in range(n_sensors)])  # 0 where the offset is spent
    mean = np.zeros(n_sensors)
    box = np.zeros(n_sensors)
    n_mean = np.zeros(n_sensors)
    n_box = np.zeros(n_sensors)
    square = np.zeros(n_sensors)
    count = np.zeros(n_sensors)
    total = 0.0
    for fit in fits:
        n = fit.positions.size
        r = noise.whiten(fit.data - fit.model, fit.positions, times=fit.times) / noise_scale  # (n_sensors, n_loads)
        total += float(np.sum(r * r))
        n_eff = n - 1 + informs  # readings that inform, per sensor
        if short or n >= MIN_LOADS:
            square += np.sum(r * r, axis=1)
            count += n_eff
        v = _mean_variances(noise, fit, n)
        share = 1.0 - _leverages(noise, fit, noise_scale) / np.maximum(v, MIN_MEAN_VARIANCE)
        tested = (v >= MIN_MEAN_VARIANCE) & (n_eff > 0) & (share >= MIN_MEAN_VARIANCE) & (short or n >= MIN_LOADS)
        mean += np.where(tested, n * np.mean(r, axis=1) ** 2 / np.maximum(v, MIN_MEAN_VARIANCE), 0.0)
        n_mean += np.where(tested, share, 0.0)
        if n < MIN_LOADS:
            continue
        h = max(1, min(5, n // 10))
        y = r - np.mean(r, axis=1, keepdims=True)
        variance = np.maximum(np.sum(y * y, axis=1), 1e-300)
        for k in range(1, h + 1):
            rho = np.sum(y[:, k:] * y[:, :-k], axis=1) / variance
            box += n_eff * (n_eff + 2) * rho**2 / (n_eff - k)
        n_box += h
    return mean, box, n_mean, n_box, square / np.maximum(count, 1), total


def _sum_sf(value, m, nu, k):
    """P(m F(m, nu) + chi-square(k) > value): the F part's tail averaged over the chi-square part's density."""
    if k == 0:
        return float(special.fdtrc(m, nu, value / m))

    def integrand(y):
        return np.exp(special.xlogy(k / 2 - 1, y) - y / 2 - special.gammaln(k / 2) - (k / 2) * np.log(2.0)) * \
            special.fdtrc(m, nu, (value - y) / m)

    inner, _ = integrate.quad(integrand, 0.0, value, epsabs=0.0, epsrel=1e-8, limit=200)
    return min(1.0, float(special.chdtrc(k, value)) + inner)


def residual_p_values(noise, fits, noise_scale, *, dof=None):
    """p-value per sensor of the mean + Ljung-Box test of the whitened residuals (nan if untested).

    ``dof``: the residual degrees of freedom nu on which ``noise_scale`` was
    estimated (:func:`residual_dof`); None when the noise scale is known.
    """
    mean, box, m, k, square, total = _residual_terms(noise, fits, noise_scale, dof is not None)
    p = np.full(noise.n_sensors, np.nan)
    for i in range(noise.n_sensors):
        if m[i] + k[i] == 0 or square[i] < 0.25:
            continue
        if dof is None:
            p[i] = special.chdtrc(m[i] + k[i], mean[i] + box[i])
        elif m[i] and dof - m[i] >= 1.0 and total > mean[i]:
            f = (mean[i] / m[i]) / ((total - mean[i]) / (dof - m[i]))
            p[i] = _sum_sf(m[i] * f + box[i], m[i], dof - m[i], k[i])
        elif k[i]:  # too few degrees of freedom for the mean: the autocorrelations alone
            p[i] = special.chdtrc(k[i], box[i])
    return p


def fit_warnings(noise, fits, sensor_names, *, noise_scale, noise_configured, tau_at_bound, tau_side,
                 residual_p=None):
    """Messages (tuple of str) saying why the fit may not be trusted; empty when nothing is found.

    ``tau_side`` is "flat" or "rough": the end of the tau grid that holds mass; ``residual_p`` the
    :func:`residual_p_values` of ``fits`` when the caller has them already.
    """
    out = []
    lo, hi = NOISE_SCALE_RANGE
    if noise_configured and not lo <= noise_scale <= hi:
        if noise_scale > hi:
            causes = ("the configured noise_std is too small or in the wrong unit (rad vs mm/m, m vs mm), "
                      "or the model misses something: a sensor with the wrong sign or position, wrong load "
                      "positions, or an unmodelled effect (temperature drift, offsets, dynamics, support "
                      "settlement)")
        else:
            causes = ("the configured noise_std is too large or in the wrong unit (rad vs mm/m, m vs mm), or the "
                      "data were smoothed or averaged before the inversion")
        out.append(f"the estimated noise is {noise_scale:.3g} times the configured noise_std (expected "
                   f"{lo:g} to {hi:g}): {causes}; {DIAGNOSE}.")
    if tau_at_bound:
        if tau_side == "flat":
            what = ("the data favour an ever flatter EI field: the credible bands may be too narrow; check the "
                    "prior's smoothness_std, and whether an unmodelled effect or a wrong unit absorbs the signal")
        else:
            what = ("the data favour an ever rougher EI field: an unmodelled effect, a wrong sensor sign or "
                    "position, or wrong load positions are being explained by a jagged EI")
        out.append(f"the prior smoothness tau reaches the end of its range: {what}; {DIAGNOSE}.")
    p = residual_p_values(noise, fits, noise_scale) if residual_p is None else residual_p
    bad = [i for i in range(p.size) if np.isfinite(p[i]) and p[i] < RESIDUAL_LEVEL / p.size]
    if bad:
        names = ", ".join(f"{sensor_names[i]} (p = {p[i]:.1e})" for i in bad)
        out.append(f"systematic residuals at {names} (mean and Ljung-Box test of the whitened residuals, "
                   f"Bonferroni over {p.size} sensors): the model does not explain these readings; check the "
                   f"sensor's sign, position and unit, the load positions of the crossings, the noise "
                   f"correlation length, and unmodelled effects (temperature drift, offsets, dynamics); {DIAGNOSE}.")
    return tuple(out)

"""Say when a fit is not to be trusted.

Three checks on a finished inversion, each a message that names the likely
causes and points at ``sensorplan diagnose``:

* the noise scale alpha (estimated / configured noise) outside
  [0.5, 2]: the configured noise or its units are wrong, or the model
  misses something;
* hyper-posterior mass of tau at a hard end of its grid (or a point
  estimate of tau on its optimiser's bound);
* a systematic residual: per sensor, the whitened residuals r / alpha of
  every crossing (iid N(0, 1) under the model) are tested for a non-zero
  mean and for autocorrelation (Ljung-Box on the sample autocorrelations
  rho_k, lags 1..h with h = max(1, min(5, n_loads // 10)): with more lags
  the chi-square tail is too light at a hundred positions, simulated); the
  statistic, summed over crossings, n mean^2 + n (n + 2) sum_k rho_k^2 / (n - k)
  is chi-square with n_crossings (1 + h) degrees of freedom.  A sensor is
  flagged when p < 1e-3 / n_sensors (Bonferroni) and its residuals are not
  negligible (mean square of r / alpha at least 0.25: the structure of a
  residual far below the noise, e.g. of noise-free data, does not matter).

Owns: fit_warnings.  May import: model, errors.
"""

import numpy as np
from scipy import special

__all__ = ["fit_warnings", "residual_p_values", "NOISE_SCALE_RANGE", "RESIDUAL_LEVEL"]

NOISE_SCALE_RANGE = (0.5, 2.0)
RESIDUAL_LEVEL = 1e-3  # family-wise level of the residual test over the sensors
MIN_LOADS = 20  # crossings with fewer positions are not tested for autocorrelation
DIAGNOSE = "run `sensorplan diagnose` to test these explanations against the data"


def residual_p_values(noise, fits, noise_scale):
    """p-value per sensor of the mean + Ljung-Box test of the whitened residuals (nan if untested)."""
    n_sensors = noise.n_sensors
    q = np.zeros(n_sensors)
    square = np.zeros(n_sensors)
    dof = count = 0
    for fit in fits:
        n = fit.positions.size
        if n < MIN_LOADS:
            continue
        r = noise.whiten(fit.data - fit.model, fit.positions, times=fit.times) / noise_scale  # (n_sensors, n_loads)
        h = max(1, min(5, n // 10))
        square += np.sum(r * r, axis=1)
        count += n
        q += n * np.mean(r, axis=1) ** 2
        y = r - np.mean(r, axis=1, keepdims=True)
        variance = np.maximum(np.sum(y * y, axis=1), 1e-300)
        for k in range(1, h + 1):
            rho = np.sum(y[:, k:] * y[:, :-k], axis=1) / variance
            q += n * (n + 2) * rho**2 / (n - k)
        dof += 1 + h
    if dof == 0:
        return np.full(n_sensors, np.nan)
    return np.where(square / count >= 0.25, special.chdtrc(dof, q), np.nan)


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

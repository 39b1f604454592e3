"""The gap between a fitted model and the data: noise and systematic parts, structure tests.

Owns: residual statistics of the diagnosis.  May import: the foundations.
"""

import math

import numpy as np
from scipy import special

from .results import Gap, ResidualMap, SensorGap

__all__ = ["residual_gap"]


def residual_gap(problem, theta, alpha):
    """(:class:`Gap`, :class:`ResidualMap`): the residual split into noise and systematic parts, per sensor."""
    residuals = problem.residuals(theta)
    grid = _common_grid(problem.crossings)
    by_sensor, means, p_values, p_structure, tested = {}, [], [], [], len(problem.crossings) >= 2
    for i, name in enumerate(problem.sensor_names):
        gap, mean, lb_dof = _sensor_gap(problem, residuals, i, grid, alpha)
        by_sensor[name] = gap
        means.append(mean)
        p_values += [gap.p_systematic, gap.p_ljung_box]
        p_structure.append(gap.p_ljung_box)
        tested = tested or lb_dof > 0
    all_res = np.concatenate([r.ravel() for r in residuals])
    sys_rms = math.sqrt(np.mean([v.systematic_rms ** 2 for v in by_sensor.values()]))
    noise_rms = math.sqrt(np.mean([v.noise_rms ** 2 for v in by_sensor.values()]))
    p_min = min(1.0, min(p_values) * len(p_values))  # Bonferroni
    score = np.max(np.abs(np.stack(means)), axis=0)
    worst = []
    for k in np.argsort(score)[::-1]:
        if all(abs(grid[k] - w) >= 1.0 for w in worst):
            worst.append(float(grid[k]))
        if len(worst) == 5:
            break
    # A gap is significant when the mean residual is both statistically and
    # practically non-zero, or when the whitened residuals are correlated in
    # load position (Ljung-Box): a gap that changes sign from crossing to
    # crossing (vibration with a random phase, for instance) cancels in the
    # mean but not in the correlation.
    p_lb_min = min(1.0, min(p_structure) * len(p_structure))  # Bonferroni over sensors
    significant = (p_min < 1e-3 and sys_rms > 0.1 * noise_rms) or p_lb_min < 1e-3
    gap = Gap(float(np.sqrt(np.mean(all_res**2))), systematic_rms=float(sys_rms), noise_rms=float(noise_rms),
              by_sensor=by_sensor, worst_positions_m=tuple(sorted(worst)), p_value=float(p_min),
              significant=bool(significant), testable=bool(tested))
    return gap, ResidualMap(grid, np.stack(means))


def _common_grid(crossings):
    """The load positions common to every crossing (those of the first crossing inside all of them)."""
    ref = crossings.crossings[0].positions
    if len(crossings) < 2:
        return ref
    lo = max(c.positions[0] for c in crossings)
    hi = min(c.positions[-1] for c in crossings)
    return ref[(ref >= lo) & (ref <= hi)]


def _sensor_gap(problem, residuals, i, grid, alpha):
    """(:class:`SensorGap`, mean residual / noise std on ``grid``, Ljung-Box degrees of freedom) of sensor ``i``.

    With one crossing the noise comes from first differences (corrected for
    the AR(1) correlation) and the mean cannot be tested (p = 1).
    """
    crossings = problem.crossings
    n_c = len(crossings)
    stacked = np.stack([np.interp(grid, c.positions, r[i]) for c, r in zip(crossings, residuals)])
    mean = stacked.mean(axis=0)
    if n_c >= 2:
        noise_var = float(np.mean(stacked.var(axis=0, ddof=1)))
        sys_var = max(float(np.mean(mean**2)) - noise_var / n_c, 0.0)
        p_sys = _systematic_p(problem.noise.subset([i]), stacked, grid)
    else:
        rho = problem.noise.rho(crossings.crossings[0].positions)
        d = np.diff(stacked[0])
        r1 = float(np.mean(rho)) if rho.size else 0.0
        noise_var = float(np.mean(d**2)) / (2.0 * max(1.0 - r1, 1e-3))
        sys_var = max(float(np.mean(mean**2)) - noise_var, 0.0)
        p_sys = 1.0
    p_lb, dof = _ljung_box(problem, residuals, i, alpha)
    rms = math.sqrt(float(np.mean(np.concatenate([r[i] for r in residuals]) ** 2)))
    gap = SensorGap(rms, systematic_rms=math.sqrt(sys_var), noise_rms=math.sqrt(noise_var), p_systematic=p_sys,
                    p_ljung_box=p_lb)
    return gap, mean / math.sqrt(max(noise_var, 1e-300)), dof


def _systematic_p(noise, stacked, grid):
    """p-value of a non-zero mean of one sensor's residuals over the crossings, ``stacked`` (crossings, grid).

    The residuals are whitened along the load position with the noise
    model first (AR(1): the readings of a crossing are correlated), so that
    under the model the whitened means at the grid points are independent:
    n_c sum(mean^2) / s^2 is then chi^2 with one degree of freedom per grid
    point (s^2: the crossing-to-crossing variance of the whitened
    residuals).  Unwhitened, correlated noise makes the statistic far
    heavier-tailed than that chi^2, and effect-free data fail the test.
    """
    white = noise.whiten(stacked[:, None, :], grid, sensor_axis=1)[:, 0, :]
    n_c = stacked.shape[0]
    var = float(np.mean(white.var(axis=0, ddof=1)))
    chi2 = n_c * float(np.sum(white.mean(axis=0) ** 2)) / max(var, 1e-300)
    return float(special.chdtrc(grid.size, chi2))


def _ljung_box(problem, residuals, i, alpha, lags=10):
    """(p-value, degrees of freedom) of the Ljung-Box test of sensor ``i``'s whitened residuals (p = 1 untested)."""
    q, dof = 0.0, 0
    for c, r in zip(problem.crossings, residuals):
        w = problem.noise.subset([i]).whiten(r[i:i + 1], c.positions)[0]
        n = w.size
        if n <= lags + 2:
            continue
        w = w - w.mean()
        denom = float(w @ w)
        if denom == 0.0:
            continue
        acf = np.array([float(w[:-k] @ w[k:]) / denom for k in range(1, lags + 1)])
        q += n * (n + 2) * float(np.sum(acf**2 / (n - np.arange(1, lags + 1))))
        dof += lags
    return (float(special.chdtrc(dof, q)) if dof else 1.0), dof



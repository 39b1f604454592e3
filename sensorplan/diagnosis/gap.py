"""The gap between a fitted model and the data: noise and systematic parts, structure tests.

The systematic test asks whether the residuals share a mean across the
crossings (per sensor and load position) that the noise does not explain.
The noise variance is never taken as known: it is estimated from the same
residuals, so the statistic follows an F distribution with the degrees of
freedom that estimate has (a chi^2 with a variance from one degree of
freedom called p = 5e-22 what F(1, 1) calls 0.6).

* Few readings at common load positions (static load steps, short
  records): the exact test of the linearised model.  The whitened
  residual r is projected off the span of the whitened Jacobian J at the
  fit, which removes every trace of the fitted parameters (in the
  linearised model (I - P_J) r = (I - P_J) e whatever the prior did), and
  the systematic columns A (one per sensor and position, the same in every
  crossing) are tested against what is left:
  F = (|P_A~ r|^2 / q) / (|r_rest|^2 / nu), A~ = (I - P_J) A of rank q,
  nu = N - rank[J A], which is F(q, nu) under the model, exactly.
* Dense records (positions differ between crossings, or many positions):
  the means over crossings on a common grid, whitened along the position,
  against the crossing-to-crossing variance of the same residuals:
  n_c sum(mean^2) / s^2 ~ G F(G, G (n_c - 1)) per sensor (Bonferroni
  over the sensors); the fitted parameters are few against G there.

Owns: residual statistics of the diagnosis.  May import: the foundations.
"""

import math
from dataclasses import replace

import numpy as np
from scipy import special, stats

from .results import Gap, ResidualMap, SensorGap

__all__ = ["residual_gap", "systematic_f_test", "EXACT_MAX_COLUMNS"]

EXACT_MAX_COLUMNS = 64  # the exact test when every crossing has the same positions and sensors x positions <= this


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
    exact = systematic_f_test(problem, theta) if tested else None
    if exact is not None:  # few readings at common positions: one exact F test (its p is uniform under the model)
        p_sys = exact[0]
        p_min = p_sys if not any(p < 1.0 for p in p_structure) else min(1.0, 2.0 * min(p_sys, p_lb_min))
        tested = exact[2] > 0
        for name, p in zip(problem.sensor_names, exact[1]):
            by_sensor[name] = replace(by_sensor[name], p_systematic=float(p))
    else:
        p_sys = p_min
    significant = (p_sys < 1e-3 and sys_rms > 0.1 * noise_rms) or p_lb_min < 1e-3
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
    # s^2 has G (n_c - 1) degrees of freedom: the statistic is G F(G, G (n_c - 1)), not chi^2(G); G counts the
    # whitened points that carry information (one fewer when the time model marginalises a wander offset)
    g = noise.dof(grid.size)
    return float(stats.f.sf(chi2 / g, g, g * (n_c - 1)))


def _ljung_box(problem, residuals, i, alpha, lags=10):
    """(p-value, degrees of freedom) of the Ljung-Box test of sensor ``i``'s whitened residuals (p = 1 untested)."""
    q, dof = 0.0, 0
    for c, r in zip(problem.crossings, residuals):
        w = problem.noise.subset([i]).whiten(r[i:i + 1], c.positions, times=c.times)[0]
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




def systematic_f_test(problem, theta, *, rtol=1e-9):
    """The exact F test of a systematic residual (module docstring), or None where it does not apply.

    Applies when every crossing has the same load positions (G of them), S G <= :data:`EXACT_MAX_COLUMNS`
    and at least two crossings.  Returns (p, p per sensor, nu): the p-value of all systematic columns
    together, that of each sensor's columns (against the same denominator) and the residual degrees of
    freedom nu (0: nothing left to estimate the noise from; p = 1 then).
    """
    crossings = problem.crossings
    first = crossings.crossings[0].positions
    n_s, n_g = problem.noise.n_sensors, first.size
    if (len(crossings) < 2 or n_s * n_g > EXACT_MAX_COLUMNS
            or any(c.positions.shape != first.shape or not np.array_equal(c.positions, first) for c in crossings)
            or any(c.times is not None for c in crossings)):  # readings at their own times: whitened apart
        return None
    residual, jacobian = problem.rows(theta)[:2]
    # the systematic columns in whitened rows: W_i e_g for sensor i, position g, repeated in every crossing
    unit = np.stack([problem.noise.whiten(_indicator(n_s, n_g, g), first) for g in range(n_g)])  # (G, S, G)
    block = np.zeros((n_s * n_g, n_s * n_g))  # rows of one crossing (sensor-major) x columns (i, g)
    for i in range(n_s):
        block[i * n_g:(i + 1) * n_g, i * n_g:(i + 1) * n_g] = unit[:, i, :].T
    columns = np.tile(block, (len(crossings), 1))
    basis_j = _basis(jacobian, rtol)
    rest = residual - basis_j @ (basis_j.T @ residual)
    tilde = columns - basis_j @ (basis_j.T @ columns)
    basis_a = _basis(tilde, rtol, scale=float(np.linalg.norm(columns, 2)))
    q = basis_a.shape[1]
    nu = residual.size - basis_j.shape[1] - q
    if q == 0 or nu <= 0:
        return 1.0, np.ones(n_s), max(nu, 0)
    explained = basis_a.T @ rest
    denominator = max(float(rest @ rest - explained @ explained), 1e-300) / nu
    p_all = float(stats.f.sf(float(explained @ explained) / q / denominator, q, nu))
    per_sensor = []
    for i in range(n_s):
        b = _basis(tilde[:, i * n_g:(i + 1) * n_g], rtol, scale=float(np.linalg.norm(columns, 2)))
        k = b.shape[1]
        part = b.T @ rest
        per_sensor.append(float(stats.f.sf(float(part @ part) / k / denominator, k, nu)) if k else 1.0)
    return p_all, np.array(per_sensor), nu


def _indicator(n_sensors, n_positions, g):
    out = np.zeros((n_sensors, n_positions))
    out[:, g] = 1.0
    return out


def _basis(matrix, rtol, *, scale=None):
    """Orthonormal basis of the column span of ``matrix`` (rank-revealing SVD; relative to ``scale`` if given)."""
    if matrix.shape[1] == 0:
        return np.zeros((matrix.shape[0], 0))
    u, sv, _ = np.linalg.svd(matrix, full_matrices=False)
    ref = float(sv[0]) if scale is None else scale
    return u[:, :int(np.sum(sv > rtol * max(ref, 1e-300) * max(matrix.shape)))]

"""The exact restricted log-likelihood of evenly sampled segments under white + OU + random-walk noise, fast.

The model and its whitening are those of :mod:`sensorplan.model.statespace`
(the Kalman filter of the two states OU and walk, the walk's level at the
start of each segment marginalised by projecting the whitened constant out:
the restricted likelihood).  On an even time grid the filter's gains
converge to constants after a transient; from there the map from readings to
innovations is a time-invariant second-order recursion, an ARMA(2, 2) filter
applied in C by :func:`scipy.signal.lfilter`, started from the exact state by
:func:`scipy.signal.lfiltic`.  The transient runs as the full time-varying
filter, so the result equals the dense computation to rounding
(tests/test_noise_estimate.py checks it against the InnovationFilter).

Reference: Durbin & Koopman, *Time Series Analysis by State Space Methods*
(2nd ed., 2012), section 4.3 (the filter), chapter 7 (the likelihood by the
prediction-error decomposition) and chapter 5 (a diffuse initial level);
Harvey, *Forecasting, Structural Time Series Models and the Kalman Filter*
(1989), chapter 3 (the steady-state filter of a time-invariant model).
"""

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Gains", "gains", "restricted_loglik"]

_TOL = 1e-12  # change of the gains and of log S per step below which the filter has converged


@dataclass(frozen=True, eq=False)
class Gains:
    """The Kalman filter of one parameter set on an even grid of step ``dt``, up to convergence.

    ``k0``, ``k1``, ``s`` are the gains of the OU and walk states and the
    innovation variances of the first ``n`` steps; when ``converged`` the
    last values hold for every later step.
    """

    k0: np.ndarray
    k1: np.ndarray
    s: np.ndarray
    phi: float
    converged: bool


def gains(white, correlated, tau, walk, dt, n_max):
    """The filter's gains for up to ``n_max`` steps, stopping early once converged."""
    phi = math.exp(-dt / tau)
    qu = correlated**2 * -math.expm1(-2.0 * dt / tau)
    qb = walk**2 * dt
    r = white**2
    p00, p01, p11 = correlated**2, 0.0, 0.0
    k0s, k1s, ss = [], [], []
    a0 = a1 = ls = -1.0
    converged = False
    for _ in range(max(int(n_max), 1)):
        s = p00 + 2.0 * p01 + p11 + r
        g0 = (p00 + p01) / s
        g1 = (p01 + p11) / s
        k0s.append(g0)
        k1s.append(g1)
        ss.append(s)
        log_s = math.log(s)
        if abs(g0 - a0) < _TOL and abs(g1 - a1) < _TOL and abs(log_s - ls) < _TOL:
            converged = True
            break
        a0, a1, ls = g0, g1, log_s
        p00, p01, p11 = p00 - g0 * g0 * s, p01 - g0 * g1 * s, p11 - g1 * g1 * s
        p00, p01, p11 = phi * phi * p00 + qu, phi * p01, p11 + qb
    return Gains(np.array(k0s), np.array(k1s), np.array(ss), phi, converged)


def _steady_filter(g):
    """(b, a) of the time-invariant map from readings to (unscaled) innovations."""
    phi, k0, k1 = g.phi, float(g.k0[-1]), float(g.k1[-1])
    # the filter in innovation form: a_{k+1} = A a_k + B y_k, e_k = y_k - H a_k, H = [1, 1], A = F (I - K H), B = F K
    a00, a01, a10, a11 = phi * (1.0 - k0), -phi * k0, -k1, 1.0 - k1
    b0, b1 = phi * k0, k1
    trace, det = a00 + a11, a00 * a11 - a01 * a10
    c0 = (a10 - a11) * b0 + (a01 - a00) * b1
    return np.array([1.0, -(trace + b0 + b1), det - c0]), np.array([1.0, -trace, det])


def _transient(g, columns, head):
    """Innovations of the first ``head`` readings of every column (list of arrays), all columns at once."""
    width = len(columns)
    y = np.zeros((head, width))
    for c, col in enumerate(columns):
        y[:min(head, col.size), c] = col[:head]
    e = np.empty_like(y)
    state0 = np.zeros(width)
    state1 = np.zeros(width)
    last = g.s.size - 1
    phi = g.phi
    for k in range(head):
        j = k if k < last else last
        err = y[k] - state0 - state1
        e[k] = err
        state0 = phi * (state0 + g.k0[j] * err)
        state1 = state1 + g.k1[j] * err
    return e


def _group_terms(g, segments):
    """The restricted -2 log-likelihood terms (without 2 pi) of segments sharing one grid step."""
    from scipy.signal import lfilter, lfiltic  # here: scipy.signal costs 0.4 s to import (scipy.stats)

    longest = max(y.size for y in segments)
    if not g.converged and g.s.size < longest:
        raise ValueError("gains computed for fewer steps than the segment has")
    head = min(longest, g.s.size + 2)
    columns = [c for y in segments for c in (y, np.ones(y.size))]
    early = _transient(g, columns, head)
    b, a = _steady_filter(g) if g.converged else (None, None)
    total = 0.0
    for i, y in enumerate(segments):
        n = y.size
        e = np.empty((n, 2))
        h = min(n, head)
        e[:h] = early[:h, 2 * i:2 * i + 2]
        if n > h:
            for c, col in enumerate((y, np.ones(n))):
                zi = lfiltic(b, a, e[h - 1:h - 3:-1, c], col[h - 1:h - 3:-1])
                e[h:, c] = lfilter(b, a, col[h:], zi=zi)[0]
        used = min(n, g.s.size)
        scale = np.empty(n)
        scale[:used] = g.s[:used]
        scale[used:] = g.s[-1]
        log_det = float(np.log(g.s[:used]).sum()) + (n - used) * math.log(g.s[-1])
        w = e / np.sqrt(scale)[:, None]
        vv, gv, gg = float(w[:, 0] @ w[:, 0]), float(w[:, 1] @ w[:, 0]), float(w[:, 1] @ w[:, 1])
        # log det Sigma + log(1' S^-1 1) + y' S^-1 y - (1' S^-1 y)^2 / (1' S^-1 1)
        total += log_det + math.log(gg) + vv - gv * gv / gg
    return total


def restricted_loglik(params, segments, dts):
    """Restricted log-likelihood of ``segments`` (arrays, each evenly sampled with step ``dts[i]``).

    ``params`` = (white, correlated, tau, walk), all positive.  The walk's
    level at the start of each segment is marginalised (one reading's worth
    per segment: n - 1 degrees of freedom each).
    """
    white, correlated, tau, walk = (float(p) for p in params)
    groups = {}
    for y, dt in zip(segments, dts):
        groups.setdefault(float(dt), []).append(np.asarray(y, dtype=float))
    total, dof = 0.0, 0
    for dt, group in groups.items():
        g = gains(white, correlated, tau, walk, dt, max(y.size for y in group))
        total += _group_terms(g, group)
        dof += sum(y.size - 1 for y in group)
    return -0.5 * (total + dof * math.log(2.0 * math.pi))

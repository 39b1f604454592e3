"""Whitening a uniformly sampled logger channel under the noise model in time.

A channel's noise is white + Ornstein-Uhlenbeck + random walk
(:mod:`sensorplan.model.statespace`).  On a uniform grid the Kalman filter of
that model has constant gains once its covariance has converged (the
steady state of the discrete algebraic Riccati equation, Durbin & Koopman
2012, section 4.3.4), so the innovation filter of
:class:`~sensorplan.model.statespace.InnovationFilter` becomes a linear
time-invariant recursion: with the predicted state x_k (OU, walk),

    e_k = (y_k - 1^T x_k) / s,    x_{k+1} = F (x_k + K (y_k - 1^T x_k)),

a rational filter applied by :func:`scipy.signal.lfilter` to a record of
millions of samples, and to a vehicle's template at any entry time by the
same filter (the template is zero before the entry, so the filter started at
rest just before it gives the record's whitened column exactly).

The filter starts at the steady-state covariance (the state before the
record is unknown with that spread); the walk's level at the start is an
unknown offset, marginalised as in :mod:`~sensorplan.model.statespace` by
projecting the whitened constant out.  Away from the first seconds of a
record the whitened values equal the exact filter's (tests compare them).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Whitener", "whitener"]


def _parts(noise, channel):
    """(white, correlated, correlation time, walk) of ``channel`` of the NoiseModel ``noise``."""
    return (float(noise.std[channel]), float(noise.correlated_std[channel]),
            float(noise.correlation_time_s[channel]), float(noise.random_walk[channel]))


def _steady_state(parts, dt):
    """(F diagonal, K, s) of the converged Kalman filter on a grid of step ``dt``."""
    from scipy.linalg import solve_discrete_are

    white, correlated, tau, walk = parts
    phi, q = [], []
    if correlated > 0.0:
        a = np.exp(-dt / tau)
        phi.append(a)
        q.append(correlated**2 * -np.expm1(-2.0 * dt / tau))
    if walk > 0.0:
        phi.append(1.0)
        q.append(walk**2 * dt)
    f = np.diag(phi)
    c = np.ones((len(phi), 1))
    # predicted covariance P = F (P - P c (c'Pc + r)^-1 c'P) F' + Q  (scipy's DARE with a = F', b = c)
    p = solve_discrete_are(f.T, c, np.diag(q), np.array([[white**2]]))
    s2 = float((c.T @ p @ c)[0, 0]) + white**2
    return np.array(phi), (p @ c)[:, 0] / s2, np.sqrt(s2)


@dataclass(frozen=True, eq=False)
class Whitener:
    """The steady-state innovation filter of one channel on a grid of step ``dt``.

    Attributes
    ----------
    numerator, denominator : ndarray
        The filter y -> e as a rational transfer function (``lfilter``).
    scale : float
        Innovation std s [rad or m].
    pole : float
        Largest modulus of the filter's poles (< 1): the whitened column of
        a finite template decays like pole**k after it.
    offset : bool
        Whether the walk's starting level is marginalised.
    """

    numerator: np.ndarray
    denominator: np.ndarray
    scale: float
    pole: float
    offset: bool

    def apply(self, x):
        """Filter ``x`` along its last axis from rest (a column that is zero before its first sample)."""
        from scipy.signal import lfilter

        return lfilter(self.numerator, self.denominator, np.asarray(x, dtype=float), axis=-1)

    def tail(self, tolerance=1e-6):
        """Samples after a template's end until its whitened column has decayed to ``tolerance``."""
        if self.pole <= 0.0:
            return 1
        return int(np.ceil(np.log(tolerance) / np.log(self.pole))) + 1

    def record(self, y):
        """Whitened record and its whitened constant (the offset's column), the constant projected out.

        Returns ``(r, ones)``: ``r`` is orthogonal to ``ones``; a template's
        whitened column m enters the test as ``m - ones (ones . m) / |ones|^2``.
        """
        y = np.asarray(y, dtype=float)
        base = float(np.median(y[: min(y.size, 100)]))  # a large logger zero would only cost precision
        r = self.apply(y - base)
        if not self.offset:
            return r, np.zeros_like(r)
        ones = self.apply(np.ones_like(y))
        return r - ones * (float(ones @ r) / float(ones @ ones)), ones


def whitener(noise, dt, channel=0):
    """The :class:`Whitener` of ``channel`` of ``noise`` (a :class:`~sensorplan.model.noise.NoiseModel`, one
    entry per logger channel) on a grid of step ``dt`` [s]."""
    from scipy.signal import ss2tf

    parts = _parts(noise, channel)
    white, correlated, _, walk = parts
    if correlated <= 0.0 and walk <= 0.0:
        return Whitener(np.array([1.0 / white]), np.array([1.0]), white, 0.0, False)
    phi, gain, s = _steady_state(parts, float(dt))
    d = phi.size
    f = np.diag(phi)
    ones = np.ones((1, d))
    a = f @ (np.eye(d) - gain[:, None] @ ones)
    b = (f @ gain)[:, None]
    num, den = ss2tf(a, b, -ones / s, np.array([[1.0 / s]]))
    pole = float(np.max(np.abs(np.linalg.eigvals(a))))
    return Whitener(np.asarray(num[0], float), np.asarray(den, float), float(s), pole, walk > 0.0)

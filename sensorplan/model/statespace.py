"""Whitening under white + Ornstein-Uhlenbeck + random-walk noise in time.

One sensor's reading error at times t_1 < ... < t_n is

    e_k = w_k + u(t_k) + b(t_k),

w white (std ``white``), u a stationary Ornstein-Uhlenbeck process (std
``correlated``, correlation time ``tau``: corr(u(t), u(s)) = exp(-|t - s| / tau))
and b a random walk (wander: var(b(t) - b(s)) = q^2 |t - s|, ``q`` in unit per
sqrt(s)).  The pair (u, b) is a two-state Gauss-Markov process, so the
covariance Sigma of the n readings has a Kalman filter whose innovations are
its whitening: e = L^{-1} y with Sigma = L L^T, computed by a recursion over
the readings (O(n) per column) without forming Sigma.  The filter's gains do
not depend on the data, so they are computed once per time grid and applied to
any number of columns at once.

The random walk has no starting level: its level at the first reading is an
unknown offset of the crossing, marginalised exactly under a flat prior by
projecting the whitened constant out of every whitened column (the restricted
likelihood: one reading's worth of information is spent on the offset).

Reference: Durbin & Koopman, *Time Series Analysis by State Space Methods*
(2nd ed., 2012), sections 4.3 (the Kalman filter and its innovations) and 5.7
(diffuse initial states, equivalent to the projection used here).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["InnovationFilter", "innovation_filter"]


@dataclass(frozen=True, eq=False)
class InnovationFilter:
    """The data-independent part of the Kalman filter on one time grid.

    Attributes
    ----------
    gain : ndarray (n, d)
        Kalman gains of the d active states (OU first, then the walk).
    scale : ndarray (n,)
        Innovation standard deviations sqrt(S_k).
    transition : ndarray (n, d)
        Diagonal transition from reading k to k + 1 (the last row unused).
    offset : bool
        Whether the walk's starting level is marginalised (projected out).
    white : float
        The white-noise std (used when no state is active).
    """

    gain: np.ndarray
    scale: np.ndarray
    transition: np.ndarray
    offset: bool
    white: float

    @property
    def n_states(self):
        return self.gain.shape[1]

    def innovations(self, values):
        """Whitened innovations of ``values`` (n, ...) along the first axis, before the offset projection."""
        values = np.asarray(values, dtype=float)
        n = values.shape[0]
        if self.n_states == 0:
            return values / self.white
        flat = values.reshape(n, -1)
        out = np.empty_like(flat)
        state = np.zeros((self.n_states, flat.shape[1]))
        gain, scale, trans = self.gain, self.scale, self.transition
        for k in range(n):
            err = flat[k] - state.sum(axis=0)
            out[k] = err / scale[k]
            state += gain[k][:, None] * err[None, :]
            state *= trans[k][:, None]
        return out.reshape(values.shape)

    def whiten(self, values):
        """Sigma^{-1/2} values along the first axis, the walk's offset marginalised when it has one."""
        out = self.innovations(values)
        if not self.offset:
            return out
        ones = self.innovations(np.ones(out.shape[0]))
        shape = (-1,) + (1,) * (out.ndim - 1)
        coef = np.tensordot(ones, out, axes=(0, 0)) / float(ones @ ones)
        return out - ones.reshape(shape) * coef[None, ...]

    def log_det(self):
        """log det Sigma, plus log(1^T Sigma^{-1} 1) when the offset is marginalised (restricted likelihood)."""
        value = 2.0 * float(np.sum(np.log(self.scale)))
        if self.offset:
            ones = self.innovations(np.ones(self.scale.size))
            value += float(np.log(ones @ ones))
        return value

    @property
    def dof(self):
        """Readings that carry information about anything but the offset."""
        return self.scale.size - int(self.offset)


def innovation_filter(times, *, white, correlated=0.0, correlation_time=0.0, random_walk=0.0):
    """The :class:`InnovationFilter` of one sensor's noise on readings at ``times`` [s] (increasing).

    ``white``, ``correlated``, ``random_walk`` in the sensor's unit (per
    sqrt(s) for the walk), ``correlation_time`` in s.  ``white`` must be
    positive (every reading has some independent error).
    """
    times = np.asarray(times, dtype=float)
    n = times.size
    ou = correlated > 0.0 and correlation_time > 0.0
    walk = random_walk > 0.0
    d = int(ou) + int(walk)
    dt = np.diff(times)
    phi_ou = np.exp(-dt / correlation_time) if ou else np.zeros(0)
    # Process noise of each step, and the transition (OU decays, the walk stays).
    q_ou = correlated**2 * -np.expm1(-2.0 * dt / correlation_time) if ou else None
    q_walk = random_walk**2 * dt if walk else None
    gain = np.zeros((n, d))
    scale = np.zeros(n)
    trans = np.ones((n, d))
    p = np.zeros((d, d))  # predicted state covariance
    if ou:
        p[0, 0] = correlated**2
        trans[:-1, 0] = phi_ou
    r = white**2
    for k in range(n):
        s = float(p.sum()) + r
        kg = p.sum(axis=1) / s
        gain[k] = kg
        scale[k] = np.sqrt(s)
        p = p - np.outer(kg, kg) * s
        if k + 1 < n:
            f = trans[k]
            p = p * np.outer(f, f)
            if ou:
                p[0, 0] += q_ou[k]
            if walk:
                p[-1, -1] += q_walk[k]
    return InnovationFilter(gain=gain, scale=scale, transition=trans, offset=walk, white=float(white))

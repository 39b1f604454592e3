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

DENSE_ROWS = 1000  # up to this many readings the whitening is applied as a dense triangular matrix (8 MB)


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
        if n <= DENSE_ROWS:
            return (self.matrix() @ flat).reshape(values.shape)
        return self._recursion(flat).reshape(values.shape)

    def matrix(self):
        """L^{-1} as a dense lower-triangular matrix (formed once; grids up to ``DENSE_ROWS`` readings)."""
        found = self.__dict__.get("_matrix")
        if found is None:
            found = self._recursion(np.eye(self.scale.size))
            object.__setattr__(self, "_matrix", found)
        return found

    def _recursion(self, flat):
        """The filter run over the readings, all columns at once: O(n) steps."""
        n = flat.shape[0]
        out = np.empty_like(flat)
        state = np.zeros((self.n_states, flat.shape[1]))
        gain, scale, trans = self.gain, self.scale, self.transition
        for k in range(n):
            err = flat[k] - state.sum(axis=0)
            out[k] = err / scale[k]
            state += gain[k][:, None] * err[None, :]
            state *= trans[k][:, None]
        return out

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
    if ou:
        trans[:-1, 0] = phi_ou
    # predicted covariance of (u, b) as scalars (a 2 x 2 symmetric matrix; absent states stay 0)
    puu, pub, pbb = (correlated**2 if ou else 0.0), 0.0, 0.0
    r = white**2
    f = trans[:, 0].tolist() if ou else [1.0] * n
    qo = q_ou.tolist() if ou else [0.0] * n
    qw = q_walk.tolist() if walk else [0.0] * n
    for k in range(n):
        s = puu + 2.0 * pub + pbb + r
        ku, kb = (puu + pub) / s, (pub + pbb) / s
        gain[k] = [g for g, on in ((ku, ou), (kb, walk)) if on]
        scale[k] = s
        puu, pub, pbb = puu - ku * ku * s, pub - ku * kb * s, pbb - kb * kb * s
        if k + 1 < n:
            puu = f[k] * f[k] * puu + qo[k]
            pub = f[k] * pub
            pbb = pbb + qw[k]
    return InnovationFilter(gain=gain, scale=np.sqrt(scale), transition=trans, offset=walk, white=float(white))

"""Gaussian Markov random field priors on log EI (and spring log-stiffnesses).

The prior on the latent field eta = log EI (one value per element) is

    eta ~ N(eta_0, Q^{-1}),  Q = tau D^T D + I / marginal_std^2,

with D the first- or second-difference operator (the paper's GMRF, eq.
gmrf) and a weak marginal log-normal component that keeps Q invertible
where the data are silent.  tau = 1 / smoothness_std^2 in the
parameterisation below.  Spring log-stiffnesses get independent normal
priors centred on the configured stiffness.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sparse

from .._validation import as_float

__all__ = ["GMRFPrior", "difference_operator"]


def difference_operator(n, order):
    """Sparse (n - order) x n difference matrix of the given order (1 or 2)."""
    if order not in (1, 2):
        from .._errors import ConfigError

        raise ConfigError(f"The 'order' parameter of GMRFPrior must be 1 or 2. Got {order!r} instead.")
    if n <= order:
        return sparse.csr_matrix((0, n))
    if order == 1:
        return sparse.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n), format="csr")
    return sparse.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2],
                        shape=(n - 2, n), format="csr")


@dataclass(frozen=True)
class GMRFPrior:
    """Prior on (log EI per element, log spring stiffnesses).

    Parameters
    ----------
    order : int
        1 (first differences, piecewise-flat fields) or 2 (second
        differences, smooth fields).
    smoothness_std : float
        Standard deviation of one difference of log EI; tau = 1 / smoothness_std^2.
    marginal_std : float
        Standard deviation of log EI about the nominal in each element (the
        proper component; 0.5 means about a factor 1.65 either way).
    spring_std : float
        Standard deviation of each spring log-stiffness.
    """

    order: int = 1
    smoothness_std: float = 0.1
    marginal_std: float = 0.5
    spring_std: float = 1.0

    def __post_init__(self):
        if self.order not in (1, 2):
            difference_operator(3, self.order)
        for name in ("smoothness_std", "marginal_std", "spring_std"):
            object.__setattr__(self, name, as_float(getattr(self, name), name, "GMRFPrior",
                                                    low=0.0, low_open=True))

    @property
    def tau(self):
        """Precision of one difference, 1 / smoothness_std^2."""
        return 1.0 / self.smoothness_std**2

    def structure(self, n_elements):
        """D^T D (dense), the roughness structure of the GMRF."""
        d = difference_operator(n_elements, self.order)
        return (d.T @ d).toarray()

    def precision(self, n_elements, n_springs=0, *, tau=None):
        """Prior precision of (log EI, log k), dense (n_params, n_params)."""
        tau = self.tau if tau is None else tau
        q = np.zeros((n_elements + n_springs, n_elements + n_springs))
        q[:n_elements, :n_elements] = tau * self.structure(n_elements)
        q[np.arange(n_elements), np.arange(n_elements)] += 1.0 / self.marginal_std**2
        q[np.arange(n_elements, n_elements + n_springs), np.arange(n_elements, n_elements + n_springs)] = (
            1.0 / self.spring_std**2)
        return q

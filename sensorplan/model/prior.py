"""Gaussian Markov random field priors on log EI (and spring log-stiffnesses).

The prior on the latent field eta = log EI (one value per element) is

    eta ~ N(eta_0, Q^{-1}),  Q = tau D^T D + I / marginal_std^2,

with D the first- or second-difference operator (the paper's GMRF, eq.
gmrf) and a weak marginal log-normal component that keeps Q invertible
where the data are silent.  tau = 1 / smoothness_std^2 in the
parameterisation below.  Spring log-stiffnesses get independent normal
priors centred on the configured stiffness.

The overall level of the field is an unknown of its own: eta = eta_0 +
l 1 + delta with l ~ N(0, level_std^2) and delta of the GMRF above.  Without
it the mean of n elements' log EI has the prior std marginal_std / sqrt(n)
(0.09 for 30 elements at 0.5): a nominal EI off by 2x as a whole would be
held near the nominal and the error pushed into springs or sensor gains.
Marginalising l keeps one parameter per element; since D 1 = 0 the
precision is, by Woodbury,

    Q = tau D^T D + I / m^2 - c 1 1^T,  c = m^-4 / (level_std^-2 + n m^-2),

(m = marginal_std), a rank-one change of the fixed part alone.

:class:`HyperPrior` is the prior of the two hyperparameters of the
inversion: a log-normal (or penalised-complexity) prior on the smoothness
std sigma = tau^{-1/2} and a log-normal prior on the noise scale alpha.
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sparse

from .._errors import ConfigError
from .._validation import as_float

__all__ = ["GMRFPrior", "HyperPrior", "difference_operator"]


def difference_operator(n, order):
    """Sparse (n - order) x n difference matrix of the given order (1 or 2)."""
    if order not in (1, 2):
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
    level_std : float
        Standard deviation of the overall level of log EI, a factor common
        to every element on top of ``marginal_std`` (1.0: the nominal EI as
        a whole is right within a factor e at one standard deviation).  0
        leaves the level to the elements' own prior (std
        ``marginal_std / sqrt(n)`` for n elements).
    """

    order: int = 1
    smoothness_std: float = 0.1
    marginal_std: float = 0.5
    spring_std: float = 1.0
    level_std: float = 1.0

    def __post_init__(self):
        if self.order not in (1, 2):
            difference_operator(3, self.order)
        for name in ("smoothness_std", "marginal_std", "spring_std"):
            object.__setattr__(self, name, as_float(getattr(self, name), name, "GMRFPrior",
                                                    low=0.0, low_open=True))
        object.__setattr__(self, "level_std", as_float(self.level_std, "level_std", "GMRFPrior", low=0.0))

    @property
    def tau(self):
        """Precision of one difference, 1 / smoothness_std^2."""
        return 1.0 / self.smoothness_std**2

    def structure(self, n_elements):
        """D^T D (dense), the roughness structure of the GMRF."""
        d = difference_operator(n_elements, self.order)
        return (d.T @ d).toarray()

    def ei_fixed_precision(self, n_elements):
        """The tau-free part of log EI's prior precision: I / marginal_std^2 - c 1 1^T (the level, see the module)."""
        inverse = 1.0 / self.marginal_std**2
        q = np.eye(n_elements) * inverse
        if self.level_std > 0.0 and n_elements:
            q -= inverse**2 / (1.0 / self.level_std**2 + n_elements * inverse)
        return q

    def precision(self, n_elements, n_springs=0, *, tau=None):
        """Prior precision of (log EI, log k), dense (n_params, n_params)."""
        tau = self.tau if tau is None else tau
        q = np.zeros((n_elements + n_springs, n_elements + n_springs))
        q[:n_elements, :n_elements] = tau * self.structure(n_elements) + self.ei_fixed_precision(n_elements)
        q[np.arange(n_elements, n_elements + n_springs), np.arange(n_elements, n_elements + n_springs)] = (
            1.0 / self.spring_std**2)
        return q


@dataclass(frozen=True)
class HyperPrior:
    """Prior of the hyperparameters tau (prior precision scale) and alpha (noise scale).

    The smoothness std sigma = tau^{-1/2} (the std of one difference of
    log EI) has one of two priors, both with the scale U (``smoothness_scale``,
    by default the GMRFPrior's ``smoothness_std``, see :meth:`for_prior`):

    * ``family="lognormal"`` (default): log sigma ~ N(log U, s^2) with
      s = ``smoothness_log_std``: the configured smoothness is the prior
      median and right within a factor e^s at one standard deviation.  Its
      tails in log tau are Gaussian: where the data say little about tau (one
      crossing, high noise) the mixture over tau is as wide as the stated
      belief and no wider, and the flat field (tau -> infinity) is ruled out
      a priori.
    * ``family="pc"``: the penalised-complexity prior of Simpson et al.
      (2017, Statist. Sci. 32(1), eq. 3.3), exponential p(sigma) =
      lambda exp(-lambda sigma) with P(sigma > U) = ``smoothness_tail``.  It
      shrinks towards the flat field at a constant rate and its tail in
      log tau decays only like tau^{-1/2}: robust when the configured
      smoothness is far off, but with weak data its mixture over tau is
      wider than a truth of the configured smoothness needs (95 % bands
      covering about 0.98).

    log alpha ~ N(0, ``noise_log_std``^2): the configured noise is right
    within a factor exp(noise_log_std) at one standard deviation.

    Parameters
    ----------
    smoothness_scale : float, optional
        U, the prior median of sigma (lognormal) or the scale of the PC
        prior; defaults to the GMRFPrior's ``smoothness_std``.
    smoothness_tail : float
        P(sigma > U) under the PC prior (0.5 makes U the median).
    noise_log_std : float
        Standard deviation of log alpha.
    family : {"lognormal", "pc"}
    smoothness_log_std : float
        Standard deviation of log sigma under the log-normal prior.
    """

    smoothness_scale: float | None = None
    smoothness_tail: float = 0.5
    noise_log_std: float = 1.0
    family: str = "lognormal"
    smoothness_log_std: float = 0.5

    def __post_init__(self):
        if self.smoothness_scale is not None:
            object.__setattr__(self, "smoothness_scale", as_float(
                self.smoothness_scale, "smoothness_scale", "HyperPrior", low=0.0, low_open=True))
        tail = as_float(self.smoothness_tail, "smoothness_tail", "HyperPrior", low=0.0, low_open=True)
        if tail >= 1.0:
            raise ConfigError(f"The 'smoothness_tail' parameter of HyperPrior must be a probability in (0, 1). "
                              f"Got {self.smoothness_tail!r} instead.")
        object.__setattr__(self, "smoothness_tail", tail)
        for name in ("noise_log_std", "smoothness_log_std"):
            object.__setattr__(self, name, as_float(getattr(self, name), name, "HyperPrior", low=0.0,
                                                    low_open=True))
        if self.family not in ("lognormal", "pc"):
            raise ConfigError(f"The 'family' parameter of HyperPrior must be 'lognormal' or 'pc'. "
                              f"Got {self.family!r} instead.")

    def for_prior(self, prior):
        """This hyperprior with the scale taken from ``prior.smoothness_std`` where not given."""
        if self.smoothness_scale is not None:
            return self
        return dataclasses.replace(self, smoothness_scale=prior.smoothness_std)

    @property
    def rate(self):
        """lambda = -log(smoothness_tail) / smoothness_scale of the PC prior [1/std]."""
        return -math.log(self.smoothness_tail) / self._scale()

    def log_density_log_tau(self, log_tau):
        """log p(log tau): the prior of sigma = exp(-log_tau / 2) with its Jacobian."""
        log_tau = np.asarray(log_tau, dtype=float)
        if self.family == "lognormal":  # log sigma = -log tau / 2 is normal; |d log sigma / d log tau| = 1/2
            s = self.smoothness_log_std
            z = (-0.5 * log_tau - math.log(self._scale())) / s
            return -0.5 * z**2 - math.log(2.0 * s * math.sqrt(2.0 * math.pi))
        lam = self.rate
        sigma = np.exp(-0.5 * log_tau)
        return math.log(0.5 * lam) + np.log(sigma) - lam * sigma

    def sample_smoothness(self, rng, size=None):
        """Draws of the smoothness std sigma from this hyperprior (``rng``: numpy Generator or seed)."""
        rng = np.random.default_rng(rng)
        if self.family == "lognormal":
            return self._scale() * np.exp(self.smoothness_log_std * rng.standard_normal(size))
        return rng.exponential(1.0 / self.rate, size)

    def _scale(self):
        if self.smoothness_scale is None:
            raise ConfigError("HyperPrior.smoothness_scale is not set; use HyperPrior.for_prior(prior).")
        return self.smoothness_scale

    def log_density_log_noise(self, log_noise_scale):
        """log p(log alpha), the normal density of log alpha."""
        s = self.noise_log_std
        z = np.asarray(log_noise_scale, dtype=float) / s
        return -0.5 * z**2 - math.log(s * math.sqrt(2.0 * math.pi))

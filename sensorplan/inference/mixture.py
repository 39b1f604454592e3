"""Gaussian mixtures: the posterior when the hyperparameters are integrated out.

Each component is the Laplace posterior N(theta_k, C_k) at one node
(tau_k, alpha_k) of the quadrature over log tau, with weight w_k.  Marginal
quantiles are found per element by solving the mixture CDF
sum_k w_k Phi((x - m_k) / s_k) = p (vectorised safeguarded Newton); where a
single Gaussian is needed, the mean and covariance are moment-matched.

Owns: GaussianMixture, mixture_quantile.  May import: the foundations.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import special

from .._errors import ConfigError

__all__ = ["GaussianMixture", "mixture_quantile"]


def _cdf_pdf(x, weights, means, stds):
    z = (x[None] - means) / stds
    cdf = np.tensordot(weights, special.ndtr(z), axes=1)
    pdf = np.tensordot(weights, np.exp(-0.5 * z**2) / (stds * np.sqrt(2.0 * np.pi)), axes=1)
    return cdf, pdf


def mixture_quantile(weights, means, stds, probability):
    """Quantile of each column of a 1-D Gaussian mixture.

    Parameters
    ----------
    weights : ndarray (K,)
        Component weights (sum 1).
    means, stds : ndarray (K, n)
        Component means and standard deviations of n independent columns.
    probability : float
        In (0, 1).

    Returns
    -------
    ndarray (n,)
        x with sum_k w_k Phi((x - m_k) / s_k) = probability per column, to
        machine precision.  The component quantiles bracket the root; the
        iteration is Newton, falling back to bisection when a step leaves the
        bracket.
    """
    weights = np.asarray(weights, dtype=float)
    means = np.atleast_2d(np.asarray(means, dtype=float))
    stds = np.maximum(np.atleast_2d(np.asarray(stds, dtype=float)), 1e-300)
    component = means + stds * special.ndtri(probability)
    lo, hi = component.min(axis=0), component.max(axis=0)
    if weights.size == 1:
        return component[0]
    x = np.tensordot(weights, component, axes=1)
    scale = np.maximum(hi - lo, 1e-300)
    active = np.arange(x.size)  # columns still iterating (each column's root is found independently)
    for _ in range(200):
        cols = active
        xa = x[cols]
        cdf, pdf = _cdf_pdf(xa, weights, means[:, cols], stds[:, cols])
        below = cdf < probability
        lo[cols] = np.where(below, xa, lo[cols])
        hi[cols] = np.where(below, hi[cols], xa)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = xa - (cdf - probability) / pdf
        # a Newton step onto the bracket's end is kept: at the root the step is zero and x is an end
        # (a strict test would bisect away from the converged root)
        inside = np.isfinite(newton) & (newton >= lo[cols]) & (newton <= hi[cols])
        new = np.where(inside, newton, 0.5 * (lo[cols] + hi[cols]))
        done = np.abs(new - xa) <= 1e-13 * scale[cols] + 1e-15 * np.abs(xa)
        x[cols] = new
        active = cols[~done]
        if not active.size:
            break
    return x


@dataclass(frozen=True, eq=False)
class GaussianMixture:
    """A Gaussian mixture over the parameters: one component per node of the quadrature over log tau.

    Attributes
    ----------
    weights : ndarray (K,)
        Normalised weights: the hyper-posterior mass of each node of log tau.
    thetas : ndarray (K, n_params)
        Component means (the MAP at each node).
    covariances : ndarray (K, n_params, n_params)
        Component (Laplace) covariances.
    taus : ndarray (K,)
        The node's prior precision scale tau.
    noise_scales : ndarray (K,)
        The node's noise scale alpha (its conditional mode).
    """

    weights: np.ndarray
    thetas: np.ndarray
    covariances: np.ndarray
    taus: np.ndarray
    noise_scales: np.ndarray

    @classmethod
    def single(cls, theta, covariance, tau, noise_scale):
        """The one-component mixture of a point estimate of the hyperparameters."""
        return cls(np.ones(1), np.asarray(theta, dtype=float)[None], np.asarray(covariance, dtype=float)[None],
                   np.array([float(tau)]), np.array([float(noise_scale)]))

    @property
    def n_components(self):
        return self.weights.size

    @property
    def log_tau(self):
        """Nodes of the hyper-posterior of log tau (its mass at each node is ``weights``)."""
        return np.log(self.taus)

    @cached_property
    def mean(self):
        """Mixture mean of the parameters."""
        return self.weights @ self.thetas

    @cached_property
    def covariance(self):
        """Moment-matched covariance: sum_k w_k (C_k + (m_k - m)(m_k - m)^T)."""
        d = self.thetas - self.mean
        cov = np.tensordot(self.weights, self.covariances, axes=1) + (d.T * self.weights) @ d
        return 0.5 * (cov + cov.T)

    @cached_property
    def component_stds(self):
        """Standard deviations of each parameter in each component, shape (K, n_params)."""
        return np.sqrt(np.clip(np.diagonal(self.covariances, axis1=1, axis2=2), 0.0, None))

    def quantile(self, probability, index=slice(None)):
        """Marginal quantile of the parameters ``index`` (exact for the mixture)."""
        if not 0.0 < probability < 1.0:
            raise ConfigError(f"The 'probability' parameter must be in (0, 1). Got {probability!r} instead.")
        return mixture_quantile(self.weights, self.thetas[:, index], self.component_stds[:, index], probability)

    def cdf(self, values, index=slice(None)):
        """Marginal P(theta_i <= values_i) of the parameters ``index`` (exact for the mixture)."""
        stds = np.maximum(self.component_stds[:, index], 1e-300)
        return _cdf_pdf(np.asarray(values, float), self.weights, self.thetas[:, index], stds)[0]

    def linear_cdf(self, coefficients, value):
        """P(coefficients . theta <= value) under the mixture."""
        a = np.asarray(coefficients, dtype=float)
        means = self.thetas[:, : a.size] @ a
        var = np.einsum("i,kij,j->k", a, self.covariances[:, : a.size, : a.size], a)
        z = (value - means) / np.sqrt(np.maximum(var, 1e-300))
        return float(self.weights @ special.ndtr(z))

    def sample(self, rng, size, index=slice(None)):
        """``size`` draws of the parameters ``index``, shape (size, n)."""
        rng = np.random.default_rng(rng)
        counts = rng.multinomial(size, self.weights)
        draws = [rng.multivariate_normal(self.thetas[k, index], self.covariances[k][index, index], size=c,
                                         method="eigh") for k, c in enumerate(counts) if c]
        out = np.concatenate(draws)
        return out[rng.permutation(size)]

"""Fits of the joint model with its hyperparameters integrated out (as ``invert`` fits), and warm starts.

Owns: :class:`IntegratedModel`, :func:`integrated_fit`, :func:`blocks_of`, :func:`warm_start`.
May import: inference and the model layer.
"""

import math
from dataclasses import dataclass

import numpy as np

from ...inference.hyperposterior import integrate_problem
from ...model.prior import HyperPrior

__all__ = ["IntegratedModel", "blocks_of", "integrated_fit", "warm_start"]


@dataclass(frozen=True, eq=False)
class IntegratedModel:
    """A model fitted with its hyperparameters integrated out, as ``invert`` does."""

    problem: object
    mixture: object
    noise_scale: float  # at the mode of the hyper-posterior
    tau: float
    theta_mode: np.ndarray  # MAP at the mode
    converged: bool

    def band(self, probability=0.95):
        """(low, high) of every parameter, from the mixture's quantiles."""
        a = 0.5 * (1.0 - probability)
        return self.mixture.quantile(a), self.mixture.quantile(1.0 - a)


def integrated_fit(problem, prior, *, start=None, noise_scale=1.0, tau=None):
    """The problem fitted as ``invert`` fits (hyperparameters integrated under the default hyperprior).

    Each node of the tau grid is solved to a Newton decrement of ~0.01
    (log-density units), as the quick fits and the hyper-posterior's own
    node tolerance; Gauss-Newton gets 10 evaluations (a node that converges
    at all does so in <= 8 here) before Levenberg-Marquardt takes over: on
    grossly misfitting data (a sign-flipped sensor, position offsets next to
    a settled bearing) Gauss-Newton crawls, and Levenberg-Marquardt to that
    decrement takes 10-30 evaluations.
    """
    hyperprior = HyperPrior().for_prior(prior)
    fit = integrate_problem(problem, problem.rough, problem.fixed, problem.theta0, hyperprior,
                            noise_scale=noise_scale, tau=prior.tau if tau is None else tau, start=start,
                            max_iter=40, tol=0.02 / max(problem.n_data, 1), gauss_newton_max_iter=10, atol=0.01,
                            secant=True)
    mix = fit.mixture
    top = int(np.argmax(mix.weights))
    return IntegratedModel(problem, mix, float(fit.noise_scale_mode), float(math.exp(fit.log_tau_mode)),
                           np.array(mix.thetas[top]), bool(fit.converged))


def blocks_of(problem, theta):
    """The parameter vector as {"log_ei": ..., effect name: ...} (to warm-start a larger model)."""
    out = {"log_ei": theta[:problem.n_elements].copy()}
    for b, sl in zip(problem.blocks, problem.slices):
        out[b.name] = theta[sl].copy()
    return out


def warm_start(problem, blocks):
    """Start vector of ``problem`` from the blocks of a smaller model's fit (new blocks at their prior mean)."""
    theta = problem.theta0.copy()
    theta[:problem.n_elements] = blocks["log_ei"]
    for b, sl in zip(problem.blocks, problem.slices):
        if b.name in blocks and blocks[b.name].size == sl.stop - sl.start:
            theta[sl] = blocks[b.name]
    return theta

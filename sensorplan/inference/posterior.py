"""Posterior results of the Bayesian identification of EI(x)."""

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import stats

from .._errors import ConfigError

__all__ = ["PosteriorResult", "CrossingFit", "linear_gaussian_posterior"]


def linear_gaussian_posterior(jacobian, data, prior_mean, prior_precision, *, noise_std=1.0):
    """Exact posterior of y = A m + e, e ~ N(0, noise_std^2 I), m ~ N(m0, Q^{-1}).

    ``jacobian`` and ``data`` must already be whitened by the noise
    correlation.  Returns ``(mean, covariance, precision)`` (paper eq. qpost).
    """
    a = np.asarray(jacobian, dtype=float)
    precision = a.T @ a / noise_std**2 + prior_precision
    rhs = a.T @ np.asarray(data, dtype=float) / noise_std**2 + prior_precision @ prior_mean
    chol = np.linalg.cholesky(precision)
    mean = np.linalg.solve(chol.T, np.linalg.solve(chol, rhs))
    inv_chol = np.linalg.inv(chol)
    covariance = inv_chol.T @ inv_chol
    return mean, covariance, precision


@dataclass(frozen=True, eq=False)
class CrossingFit:
    """Data and model of one crossing after the inversion.

    ``model_std`` is the posterior standard deviation of the prediction
    (parameter uncertainty); ``noise_std`` is per sensor.
    """

    label: str
    positions: np.ndarray
    data: np.ndarray
    model: np.ndarray
    model_std: np.ndarray
    noise_std: np.ndarray

    def predictive_band(self, level=0.95):
        """Posterior predictive band of the readings, shape (2, n_sensors, n_loads)."""
        z = stats.norm.ppf(0.5 + level / 2)
        std = np.sqrt(self.model_std**2 + self.noise_std[:, None] ** 2)
        return np.stack([self.model - z * std, self.model + z * std])


@dataclass(frozen=True, eq=False)
class PosteriorResult:
    """Laplace (or exact Gaussian) posterior of log EI per element and spring log-stiffnesses.

    Attributes
    ----------
    edges : ndarray (n_elements + 1,)
        Element edges [m].
    theta : ndarray (n_params,)
        MAP of the parameters: log EI per element then log k per spring
        (or the compliance 1/EI for ``parameterisation="compliance"``).
    covariance : ndarray (n_params, n_params)
        Laplace covariance (exact in the linear-Gaussian case).
    ei_nominal : ndarray (n_elements,)
    spring_names : tuple of str
    spring_nominal : ndarray
    noise_std : ndarray (n_sensors,)
        Estimated noise standard deviation of each sensor.
    noise_scale : float
        Estimated multiplier of the configured noise.
    tau : float
        Prior precision of one difference of log EI.
    log_evidence : float
        Laplace log marginal likelihood at the hyperparameters.
    converged : bool
    n_iter : int
        Gauss-Newton / Levenberg-Marquardt iterations in total.
    excluded_crossings : tuple of str
    fits : tuple of CrossingFit
    """

    edges: np.ndarray
    theta: np.ndarray
    covariance: np.ndarray
    parameterisation: str
    ei_nominal: np.ndarray
    spring_names: tuple
    spring_nominal: np.ndarray
    sensor_names: tuple
    noise_std: np.ndarray
    noise_scale: float
    tau: float
    log_evidence: float
    converged: bool
    n_iter: int
    excluded_crossings: tuple = ()
    fits: tuple = ()
    hyper_method: str = "evidence"
    messages: tuple = field(default_factory=tuple)

    @property
    def n_elements(self):
        return self.ei_nominal.size

    @property
    def n_springs(self):
        return len(self.spring_names)

    @cached_property
    def std(self):
        """Posterior standard deviation of each parameter."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @cached_property
    def ei_map(self):
        """EI at the MAP [N m^2] (the posterior median of EI for log EI parameters)."""
        t = self.theta[: self.n_elements]
        return np.exp(t) if self.parameterisation == "log_ei" else 1.0 / t

    @cached_property
    def ei_mean(self):
        """Posterior mean of EI [N m^2]: exp(eta + var/2) for the log-normal posterior."""
        if self.parameterisation == "log_ei":
            return np.exp(self.theta[: self.n_elements] + 0.5 * self.std[: self.n_elements] ** 2)
        return self.ei_map

    def credible_interval(self, level=0.95, *, method="lognormal", rng=None, n_samples=20000):
        """Equal-tailed credible interval of EI per element, shape (n_elements, 2) [N m^2].

        Parameters
        ----------
        level : float
            Probability mass inside the interval, e.g. 0.75 or 0.95.
        method : {"lognormal", "delta", "sampling"}
            ``lognormal`` maps the Gaussian quantiles of the parameter
            through EI = exp(eta) (or 1/v); ``delta`` uses the delta method
            (EI +- z EI sd); ``sampling`` maps draws of the Gaussian posterior.
        """
        if not 0.0 < level < 1.0:
            raise ConfigError(f"The 'level' parameter must be in (0, 1). Got {level!r} instead.")
        n = self.n_elements
        z = stats.norm.ppf(0.5 + level / 2)
        t, s = self.theta[:n], self.std[:n]
        to_ei = np.exp if self.parameterisation == "log_ei" else (lambda v: 1.0 / v)
        if method == "lognormal":
            bounds = np.sort(np.stack([to_ei(t - z * s), to_ei(t + z * s)], axis=1), axis=1)
            return bounds
        if method == "delta":
            deriv = self.ei_map if self.parameterisation == "log_ei" else self.ei_map**2
            half = z * deriv * s
            return np.stack([self.ei_map - half, self.ei_map + half], axis=1)
        if method == "sampling":
            if rng is None:
                raise ConfigError("method='sampling' needs an rng (numpy Generator or seed).")
            rng = np.random.default_rng(rng)
            cov = self.covariance[:n, :n]
            draws = rng.multivariate_normal(t, cov, size=n_samples, method="eigh")
            values = to_ei(draws)
            return np.quantile(values, [0.5 - level / 2, 0.5 + level / 2], axis=0).T
        raise ConfigError(f"The 'method' parameter must be 'lognormal', 'delta' or 'sampling'. "
                          f"Got {method!r} instead.")

    def springs(self, level=0.95):
        """Spring stiffness MAP and interval: {name: {"map", "low", "high", "nominal"}}."""
        z = stats.norm.ppf(0.5 + level / 2)
        out = {}
        n = self.n_elements
        for i, name in enumerate(self.spring_names):
            t, s = self.theta[n + i], self.std[n + i]
            out[name] = {"map": float(np.exp(t)), "low": float(np.exp(t - z * s)),
                         "high": float(np.exp(t + z * s)), "nominal": float(self.spring_nominal[i])}
        return out

    def summary(self):
        lines = [f"Bayesian identification of EI: {self.n_elements} elements, {self.n_springs} springs, "
                 f"hyperparameters by {self.hyper_method}",
                 f"  converged: {self.converged} after {self.n_iter} iterations; log evidence "
                 f"{self.log_evidence:.3f}",
                 "  noise std: " + ", ".join(f"{n}={s:.3g}" for n, s in zip(self.sensor_names, self.noise_std))
                 + f" (scale {self.noise_scale:.3f} of configured); tau = {self.tau:.4g}"]
        if self.excluded_crossings:
            lines.append("  excluded crossings: " + ", ".join(self.excluded_crossings))
        ci = self.credible_interval(0.95)
        lines.append(f"  {'x_left':>8s} {'x_right':>8s} {'EI mean':>11s} {'95% low':>11s} {'95% high':>11s} "
                     f"{'nominal':>11s}  [N m^2]")
        for j in range(self.n_elements):
            lines.append(f"  {self.edges[j]:8.2f} {self.edges[j + 1]:8.2f} {self.ei_mean[j]:11.4e} "
                         f"{ci[j, 0]:11.4e} {ci[j, 1]:11.4e} {self.ei_nominal[j]:11.4e}")
        for name, s in self.springs().items():
            lines.append(f"  spring {name}: {s['map']:.4g} (95% {s['low']:.3g} to {s['high']:.3g}; "
                         f"nominal {s['nominal']:.3g})")
        return "\n".join(lines)

    def to_dict(self):
        """JSON-ready dictionary (units: m, N m^2, N/m, N m/rad, rad or m)."""
        return {
            "edges_m": self.edges.tolist(),
            "ei_mean": self.ei_mean.tolist(),
            "ei_ci75": self.credible_interval(0.75).tolist(),
            "ei_ci95": self.credible_interval(0.95).tolist(),
            "ei_nominal": self.ei_nominal.tolist(),
            "springs": self.springs(),
            "noise_std": dict(zip(self.sensor_names, map(float, self.noise_std))),
            "noise_scale": float(self.noise_scale),
            "tau": float(self.tau),
            "log_evidence": float(self.log_evidence),
            "converged": bool(self.converged),
            "n_iter": int(self.n_iter),
            "excluded_crossings": list(self.excluded_crossings),
            "hyperparameters": self.hyper_method,
            "units": {"edges_m": "m", "ei": "N m^2", "springs": "N m/rad (rotational), N/m (vertical)",
                      "noise_std": "rad (rotation) or m (deflection)"},
        }

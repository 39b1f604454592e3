"""Posterior results of the Bayesian identification of EI(x).

The posterior is a Gaussian mixture over the nodes of log tau
(:class:`~sensorplan.inference.mixture.GaussianMixture`; one component when
the hyperparameters are point estimates).  Intervals, standard deviations
and means are those of the mixture; ``theta`` and ``covariance`` are its
moment-matched mean and covariance.
"""

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import special

from .._errors import ConfigError
from ..verdict import Verdict
from .hyperposterior import BOUND_MASS
from .mixture import GaussianMixture

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
    (parameter uncertainty); ``noise_std`` is per sensor; ``times`` the
    readings' times when the crossing carries them.
    """

    label: str
    positions: np.ndarray
    data: np.ndarray
    model: np.ndarray
    model_std: np.ndarray
    noise_std: np.ndarray
    times: np.ndarray | None = field(default=None, kw_only=True)

    def predictive_band(self, level=0.95):
        """Posterior predictive band of the readings, shape (2, n_sensors, n_loads)."""
        z = special.ndtri(0.5 + level / 2)
        std = np.sqrt(self.model_std**2 + self.noise_std[:, None] ** 2)
        return np.stack([self.model - z * std, self.model + z * std])


@dataclass(frozen=True, eq=False)
class PosteriorResult:
    """Posterior of log EI per element and spring log-stiffnesses: a Laplace (or exact Gaussian) mixture.

    Attributes
    ----------
    edges : ndarray (n_elements + 1,)
        Element edges [m].
    theta : ndarray (n_params,)
        Log EI per element then log k per spring (or the compliance 1/EI
        for ``parameterisation="compliance"``): the MAP for a point estimate
        of the hyperparameters, the mixture mean when they are integrated.
    covariance : ndarray (n_params, n_params)
        Laplace covariance (exact in the linear-Gaussian case), moment-matched
        over the mixture when the hyperparameters are integrated.
    ei_nominal : ndarray (n_elements,)
    spring_names : tuple of str
    spring_nominal : ndarray
    noise_std : ndarray (n_sensors,)
        Estimated noise standard deviation of each sensor.
    noise_scale : float
        Estimated multiplier of the configured noise (its posterior mean
        when integrated).
    tau : float
        Prior precision of one difference of log EI (the mode of its
        hyper-posterior when integrated).
    log_evidence : float
        Laplace log marginal likelihood at the hyperparameters; when they
        are integrated, log p(y) with the hyperparameters integrated over
        their prior.
    converged : bool
    n_iter : int
        Gauss-Newton / Levenberg-Marquardt iterations in total.
    excluded_crossings : tuple of str
    fits : tuple of CrossingFit
    hyper_method : str
    messages : tuple of str
        Convergence messages.
    mixture : GaussianMixture
        The posterior: weights, component means and covariances, and the
        nodes (tau, alpha) of the hyper-posterior.
    tau_mass_at_bound : float
        Hyper-posterior mass of the end nodes of the log tau grid that were
        cut by its hard bounds (0 when the grid ended on negligible weight).
    warnings : tuple of str
        Reasons not to trust the fit (see :mod:`sensorplan.inference.checks`).
    damage : DamageDetection or None
        The damage detector's verdict on the same data (:func:`sensorplan.detect_damage`).
    damage_probability : float or None
        Posterior probability of a local loss with sharp edges somewhere on
        the bridge; the bands average over those hypotheses
        (:mod:`sensorplan.inference.damage`).
    hyper_nodes : GaussianMixture or None
        The mixture over the nodes of log tau alone (before the damage
        hypotheses were added).
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
    mixture: GaussianMixture | None = None
    tau_mass_at_bound: float = 0.0
    warnings: tuple = field(default_factory=tuple)
    damage: object = None
    damage_probability: float | None = None
    hyper_nodes: GaussianMixture | None = None
    sensor_kinds: tuple = ()  # "rotation" / "deflection" per sensor (engineering units in the summary)
    verdict: Verdict | None = None

    def __post_init__(self):
        if self.mixture is None:
            object.__setattr__(self, "mixture", GaussianMixture.single(self.theta, self.covariance, self.tau,
                                                                       self.noise_scale))
        if self.hyper_nodes is None:
            object.__setattr__(self, "hyper_nodes", self.mixture)

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

    @property
    def tau_at_bound(self):
        """True when hyper-posterior mass of tau reaches a hard end of its grid (it should not)."""
        return self.tau_mass_at_bound > BOUND_MASS

    @cached_property
    def ei_mean(self):
        """Posterior mean of EI [N m^2]: sum_k w_k exp(eta_k + s_k^2/2) over the log-normal components."""
        n = self.n_elements
        if self.parameterisation == "log_ei":
            mix = self.mixture
            return mix.weights @ np.exp(mix.thetas[:, :n] + 0.5 * mix.component_stds[:, :n] ** 2)
        return self.ei_map

    def _quantiles(self, level, index):
        """Lower and upper equal-tailed quantiles of the parameters ``index`` under the posterior."""
        mix = self.mixture
        if mix.n_components == 1:
            z = special.ndtri(0.5 + level / 2)
            t, s = mix.thetas[0, index], mix.component_stds[0, index]
            return t - z * s, t + z * s
        return mix.quantile(0.5 - level / 2, index), mix.quantile(0.5 + level / 2, index)

    def credible_interval(self, level=0.95, *, method="lognormal", rng=None, n_samples=20000):
        """Equal-tailed credible interval of EI per element, shape (n_elements, 2) [N m^2].

        Parameters
        ----------
        level : float
            Probability mass inside the interval, e.g. 0.75 or 0.95.
        method : {"lognormal", "delta", "sampling"}
            ``lognormal`` maps the quantiles of the parameter (those of the
            Gaussian mixture, per element) through EI = exp(eta) (or 1/v);
            ``delta`` uses the delta method on the moment-matched Gaussian
            (EI +- z EI sd); ``sampling`` maps draws of the posterior mixture.
        """
        if not 0.0 < level < 1.0:
            raise ConfigError(f"The 'level' parameter must be in (0, 1). Got {level!r} instead.")
        n = self.n_elements
        z = special.ndtri(0.5 + level / 2)
        s = self.std[:n]
        to_ei = np.exp if self.parameterisation == "log_ei" else (lambda v: 1.0 / v)
        if method == "lognormal":
            low, high = self._quantiles(level, slice(0, n))
            return np.sort(np.stack([to_ei(low), to_ei(high)], axis=1), axis=1)
        if method == "delta":
            deriv = self.ei_map if self.parameterisation == "log_ei" else self.ei_map**2
            half = z * deriv * s
            return np.stack([self.ei_map - half, self.ei_map + half], axis=1)
        if method == "sampling":
            if rng is None:
                raise ConfigError("method='sampling' needs an rng (numpy Generator or seed).")
            draws = self.mixture.sample(rng, n_samples, slice(0, n))
            values = to_ei(draws)
            return np.quantile(values, [0.5 - level / 2, 0.5 + level / 2], axis=0).T
        raise ConfigError(f"The 'method' parameter must be 'lognormal', 'delta' or 'sampling'. "
                          f"Got {method!r} instead.")

    def springs(self, level=0.95):
        """Spring stiffness and interval: {name: {"map", "low", "high", "nominal"}}.

        "map" is exp of ``theta`` (the MAP, or the mixture mean of log k).
        """
        out = {}
        n = self.n_elements
        low, high = self._quantiles(level, slice(n, n + self.n_springs))
        for i, name in enumerate(self.spring_names):
            out[name] = {"map": float(np.exp(self.theta[n + i])), "low": float(np.exp(low[i])),
                         "high": float(np.exp(high[i])), "nominal": float(self.spring_nominal[i])}
        return out

    def _detector_lines(self):
        """The detector's lines, its loss estimate only where the verdict concludes a local loss."""
        lines = self.damage.summary().splitlines()
        if self.damage.detected and (self.verdict is None or self.verdict.status != "local_damage"):
            lines = [lines[0], f"  statistic above its threshold, but no loss is concluded: see the verdict "
                               f"({self.verdict.status if self.verdict else 'none'})"]
        return lines

    def summary(self):
        how = "integrated out" if self.hyper_method == "integrated" else f"by {self.hyper_method}"
        lines = [f"Bayesian identification of EI: {self.n_elements} elements, {self.n_springs} springs, "
                 f"hyperparameters {how}",
                 f"  converged: {self.converged} after {self.n_iter} iterations; log evidence "
                 f"{self.log_evidence:.3f}",
                 "  noise std: " + ", ".join(f"{n}={_engineering(s, k)}" for n, s, k in
                                             zip(self.sensor_names, self.noise_std,
                                                 self.sensor_kinds or (None,) * len(self.sensor_names)))
                 + f" (scale {self.noise_scale:.3f} of configured); tau = {self.tau:.4g}"]
        mix = self.hyper_nodes
        if mix.n_components > 1:
            cdf = np.cumsum(mix.weights)
            lo, hi = mix.taus[np.searchsorted(cdf, 0.025)], mix.taus[min(np.searchsorted(cdf, 0.975), cdf.size - 1)]
            lines.append(f"  tau integrated over {mix.n_components} nodes: mode {self.tau:.4g}, 95 % of the "
                         f"hyper-posterior in [{lo:.3g}, {hi:.3g}]; mass at the grid ends "
                         f"{self.tau_mass_at_bound:.1e}")
        if self.verdict is not None:
            lines.insert(0, f"VERDICT ({self.verdict.status}): {self.verdict.summary}")
        for text in self.warnings:
            lines.append(f"  WARNING: {text}")
        if self.damage is not None:
            lines += ["  " + line for line in self._detector_lines()]
        if self.damage_probability is not None:
            lines.append(f"  the bands average over local-loss hypotheses (posterior probability of a loss "
                         f"{self.damage_probability:.2f})")
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
            "hyper_posterior": {"log_tau": self.hyper_nodes.log_tau.tolist(),
                                "weights": self.hyper_nodes.weights.tolist(),
                                "noise_scale": self.hyper_nodes.noise_scales.tolist(),
                                "mass_at_bound": float(self.tau_mass_at_bound),
                                "at_bound": bool(self.tau_at_bound)},
            "warnings": list(self.warnings),
            "damage": None if self.damage is None else self.damage.to_dict(),
            "damage_probability": self.damage_probability,
            "verdict": None if self.verdict is None else self.verdict.to_dict(),
            "units": {"edges_m": "m", "ei": "N m^2", "springs": "N m/rad (rotational), N/m (vertical)",
                      "noise_std": "rad (rotation) or m (deflection)"},
        }


def _engineering(value, kind):
    """A reading's size in the unit an engineer reads: urad for tilt, mm for deflection (SI without a kind)."""
    if kind == "rotation":
        return f"{value * 1e6:.3g} µrad"
    if kind == "deflection":
        return f"{value * 1e3:.3g} mm"
    return f"{value:.3g}"

"""Bayesian identification of EI(x) (and spring stiffnesses) from crossings: :func:`invert`.

The model and its parameters are :class:`~.ei_problem.EIProblem` (whitened
data r = W (y - F(theta)) / std ~ N(0, alpha^2 I), GMRF prior
theta ~ N(theta_0, Q(tau)^{-1}), Q(tau) = tau S + F).

* MAP by Gauss-Newton with a Levenberg-Marquardt safeguard (the engine's
  :func:`~.engine.solve_map`): a step is accepted only if it lowers the
  negative log posterior, so every iterate decreases the objective.
* Laplace covariance H^{-1}, H = J^T J / alpha^2 + Q at the MAP; exact for
  the linear-Gaussian case.
* Hyperparameters integrated out (default, ``hyper="integrated"``): a
  log-normal (or PC) prior on tau^{-1/2} and a log-normal prior on alpha, alpha by Laplace,
  log tau by quadrature; the posterior is a Gaussian mixture
  (:mod:`.hyperposterior`).
* Or point estimates (:mod:`.laplace`): evidence maximisation (MacKay's fixed-point
  conditions alpha^2 = |r|^2 / (M - gamma), tau = gamma_tau / (d^T S d) of
  the Laplace evidence, interleaved with the MAP), quasi-optimality or GCV
  on the linearised problem, or fixed values.
* Local-loss hypotheses of the damage detector in the bands (:mod:`.damage`).
* Checks of the result (:mod:`.checks`): noise scale far from 1, tau at the
  end of its range, systematic residuals, each a SensorplanWarning.
"""

import warnings
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError, SensorplanWarning
from .._threads import single_threaded
from ..model.crossings import Crossings
from ..model.prior import GMRFPrior, HyperPrior
from ..verdict import inversion_verdict
from .checks import NOISE_SCALE_RANGE, RESIDUAL_LEVEL, fit_warnings, residual_dof, residual_p_values
from .damage import damage_hypotheses
from .detector import detect_damage
from .ei_problem import EIProblem, prior_matrices
from .hyperposterior import BOUND_MASS, LOG_TAU_BOUNDS, integrate_problem
from .laplace import fit_problem
from .mixture import GaussianMixture
from .posterior import PosteriorResult
from .screening import check_case_data_scale, screen_crossings

__all__ = ["invert", "HYPER_METHODS"]

HYPER_METHODS = ("integrated", "evidence", "fixed", "quasi-optimality", "gcv")


@dataclass(frozen=True, eq=False)
class _HyperFit:
    """The posterior mixture and the summary numbers of one hyperparameter method."""

    mixture: GaussianMixture
    noise_scale: float
    tau: float
    log_evidence: float
    converged: bool
    n_iter: int
    mass_at_bound: float  # tau mass at a hard end of its range (1.0 for a point estimate on a bound)
    flat_side: bool  # that end is the flat one (large tau)


def _fit(problem, prior, *, hyper, hyperprior, noise_scale, tau, start, max_iter, max_outer, tol):
    """The posterior of ``problem`` under ``prior`` by the hyperparameter method ``hyper``."""
    rough, fixed = prior_matrices(problem, prior)
    tau = prior.tau if tau is None else tau
    if hyper == "integrated":
        hyperprior = (HyperPrior() if hyperprior is None else hyperprior).for_prior(prior)
        fit = integrate_problem(problem, rough, fixed, problem.theta0, hyperprior, noise_scale=noise_scale,
                                tau=tau, start=start, max_iter=max_iter, tol=tol)
        mix = fit.mixture
        return _HyperFit(mix, float(mix.weights @ mix.noise_scales), float(np.exp(fit.log_tau_mode)),
                         fit.log_evidence, fit.converged, fit.n_iter, fit.mass_at_bound,
                         bool(mix.weights[-1] >= mix.weights[0]))
    fit = fit_problem(problem, rough, fixed, problem.theta0, hyper=hyper, noise_scale=noise_scale, tau=tau,
                      start=start, max_iter=max_iter, max_outer=max_outer, tol=tol)
    log_tau = float(np.log(fit.tau))
    lo, hi = LOG_TAU_BOUNDS
    on_bound = hyper != "fixed" and (log_tau <= lo + 1e-3 or log_tau >= hi - 1e-3)
    return _HyperFit(GaussianMixture.single(fit.theta, fit.covariance, fit.tau, fit.noise_scale), fit.noise_scale,
                     fit.tau, fit.log_evidence, fit.converged, fit.n_iter, float(on_bound), log_tau > 0.5 * (lo + hi))


@single_threaded
def invert(case, crossings, *, prior=None, estimate_springs=True, parameterisation="log_ei",
           hyper="integrated", hyperprior=None, noise_scale=1.0, tau=None, screen=True, mesh=None, start=None,
           max_iter=100, max_outer=200, tol=1e-10, check_scale=True, detect=True, false_alarm=0.05,
           nuisance="smooth", damage_prior=0.5, damage_log_std=0.5, rng=0):
    """Identify EI(x) (and spring stiffnesses) from measured crossings.

    Parameters
    ----------
    case : Case
        Model: bridge, nominal EI, vehicle, sensors, noise model.
    crossings : Crossings
        Data; sensor columns must be sensors of ``case``.
    prior : GMRFPrior, optional
        Prior on log EI and the spring log-stiffnesses (default ``GMRFPrior()``).
    estimate_springs : bool
        Estimate the elastic springs jointly (nuisance parameters).
    parameterisation : {"log_ei", "compliance"}
        ``compliance`` is the linear-Gaussian case of a determinate bridge.
    hyper : {"integrated", "evidence", "fixed", "quasi-optimality", "gcv"}
        How the noise scale and tau are treated: integrated out under ``hyperprior`` (the posterior is a Gaussian
        mixture over log tau), or point estimates (evidence maximisation, fixed values, quasi-optimality or GCV).
    hyperprior : HyperPrior, optional
        Prior of tau and the noise scale for ``"integrated"`` (default ``HyperPrior()``: log-normal prior with
        median smoothness_std and log std 0.5, log-normal noise scale).
    noise_scale, tau : float
        Start values (``fixed``: the values used).  ``tau`` defaults to the prior's.
    screen : bool
        Exclude crossings that do not match the others (with a warning).
    mesh, start : Mesh, array_like, optional
        Inversion mesh (default: the case's) and start parameters (default: the nominal).
    check_scale : bool or str
        Refuse data far off the model's scale (a unit slip); a string names the data source in the message.
    detect : bool
        Run the damage detector (:func:`sensorplan.detect_damage`) on the data and let the bands average
        over local-loss hypotheses (:mod:`sensorplan.inference.damage`; log-EI parameterisation).
    false_alarm, nuisance, rng : the detector's false-alarm rate, nuisance and seed (or Generator).
    damage_prior : float
        Prior probability of a local loss somewhere, in the band averaging.
    damage_log_std : float
        Std of the half-normal prior of a loss's step in log EI (0.5: a 39 % loss at one std); the proper
        prior makes every loss hypothesis pay its Occam factor.

    Returns
    -------
    PosteriorResult
        With ``warnings`` (also emitted as SensorplanWarning) when the fit is not to be trusted: noise scale outside
        [0.5, 2], tau at the end of its range, or systematic residuals.
    """
    crossings, excluded = _checked_data(case, crossings, hyper=hyper, check_scale=check_scale, screen=screen, mesh=mesh)
    prior = GMRFPrior() if prior is None else prior
    problem = EIProblem(case, crossings, estimate_springs=estimate_springs and bool(case.bridge.spring_names),
                        parameterisation=parameterisation, mesh=mesh)
    fit = _fit(problem, prior, hyper=hyper, hyperprior=hyperprior, noise_scale=noise_scale, tau=tau, start=start,
               max_iter=max_iter, max_outer=max_outer, tol=tol)
    mixture, detection, probability = fit.mixture, None, None
    if detect and parameterisation == "log_ei":
        detection = detect_damage(problem.inversion_case, crossings, false_alarm=false_alarm, nuisance=nuisance, rng=rng)
        mixture, probability = _with_damage(mixture, problem, prior, detection, damage_prior, damage_log_std)
    return _posterior(problem, fit, mixture, hyper=hyper, excluded=excluded, detection=detection, prior=prior,
                      probability=probability, detector_run=detect and parameterisation == "log_ei")


def _checked_data(case, crossings, *, hyper, check_scale, screen, mesh):
    """The options and data checked, and the crossings kept by the screening with the labels it excluded."""
    if hyper not in HYPER_METHODS:
        raise ConfigError(f"The 'hyper' parameter must be one of {HYPER_METHODS}. Got {hyper!r} instead.")
    if not isinstance(crossings, Crossings):
        raise DataError("The 'crossings' parameter must be a Crossings object (see read_crossings).")
    if check_scale:
        check_case_data_scale(case, crossings, source=check_scale if isinstance(check_scale, str) else "data")
    excluded = ()
    if screen and len(crossings) >= 2:
        crossings, excluded, reasons = screen_crossings(crossings)
        for label, reason in zip(excluded, reasons):  # stacklevel: the caller of invert (through its decorator)
            warnings.warn(f"crossing '{label}' excluded: {reason}", SensorplanWarning, stacklevel=3)
    if mesh is not None:
        mesh.check_fits(case.bridge)
    return crossings, excluded


def _posterior(problem, fit, mixture, *, hyper, excluded, detection, probability, prior, detector_run=True):
    """The result of :func:`invert`, its convergence and trust warnings emitted."""
    theta, covariance, alpha = mixture.mean, mixture.covariance, fit.noise_scale
    messages = []
    if not fit.converged:
        messages.append("the MAP or the hyperparameter iteration did not converge")
        warnings.warn("sensorplan invert: the Gauss-Newton / evidence iteration did not converge; "
                      "results are reported with converged = false.", SensorplanWarning, stacklevel=3)
    fits = problem.fits(theta, covariance, alpha)
    # the noise scale is estimated (unless fixed) from the fit's residual degrees of freedom
    dof = None if hyper == "fixed" else residual_dof(problem.n_data, fit.mixture, *prior_matrices(problem, prior))
    residual_p = residual_p_values(problem.noise, fits, alpha, dof=dof)
    trust = fit_warnings(problem.noise, fits, problem.sensors.names, noise_scale=alpha,
                         noise_configured=problem.case.noise is not None,
                         tau_at_bound=fit.mass_at_bound > BOUND_MASS, tau_side="flat" if fit.flat_side else "rough",
                         residual_p=residual_p)
    for text in trust:
        warnings.warn(text, SensorplanWarning, stacklevel=3)
    verdict = _verdict(problem, mixture, alpha, residual_p, detection, probability, detector_run=detector_run)
    return PosteriorResult(
        edges=problem.mesh.edges.copy(), theta=theta, covariance=covariance,
        parameterisation=problem.parameterisation, ei_nominal=problem.ei_nominal,
        spring_names=tuple(problem.spring_names), spring_nominal=problem.spring_nominal,
        sensor_names=problem.sensors.names, sensor_kinds=tuple(problem.sensors.kinds),
        noise_std=alpha * problem.noise.std, noise_scale=alpha,
        tau=fit.tau, log_evidence=fit.log_evidence, converged=bool(fit.converged), n_iter=fit.n_iter,
        excluded_crossings=tuple(excluded), fits=fits, hyper_method=hyper, messages=tuple(messages),
        mixture=mixture, tau_mass_at_bound=fit.mass_at_bound, warnings=trust, damage=detection,
        damage_probability=probability, hyper_nodes=fit.mixture, verdict=verdict)


def _verdict(problem, mixture, alpha, residual_p, detection, probability, *, detector_run=True):
    """The one verdict on the data (:func:`sensorplan.verdict.inversion_verdict`) from the posterior's log EI."""
    theta, covariance = mixture.mean, mixture.covariance
    n = problem.n_elements
    std = np.sqrt(np.clip(np.diag(covariance)[:n], 0.0, None))
    below = None
    if problem.parameterisation == "log_ei":
        log_mean, log_std = theta[:n], std
        below = mixture.cdf(np.log(problem.ei_nominal), slice(0, n))  # the mixture's own (skewed) tails
    else:  # compliance v: log EI = -log v, to first order std(log EI) = std(v) / v
        log_mean, log_std = -np.log(theta[:n]), std / theta[:n]
    return inversion_verdict(
        edges=problem.mesh.edges, log_mean=log_mean, log_std=log_std, log_nominal=np.log(problem.ei_nominal),
        residual_p=residual_p, residual_level=RESIDUAL_LEVEL, noise_limit=NOISE_SCALE_RANGE[1],
        sensor_names=problem.sensors.names, noise_scale=alpha, noise_configured=problem.case.noise is not None,
        detection=detection, damage_probability=probability, below=below, detector_run=detector_run)


def _with_damage(mixture, problem, prior, detection, damage_prior, damage_log_std):
    """The posterior mixture extended by the local-loss hypotheses of the detector's zones."""
    lin = problem.evaluate(mixture.mean) if detection.testable else None
    if lin is None:  # no testable zone, or the mixture mean is outside the model's domain: keep the undamaged posterior
        return mixture, None
    w, thetas, covs, comp, _, probability = damage_hypotheses(
        mixture.weights, mixture.thetas, mixture.covariances, mixture.taus, mixture.noise_scales, problem.theta0,
        lin.jtj, prior=prior, n_elements=problem.n_elements, edges=problem.mesh.edges, zones=detection.zones,
        prior_damage=damage_prior, loss_log_std=damage_log_std)
    return GaussianMixture(w, thetas, covs, mixture.taus[comp], mixture.noise_scales[comp]), probability

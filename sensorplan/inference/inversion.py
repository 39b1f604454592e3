"""Bayesian identification of EI(x) (and spring stiffnesses) from crossings.

Model (paper section Bayesian Inference Framework): whitened data
r = W (y - F(theta)) / std ~ N(0, alpha^2 I), where W applies the AR(1)
whitening per sensor and crossing, std the configured noise of each sensor
and alpha a common noise scale; prior theta ~ N(theta_0, Q(tau)^{-1}) with
Q(tau) = tau S + F (GMRF roughness S on log EI plus the fixed proper part F).

* MAP by Gauss-Newton with a Levenberg-Marquardt safeguard: a step is
  accepted only if it lowers the negative log posterior, so every iterate
  decreases the objective.
* Laplace covariance H^{-1}, H = J^T J / alpha^2 + Q at the MAP; exact for
  the linear-Gaussian case.
* Hyperparameters by evidence maximisation: MacKay's fixed-point updates
  alpha^2 = |r|^2 / (M - gamma), tau = gamma_tau / (d^T S d), which are the
  stationarity conditions of the Laplace evidence, interleaved with the MAP.
  Quasi-optimality and GCV choose tau on the linearised problem instead.
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from ..model.crossings import Crossings
from .._errors import ConfigError, DataError, SensorplanWarning
from ..model.forward import influence_lines
from ..model.noise import NoiseModel
from .posterior import CrossingFit, PosteriorResult
from ..model.prior import GMRFPrior
from .screening import screen_crossings
from .._threads import single_threaded

__all__ = ["invert", "fit_problem", "HYPER_METHODS"]

HYPER_METHODS = ("evidence", "fixed", "quasi-optimality", "gcv")
_DEFAULT_STD = {"rotation": 1e-6, "deflection": 1e-4}


class _Problem:
    """Whitened residuals and Jacobians of all crossings for a parameter vector."""

    def __init__(self, case, crossings, *, estimate_springs, parameterisation, mesh=None):
        self.case = case
        self.mesh = case.mesh if mesh is None else mesh
        index = [case.sensors.names.index(n) for n in crossings.sensor_names]
        self.sensors = case.sensors.subset(index)
        if case.noise is not None:
            self.noise = case.noise.subset(index)
        else:
            self.noise = NoiseModel([_DEFAULT_STD[k] for k in self.sensors.kinds])
        self.crossings = crossings
        self.parameterisation = parameterisation
        self.n_elements = self.mesh.n_elements
        self.spring_names = case.bridge.spring_names if estimate_springs else ()
        self.n_springs = len(self.spring_names)
        self.n_params = self.n_elements + self.n_springs
        self.ei_nominal = np.asarray(case.ei_at(self.mesh.midpoints), dtype=float)
        self.spring_nominal = case.bridge.spring_stiffness() if estimate_springs else np.zeros(0)
        if parameterisation == "log_ei":
            self.theta0 = np.concatenate([np.log(self.ei_nominal), np.log(self.spring_nominal)])
        elif parameterisation == "compliance":
            if self.n_springs or len(case.bridge.spring_parameters) or case.bridge.n_spans > 1 or any(
                    k > 0 for k in case.bridge.rotational_springs):
                raise ConfigError("parameterisation='compliance' is the linear-Gaussian case: it needs a "
                                  "statically determinate bridge (one pinned span, rigid supports).")
            self.theta0 = 1.0 / self.ei_nominal
        else:
            raise ConfigError(f"The 'parameterisation' parameter must be 'log_ei' or 'compliance'. "
                              f"Got {parameterisation!r} instead.")
        self.white_data = [self.noise.whiten(c.values, c.positions) for c in crossings]
        self.n_data = sum(w.size for w in self.white_data)
        self.log_det_noise = sum(
            self.noise.log_det_gamma(c.positions) * self.sensors.n_sensors
            + 2.0 * c.n_loads * np.sum(np.log(self.noise.std)) for c in crossings)
        self.n_evaluations = 0
        self._last = None

    def split(self, theta):
        n = self.n_elements
        if self.parameterisation == "log_ei":
            ei = np.exp(theta[:n])
        else:
            if np.any(theta[:n] <= 0.0):
                return None, None
            ei = 1.0 / theta[:n]
        bridge = self.case.bridge
        if self.n_springs:
            bridge = bridge.with_spring_stiffness(np.exp(theta[n:]))
        return ei, bridge

    def lines(self, theta):
        """Influence lines per distinct position set (shared between crossings)."""
        ei, bridge = self.split(theta)
        if ei is None:
            return None
        self.n_evaluations += 1
        out = {}
        for c in self.crossings:
            key = c.positions.tobytes()
            if key not in out:
                out[key] = influence_lines(bridge, self.mesh, ei, self.sensors, self.case.vehicle,
                                           c.positions)
        return out

    def evaluate(self, theta, *, jacobian=True):
        """Linearisation of the whitened misfit at ``theta``, or None if invalid.

        Crossings that share positions and load factors share one whitened
        Jacobian; only the normal-equation quantities r.r, J^T J and J^T r
        are formed (J is never stacked).
        """
        key = theta.tobytes()
        if self._last is not None and self._last[0] == key and (self._last[1].jtj is not None or not jacobian):
            return self._last[1]
        if not np.all(np.isfinite(theta)):
            return None
        try:
            lines = self.lines(theta)
        except ConfigError:  # a trial step made the bridge unstable (extreme springs): reject it
            return None
        if lines is None:
            return None
        rr = 0.0
        jtj = np.zeros((self.n_params, self.n_params)) if jacobian else None
        jtr = np.zeros(self.n_params) if jacobian else None
        groups = {}
        for c, wd in zip(self.crossings, self.white_data):
            ln = lines[c.positions.tobytes()]
            gkey = c.positions.tobytes() + c.load_factor.tobytes()
            if gkey not in groups:
                pred = ln.predictions * c.load_factor[None, :]
                white_pred = self.noise.whiten(pred, c.positions)
                wj = None
                if jacobian:
                    j = self._raw_jacobian(ln) * c.load_factor[None, :, None]
                    wj = self.noise.whiten(j, c.positions).reshape(-1, self.n_params)
                groups[gkey] = (white_pred, wj)
            white_pred, wj = groups[gkey]
            r = (wd - white_pred).ravel()
            rr += float(r @ r)
            if jacobian:
                jtr += wj.T @ r
        if jacobian:
            counts = {}
            for c in self.crossings:
                gkey = c.positions.tobytes() + c.load_factor.tobytes()
                counts[gkey] = counts.get(gkey, 0) + 1
            for gkey, n in counts.items():
                wj = groups[gkey][1]
                jtj += n * (wj.T @ wj)
        out = _Linearisation(rr, jtj, jtr)
        self._last = (key, out)
        return out

    def _raw_jacobian(self, ln):
        if self.parameterisation == "log_ei":
            return ln.jacobian("log_ei", springs=self.n_springs > 0)
        return ln.jacobian("compliance")

    def fits(self, theta, covariance, alpha):
        """Data, model and posterior predictive spread per crossing."""
        lines = self.lines(theta)
        out = []
        cache = {}
        for c in self.crossings:
            ln = lines[c.positions.tobytes()]
            gkey = c.positions.tobytes() + c.load_factor.tobytes()
            if gkey not in cache:
                pred = ln.predictions * c.load_factor[None, :]
                j = self._raw_jacobian(ln) * c.load_factor[None, :, None]
                var = np.sum((j @ covariance) * j, axis=-1)
                cache[gkey] = (pred, np.sqrt(np.clip(var, 0.0, None)))
            pred, std = cache[gkey]
            out.append(CrossingFit(c.label, c.positions, c.values, pred, std, alpha * self.noise.std))
        return tuple(out)


@dataclass(frozen=True)
class _Linearisation:
    """Whitened misfit r.r and the normal-equation terms J^T J, J^T r (r = y - F)."""

    rr: float
    jtj: np.ndarray
    jtr: np.ndarray


def _prior_matrices(problem, prior):
    """Roughness S and fixed part F of the prior precision in the problem's parameters."""
    n, s = problem.n_elements, problem.n_springs
    rough = np.zeros((problem.n_params, problem.n_params))
    rough[:n, :n] = prior.structure(n)
    fixed = prior.precision(n, s, tau=0.0)
    if problem.parameterisation == "compliance":
        # Same quadratic form to first order: d log EI = -d v / v_0.
        scale = 1.0 / problem.theta0
        rough = rough * np.outer(scale, scale)
        fixed = fixed * np.outer(scale, scale)
    return rough, fixed


def _solve_map(problem, theta, alpha, q, theta0, *, max_iter, tol):
    """Levenberg-Marquardt MAP; returns theta, linearisation, iterations, converged."""
    lin = problem.evaluate(theta)
    if lin is None:
        raise DataError("The start point gives an invalid model (non-positive EI).")

    def objective(rr, t_):
        d = t_ - theta0
        return 0.5 * rr / alpha**2 + 0.5 * d @ q @ d

    obj = objective(lin.rr, theta)
    mu = 0.0
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        d = theta - theta0
        grad = -lin.jtr / alpha**2 + q @ d
        hess = lin.jtj / alpha**2 + q
        diag = np.diag(hess).copy()
        accepted = False
        for _ in range(30):
            try:
                step = -scipy.linalg.solve(hess + mu * np.diag(diag), grad, assume_a="pos")
            except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
                mu = max(10 * mu, 1e-6)
                continue
            trial = theta + step
            trial_lin = problem.evaluate(trial, jacobian=False)
            if trial_lin is not None:
                obj_t = objective(trial_lin.rr, trial)
                if obj_t <= obj:
                    accepted = True
                    break
            mu = max(4.0 * mu, 1e-4)
        if not accepted:
            # No decrease possible along damped steps: at a (numerical) minimum.
            converged = float(np.max(np.abs(grad) / np.sqrt(diag))) < 1e-6
            break
        decrease = obj - obj_t
        theta, obj = trial, obj_t
        lin = problem.evaluate(theta)
        mu = mu / 3.0 if mu > 1e-8 else 0.0
        newton_decrement = float(-step @ grad)
        if newton_decrement < tol * max(1.0, abs(obj)) or decrease <= tol * 1e-3 * max(1.0, abs(obj)):
            converged = True
            break
    return theta, lin, it, converged


def _log_evidence(problem, lin, theta, theta0, alpha, q):
    d = theta - theta0
    hess = lin.jtj / alpha**2 + q
    _, logdet_h = np.linalg.slogdet(hess)
    _, logdet_q = np.linalg.slogdet(q)
    m = problem.n_data
    return float(-0.5 * lin.rr / alpha**2 - 0.5 * d @ q @ d - 0.5 * logdet_h + 0.5 * logdet_q
                 - m * math.log(alpha) - 0.5 * problem.log_det_noise - 0.5 * m * math.log(2 * math.pi))


def _linearised_data(lin, theta):
    """J^T y and y.y for the linearised data y = r + J theta."""
    jty = lin.jtr + lin.jtj @ theta
    yy = lin.rr + 2.0 * theta @ lin.jtr + theta @ lin.jtj @ theta
    return jty, float(yy)


def _maximise_linear_evidence(lin, theta, theta0, rough, fixed, alpha, tau, m):
    """(alpha, tau) maximising the evidence of the model linearised at the MAP.

    For y_lin = J theta + e the evidence is Gaussian in closed form, so the
    two hyperparameters are optimised without new forward evaluations; the
    outer loop re-linearises until they settle (one pass when F is linear).
    """
    jtj = lin.jtj
    jty, yy = _linearised_data(lin, theta)

    def negative(params):
        a = math.exp(params[0])
        t = math.exp(params[1])
        q = t * rough + fixed
        h = jtj / a**2 + q
        try:
            ch = scipy.linalg.cho_factor(h)
            cq = scipy.linalg.cho_factor(q)
        except np.linalg.LinAlgError:
            return 1e300, np.zeros(2)
        x = scipy.linalg.cho_solve(ch, jty / a**2 + q @ theta0)
        rr = yy - 2 * x @ jty + x @ jtj @ x
        d = x - theta0
        logdet_h = 2 * np.sum(np.log(np.diag(ch[0])))
        logdet_q = 2 * np.sum(np.log(np.diag(cq[0])))
        value = -0.5 * rr / a**2 - 0.5 * d @ q @ d - 0.5 * logdet_h + 0.5 * logdet_q - m * math.log(a)
        # Gradient by the envelope theorem (x is the optimum of the quadratic terms).
        h_inv_jtj = scipy.linalg.cho_solve(ch, jtj)
        g_a = rr / a**2 + np.trace(h_inv_jtj) / a**2 - m
        g_t = t * (-0.5 * d @ rough @ d - 0.5 * np.trace(scipy.linalg.cho_solve(ch, rough))
                   + 0.5 * np.trace(scipy.linalg.cho_solve(cq, rough)))
        return -float(value), -np.array([g_a, g_t])

    start = np.array([math.log(alpha), math.log(tau)])
    best = scipy.optimize.minimize(negative, start, jac=True, method="L-BFGS-B",
                                   bounds=[(start[0] - 30, start[0] + 30), (math.log(1e-8), math.log(1e14))],
                                   options={"ftol": 1e-13, "gtol": 1e-7, "maxiter": 500})
    x = best.x if negative(best.x)[0] <= negative(start)[0] else start
    return math.exp(x[0]), math.exp(x[1])


def _tau_by_criterion(lin, theta, theta0, alpha, rough, fixed, method, taus, m):
    """Choose tau on the problem linearised at ``theta`` by quasi-optimality or GCV."""
    jtj = lin.jtj / alpha**2
    jty, yy = _linearised_data(lin, theta)
    sols, scores = [], []
    for tau in taus:
        q = tau * rough + fixed
        h = jtj + q
        x = scipy.linalg.solve(h, jty / alpha**2 + q @ theta0, assume_a="pos")
        sols.append(x)
        if method == "gcv":
            res = yy - 2 * x @ jty + x @ lin.jtj @ x
            trace = np.trace(scipy.linalg.solve(h, jtj, assume_a="pos"))
            scores.append(m * res / max(m - trace, 1e-12) ** 2)
    if method == "gcv":
        return float(taus[int(np.argmin(scores))])
    diffs = np.array([np.linalg.norm(sols[i + 1] - sols[i]) for i in range(len(taus) - 1)])
    # Quasi-optimality: the smallest interior local minimum of |x(tau_k+1) - x(tau_k)|.  At the
    # ends of the grid the solution stops changing because the prior (large tau) or the data
    # (small tau) dominates; those trivial minima are not the criterion's choice.
    interior = [i for i in range(1, diffs.size - 1) if diffs[i] <= diffs[i - 1] and diffs[i] <= diffs[i + 1]]
    k = min(interior, key=lambda i: diffs[i]) if interior else int(np.argmin(diffs))
    return float(np.sqrt(taus[k] * taus[k + 1]))


@dataclass(frozen=True, eq=False)
class Fit:
    """Result of :func:`fit_problem` (internal)."""

    theta: np.ndarray
    covariance: np.ndarray
    noise_scale: float
    tau: float
    log_evidence: float
    converged: bool
    n_iter: int
    linearisation: object


def fit_problem(problem, rough, fixed, theta0, *, hyper="evidence", noise_scale=1.0, tau=1.0, start=None,
                max_iter=100, max_outer=200, tol=1e-10):
    """MAP, Laplace covariance and hyperparameters of any problem with ``evaluate``.

    ``problem`` provides ``evaluate(theta, jacobian=True)`` (a linearisation
    with rr, jtj, jtr), ``n_data`` and ``log_det_noise``; the prior precision
    is ``tau * rough + fixed`` about ``theta0``.
    """
    alpha = float(noise_scale)
    tau_value = float(tau)
    theta = theta0.copy() if start is None else np.asarray(start, dtype=float).copy()
    total_iter = 0
    converged = False
    n_outer = max_outer if hyper == "evidence" else 1
    m = problem.n_data
    for _ in range(n_outer):
        q = tau_value * rough + fixed
        theta, lin, it, map_ok = _solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
        total_iter += it
        if hyper != "evidence":
            converged = map_ok
            break
        new_alpha, new_tau = _maximise_linear_evidence(lin, theta, theta0, rough, fixed, alpha, tau_value, m)
        change = max(abs(math.log(new_alpha / alpha)), abs(math.log(new_tau / tau_value)))
        alpha, tau_value = new_alpha, new_tau
        if change < 1e-5 and map_ok:
            converged = True
            break
    if hyper in ("quasi-optimality", "gcv"):
        taus = np.logspace(-4, 10, 57)
        tau_value = _tau_by_criterion(lin, theta, theta0, alpha, rough, fixed, hyper, taus, m)
        q = tau_value * rough + fixed
        theta, lin, it, converged = _solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
        total_iter += it
        hess = lin.jtj / alpha**2 + q
        gamma = float(np.trace(scipy.linalg.solve(hess, lin.jtj / alpha**2, assume_a="pos")))
        alpha = math.sqrt(max(lin.rr, 1e-300) / max(m - gamma, 1.0))
    q = tau_value * rough + fixed
    if hyper == "evidence":
        # Final MAP and Laplace approximation at the converged hyperparameters.
        theta, lin, it, map_ok = _solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
        total_iter += it
        converged = converged and map_ok
    hess = lin.jtj / alpha**2 + q
    covariance = scipy.linalg.inv(hess)
    covariance = 0.5 * (covariance + covariance.T)
    log_ev = _log_evidence(problem, lin, theta, theta0, alpha, q)
    return Fit(theta, covariance, alpha, tau_value, log_ev, bool(converged), total_iter, lin)


@single_threaded
def invert(case, crossings, *, prior=None, estimate_springs=True, parameterisation="log_ei",
           hyper="evidence", noise_scale=1.0, tau=None, screen=True, mesh=None, start=None,
           max_iter=100, max_outer=200, tol=1e-10):
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
    hyper : {"evidence", "fixed", "quasi-optimality", "gcv"}
        How the noise scale and tau are chosen.
    noise_scale, tau : float
        Start values (``fixed``: the values used).  ``tau`` defaults to the prior's.
    screen : bool
        Exclude crossings that do not match the others (with a warning).
    mesh : Mesh, optional
        Inversion mesh (default: the case's).
    start : array_like, optional
        Start parameters (default: the nominal).

    Returns
    -------
    PosteriorResult
    """
    if hyper not in HYPER_METHODS:
        raise ConfigError(f"The 'hyper' parameter must be one of {HYPER_METHODS}. Got {hyper!r} instead.")
    if not isinstance(crossings, Crossings):
        raise DataError("The 'crossings' parameter must be a Crossings object (see read_crossings).")
    prior = GMRFPrior() if prior is None else prior
    excluded = ()
    if screen and len(crossings) >= 2:
        crossings, excluded, reasons = screen_crossings(crossings)
        for label, reason in zip(excluded, reasons):
            warnings.warn(f"crossing '{label}' excluded: {reason}", SensorplanWarning, stacklevel=2)
    if mesh is not None:
        mesh.check_fits(case.bridge)
    problem = _Problem(case, crossings, estimate_springs=estimate_springs and bool(case.bridge.spring_names),
                       parameterisation=parameterisation, mesh=mesh)
    rough, fixed = _prior_matrices(problem, prior)
    fit = fit_problem(problem, rough, fixed, problem.theta0, hyper=hyper, noise_scale=noise_scale,
                      tau=prior.tau if tau is None else tau, start=start, max_iter=max_iter,
                      max_outer=max_outer, tol=tol)
    theta, covariance, alpha, tau_value = fit.theta, fit.covariance, fit.noise_scale, fit.tau
    messages = []
    if not fit.converged:
        messages.append("the MAP or the hyperparameter iteration did not converge")
        warnings.warn("sensorplan invert: the Gauss-Newton / evidence iteration did not converge; "
                      "results are reported with converged = false.", SensorplanWarning, stacklevel=2)
    converged, total_iter, log_ev = fit.converged, fit.n_iter, fit.log_evidence
    fits = problem.fits(theta, covariance, alpha)
    return PosteriorResult(
        edges=problem.mesh.edges.copy(), theta=theta, covariance=covariance,
        parameterisation=parameterisation, ei_nominal=problem.ei_nominal,
        spring_names=tuple(problem.spring_names), spring_nominal=problem.spring_nominal,
        sensor_names=problem.sensors.names, noise_std=alpha * problem.noise.std, noise_scale=alpha,
        tau=tau_value, log_evidence=log_ev, converged=bool(converged), n_iter=total_iter,
        excluded_crossings=tuple(excluded), fits=fits, hyper_method=hyper, messages=tuple(messages))

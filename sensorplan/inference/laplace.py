"""One Laplace / evidence engine for every Bayesian problem of the package.

A *problem* gives the whitened misfit of a parameter vector and its
normal-equation terms (:class:`Linearisation`); the engine finds the MAP by
Levenberg-Marquardt, the Laplace covariance, and the hyperparameters (noise
scale alpha, prior scale tau) by evidence maximisation, quasi-optimality or
GCV.  :class:`WhitenedData` is the shared base of the problems: the sensors
and noise model of the crossings' columns, the whitened data, the data count
and the noise log-determinant (optionally restricted to row masks).

Owns: MAP, Laplace, evidence.  May import: model, errors.
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from .._errors import DataError
from ..model.noise import NoiseModel

__all__ = ["Linearisation", "WhitenedData", "Fit", "fit_problem", "solve_map", "log_evidence", "SecantCurvature"]

# Floor of log alpha (estimated / configured noise): noise-free data (as `simulate` without --noise writes them)
# would drive alpha to 0 and the evidence to a division by zero; the floor keeps the estimate at 1e-3 of the
# configured noise and the fit is flagged (noise scale outside NOISE_SCALE_RANGE in inference/checks.py).
LOG_NOISE_FLOOR = math.log(1e-3)
DEFAULT_STD = {"rotation": 1e-6, "deflection": 1e-4}


def data_sensors(case, names):
    """The case's sensors ``names`` (in that order) and their noise model (``DEFAULT_STD`` where none is set)."""
    index = [case.sensors.names.index(n) for n in names]
    sensors = case.sensors.subset(index)
    if case.noise is not None:
        return sensors, case.noise.subset(index)
    return sensors, NoiseModel([DEFAULT_STD[k] for k in sensors.kinds])


class WhitenedData:
    """Sensors, noise and whitened data of ``crossings`` (rows selected by ``masks``).

    Sensors without a configured noise model get ``DEFAULT_STD`` of their
    kind (the evidence then estimates the common scale).
    """

    def __init__(self, case, crossings, *, masks=None):
        self.case = case
        self.crossings = crossings
        self.sensors, self.noise = data_sensors(case, crossings.sensor_names)
        self.masks = [np.ones(c.n_loads, bool) for c in crossings] if masks is None else masks
        self.white_data = [self.noise.whiten(c.values[:, m], c.positions[m])
                           for c, m in zip(crossings, self.masks)]
        self.n_data = sum(w.size for w in self.white_data)
        n_sensors = self.sensors.n_sensors
        self.log_det_noise = sum(
            self.noise.log_det_gamma(c.positions[m]) * n_sensors + 2.0 * m.sum() * np.sum(np.log(self.noise.std))
            for c, m in zip(crossings, self.masks) if m.any())


@dataclass(frozen=True)
class Linearisation:
    """Whitened misfit r.r and the normal-equation terms J^T J, J^T r (r = y - F)."""

    rr: float
    jtj: np.ndarray
    jtr: np.ndarray



STALL_STEPS = 3  # accepted steps that must gain less than atol together for a stall (see solve_map)


class SecantCurvature:
    """The residuals' own curvature sum_i r_i d2 r_i, learnt from the steps of :func:`solve_map` (internal).

    Gauss-Newton models the Hessian of |r|^2 / 2 by J^T J alone.  Where a
    weakly informed parameter enters nonlinearly (the log stiffness of a
    support spring near its pinned or clamped limit) the dropped term is
    not small: on three spans with load-position offsets the true curvature
    along one spring's log stiffness was 2.6 times J^T J + Q, every
    Gauss-Newton step overshot it, and Levenberg-Marquardt crawled through
    15-20 damped evaluations per node of the hyperparameter grid.  This is
    the structured secant update of NL2SOL (Dennis, Gay and Welsch, ACM
    TOMS 7, 1981): after each accepted step s the matrix ``s_matrix``
    (alpha-free: the term of |r|^2 / 2) is updated so that J+^T J+ + S+
    maps s onto the change of the gradient, with their sizing factor.  One
    object passed to successive fits (the nodes of a grid in tau: only the
    prior changes) carries what it learnt to the next.
    """

    def __init__(self, n):
        self.s_matrix = np.zeros((n, n))

    def update(self, step, gradient_change, jtj_new):
        """After an accepted ``step``: ``gradient_change`` of |r|^2 / 2 (alpha-free), J^T J at the new point."""
        y = gradient_change
        ys = float(y @ step)
        if not ys > 0.0:
            return
        s_mat = self.s_matrix
        sharp = y - jtj_new @ step  # what J^T J at the new point does not explain
        ss = float(step @ s_mat @ step)
        if ss != 0.0:  # sizing (NL2SOL): S shrunk where the step sees less curvature than it holds
            s_mat = s_mat * min(1.0, abs(float(step @ sharp)) / abs(ss))
        u = sharp - s_mat @ step
        updated = (s_mat + (np.outer(u, y) + np.outer(y, u)) / ys - float(u @ step) * np.outer(y, y) / ys**2)
        if np.all(np.isfinite(updated)):
            self.s_matrix = 0.5 * (updated + updated.T)


def solve_map(problem, theta, alpha, q, theta0, *, max_iter, tol, stop=None, atol=0.0, curvature=None):
    """Levenberg-Marquardt MAP; returns theta, linearisation, iterations, converged.

    Converged when the Newton decrement is below ``tol`` times the objective
    or below ``atol`` (log-density units), or the objective stops falling.
    With ``atol``, also when the last ``STALL_STEPS`` accepted steps gained
    less than ``atol`` together while the decrement is below ``10 atol``:
    in a flat direction Levenberg-Marquardt can crawl with every step gaining
    a twentieth of what the quadratic model predicts (a freed vertical spring
    next to the case's estimated springs: decrements 0.02-0.04 and gains of
    0.0002-0.001 for ten steps), and what is left to gain is below ``atol``.
    ``stop(theta, lin)``, if given, is asked after every accepted step whether
    to give up (the fit is then returned as not converged).  ``curvature``
    (a :class:`SecantCurvature`): the steps also use, and update, the
    residuals' curvature that Gauss-Newton leaves out.
    """
    lin = problem.evaluate(theta)
    if lin is None:
        raise DataError("The start point gives an invalid model (non-positive EI).")

    def objective(rr, t_):
        d = t_ - theta0
        return 0.5 * rr / alpha**2 + 0.5 * d @ q @ d

    obj = objective(lin.rr, theta)
    mu = 0.0
    nu = 2.0  # growth of mu over successive rejections (Nielsen)
    converged = False
    gains = []
    it = 0
    # the step uses the curvature's model (once it holds any: then by which model predicted the last gain better)
    augmented = curvature is not None and bool(np.any(curvature.s_matrix))
    for it in range(1, max_iter + 1):
        d = theta - theta0
        grad = -lin.jtr / alpha**2 + q @ d
        hess = lin.jtj / alpha**2 + q
        diag = np.diag(hess).copy()
        extra = curvature.s_matrix / alpha**2 if curvature is not None else None
        model = hess + extra if augmented else hess
        accepted = False
        for _ in range(30):
            try:
                with warnings.catch_warnings():
                    # an ill-conditioned system (a stiff spring the data barely inform, far from the optimum)
                    # is solved all the same: a step counts only if it lowers the objective, else it is damped
                    warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
                    step = -scipy.linalg.solve(model + mu * np.diag(diag), grad, assume_a="pos")
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
            mu = max(nu * mu, 1e-4)
            nu *= 2.0
        if not accepted:
            # No decrease possible along damped steps: at a (numerical) minimum.
            converged = float(np.max(np.abs(grad) / np.sqrt(diag))) < 1e-6
            break
        decrease = obj - obj_t
        if extra is not None:  # NL2SOL's switch: the next step by the model that predicted this gain better
            linear = -float(grad @ step)
            plain = linear - 0.5 * float(step @ hess @ step)
            with_curvature = plain - 0.5 * float(step @ extra @ step)
            augmented = abs(with_curvature - decrease) < abs(plain - decrease)
        previous = lin
        theta, obj = trial, obj_t
        lin = problem.evaluate(theta)
        if curvature is not None and lin is not None and lin.jtj is not None:
            curvature.update(step, previous.jtr - lin.jtr, lin.jtj)
        # Nielsen's update (Madsen, Nielsen & Tingleff 2004, eq. 3.16): mu falls by up to 3 as the gain ratio
        # rho nears 1 and is kept at rho ~ 0.5.  The earlier mu / 3 after every accepted step followed by x4
        # after a rejection alternated (a third of all evaluations were rejected trial points on three spans
        # with moved loads or axle loads; 534 of 1644 -> 273 of 1343 on one dataset)
        predicted = -float(grad @ step) - 0.5 * float(step @ model @ step)
        rho = decrease / predicted if predicted > 0 else 1.0
        mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
        mu = mu if mu > 1e-8 else 0.0
        nu = 2.0
        newton_decrement = float(-step @ grad)
        gains.append(decrease)
        stalled = (atol > 0 and len(gains) >= STALL_STEPS and sum(gains[-STALL_STEPS:]) < atol
                   and newton_decrement < 10 * atol)
        if (newton_decrement < max(tol * max(1.0, abs(obj)), atol)
                or decrease <= tol * 1e-3 * max(1.0, abs(obj)) or stalled):
            converged = True
            break
        if stop is not None and lin is not None and stop(theta, lin):
            break
    return theta, lin, it, converged


def log_evidence(problem, lin, theta, theta0, alpha, q):
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
        except (np.linalg.LinAlgError, ValueError):  # not positive definite, or overflowed to inf
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
                                   bounds=[(max(start[0] - 30, LOG_NOISE_FLOOR), start[0] + 30), (math.log(1e-8), math.log(1e14))],
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
        theta, lin, it, map_ok = solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
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
        theta, lin, it, converged = solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
        total_iter += it
        hess = lin.jtj / alpha**2 + q
        gamma = float(np.trace(scipy.linalg.solve(hess, lin.jtj / alpha**2, assume_a="pos")))
        alpha = math.sqrt(max(lin.rr, 1e-300) / max(m - gamma, 1.0))
    q = tau_value * rough + fixed
    if hyper == "evidence":
        # Final MAP and Laplace approximation at the converged hyperparameters.
        theta, lin, it, map_ok = solve_map(problem, theta, alpha, q, theta0, max_iter=max_iter, tol=tol)
        total_iter += it
        converged = converged and map_ok
    hess = lin.jtj / alpha**2 + q
    covariance = scipy.linalg.inv(hess)
    covariance = 0.5 * (covariance + covariance.T)
    log_ev = log_evidence(problem, lin, theta, theta0, alpha, q)
    return Fit(theta, covariance, alpha, tau_value, log_ev, bool(converged), total_iter, lin)



"""Hyperparameter point estimates: evidence maximisation, quasi-optimality, GCV or fixed values.

:func:`fit_problem` finds the MAP (the engine's :func:`~.engine.solve_map`),
the Laplace covariance and the hyperparameters (noise scale alpha, prior
scale tau) of any :class:`~.engine.LinearisedProblem`.  The integration over
the hyperparameters is :mod:`.hyperposterior`.

Owns: the point estimates of the hyperparameters.  May import: model, errors.
"""

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from .engine import LOG_NOISE_FLOOR, log_evidence, solve_map

__all__ = ["Fit", "fit_problem"]


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



"""The steps of the engine: Levenberg-Marquardt MAP, the residuals' secant curvature, the Laplace evidence.

A *problem* (:class:`~.problem.LinearisedProblem`) gives the whitened misfit
of a parameter vector and its normal-equation terms; the prior is Gaussian,
precision ``q`` about ``theta0``, and ``alpha`` scales the noise.
:func:`solve_map` finds the MAP of |r|^2 / (2 alpha^2) + (theta - theta0)^T q
(theta - theta0) / 2, :func:`log_evidence` is the Laplace evidence there.

Owns: the MAP iteration, the secant curvature, the Laplace evidence.  May import: errors.
"""

import math
import warnings

import numpy as np
import scipy.linalg

from ..._errors import DataError

__all__ = ["LOG_NOISE_FLOOR", "STALL_STEPS", "SecantCurvature", "solve_map", "log_evidence"]

# Floor of log alpha (estimated / configured noise): noise-free data (as `simulate` without --noise writes them)
# would drive alpha to 0 and the evidence to a division by zero; the floor keeps the estimate at 1e-3 of the
# configured noise and the fit is flagged (noise scale outside NOISE_SCALE_RANGE in inference/checks.py).
LOG_NOISE_FLOOR = math.log(1e-3)
STALL_STEPS = 3  # accepted steps that must gain less than atol together for a stall (see solve_map)
MAX_DAMPING = 30  # damped trial steps per iteration before the iteration is declared at a minimum


class SecantCurvature:
    """The residuals' own curvature sum_i r_i d2 r_i, learnt from the steps of :func:`solve_map`.

    Gauss-Newton models the Hessian of |r|^2 / 2 by J^T J alone.  Where a
    weakly informed parameter enters nonlinearly (the log stiffness of a
    support spring near its pinned or clamped limit) the dropped term is
    not small: the true curvature along it can be a multiple of J^T J + Q,
    every Gauss-Newton step overshoots and Levenberg-Marquardt crawls
    through many damped evaluations.  This is the structured secant update
    of NL2SOL (Dennis, Gay and Welsch, ACM TOMS 7, 1981): after each
    accepted step s the matrix ``s_matrix`` (alpha-free: the term of
    |r|^2 / 2) is updated so that J+^T J+ + S+ maps s onto the change of the
    gradient, with their sizing factor.  One object passed to successive
    fits (the nodes of a grid in tau: only the prior changes) carries what
    it learnt to the next.
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


def _damped_step(problem, theta, grad, model, diag, objective, obj, mu, nu):
    """The first damped step (damping ``mu``, growing by ``nu``) that does not raise the objective.

    Returns (step, trial point, its objective, mu, nu); the step is None
    when ``MAX_DAMPING`` tries all failed.
    """
    for _ in range(MAX_DAMPING):
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
                return step, trial, obj_t, mu, nu
        mu = max(nu * mu, 1e-4)
        nu *= 2.0
    return None, None, None, mu, nu


def _next_damping(mu, decrease, grad, step, model):
    """Nielsen's update of mu after an accepted step (Madsen, Nielsen & Tingleff 2004, eq. 3.16).

    mu falls by up to 3 as the gain ratio rho nears 1 and is kept at
    rho ~ 0.5, which avoids alternating between shrinking after every
    accepted step and growing after every rejected one.
    """
    predicted = -float(grad @ step) - 0.5 * float(step @ model @ step)
    rho = decrease / predicted if predicted > 0 else 1.0
    mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
    return mu if mu > 1e-8 else 0.0


def _settled(newton_decrement, decrease, obj, gains, tol, atol):
    """Whether the iteration has converged after an accepted step (see :func:`solve_map`)."""
    stalled = (atol > 0 and len(gains) >= STALL_STEPS and sum(gains[-STALL_STEPS:]) < atol
               and newton_decrement < 10 * atol)
    return (newton_decrement < max(tol * max(1.0, abs(obj)), atol)
            or decrease <= tol * 1e-3 * max(1.0, abs(obj)) or stalled)


def solve_map(problem, theta, alpha, q, theta0, *, max_iter, tol, stop=None, atol=0.0, curvature=None):
    """Levenberg-Marquardt MAP; returns theta, linearisation, iterations, converged.

    Converged when the Newton decrement is below ``tol`` times the objective
    or below ``atol`` (log-density units), or the objective stops falling.
    With ``atol``, also when the last ``STALL_STEPS`` accepted steps gained
    less than ``atol`` together while the decrement is below ``10 atol``:
    in a flat direction Levenberg-Marquardt can crawl with every step
    gaining a small fraction of what the quadratic model predicts, and what
    is left to gain is below ``atol``.  ``stop(theta, lin)``, if given, is
    asked after every accepted step whether to give up (the fit is then
    returned as not converged).  ``curvature`` (a :class:`SecantCurvature`):
    the steps also use, and update, the residuals' curvature that
    Gauss-Newton leaves out.
    """
    lin = problem.evaluate(theta)
    if lin is None:
        raise DataError("The start point gives an invalid model (non-positive EI).")

    def objective(rr, t_):
        d = t_ - theta0
        return 0.5 * rr / alpha**2 + 0.5 * d @ q @ d

    obj = objective(lin.rr, theta)
    mu, nu = 0.0, 2.0  # damping and its growth over successive rejections (Nielsen)
    converged = False
    gains = []
    it = 0
    # the step uses the curvature's model (once it holds any: then by which model predicted the last gain better)
    augmented = curvature is not None and bool(np.any(curvature.s_matrix))
    for it in range(1, max_iter + 1):
        grad = -lin.jtr / alpha**2 + q @ (theta - theta0)
        hess = lin.jtj / alpha**2 + q
        diag = np.diag(hess).copy()
        extra = curvature.s_matrix / alpha**2 if curvature is not None else None
        model = hess + extra if augmented else hess
        step, trial, obj_t, mu, nu = _damped_step(problem, theta, grad, model, diag, objective, obj, mu, nu)
        if step is None:  # no decrease possible along damped steps: at a (numerical) minimum
            converged = float(np.max(np.abs(grad) / np.sqrt(diag))) < 1e-6
            break
        decrease = obj - obj_t
        if extra is not None:  # NL2SOL's switch: the next step by the model that predicted this gain better
            plain = -float(grad @ step) - 0.5 * float(step @ hess @ step)
            augmented = abs(plain - 0.5 * float(step @ extra @ step) - decrease) < abs(plain - decrease)
        previous = lin
        theta, obj = trial, obj_t
        lin = problem.evaluate(theta)
        if curvature is not None and lin is not None and lin.jtj is not None:
            curvature.update(step, previous.jtr - lin.jtr, lin.jtj)
        mu, nu = _next_damping(mu, decrease, grad, step, model), 2.0
        gains.append(decrease)
        if _settled(float(-step @ grad), decrease, obj, gains, tol, atol):
            converged = True
            break
        if stop is not None and lin is not None and stop(theta, lin):
            break
    return theta, lin, it, converged


def log_evidence(problem, lin, theta, theta0, alpha, q):
    """Laplace log evidence of ``problem`` at the MAP ``theta`` (linearisation ``lin``), noise scale ``alpha``."""
    d = theta - theta0
    hess = lin.jtj / alpha**2 + q
    _, logdet_h = np.linalg.slogdet(hess)
    _, logdet_q = np.linalg.slogdet(q)
    m = problem.n_data
    return float(-0.5 * lin.rr / alpha**2 - 0.5 * d @ q @ d - 0.5 * logdet_h + 0.5 * logdet_q
                 - m * math.log(alpha) - 0.5 * problem.log_det_noise - 0.5 * m * math.log(2 * math.pi))

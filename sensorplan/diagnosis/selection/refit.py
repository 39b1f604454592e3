"""Quick refits of the joint model: Levenberg-Marquardt from a warm start at fixed hyperparameters.

Every candidate of the selection starts at the MAP of the model it extends
(its own parameters at their prior means) with that model's noise scale and
tau held: a few steps then reach its optimum (the effects are small
extensions of a model already fitted), and its Laplace evidence is
compared with the others'.  A fit that is not converged carries a
*ceiling*, an estimate of the evidence it could still reach, so that it can
give up once it cannot matter to a decision.

Owns: :class:`QuickFit`, :func:`quick_fit`.  May import: inference and the selection's policy.
"""

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from ..._errors import DataError
from ...inference.engine import log_evidence, solve_map
from .policy import DEFAULT_POLICY

__all__ = ["QuickFit", "quick_fit"]


@dataclass(frozen=True, eq=False)
class QuickFit:
    """MAP and Laplace evidence of an extended model at fixed hyperparameters.

    ``ceiling``: the log evidence the fit could still reach by an estimate
    (its log evidence plus ``ceiling_decrements`` Newton decrements plus
    ``ceiling_margin``, :class:`~.policy.SelectionPolicy`; = the log
    evidence once converged).  ``abandoned``: stopped before convergence
    because the ceiling fell below the level that matters (not converged).
    """

    problem: Any  # the JointProblem fitted
    theta: np.ndarray
    hessian: np.ndarray
    log_evidence: float
    converged: bool
    n_iter: int
    noise_scale: float
    tau: float
    ceiling: float = math.inf
    abandoned: bool = False

    @property
    def covariance(self):
        return np.linalg.inv(self.hessian)


def _evidence(problem, lin, theta, alpha, q, policy):
    """Laplace log evidence at ``theta``, the Hessian, and the ceiling (see :class:`QuickFit`)."""
    # plus the log prior of the effects' discrete choices (a sensor's sign)
    ev = log_evidence(problem, lin, theta, problem.theta0, alpha, q) + problem.log_prior_constant
    hess = lin.jtj / alpha**2 + q
    grad = -lin.jtr / alpha**2 + q @ (theta - problem.theta0)
    try:
        with warnings.catch_warnings():  # ill-conditioned far from the optimum: a large decrement, a high ceiling
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            decrement = float(grad @ scipy.linalg.solve(hess, grad, assume_a="pos"))
    except (np.linalg.LinAlgError, ValueError):
        decrement = math.inf
    # far from the optimum Levenberg-Marquardt converges linearly along curved valleys: a few decrements bound
    # what is left
    return ev, hess, ev + policy.ceiling_decrements * max(decrement, 0.0) + policy.ceiling_margin


def quick_fit(problem, start, alpha, tau, *, max_iter=40, floor=None, budget=False, policy=DEFAULT_POLICY):
    """Levenberg-Marquardt from ``start`` with the hyperparameters held; None if the start is invalid.

    With ``floor``, the fit gives up (``abandoned``) once its ceiling falls
    below ``floor``: it cannot matter to a decision that needs that level.
    With ``budget`` (a fit that counts only if it converges within
    ``max_iter`` steps), also once ``policy.budget_pace`` times the larger of
    its last two gains in every step left would not reach ``floor``: far
    from its optimum the ceiling is no guide.
    """
    q = tau * problem.rough + problem.fixed
    stop, pace = _stopping_rule(problem, alpha, q, floor, budget, max_iter, policy)
    try:
        # stop when the Newton decrement is ~0.01 (log-density units): enough for Bayes factors and scores.
        # Relative to the objective (~ n_data / 2 at the base fit's noise scale) and at least 0.01 absolute:
        # an effect that explains the gap shrinks the objective, and a purely relative test would then ask
        # for ever smaller decrements
        tol = 0.02 / max(problem.n_data, 1)
        theta, lin, it, ok = solve_map(problem, start, alpha, q, problem.theta0, max_iter=max_iter, tol=tol,
                                       stop=stop, atol=0.01)
    except DataError:
        return None
    if lin is None or lin.jtj is None:
        lin = problem.evaluate(theta)
    ev, hess, ceiling = _evidence(problem, lin, theta, alpha, q, policy)
    finite = bool(np.isfinite(ev) and np.all(np.isfinite(hess)))
    converged = bool(ok and finite)
    return QuickFit(problem, theta, hess, float(ev), converged, it, alpha, tau,
                    ceiling=float(ev) if converged else float(ceiling),
                    abandoned=bool(not converged and floor is not None and (ceiling < floor or pace.too_slow)))


class _Pace:
    """The evidence a fit reached at each step, and whether it gave up at its pace (``too_slow``)."""

    def __init__(self):
        self.reached = []
        self.too_slow = False


def _stopping_rule(problem, alpha, q, floor, budget, max_iter, policy):
    """(the ``stop`` callback of :func:`solve_map` or None, the fit's :class:`_Pace`) for ``floor``, ``budget``."""
    pace = _Pace()
    if floor is None:
        return None, pace

    def stop(theta, lin):
        ev, _, ceiling = _evidence(problem, lin, theta, alpha, q, policy)
        reached = pace.reached
        reached.append(ev)
        if ceiling < floor:
            return True
        if not budget or len(reached) < 3:
            return False
        gain = max(reached[-1] - reached[-2], reached[-2] - reached[-3])
        pace.too_slow = ev < floor and policy.budget_pace * gain * (max_iter - len(reached)) < floor - ev
        return pace.too_slow

    return stop, pace

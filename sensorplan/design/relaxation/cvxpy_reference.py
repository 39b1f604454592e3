"""Reference relaxation: the generic cvxpy formulation of any criterion, solved by Clarabel.

Owns: the cvxpy model of the relaxation and the Clarabel solve-and-check.
May import: errors, design.relaxation.
"""

import time
import warnings

import numpy as np

from ..._errors import SolverError
from .base import Relaxation, repair_weights
from .registry import register_relaxation_solver

__all__ = ["solve_relaxation_cvxpy", "solve_clarabel"]


@register_relaxation_solver("cvxpy")
def solve_relaxation_cvxpy(problem, *, start_layout=None, tol=1e-8, candidates=None):
    """Reference relaxation with cvxpy + Clarabel (optionally restricted to ``candidates``)."""
    import cvxpy as cp

    start = time.perf_counter()
    idx = np.arange(problem.n_candidates) if candidates is None else np.asarray(candidates)
    m = idx.size
    w = cp.Variable(m)
    q = problem.criterion.cvxpy_precision(cp, problem, w, idx)
    constraints = [w >= 0, w <= 1, cp.sum(w) == problem.count]
    a_ub, b_ub = problem.inequalities
    if a_ub.shape[0]:
        rows = a_ub[:, idx]
        keep = np.any(rows != 0, axis=1)
        if np.any(~keep & (b_ub < 0)):
            raise SolverError("The restricted candidate set cannot satisfy the span minimum counts.")
        if keep.any():
            constraints.append(rows[keep] @ w <= b_ub[keep])
    objective, handle = problem.criterion.cvxpy_objective(cp, q, constraints)
    prob = cp.Problem(objective, constraints)
    solve_clarabel(cp, prob, w, tol=tol, what="relaxation")
    status = prob.status
    weights = np.zeros(problem.n_candidates)
    weights[idx] = np.clip(w.value, 0.0, 1.0)
    weights = repair_weights(problem, weights)
    stats = {"solver": "CLARABEL", "status": status, "time_s": time.perf_counter() - start,
             "iterations": prob.solver_stats.num_iters if prob.solver_stats else None,
             "solver_value": float(prob.value)}
    bound = problem.criterion.cvxpy_bound(problem, weights, handle)
    utility = problem.criterion.relaxed_utility(problem, weights)
    if status == cp.OPTIMAL_INACCURATE:
        stats["warning"] = "Clarabel reported an inaccurate solution; the bound is certified independently"
    return Relaxation(weights, utility, max(bound, utility), "cvxpy-clarabel", stats)


def solve_clarabel(cp, prob, w, *, tol, what):
    """Solve the cvxpy problem ``prob`` (variable ``w``) with Clarabel at tolerance ``tol``; SolverError
    (naming ``what``) unless it is (inaccurately) optimal.

    "Solution may be inaccurate" is not a warning here: the status is
    reported in the result and every bound is certified independently
    (:meth:`DesignProblem.dual_bound`).
    """
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol)
    except cp.error.SolverError as exc:
        raise SolverError(f"Clarabel failed on the {what}: {exc}") from None
    if w.value is None or prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        raise SolverError(f"The {what} could not be solved (status {prob.status}); check the constraints.")

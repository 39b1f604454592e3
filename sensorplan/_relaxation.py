"""Convex relaxation of the placement problem, with certified bounds.

Two solvers return the same thing, a :class:`Relaxation` whose ``bound`` is
a certified upper bound on the relaxed utility (hence on every integer
layout), computed by :meth:`DesignProblem.dual_bound` independently of the
solver's own accuracy claims:

* ``solve_relaxation_cvxpy``: the generic cvxpy formulation solved by
  Clarabel (the reference);
* ``solve_relaxation_fast``: column generation.  A small restricted problem
  over a working set of candidates is solved by a log-barrier Newton method
  (exact Hessians, cost m^2 P^2 for m working candidates) and the working set
  grows with the candidates the linear oracle over *all* candidates wants,
  until the duality gap is below the tolerance.  E (non-smooth) solves the
  restricted problem with cvxpy instead.
"""

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize

from ._errors import SolverError

__all__ = ["Relaxation", "solve_relaxation_cvxpy", "solve_relaxation_fast"]


@dataclass(frozen=True, eq=False)
class Relaxation:
    """Solution of the relaxed problem.

    Attributes
    ----------
    weights : ndarray (C,)
    utility : float
        Utility at ``weights`` (a feasible relaxed point).
    bound : float
        Certified bound on the relaxed optimum (utility >= ... <= bound).
    method : str
    stats : dict
        Solver name, status, iterations, time.
    """

    weights: np.ndarray
    utility: float
    bound: float
    method: str
    stats: dict = field(default_factory=dict)

    @property
    def relative_gap(self):
        return (self.bound - self.utility) / max(1.0, abs(self.bound))


def solve_relaxation_cvxpy(problem, *, tol=1e-8, candidates=None):
    """Reference relaxation with cvxpy + Clarabel (optionally restricted to ``candidates``)."""
    import cvxpy as cp

    start = time.perf_counter()
    idx = np.arange(problem.n_candidates) if candidates is None else np.asarray(candidates)
    m = idx.size
    p = problem.n_params
    w = cp.Variable(m)
    flat = problem.flat_blocks[idx].T  # (P*P, m)
    q = problem.q0 + cp.reshape(flat @ w, (p, p), order="C")
    q = 0.5 * (q + q.T)
    constraints = [w >= 0, w <= 1, cp.sum(w) == problem.count]
    a_ub, b_ub = problem.inequalities
    if a_ub.shape[0]:
        rows = a_ub[:, idx]
        keep = np.any(rows != 0, axis=1)
        if np.any(~keep & (b_ub < 0)):
            raise SolverError("The restricted candidate set cannot satisfy the span minimum counts.")
        if keep.any():
            constraints.append(rows[keep] @ w <= b_ub[keep])
    lmi = None
    if problem.criterion.name == "E":
        # maximise t s.t. Q(w) - t I >= 0: the PSD constraint's dual is the
        # matrix Z of the certified bound
        t = cp.Variable()
        lmi = q - t * np.eye(p) >> 0
        constraints.append(lmi)
        objective = cp.Maximize(t)
    else:
        objective = problem.criterion.cvxpy_objective(cp, q, constraints)
    prob = cp.Problem(objective, constraints)
    try:
        with warnings.catch_warnings():
            # the status is checked and reported below
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol)
    except cp.error.SolverError as exc:
        raise SolverError(f"Clarabel failed on the relaxation: {exc}") from None
    status = prob.status
    if w.value is None or status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        raise SolverError(f"The relaxation could not be solved (status {status}); check the constraints.")
    weights = np.zeros(problem.n_candidates)
    weights[idx] = np.clip(w.value, 0.0, 1.0)
    weights = _repair(problem, weights)
    stats = {"solver": "CLARABEL", "status": status, "time_s": time.perf_counter() - start,
             "iterations": prob.solver_stats.num_iters if prob.solver_stats else None,
             "solver_value": float(prob.value)}
    if problem.criterion.name == "E":
        dual = lmi.dual_value
        bound = problem.e_bound(dual) if dual is not None else problem.dual_bound(weights)
    else:
        bound = problem.dual_bound(weights)
    utility = problem.criterion.utility(problem.precision(weights))
    if status == cp.OPTIMAL_INACCURATE:
        stats["warning"] = "Clarabel reported an inaccurate solution; the bound is certified independently"
    return Relaxation(weights, utility, max(bound, utility), "cvxpy-clarabel", stats)


def _repair(problem, w):
    """Project solver round-off: clip to [0, 1] and rescale to the exact count."""
    w = np.clip(w, 0.0, 1.0)
    total = w.sum()
    if total > 0:
        w = w * (problem.count / total)
        w = np.clip(w, 0.0, 1.0)
    return w


def solve_relaxation_fast(problem, *, tol=1e-7, start_layout=None, max_rounds=30):
    """Column-generation relaxation with a certified duality gap (relative ``tol``)."""
    t0 = time.perf_counter()
    c = problem.n_candidates
    w_uniform = np.full(c, problem.count / c)
    g = problem.gradient(w_uniform)
    size = min(c, max(3 * problem.count + 10, 20))
    working = set(np.argsort(g)[::-1][:size].tolist())
    if start_layout is not None:
        working |= set(int(i) for i in start_layout)
    weights = None
    newton_iters = 0
    for rounds in range(1, max_rounds + 1):
        idx = np.array(sorted(working))
        if problem.criterion.name == "E":
            rel = solve_relaxation_cvxpy(problem, candidates=idx, tol=tol * 1e-2)
            weights = rel.weights
        else:
            weights, it = _barrier_restricted(problem, idx, weights, tol=tol * 1e-2)
            newton_iters += it
        utility = problem.criterion.utility(problem.precision(weights))
        if problem.criterion.name == "E":
            bound = rel.bound
            grad = problem.flat_blocks @ problem.criterion.gradient_matrix(problem.precision(weights)).ravel()
        else:
            grad = problem.gradient(weights)
            best, _ = problem.linear_max(grad)
            bound = utility + max(0.0, best - float(grad @ weights))
        gap = (bound - utility) / max(1.0, abs(bound))
        if gap <= tol or len(working) == c:
            break
        outside = np.array([i for i in range(c) if i not in working])
        add = outside[np.argsort(grad[outside])[::-1][: max(problem.count, 10)]]
        _, s = problem.linear_max(grad)
        add = np.union1d(add, np.nonzero(s > 1e-9)[0])
        before = len(working)
        working |= set(add.tolist())
        if len(working) == before:
            break
    if problem.criterion.name == "E":
        bound = max(bound, problem.dual_bound(weights))
        bound = min(bound, rel.bound) if np.isfinite(rel.bound) else bound
    stats = {"solver": "column-generation+barrier-newton" if problem.criterion.name != "E"
             else "column-generation+clarabel", "status": "optimal" if gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "newton_iterations": newton_iters,
             "time_s": time.perf_counter() - t0}
    return Relaxation(weights, utility, max(bound, utility), "fast", stats)


def _restricted_hessian(problem, idx, q):
    """Hessian of the utility restricted to candidates ``idx`` (D, Ds, A)."""
    crit = problem.criterion
    blocks = problem.blocks[idx]
    chol = np.linalg.cholesky(q)
    inv = scipy.linalg.cho_solve((chol, True), np.eye(q.shape[0]))
    if crit.name in ("D", "Ds"):
        li = np.linalg.inv(chol)  # Q^{-1} = L^-T L^-1
        b = (li @ blocks @ li.T).reshape(idx.size, -1)
        h = -b @ b.T
        if crit.name == "Ds" and crit.n_keep < q.shape[0]:
            k = crit.n_keep
            qs = q[k:, k:]
            ls = np.linalg.inv(np.linalg.cholesky(qs))
            bs = (ls @ blocks[:, k:, k:] @ ls.T).reshape(idx.size, -1)
            h += bs @ bs.T
        return h
    # A: utility -tr(C Q^-1 C^T); H_ij = -2 tr(M I_i Q^-1 I_j), M = Q^-1 C^T C Q^-1
    qi_ct = inv @ crit.targets.T
    mmat = qi_ct @ qi_ct.T
    y = (mmat @ blocks @ inv).reshape(idx.size, -1)
    h = -2.0 * y @ blocks.reshape(idx.size, -1).T
    return 0.5 * (h + h.T)


def _barrier_restricted(problem, idx, w_prev, *, tol):
    """Maximise the utility over candidates ``idx`` by a log-barrier Newton method."""
    c = problem.n_candidates
    m = idx.size
    a_ub, b_ub = problem.inequalities
    rows = a_ub[:, idx] if a_ub.shape[0] else np.zeros((0, m))
    # inequalities G x <= h: side constraints plus the box 0 <= x <= 1
    g_mat = np.vstack([rows, np.eye(m), -np.eye(m)])
    h_vec = np.concatenate([b_ub, np.ones(m), np.zeros(m)])
    x = _interior_start(g_mat, h_vec, m, problem.count, w_prev, idx)
    full = np.zeros(c)

    def utility_grad(xv):
        full[:] = 0.0
        full[idx] = xv
        q = problem.precision(full)
        try:
            u = problem.criterion.utility(q)
        except Exception:
            return -np.inf, None, None
        gm = problem.criterion.gradient_matrix(q)
        return u, problem.flat_blocks[idx] @ gm.ravel(), q

    t = 1.0
    n_ineq = h_vec.size
    u0, _, _ = utility_grad(x)
    t = max(1.0, n_ineq / max(abs(u0), 1.0))
    iters = 0
    while True:
        for _ in range(100):
            u, g, q = utility_grad(x)
            slack = h_vec - g_mat @ x
            grad = -t * g + g_mat.T @ (1.0 / slack)
            hess = -t * _restricted_hessian(problem, idx, q) + (g_mat.T * (1.0 / slack**2)) @ g_mat
            # Newton step with the equality sum(x) = count (KKT system).
            kkt = np.zeros((m + 1, m + 1))
            kkt[:m, :m] = hess
            kkt[:m, m] = 1.0
            kkt[m, :m] = 1.0
            rhs = np.concatenate([-grad, [0.0]])
            try:
                step = np.linalg.solve(kkt, rhs)[:m]
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(kkt, rhs, rcond=None)[0][:m]
            decrement = float(-grad @ step)
            iters += 1
            if decrement / 2 <= 1e-12:
                break
            # backtracking on the barrier objective, staying strictly feasible
            s = 1.0
            gs = g_mat @ step
            pos = gs > 0
            if pos.any():
                s = min(1.0, 0.99 * float(np.min(slack[pos] / gs[pos])))
            phi = -t * u - np.sum(np.log(slack))
            while s > 1e-14:
                xn = x + s * step
                sn = h_vec - g_mat @ xn
                if np.all(sn > 0):
                    un, _, _ = utility_grad(xn)
                    if np.isfinite(un) and -t * un - np.sum(np.log(sn)) <= phi - 0.25 * s * decrement:
                        break
                s *= 0.5
            if s <= 1e-14:
                break
            x = x + s * step
        if n_ineq / t < tol * max(1.0, abs(u)):
            break
        t *= 20.0
    full[:] = 0.0
    full[idx] = x
    return full.copy(), iters


def _interior_start(g_mat, h_vec, m, count, w_prev, idx):
    """A strictly feasible start: the previous solution pulled inside, or a max-slack LP point."""
    if w_prev is not None:
        x = 0.98 * w_prev[idx] + 0.02 * count / m
        if abs(x.sum() - count) < 1e-9 and np.all(h_vec - g_mat @ x > 1e-12):
            return x
    # maximise the common slack s: G x + s <= h, sum x = count, s <= 1
    a_ub = np.hstack([g_mat, np.ones((g_mat.shape[0], 1))])
    res = scipy.optimize.linprog(np.concatenate([np.zeros(m), [-1.0]]), A_ub=a_ub, b_ub=h_vec,
                                 A_eq=np.concatenate([np.ones(m), [0.0]])[None, :], b_eq=[count],
                                 bounds=[(None, None)] * m + [(None, 1.0)], method="highs")
    if res.status != 0 or res.x[-1] <= 1e-9:
        raise SolverError("The placement constraints leave no interior point in the working set; "
                          "relax the budget, span counts or spacing.")
    return res.x[:m]

"""Convex relaxation of the placement problem, with certified bounds.

Two solvers return the same thing, a :class:`Relaxation` whose ``bound`` is
a certified upper bound on the relaxed utility (hence on every integer
layout), computed by :meth:`DesignProblem.dual_bound` independently of the
solver's own accuracy claims:

* ``solve_relaxation_cvxpy``: the generic cvxpy formulation solved by
  Clarabel (the reference);
* ``solve_relaxation_fast``: column generation.  For D, Ds and A a problem
  restricted to a working set of candidates is solved by a primal-dual
  interior-point method (exact Hessians, cost m P^3 + m^2 P^2 for m working
  candidates) and the working set grows with the candidates whose gradient
  beats the count multiplier, until the duality gap over *all* candidates
  is below the tolerance.  E (non-smooth) is solved by an eigen-subspace
  cutting-plane method: small k x k SDPs, each by a Schur-complement
  primal-dual interior-point method (:func:`_lmi_ipm`; Clarabel if it
  fails).
"""

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize

from .._errors import SolverError

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
    _solve_clarabel(cp, prob, w, tol, "relaxation")
    status = prob.status
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


def _solve_clarabel(cp, prob, w, tol, what):
    """Solve ``prob`` with Clarabel; SolverError unless (inaccurately) optimal.

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


def _repair(problem, w):
    """Project solver round-off: clip to [0, 1] and rescale to the exact count."""
    w = np.clip(w, 0.0, 1.0)
    total = w.sum()
    if total > 0:
        w = w * (problem.count / total)
        w = np.clip(w, 0.0, 1.0)
    return w


def solve_relaxation_fast(problem, *, tol=1e-7, start_layout=None, max_rounds=50):
    """Relaxation by column generation with a certified duality gap (relative ``tol``).

    D, Ds and A: a primal-dual interior-point method (exact Hessians) solves
    the problem restricted to a working set of candidates; the linear
    oracle over *all* candidates then gives the certified bound, and the
    candidates whose gradient exceeds the multiplier of the count
    constraint join the working set, until the gap is below ``tol``.
    E: see :func:`_solve_e_subspace`.
    """
    if problem.criterion.name == "E":
        return _solve_e_subspace(problem, tol=tol, start_layout=start_layout, max_rounds=max_rounds)
    t0 = time.perf_counter()
    c = problem.n_candidates
    crit = problem.criterion
    g = problem.gradient(np.full(c, problem.count / c))
    size = min(c, max(4 * problem.count + 20, c // 8))
    working = set(np.argsort(-g, kind="stable")[:size].tolist())
    if start_layout is not None:
        working |= set(int(i) for i in start_layout)
    weights, nu = None, None
    newton_iters = 0
    gap = np.inf
    dropped = set()
    inner = 1e-3  # early rounds only locate the support: solve them loosely
    for rounds in range(1, max_rounds + 1):
        idx = np.array(sorted(working))
        x, nu, it = _pdip_restricted(problem, idx, weights, tol=inner)
        newton_iters += it
        weights = np.zeros(c)
        weights[idx] = x
        weights = _repair(problem, weights)
        q = problem.precision(weights)
        utility = crit.utility(q)
        grad = problem.flat_blocks @ crit.gradient_matrix(q).ravel()
        best, s = problem.linear_max(grad)
        bound = utility + max(0.0, best - float(grad @ weights))
        gap = (bound - utility) / max(1.0, abs(bound))
        if gap <= tol or len(working) == c and inner <= 0.1 * tol:
            break
        outside = np.setdiff1d(np.arange(c), idx)
        # candidates that would enter: gradient above the multiplier of sum(w) = R
        enter = outside[grad[outside] > nu]
        enter = enter[np.argsort(-grad[enter], kind="stable")][: max(2 * problem.count, 20, idx.size // 2)]
        enter = np.union1d(enter, np.setdiff1d(np.nonzero(s > 1e-9)[0], idx))
        if enter.size == 0:
            if inner <= 0.1 * tol:
                break
            inner = 0.1 * tol  # the support is found: solve accurately
            continue
        inner = max(0.1 * tol, min(inner, 0.1 * gap))
        # drop candidates that look out (small weight, gradient below the multiplier);
        # a candidate is dropped at most once, so the rounds cannot cycle
        drop = [i for i in idx[(x < 1e-2) & (grad[idx] < nu)].tolist() if i not in dropped]
        dropped.update(drop)
        working -= set(drop)
        working |= set(enter.tolist())
    stats = {"solver": "column-generation+interior-point", "status": "optimal" if gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "newton_iterations": newton_iters,
             "time_s": time.perf_counter() - t0}
    return Relaxation(weights, utility, max(bound, utility), "fast", stats)


def _derivatives(problem, blocks, flat, x, *, hessian=True, blocks_h=None):
    """Utility, gradient and Hessian in the restricted weights ``x`` (D, Ds, A).

    ``blocks`` (m, P, P) and ``flat`` (m, P*P) are the working-set blocks;
    ``blocks_h`` a single-precision copy used for the Hessian only (the
    Newton direction needs a few digits; utility, gradient and hence the
    interior-point residuals and the certificate stay in double precision).
    D: H_ij = -<A_i, A_j>, A_i = L^-1 I_i L^-T (Q = L L^T), symmetric, so the
    Gram matrix is formed on the upper triangles (off-diagonals scaled by sqrt 2).
    A: utility -tr(C Q^-1 C^T); H_ij = -2 tr(M I_i Q^-1 I_j) with
    M = Q^-1 C^T C Q^-1 = N N^T, N = Q^-1 C^T, so H_ij = -2 <B_i, B_j> with
    B_i = L^-1 I_i N.
    """
    crit = problem.criterion
    m, p, _ = blocks.shape
    q = problem.q0 + (x @ flat).reshape(p, p)
    q = 0.5 * (q + q.T)
    try:
        chol = np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        return -np.inf, None, None
    gmat = crit.gradient_matrix(q)
    u = crit.utility(q)
    grad = flat @ gmat.ravel()
    if not hessian:
        return u, grad, None
    bh = blocks if blocks_h is None else blocks_h
    dtype = bh.dtype
    stacked = bh.reshape(m * p, p)
    li = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True)
    if crit.name in ("D", "Ds"):
        lt = li.T.astype(dtype)
        # X_i = I_i L^-T; A_i = L^-1 X_i = X_i^T L^-T (A_i symmetric): two tall products
        xt = (stacked @ lt).reshape(m, p, p).transpose(0, 2, 1).reshape(m * p, p)
        a = (xt @ lt).reshape(m, p, p)
        h = -_gram_sym(a)
        if crit.name == "Ds" and crit.n_keep < p:
            k = crit.n_keep
            ls = np.linalg.inv(np.linalg.cholesky(q[k:, k:])).astype(dtype)
            h += _gram_sym(np.matmul(ls, np.matmul(bh[:, k:, k:], ls.T)))
    else:
        n = scipy.linalg.cho_solve((chol, True), crit.targets.T)
        # B_i = L^-1 I_i N: B_i^T = N^T I_i L^-T, so B^T stacked is (stacked N)^T-blocks times L^-T
        nt = n.shape[1]
        y = (stacked @ n.astype(dtype)).reshape(m, p, nt).transpose(0, 2, 1).reshape(m * nt, p)
        b = (y @ li.T.astype(dtype)).reshape(m, -1)
        h = -2.0 * (b @ b.T).astype(float)
    return u, grad, 0.5 * (h + h.T)


def _gram_sym(a):
    """<A_i, A_j>_F for symmetric A (m, P, P), from the upper triangles, in double precision."""
    p = a.shape[1]
    iu = np.triu_indices(p)
    scale = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0)).astype(a.dtype)
    v = a[:, iu[0], iu[1]] * scale
    return (v @ v.T).astype(float)


def _pdip_restricted(problem, idx, w_prev, *, tol, max_iter=200):
    """Maximise the utility over candidates ``idx``: primal-dual interior point.

    Boyd & Vandenberghe, Convex Optimization (2004), section 11.7: inequalities
    G x <= h (side constraints and the box), equality sum(x) = R; returns
    (x, nu, iterations) with nu the multiplier of the equality (the
    threshold a candidate's gradient must exceed to enter).
    """
    m = idx.size
    a_ub, b_ub = problem.inequalities
    rows = a_ub[:, idx] if a_ub.shape[0] else np.zeros((0, m))
    keep = np.any(rows != 0, axis=1)
    if np.any(~keep & (b_ub < 0)):
        raise SolverError("The working set cannot satisfy the span minimum counts.")
    rows, rhs = rows[keep], b_ub[keep]
    k = rows.shape[0]
    h_vec = np.concatenate([rhs, np.ones(m), np.zeros(m)])
    n_ineq = h_vec.size
    count = problem.count
    blocks = problem.blocks[idx]
    flat = blocks.reshape(m, -1)
    blocks_h = blocks.astype(np.float32)

    # G = [rows; I; -I] applied without forming it (the box is diagonal)
    def g_dot(v):
        return np.concatenate([rows @ v, v, -v])

    def gt_dot(v):
        return rows.T @ v[:k] + v[k:k + m] - v[k + m:]

    if w_prev is None or k:
        x = _interior_start(np.vstack([rows, np.eye(m), -np.eye(m)]), h_vec, m, count, w_prev, idx)
    else:
        x = _interior_start_box(m, count, w_prev, idx)
    slack = h_vec - g_dot(x)
    lam = 1.0 / slack
    nu = 0.0
    ones = np.ones(m)
    growth, alpha, beta = 10.0, 0.01, 0.5

    def residuals(xv, lv, nv, t):
        u, g, _ = _derivatives(problem, blocks, flat, xv, hessian=False)
        sl = h_vec - g_dot(xv)
        r_dual = -g + gt_dot(lv) + nv * ones
        r_cent = lv * sl - 1.0 / t
        r_pri = xv.sum() - count
        return u, np.sqrt(r_dual @ r_dual + r_cent @ r_cent + r_pri * r_pri)

    u, g, hess = _derivatives(problem, blocks, flat, x, blocks_h=blocks_h)
    for it in range(1, max_iter + 1):
        eta = float(slack @ lam)
        t = growth * n_ineq / eta
        r_dual = -g + gt_dot(lam) + nu * ones
        scale = max(1.0, float(np.max(np.abs(g))))
        if eta <= tol * max(1.0, abs(u)) and np.max(np.abs(r_dual)) <= tol * scale \
                and abs(x.sum() - count) <= 1e-9 * count:
            break
        d = lam / slack
        kmat = -hess
        kmat[np.diag_indices(m)] += d[k:k + m] + d[k + m:]
        if k:
            kmat += (rows.T * d[:k]) @ rows
        rhs_x = g - nu * ones - gt_dot(1.0 / (t * slack))
        # eliminate the equality: K dx + dnu 1 = rhs_x, 1^T dx = count - sum(x)
        try:
            factor = scipy.linalg.cho_factor(kmat, check_finite=False)
            y = scipy.linalg.cho_solve(factor, np.column_stack([rhs_x, ones]), check_finite=False)
            dnu = (y[:, 0].sum() - (count - x.sum())) / y[:, 1].sum()
            dx = y[:, 0] - dnu * y[:, 1]
        except (np.linalg.LinAlgError, ZeroDivisionError):
            kkt = np.zeros((m + 1, m + 1))
            kkt[:m, :m] = kmat
            kkt[:m, m] = kkt[m, :m] = 1.0
            sol = np.linalg.lstsq(kkt, np.concatenate([rhs_x, [count - x.sum()]]), rcond=None)[0]
            dx, dnu = sol[:m], sol[m]
        gdx = g_dot(dx)
        dlam = (lam * gdx - (lam * slack - 1.0 / t)) / slack
        step = 1.0
        neg = dlam < 0
        if neg.any():
            step = min(1.0, float(np.min(-lam[neg] / dlam[neg])))
        step *= 0.99
        pos = gdx > 0
        if pos.any():
            step = min(step, 0.99 * float(np.min(slack[pos] / gdx[pos])))
        r0 = np.sqrt(r_dual @ r_dual + np.sum((lam * slack - 1.0 / t) ** 2) + (x.sum() - count) ** 2)
        while step > 1e-12:
            un, rn = residuals(x + step * dx, lam + step * dlam, nu + step * dnu, t)
            if np.isfinite(un) and rn <= (1.0 - alpha * step) * r0:
                break
            step *= beta
        if step <= 1e-12:
            break
        x = x + step * dx
        lam = lam + step * dlam
        nu = nu + step * dnu
        slack = h_vec - g_dot(x)
        u, g, hess = _derivatives(problem, blocks, flat, x, blocks_h=blocks_h)
    return np.clip(x, 0.0, 1.0), float(nu), it


def _solve_e_subspace(problem, *, tol, start_layout=None, max_rounds=50, k0=10):
    """E relaxation by an eigen-subspace cutting-plane method (a spectral bundle method).

    For an orthonormal basis V (P x k), lambda_min(V^T Q V) >= lambda_min(Q)
    for every Q, so the small SDP  max_w lambda_min(V^T Q(w) V)  is a relaxation of the
    E problem (a k x k LMI over a working set of candidates, solved by
    :func:`_small_e_sdp`).  Its dual matrix Z_k gives Z = V Z_k V^T, trace one and
    PSD, hence a certified bound over *all* candidates
    (:meth:`DesignProblem.e_bound`); the eigenvectors of Q(w) with eigenvalues
    below the small SDP's value join V and candidates whose <Z, I_i> exceeds the
    count multiplier join the working set, until the gap is below ``tol``.
    Helmberg & Rendl, SIAM J. Optim. 10 (2000) 673-696.
    """
    t0 = time.perf_counter()
    c, p, r = problem.n_candidates, problem.n_params, problem.count
    w = np.full(c, r / c)
    lam, vec = np.linalg.eigh(problem.precision(w))
    basis = vec[:, : min(p, k0)]
    g = problem.flat_blocks @ (basis @ basis.T).ravel()
    size = min(c, max(4 * r + 20, c // 4))
    working = set(np.argsort(-g, kind="stable")[:size].tolist())
    if start_layout is not None:
        working |= set(int(i) for i in start_layout)
    best = (-np.inf, None)
    bound, gap, sdp_time, fallbacks = np.inf, np.inf, 0.0, 0
    for rounds in range(1, max_rounds + 1):
        idx = np.array(sorted(working))
        small_value, wr, z_small, nu, dt, used = _small_e_sdp(problem, idx, basis, tol=0.01 * tol)
        sdp_time += dt
        fallbacks += used == "clarabel"
        w = np.zeros(c)
        w[idx] = wr
        w = _repair(problem, w)
        lam, vec = np.linalg.eigh(problem.precision(w))
        if lam[0] > best[0]:
            best = (float(lam[0]), w)
        z = basis @ z_small @ basis.T
        bound = min(bound, problem.e_bound(z))
        gap = (bound - best[0]) / max(1.0, abs(bound))
        if gap <= tol:
            break
        grown = False
        trace = max(float(np.trace(z)), 1e-300)
        gz = problem.flat_blocks @ (z / trace).ravel()
        threshold = nu / trace
        if small_value < bound - 0.1 * tol * max(1.0, abs(bound)) and len(working) < c:
            # the working set limits the small SDP: add the candidates that would enter
            outside = np.setdiff1d(np.arange(c), idx)
            enter = outside[gz[outside] > threshold]
            enter = enter[np.argsort(-gz[enter], kind="stable")][: max(2 * r, 20)]
            working |= set(enter.tolist())
            grown = enter.size > 0
        # candidates with no weight and a gradient well below the threshold leave
        # (the SDP is solved afresh each round, so a smaller set only saves time)
        working -= set(idx[(wr < 1e-7) & (gz[idx] < threshold - 0.05 * abs(threshold))].tolist())
        sel = np.nonzero(lam < small_value)[0][:8]
        if sel.size:
            new = vec[:, sel] - basis @ (basis.T @ vec[:, sel])
            norms = np.linalg.norm(new, axis=0)
            if np.any(norms > 1e-8):
                basis = np.linalg.qr(np.hstack([basis, new[:, norms > 1e-8] / norms[norms > 1e-8]]))[0]
                grown = True
        if not grown:
            break
    stats = {"solver": "eigen-subspace+interior-point", "status": "optimal" if gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "subspace": basis.shape[1],
             "sdp_time_s": sdp_time, "clarabel_fallbacks": fallbacks, "time_s": time.perf_counter() - t0}
    return Relaxation(best[1], best[0], max(bound, best[0]), "fast", stats)


def _small_e_sdp(problem, idx, basis, *, tol):
    """max t s.t. V^T Q(w) V - t I >= 0 over candidates ``idx``.

    Solved by :func:`_lmi_ipm`; if that does not converge, by cvxpy + Clarabel.
    Returns (value, w, Z_k, nu, time, solver).
    """
    start = time.perf_counter()
    m = idx.size
    b0 = basis.T @ problem.q0 @ basis
    bmat = np.matmul(basis.T, np.matmul(problem.blocks[idx], basis))
    bmat = 0.5 * (bmat + bmat.transpose(0, 2, 1))
    a_ub, b_ub = problem.inequalities
    rows, rhs = np.zeros((0, m)), np.zeros(0)
    if a_ub.shape[0]:
        rows = a_ub[:, idx]
        keep = np.any(rows != 0, axis=1)
        if np.any(~keep & (b_ub < 0)):
            raise SolverError("The working set cannot satisfy the span minimum counts.")
        rows, rhs = rows[keep], b_ub[keep]
    value, w, z, nu, status, _ = _lmi_ipm(0.5 * (b0 + b0.T), bmat, rows, rhs, problem.count, tol=tol)
    if status == "optimal":
        return value, np.clip(w, 0.0, 1.0), z, abs(nu), time.perf_counter() - start, "interior-point"
    value, w, z, nu = _small_e_sdp_clarabel(b0, bmat, rows, rhs, problem.count, tol=tol)
    return value, w, z, nu, time.perf_counter() - start, "clarabel"


def _small_e_sdp_clarabel(b0, bmat, rows, rhs, count, *, tol):
    import cvxpy as cp

    m, k, _ = bmat.shape
    w = cp.Variable(m)
    t = cp.Variable()
    mat = b0 + cp.reshape(bmat.reshape(m, -1).T @ w, (k, k), order="C")
    lmi = 0.5 * (mat + mat.T) - t * np.eye(k) >> 0
    count_eq = cp.sum(w) == count
    constraints = [w >= 0, w <= 1, count_eq, lmi]
    if rows.shape[0]:
        constraints.append(rows @ w <= rhs)
    prob = cp.Problem(cp.Maximize(t), constraints)
    _solve_clarabel(cp, prob, w, tol, "E relaxation")
    z = lmi.dual_value
    nu = abs(float(count_eq.dual_value)) if count_eq.dual_value is not None else 0.0
    return float(prob.value), np.clip(w.value, 0.0, 1.0), 0.5 * (z + z.T), nu


def _lmi_ipm(b0, bmat, rows, rhs, count, *, tol=1e-9, max_iter=100):
    """max t s.t. B0 + sum_i w_i B_i - t I >= 0, 0 <= w <= 1, rows w <= rhs, sum w = count.

    A primal-dual path-following method for this small SDP (k x k LMI, m
    weights): HKM search direction with Mehrotra's predictor-corrector,
    infeasible start, the Newton system reduced to the (m + 1) x (m + 1)
    Schur complement M_ij = tr(A_i X A_j Z^-1) plus the diagonal of the
    linear inequalities (Helmberg, Rendl, Vanderbei & Wolkowicz, SIAM J.
    Optim. 6 (1996) 342-361; Todd, Toh & Tutuncu, SIAM J. Optim. 8 (1998)
    769-796).  In the dual standard form max b^T y s.t. Z = C - sum_j y_j A_j >= 0,
    y = (w, t), C = B0, A_i = -B_i, A_t = I, b = e_t; the primal matrix X is
    the LMI's multiplier (trace one).  Forming M costs m k^3 + m^2 k^2, far
    less than a general conic solver's factorisation of the full KKT system.

    Returns (t, w, X, nu, status, iterations), nu the multiplier of
    sum w = count.  ``status`` is "optimal" when the relative gap, the dual
    residuals and the sum constraint are within ``tol`` and the primal
    residual (the multiplier equations, which only affect the quality of X
    as a certificate, checked independently by the caller) within 1e-5.
    """
    m, k, _ = bmat.shape
    g_w = np.vstack([rows, np.eye(m), -np.eye(m)])  # G y <= h acts on w only
    h = np.concatenate([rhs, np.ones(m), np.zeros(m)])
    bflat = bmat.reshape(m, k * k)
    eye = np.eye(k)
    ones = np.concatenate([np.ones(m), [0.0]])

    def astar(v):  # sum_j v_j A_j
        return -(v[:m] @ bflat).reshape(k, k) + v[m] * eye

    def a_op(x):  # (<A_j, X>)_j
        return np.concatenate([-(bflat @ x.ravel()), [np.trace(x)]])

    def gt(v):
        return np.concatenate([g_w.T @ v, [0.0]])

    b = np.zeros(m + 1)
    b[m] = 1.0
    w0 = np.full(m, count / m)
    s0 = b0 + (w0 @ bflat).reshape(k, k)
    y = np.concatenate([w0, [np.linalg.eigvalsh(0.5 * (s0 + s0.T))[0] - 1.0]])
    z = eye * max(1.0, float(np.max(np.abs(s0))))
    x = eye / k
    s = np.maximum(h - g_w @ y[:m], 1.0)
    lam = np.ones(h.size)
    nu = 0.0
    n_cone = k + h.size
    best, extra = None, 0
    for it in range(1, max_iter + 1):
        r_p = b - a_op(x) - gt(lam) - nu * ones
        r_d = b0 - astar(y) - z
        r_d = 0.5 * (r_d + r_d.T)
        r_s = h - g_w @ y[:m] - s
        r_e = count - y[:m].sum()
        gap = float(np.sum(x * z) + s @ lam)
        scale = max(1.0, abs(float(y[m])))
        pobj = float(np.sum(b0 * x) + h @ lam + count * nu)
        dual_ok = (np.linalg.norm(r_d) <= tol * (1.0 + np.linalg.norm(b0))
                   and np.linalg.norm(r_s) <= tol * (1.0 + np.linalg.norm(h)) and abs(r_e) <= tol * (1.0 + count))
        ok = dual_ok and gap <= tol * scale and abs(pobj - y[m]) <= 10 * tol * scale \
            and np.linalg.norm(r_p) <= 1e-5 * (1.0 + np.linalg.norm(b))
        if ok:
            best = (float(y[m]), y[:m].copy(), x.copy(), float(nu))
            extra += 1  # a few more steps to tighten the primal residual
            if extra > 3 or gap <= 0.1 * tol * scale and np.linalg.norm(r_p) <= tol:
                break
        mu = gap / n_cone
        try:
            zc = np.linalg.cholesky(z)
            xc = np.linalg.cholesky(x)
            zi = scipy.linalg.cho_solve((zc, True), eye)
            zi = 0.5 * (zi + zi.T)
            xbz = np.matmul(np.matmul(x, bmat), zi)  # X B_j Z^-1
            mmat = np.empty((m + 1, m + 1))
            mmat[:m, :m] = bflat @ xbz.reshape(m, -1).T
            xz = x @ zi
            col = -np.einsum("ij,mji->m", xz, bmat)
            mmat[:m, m] = mmat[m, :m] = col
            mmat[m, m] = np.trace(xz)
            mmat = 0.5 * (mmat + mmat.T)
            mmat[:m, :m] += (g_w.T * (lam / s)) @ g_w
            factor = scipy.linalg.cho_factor(mmat, check_finite=False)
        except np.linalg.LinAlgError:
            break
        u1 = scipy.linalg.cho_solve(factor, ones, check_finite=False)

        def direction(rc_x, rc_lin):
            rhs_y = r_p - a_op(rc_x - x @ r_d @ zi) - gt((rc_lin - lam * r_s) / s)
            u0 = scipy.linalg.cho_solve(factor, rhs_y, check_finite=False)
            dnu = (ones @ u0 - r_e) / (ones @ u1)
            dy = u0 - dnu * u1
            dz = r_d - astar(dy)
            dx = rc_x - x @ dz @ zi
            ds = r_s - g_w @ dy[:m]
            return 0.5 * (dx + dx.T), dy, dz, ds, (rc_lin - lam * ds) / s, dnu

        def max_steps(dx, dz, ds, dlam):
            steps = []
            for chol, dmat, v, dv in ((xc, dx, lam, dlam), (zc, dz, s, ds)):
                li = scipy.linalg.solve_triangular(chol, eye, lower=True, check_finite=False)
                low = np.linalg.eigvalsh(li @ dmat @ li.T)[0]
                a = 1.0 if low >= 0 else min(1.0, -1.0 / low)
                neg = dv < 0
                if neg.any():
                    a = min(a, float(np.min(-v[neg] / dv[neg])))
                steps.append(a)
            return steps

        dx, dy, dz, ds, dlam, dnu = direction(-x, -lam * s)  # predictor (affine scaling)
        ap, ad = max_steps(dx, dz, ds, dlam)
        gap_aff = float(np.sum((x + ap * dx) * (z + ad * dz)) + (s + ad * ds) @ (lam + ap * dlam))
        sigma = (max(gap_aff, 0.0) / gap) ** 3
        dx, dy, dz, ds, dlam, dnu = direction(sigma * mu * zi - x - dx @ dz @ zi,  # corrector
                                              sigma * mu - lam * s - dlam * ds)
        ap, ad = max_steps(dx, dz, ds, dlam)
        ap, ad = 0.98 * ap, 0.98 * ad
        x = x + ap * dx
        x = 0.5 * (x + x.T)
        lam = lam + ap * dlam
        nu = nu + ap * dnu
        y = y + ad * dy
        z = z + ad * dz
        z = 0.5 * (z + z.T)
        s = s + ad * ds
    if best is None:
        return float(y[m]), y[:m], x, float(nu), "max iterations" if it == max_iter else "numerical problems", it
    return (*best, "optimal", it)


def _interior_start_box(m, count, w_prev, idx):
    """Strictly inside 0 < x < 1, sum x = count: the previous weights pulled towards uniform."""
    x = 0.9 * w_prev[idx] + 0.1 * count / m
    x *= count / x.sum()
    if np.all(x > 0) and np.all(x < 1):
        return x
    return np.full(m, count / m)


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

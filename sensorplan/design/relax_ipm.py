"""Relaxation of smooth criteria by column generation and a primal-dual interior point.

A problem restricted to a working set of candidates is solved by a
primal-dual interior-point method with the criterion's exact Hessian
(:meth:`Criterion.hessian`); the linear oracle over *all* candidates then
gives the certified bound, and the candidates whose gradient beats the
multiplier of the count constraint join the working set, until the duality
gap over all candidates is below the tolerance.

Owns: column generation, the restricted interior point, interior starts.
May import: model, errors, design.relaxation, design.problem.
"""

import time

import numpy as np
import scipy.linalg
import scipy.optimize

from .._errors import SolverError
from .relaxation import Relaxation, _repair

__all__ = ["solve_column_generation"]


def solve_column_generation(problem, *, tol=1e-7, start_layout=None, max_rounds=50):
    """Relaxation by column generation with a certified duality gap (relative ``tol``).

    D, Ds and A: a primal-dual interior-point method (exact Hessians) solves
    the problem restricted to a working set of candidates; the linear
    oracle over *all* candidates then gives the certified bound, and the
    candidates whose gradient exceeds the multiplier of the count
    constraint join the working set, until the gap is below ``tol``.
    """
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
        try:
            x, nu, it = _pdip_restricted(problem, idx, weights, tol=inner)
        except SolverError:
            if idx.size == c:
                raise
            working = set(range(c))  # the constraints need candidates outside the working set
            idx = np.arange(c)
            x, nu, it = _pdip_restricted(problem, idx, None, tol=inner)
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
    """Utility, gradient and Hessian in the restricted weights ``x``.

    ``blocks`` (m, P, P) and ``flat`` (m, P*P) are the working-set blocks;
    ``blocks_h`` a single-precision copy used for the Hessian only (the
    Newton direction needs a few digits; utility, gradient and hence the
    interior-point residuals and the certificate stay in double precision).
    """
    crit = problem.criterion
    m, p, _ = blocks.shape
    q = problem.q0 + (x @ flat).reshape(p, p)
    q = 0.5 * (q + q.T)
    try:
        chol = np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        return -np.inf, None, None
    u = crit.utility(q)
    grad = flat @ crit.gradient_matrix(q).ravel()
    if not hessian:
        return u, grad, None
    h = crit.hessian(q, chol, blocks if blocks_h is None else blocks_h)
    return u, grad, 0.5 * (h + h.T)


def _pdip_restricted(problem, idx, w_prev, *, tol, max_iter=200):
    """Maximise the utility over candidates ``idx``: primal-dual interior point.

    Boyd & Vandenberghe, Convex Optimization (2004), section 11.7: inequalities
    G x <= h (side constraints and the box), equality sum(x) = R; returns
    (x, nu, iterations) with nu the multiplier of the equality (the
    threshold a candidate's gradient must exceed to enter).
    """
    m = idx.size
    rows, rhs = _working_rows(problem, idx)
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


def _working_rows(problem, idx):
    """(rows, rhs) of the side constraints on the working set ``idx`` that still constrain it."""
    m = idx.size
    a_ub, b_ub = problem.inequalities
    rows = a_ub[:, idx] if a_ub.shape[0] else np.zeros((0, m))
    keep = np.any(rows != 0, axis=1)
    if np.any(~keep & (b_ub < 0)):
        raise SolverError("The working set cannot satisfy the span minimum counts.")
    rows, rhs = rows[keep], b_ub[keep]
    # a row constant on the working set (e.g. a budget with equal costs) is fixed by sum(x) = R:
    # drop it when it holds (it may hold with equality and leave no interior), else infeasible
    constant = np.ptp(rows, axis=1) <= 1e-12 * max(1.0, float(np.abs(rows).max(initial=0.0))) if m else \
        np.ones(rows.shape[0], bool)
    if np.any(constant & (rows[:, 0] * problem.count > rhs + 1e-9 * np.maximum(1.0, np.abs(rhs)))):
        raise SolverError("The working set cannot satisfy the budget or span counts.")
    return rows[~constant], rhs[~constant]


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


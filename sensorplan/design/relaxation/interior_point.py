"""What the interior-point methods of the relaxations share: the restricted polytope, starts, step lengths.

A relaxation restricted to a working set ``idx`` of m candidates has the
linear constraints G x <= h with G = [rows; I; -I] and h = [rhs; 1; 0] (the
side rows that still constrain the working set, then the box 0 <= x <= 1),
and the equality sum(x) = R.  :class:`RestrictedPolytope` applies G and G^T
without forming G (the box is diagonal), adds the barrier's Hessian
G^T diag(d) G to a matrix and finds a strictly feasible start;
:func:`boundary_step` is the largest step that keeps a positive vector
positive; :func:`solve_kkt` and :func:`solve_with_sum` solve the Newton
systems.  Boyd & Vandenberghe, Convex Optimization (2004), chapter 11.

Owns: the restricted polytope and the interior-point helpers.  May import: errors.
"""

import numpy as np
import scipy.linalg
import scipy.optimize

from ..._errors import SolverError

__all__ = ["working_rows", "RestrictedPolytope", "boundary_step", "solve_kkt", "solve_with_sum", "newton_step", "step_length",
           "residual_norm"]


def working_rows(problem, idx):
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


class RestrictedPolytope:
    """G x <= h, G = [rows; I; -I], h = [rhs; 1; 0], and sum(x) = ``count`` on a working set of m candidates.

    ``k`` side rows; ``n_ineq`` = k + 2 m inequalities; ``sum_row`` the row of ones of the equality.
    """

    def __init__(self, rows, rhs, count):
        self.rows, self.rhs, self.count = rows, rhs, count
        self.k, self.m = rows.shape
        self.h = np.concatenate([rhs, np.ones(self.m), np.zeros(self.m)])
        self.n_ineq = self.h.size
        self.sum_row = np.ones(self.m)

    @classmethod
    def for_working_set(cls, problem, idx):
        """The polytope of ``problem`` restricted to the candidates ``idx`` (:func:`working_rows`)."""
        rows, rhs = working_rows(problem, idx)
        return cls(rows, rhs, problem.count)

    def apply(self, v):
        """G v."""
        return np.concatenate([self.rows @ v, v, -v])

    def apply_transpose(self, v):
        """G^T v."""
        k, m = self.k, self.m
        return self.rows.T @ v[:k] + v[k:k + m] - v[k + m:]

    def slack(self, x):
        """h - G x (positive inside)."""
        return self.h - self.apply(x)

    def add_barrier_hessian(self, mat, d):
        """mat += G^T diag(d) G, in place (the box on the diagonal, the side rows as a product)."""
        k, m = self.k, self.m
        mat[np.diag_indices(m)] += d[k:k + m] + d[k + m:]
        if k:
            mat += (self.rows.T * d[:k]) @ self.rows
        return mat

    def interior_start(self, w_prev, idx):
        """A strictly feasible x: with only the box, the previous weights ``w_prev[idx]`` pulled towards
        uniform; with side rows or no previous weights, those pulled inside or a max-slack LP point."""
        if w_prev is None or self.k:
            g_mat = np.vstack([self.rows, np.eye(self.m), -np.eye(self.m)])
            return _interior_start_lp(g_mat, self.h, self.m, self.count, w_prev, idx)
        return _interior_start_box(self.m, self.count, w_prev, idx)


def _interior_start_box(m, count, w_prev, idx):
    """Strictly inside 0 < x < 1, sum x = count: the previous weights pulled towards uniform."""
    x = 0.9 * w_prev[idx] + 0.1 * count / m
    x *= count / x.sum()
    if np.all(x > 0) and np.all(x < 1):
        return x
    return np.full(m, count / m)


def _interior_start_lp(g_mat, h_vec, m, count, w_prev, idx):
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


def boundary_step(values, directions, start=1.0):
    """The largest a <= ``start`` with values + a directions >= 0 (``values`` > 0)."""
    neg = directions < 0
    if neg.any():
        return min(start, float(np.min(-values[neg] / directions[neg])))
    return start


def solve_kkt(kkt, rhs):
    """Solve a Newton (KKT) system; least squares where it is singular."""
    try:
        return np.linalg.solve(kkt, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(kkt, rhs, rcond=None)[0]


def solve_with_sum(kmat, rhs_x, sum_residual):
    """(dx, dnu) of K dx + dnu 1 = rhs_x, 1^T dx = ``sum_residual``, K positive definite.

    The equality is eliminated with one Cholesky factorisation of K and two
    right-hand sides; where K is not positive definite, the bordered system is
    solved by least squares.
    """
    m = kmat.shape[0]
    ones = np.ones(m)
    try:
        factor = scipy.linalg.cho_factor(kmat, check_finite=False)
        y = scipy.linalg.cho_solve(factor, np.column_stack([rhs_x, ones]), check_finite=False)
        dnu = (y[:, 0].sum() - sum_residual) / y[:, 1].sum()
        return y[:, 0] - dnu * y[:, 1], dnu
    except (np.linalg.LinAlgError, ZeroDivisionError):
        kkt = np.zeros((m + 1, m + 1))
        kkt[:m, :m] = kmat
        kkt[:m, m] = kkt[m, :m] = 1.0
        sol = np.linalg.lstsq(kkt, np.concatenate([rhs_x, [sum_residual]]), rcond=None)[0]
        return sol[:m], sol[m]


def newton_step(smooth, poly, point, dx, dnu, slack, t, r_dual):
    """(step length, next point) along the primal direction (``dx``, ``dnu``) from ``point`` = (x, lam, nu)
    and the dual direction it implies, the step being what :func:`step_length` allows."""
    x, lam, nu = point
    gdx = poly.apply(dx)
    dlam = (lam * gdx - (lam * slack - 1.0 / t)) / slack
    r0 = np.sqrt(r_dual @ r_dual + np.sum((lam * slack - 1.0 / t) ** 2) + (x.sum() - poly.count) ** 2)
    step = step_length(smooth, poly, point, (dx, dlam, dnu), gdx, slack, t, r0)
    return step, (x + step * dx, lam + step * dlam, nu + step * dnu)


def step_length(smooth, poly, point, direction, gdx, slack, t, r0, *, alpha=0.01, beta=0.5):
    """Step length of a primal-dual Newton step: 99 % of the way to the boundary, then backtracking until the
    residual norm decreases by the fraction ``alpha`` of the step (0 when no step does).  ``smooth`` has
    ``derivatives(x, hessian=False) -> (utility, gradient, _)``."""
    (x, lam, nu), (dx, dlam, dnu) = point, direction
    step = 0.99 * boundary_step(lam, dlam)
    step = min(step, 0.99 * boundary_step(slack, -gdx, np.inf))
    while step > 1e-12:
        un, rn = residual_norm(smooth, poly, x + step * dx, lam + step * dlam, nu + step * dnu, t)
        if np.isfinite(un) and rn <= (1.0 - alpha * step) * r0:
            break
        step *= beta
    return step


def residual_norm(smooth, poly, x, lam, nu, t):
    """(utility, norm of the primal-dual residuals: dual, centring, primal) at a trial point."""
    u, g, _ = smooth.derivatives(x, hessian=False)
    sl = poly.slack(x)
    r_dual = -g + poly.apply_transpose(lam) + nu * poly.sum_row
    r_cent = lam * sl - 1.0 / t
    r_pri = x.sum() - poly.count
    return u, np.sqrt(r_dual @ r_dual + r_cent @ r_cent + r_pri * r_pri)

"""Newton-CG for the restricted interior point on structured blocks: exact Hessian products, rare exact Hessians.

On a working set of m candidates the criterion's exact Hessian costs m P^3
(every block whitened); its product with a vector v costs about P^3
whatever m is: S = sum_j v_j I_j and the inner products <G, I_i> come from
the structured blocks (:class:`~sensorplan.design.blocks.StructuredBlocks`)
without dense blocks, and G from the criterion's Hessian operator
(:meth:`Criterion.point_derivatives`, with the utility and gradient from
one inverse of Q); the products are computed in single precision (the
directions need a few digits; utility, gradient, residuals and the
certificate stay in double precision).  The
Newton systems K dx + dnu 1 = r, 1^T dx = s (K = -H + the barrier's
Hessian) are therefore solved by conjugate gradients projected on
1^T dx = s and preconditioned by the constraint preconditioner built on
K~ = -H~ + the current barrier's Hessian, H~ an exact Hessian of an
earlier iterate (Gould, Hribar & Nocedal, SIAM J. Sci. Comput. 23 (2001),
projected preconditioned CG): every step uses the exact current Hessian,
and a new H~ is computed (on the candidates with a weight, the others by a
diagonal estimate, :class:`~.preconditioner.StaleHessian`) only when the stale one
preconditions badly.

Owns: StructuredRestricted, projected_pcg, restricted_newton_cg (the preconditioner: :mod:`.preconditioner`).
May import: design.relaxation.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..._cache import Cache
from .interior_point import RestrictedPolytope, newton_step
from .preconditioner import StaleHessian
from .working_blocks import WorkingBlocks

__all__ = ["StructuredRestricted", "StaleHessian", "Iterate", "projected_pcg", "restricted_newton_cg", "NewtonCG",
           "NEWTON_CG"]


@dataclass(frozen=True)
class NewtonCG:
    """Tolerances of the inexact Newton steps."""

    rtol: float = 1e-2  # relative residual of the projected CG (in the preconditioner's norm) ...
    rtol_final: float = 1e-8  # ... once an inexact direction failed to reduce the residuals
    max_iter: int = 60  # CG iterations per Newton step at most
    refresh_after: int = 6  # more CG iterations than this: the next step gets a new exact Hessian ...
    min_age: int = 3  # ... if the current one has served this many steps
    centring: float = 10.0  # each step aims at the surrogate duality gap divided by this


NEWTON_CG = NewtonCG()


@dataclass(frozen=True)
class Point:
    """A precision Q of the restricted problem, its lower Cholesky factor and the criterion's Hessian operator
    there (S -> G, :meth:`Criterion.hessian_operator`)."""

    q: np.ndarray
    chol: np.ndarray
    product: Callable[[np.ndarray], np.ndarray] | None = None


class StructuredRestricted:
    """Utility, gradient, Hessian products and (rarely) the exact Hessian of the criterion in the weights ``x``
    of the working set ``idx``, on structured blocks (no dense block but for the exact Hessian)."""

    products = True
    product_dtype = np.float32  # the Hessian products' precision

    def __init__(self, problem, idx):
        self.problem = problem
        self.idx = idx
        blocks = problem.blocks.subset(idx)
        self.sub = WorkingBlocks(blocks)
        self.sub_products = WorkingBlocks(blocks, dtype=self.product_dtype)
        self._last = Cache(maxsize=2)  # the line search's accepted trial point is the next iterate

    def derivatives(self, x, *, hessian=False):
        """(utility, gradient, :class:`Point`) at ``x``; (-inf, None, None) outside the domain."""
        return self._last.get((x,), lambda: self._derivatives(x))

    def _derivatives(self, x):
        crit = self.problem.criterion
        q = self.problem.q0 + self.sub.weighted(x)
        q = 0.5 * (q + q.T)
        try:
            chol = np.linalg.cholesky(q)
        except np.linalg.LinAlgError:
            return -np.inf, None, None
        utility, gradient, product = crit.point_derivatives(q, chol, dtype=self.product_dtype)
        return utility, self.sub.dot(gradient), Point(q, chol, product)

    def use_double_products(self):
        """Compute the Hessian products in double precision from now on (for accurate Newton systems)."""
        self.product_dtype, self.sub_products = np.float64, self.sub
        self._last.clear()

    def hessian_operator(self, point):
        """v -> H v at ``point`` (exact, through the criterion's Hessian products)."""
        return lambda v: self.sub_products.dot(point.product(self.sub_products.weighted(v)))


def projected_pcg(factor, apply_k, rhs, sum_residual, *, rtol, max_iter):
    """(dx, dnu, iterations) of K dx + dnu 1 = ``rhs``, 1^T dx = ``sum_residual``, K positive definite given by
    ``apply_k``; ``factor`` the Cholesky factor (scipy ``cho_factor``) of the preconditioner K~.

    The preconditioner's own solution is the start (exact when K~ = K); conjugate gradients then correct it in
    the null space of 1^T, preconditioned by the projection z = K~^-1 r - (1^T K~^-1 r / 1^T K~^-1 1) K~^-1 1,
    until the preconditioned residual is below ``rtol`` times that of ``rhs``.
    """
    y1 = scipy.linalg.cho_solve(factor, np.ones(rhs.size), check_finite=False)
    s1 = y1.sum()

    def solve(r):
        return scipy.linalg.cho_solve(factor, r, check_finite=False)

    def project(raw):  # the preconditioner applied to r, from raw = K~^-1 r (one solve per residual)
        return raw - (raw.sum() / s1) * y1

    y0 = solve(rhs)
    dx = y0 - ((y0.sum() - sum_residual) / s1) * y1
    r = rhs - apply_k(dx)
    raw = solve(r)
    z = project(raw)
    rz = float(r @ z)
    target = rtol**2 * max(float(rhs @ project(y0)), 1e-300)
    p = z
    it = 0
    while it < max_iter and rz > target:
        it += 1
        kp = apply_k(p)
        curvature = float(p @ kp)
        if curvature <= 0.0:
            break
        alpha = rz / curvature
        dx = dx + alpha * p
        r = r - alpha * kp
        raw = solve(r)
        z = project(raw)
        rz, rz_old = float(r @ z), rz
        p = z + (rz / rz_old) * p
    dnu = float(raw.sum() / s1)  # raw = K~^-1 r of the last residual
    return dx, dnu, it


@dataclass(frozen=True)
class Iterate:
    """A primal-dual iterate of the restricted interior point on the working set ``idx``: the weights ``x``
    (strictly inside), the multipliers ``lam`` of the inequalities and ``nu`` of sum(x) = R."""

    idx: np.ndarray
    x: np.ndarray
    lam: np.ndarray
    nu: float


def restricted_newton_cg(problem, idx, w_prev, *, tol, stale, resume=None, max_iter=200, options=NEWTON_CG):
    """The restricted interior point of :func:`~.smooth.restricted_interior_point` (same iterates up to the
    Newton systems' tolerance) with Newton-CG steps on structured blocks, preconditioned by ``stale``
    (a :class:`StaleHessian`, kept across rounds); continued from ``resume`` (an :class:`Iterate` on the
    same working set: the same problem to a tighter tolerance) instead of started from ``w_prev``.

    Returns (x, nu, iterations, CG iterations, the last :class:`Iterate`).
    """
    poly = RestrictedPolytope.for_working_set(problem, idx)
    smooth = StructuredRestricted(problem, idx)
    if resume is None:
        x = poly.interior_start(w_prev, idx)
        lam, nu = 1.0 / poly.slack(x), 0.0
    else:
        x, lam, nu = resume.x, resume.lam, resume.nu
    slack = poly.slack(x)
    ones = poly.sum_row
    u, g, point = smooth.derivatives(x)
    hess = stale.extend(idx, x, g) if stale.refreshes else stale.refresh(idx, point, x, g)
    refresh, cg_total, age, rtol = False, 0, 0, options.rtol
    for it in range(1, max_iter + 1):
        eta = float(slack @ lam)  # the surrogate duality gap
        t = options.centring * poly.n_ineq / eta  # barrier parameter: aim at a fraction of the gap
        r_dual = -g + poly.apply_transpose(lam) + nu * ones
        scale = max(1.0, float(np.max(np.abs(g))))
        if eta <= tol * max(1.0, abs(u)) and np.max(np.abs(r_dual)) <= tol * scale \
                and abs(x.sum() - poly.count) <= 1e-9 * poly.count:
            break
        if refresh:
            hess, age = stale.refresh(idx, point, x, g), 0
        d = lam / slack
        hess_v = smooth.hessian_operator(point)
        factor = _factor(poly.add_barrier_hessian(-hess, d))
        dx, dnu, n_cg = projected_pcg(factor, lambda v: poly.apply_transpose(d * poly.apply(v)) - hess_v(v),
                                      g - nu * ones - poly.apply_transpose(1.0 / (t * slack)),
                                      poly.count - x.sum(), rtol=rtol, max_iter=options.max_iter)
        step, after = newton_step(smooth, poly, (x, lam, nu), dx, dnu, slack, t, r_dual)
        if step <= 1e-12 and rtol > options.rtol_final:  # an inexact direction that does not descend: solve
            rtol, refresh = options.rtol_final, True  # the Newton systems accurately from now on, with
            smooth.use_double_products()  # products in double precision
            u, g, point = smooth.derivatives(x)
            continue
        if step <= 1e-12:
            break
        x, lam, nu = after
        slack = poly.slack(x)
        u, g, point = smooth.derivatives(x)
        age, cg_total = age + 1, cg_total + n_cg
        refresh = n_cg > options.refresh_after and age >= options.min_age
    return np.clip(x, 0.0, 1.0), float(nu), it, cg_total, Iterate(idx, x, lam, float(nu))


def _factor(kmat):
    """Cholesky factor of the preconditioner (a small ridge where single-precision Gram rows leave it
    numerically indefinite)."""
    try:
        return scipy.linalg.cho_factor(kmat, check_finite=False)
    except np.linalg.LinAlgError:
        ridge = 1e-6 * float(np.max(np.abs(np.diag(kmat))))
        return scipy.linalg.cho_factor(kmat + ridge * np.eye(kmat.shape[0]), check_finite=False)

"""Relaxation of smooth criteria: column generation around a primal-dual interior point.

A problem restricted to a working set of candidates is solved by a
primal-dual interior-point method with the criterion's exact Hessian
(:meth:`Criterion.hessian`; on structured blocks, whose dense blocks do not
fit in memory, Newton-CG steps with exact Hessian products instead,
:mod:`.newton_cg`); the linear oracle over *all* candidates then gives the
certified bound, and the candidates whose gradient beats the multiplier of
the count constraint join the working set (:mod:`.column_generation`),
until the duality gap over all candidates is below the tolerance.

Owns: the fast relaxation of smooth criteria and its restricted interior point.
May import: errors, design.relaxation.
"""

import time
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..._errors import SolverError
from .base import Relaxation, repair_weights
from .column_generation import Round, WorkingSet, column_generation, initial_size
from .interior_point import RestrictedPolytope, newton_step, solve_with_sum
from .newton_cg import StaleHessian, restricted_newton_cg
from .registry import register_fast_method

__all__ = ["solve_column_generation", "restricted_interior_point"]


@dataclass(frozen=True)
class RoundPolicy:
    """How the rounds of column generation treat the working set."""

    drop_below: float  # a member with a smaller weight (and a gradient below the multiplier) leaves the set
    first_tol: float  # relative tolerance of the first restricted solves (later: a tenth of the last gap)


# dense blocks (small problems): loose first rounds, members below 1 % leave (the Newton steps cost m P^3)
DENSE_ROUNDS = RoundPolicy(drop_below=1e-2, first_tol=1e-3)
# structured blocks (dense candidate grids): the relaxed optimum spreads small weights over neighbouring
# candidates; a member leaves only when its weight is negligible (dropping those to see them re-enter costs
# more rounds than keeping them costs: their preconditioner rows are kept, or diagonal), and the first rounds
# are solved tighter, so that their weights are sparse enough for members to leave at all
STRUCTURED_ROUNDS = RoundPolicy(drop_below=1e-3, first_tol=1e-4)


@register_fast_method("interior-point")
def solve_column_generation(problem, *, tol=1e-7, start_layout=None, max_rounds=50):
    """Relaxation by column generation with a certified duality gap (relative ``tol``).

    D, Ds and A: a primal-dual interior-point method (exact Hessians, or
    exact Hessian products on structured blocks) solves the problem
    restricted to a working set of candidates; the linear
    oracle over *all* candidates then gives the certified bound, and the
    candidates whose gradient exceeds the multiplier of the count
    constraint join the working set, until the gap is below ``tol``.
    """
    t0 = time.perf_counter()
    c = problem.n_candidates
    g = problem.gradient(np.full(c, problem.count / c))
    # a first working set of at most 8 R + 40 candidates: the Newton steps cost m P^3 on m candidates, and
    # the support of the relaxed optimum is a few times R (the rounds add what is missing)
    first = np.argsort(-g, kind="stable")[:initial_size(c, problem.count, 8, cap=8 * problem.count + 40)].tolist()
    policy = STRUCTURED_ROUNDS if problem.structured else DENSE_ROUNDS
    # structured blocks: the criterion says how fast the set may grow (more members per round, fewer rounds,
    # against more preconditioner rows); dense blocks: by half the set at most
    share = problem.criterion.enter_share if problem.structured else 0.5
    working = WorkingSet(c, first, start_layout=start_layout, drop_below=policy.drop_below, enter_share=share)
    tally = {"hessians": 0, "stale": None}
    if problem.structured:
        tally.update(cg_iterations=0, stale=StaleHessian(problem))
    last, rounds, newton_iters = column_generation(problem, working, partial(_solve_round, problem, tally), tol=tol,
                                                   max_rounds=max_rounds, first_tol=policy.first_tol)
    if problem.structured:
        tally["hessians"], tally["hessian_rows"] = tally["stale"].refreshes, tally["stale"].rows
    stats = {"solver": "column-generation+interior-point" + ("+newton-cg" if problem.structured else ""),
             "status": "optimal" if last.gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "newton_iterations": newton_iters,
             **{k: v for k, v in tally.items() if k not in ("stale", "iterate")}, "time_s": time.perf_counter() - t0}
    return Relaxation(last.weights, last.utility, max(last.bound, last.utility), "fast", stats)


def _solve_round(problem, tally, working, idx, w_prev, inner):
    """The restricted interior point on ``idx`` (all candidates if the constraints need more) and the
    Frank-Wolfe certificate over all candidates; ``tally`` counts the exact Hessians (the CG iterations on
    structured blocks, whose preconditioner it holds)."""
    solve = partial(_newton_cg_round, tally) if problem.structured else restricted_interior_point
    try:
        x, nu, it, count = solve(problem, idx, w_prev, tol=inner)
    except SolverError:
        if idx.size == problem.n_candidates:
            raise
        idx = working.fill()  # the constraints need candidates outside the working set
        x, nu, it, count = solve(problem, idx, None, tol=inner)
    tally["cg_iterations" if problem.structured else "hessians"] += count
    weights = np.zeros(problem.n_candidates)
    weights[idx] = x
    weights = repair_weights(problem, weights)
    crit = problem.criterion
    q = problem.precision(weights)
    utility = crit.utility(q)
    grad = problem.block_dot(crit.gradient_matrix(q))
    best, s = problem.linear_max(grad)
    bound = utility + max(0.0, best - float(grad @ weights))
    gap = (bound - utility) / max(1.0, abs(bound))
    return Round(idx=idx, x=x, weights=weights, utility=utility, bound=bound, gap=gap, threshold=nu, maximiser=s,
                 iterations=it, entry_gradient=lambda: grad)


def _newton_cg_round(tally, problem, idx, w_prev, *, tol):
    """:func:`restricted_newton_cg` with the preconditioner of ``tally``, continued from the last round's iterate
    when the working set is the same (nothing entered or left: only the tolerance is tighter)."""
    last = tally.get("iterate")
    resume = last if last is not None and np.array_equal(last.idx, idx) else None
    x, nu, it, count, tally["iterate"] = restricted_newton_cg(problem, idx, w_prev, tol=tol, stale=tally["stale"],
                                                              resume=resume)
    return x, nu, it, count


@dataclass(frozen=True)
class LazyHessian:
    """When a Newton step may reuse the criterion's Hessian of an earlier iterate (it costs m P^3 on a working set
    of m candidates; the gradient and residuals, hence the certificate, are always recomputed)."""

    max_reuse: int = 3  # Newton steps per Hessian at most: the weights move little between close iterates
    min_step: float = 0.5  # a shorter step means the reused Hessian misleads: it is refreshed and the step retried


LAZY_HESSIAN = LazyHessian()


class _Restricted:
    """Utility, gradient and Hessian of the criterion in the weights ``x`` of the working set ``idx``.

    The Hessian uses a single-precision copy of the blocks (the Newton
    direction needs a few digits; utility, gradient and hence the
    interior-point residuals and the certificate stay in double precision).
    """

    def __init__(self, problem, idx):
        self.problem = problem
        self.blocks = problem.blocks[idx]
        self.flat = self.blocks.reshape(idx.size, -1)
        self.blocks_h = self.blocks.astype(np.float32)

    def derivatives(self, x, *, hessian=True):
        """(utility, gradient, Hessian) at ``x``; (-inf, None, None) outside the domain."""
        crit = self.problem.criterion
        p = self.blocks.shape[1]
        q = self.problem.q0 + (x @ self.flat).reshape(p, p)
        q = 0.5 * (q + q.T)
        try:
            chol = np.linalg.cholesky(q)
        except np.linalg.LinAlgError:
            return -np.inf, None, None
        u = crit.utility(q)
        grad = self.flat @ crit.gradient_matrix(q).ravel()
        if not hessian:
            return u, grad, None
        h = crit.hessian(q, chol, self.blocks_h)
        return u, grad, 0.5 * (h + h.T)


def restricted_interior_point(problem, idx, w_prev, *, tol, max_iter=200):
    """Maximise the utility over candidates ``idx``: primal-dual interior point.

    Boyd & Vandenberghe, Convex Optimization (2004), section 11.7: inequalities
    G x <= h (side constraints and the box), equality sum(x) = R; returns
    (x, nu, iterations, exact Hessians computed) with nu the multiplier of
    the equality (the threshold a candidate's gradient must exceed to enter).
    """
    poly = RestrictedPolytope.for_working_set(problem, idx)
    smooth = _Restricted(problem, idx)
    x = poly.interior_start(w_prev, idx)
    slack = poly.slack(x)
    lam = 1.0 / slack
    nu = 0.0
    ones = poly.sum_row
    u, g, hess = smooth.derivatives(x)
    stale, n_exact = 0, 1  # Newton steps taken since the Hessian was computed; Hessians computed
    for it in range(1, max_iter + 1):
        eta = float(slack @ lam)  # the surrogate duality gap
        t = 10.0 * poly.n_ineq / eta  # barrier parameter: aim at a tenth of the gap
        r_dual = -g + poly.apply_transpose(lam) + nu * ones
        scale = max(1.0, float(np.max(np.abs(g))))
        if eta <= tol * max(1.0, abs(u)) and np.max(np.abs(r_dual)) <= tol * scale \
                and abs(x.sum() - poly.count) <= 1e-9 * poly.count:
            break
        kmat = poly.add_barrier_hessian(-hess, lam / slack)
        dx, dnu = solve_with_sum(kmat, g - nu * ones - poly.apply_transpose(1.0 / (t * slack)),
                                 poly.count - x.sum())
        step, after = newton_step(smooth, poly, (x, lam, nu), dx, dnu, slack, t, r_dual)
        if stale and step < LAZY_HESSIAN.min_step:  # a reused Hessian gave a short step: refresh it, retry
            hess, stale, n_exact = smooth.derivatives(x)[2], 0, n_exact + 1
            continue
        if step <= 1e-12:
            break
        x, lam, nu = after
        slack = poly.slack(x)
        refresh = step < LAZY_HESSIAN.min_step or stale + 1 >= LAZY_HESSIAN.max_reuse
        u, g, new_hess = smooth.derivatives(x, hessian=refresh)
        hess, stale = (new_hess, 0) if refresh else (hess, stale + 1)
        n_exact += refresh
    return np.clip(x, 0.0, 1.0), float(nu), it, n_exact

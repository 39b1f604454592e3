"""Relaxation of the detect criterion: epigraph barrier method with column generation.

maximise t  subject to  d^2_c(w) >= t for every damage centre c, and the
placement constraints on w (box, sum w = R, side rows), with d^2_c the
ridged Schur complement of :mod:`sensorplan.design.criteria.detect` (smooth
and concave).  A barrier method (Boyd & Vandenberghe, Convex Optimization,
2004, section 11.3, with the nonlinear constraints t - d^2_c(w) <= 0 and
their exact Hessians 2 R_c^T (A_NN + ridge)^-1 R_c, R_c = the nuisance rows
of G_i(c) [1; -x_c]) solves the problem restricted to a working set of
candidates.  The certificate over *all* candidates is
:func:`~sensorplan.design.criteria.detect.certificate` (one LP over the
distribution mu of the centres); candidates whose mu-weighted gradient
beats the multiplier of the count constraint, or that the LP's maximiser
uses, join the working set (:mod:`.column_generation`) until the certified
relative gap is below the tolerance.  With many centres (above
``ALL_CENTRES_UP_TO``) the constraints are an active set too
(:class:`CentreSet`): the worst centres at the start, and every centre the
restricted solution violates, until none is.

Owns: the detect relaxation's fast path.  May import: errors, design.criteria, design.relaxation.
"""

import time
from functools import partial

import numpy as np

from ..criteria.detect import ALL_CENTRES_UP_TO, certificate
from ..criteria.detect_algebra import HessianFactors, PackedLayout, gradients, ridged_parts
from .base import Relaxation, repair_weights
from .column_generation import Round, WorkingSet, column_generation, initial_size
from .interior_point import RestrictedPolytope, boundary_step, solve_kkt
from .registry import register_fast_method

__all__ = ["solve_detect_epigraph", "epigraph_interior_point", "CentreSet"]

FIRST_CENTRES = 24  # centres of a first active set: the worst at the uniform and at the start weights
ADDED_CENTRES = 48  # at most this many centres join the active set per restricted solve
# centres within 10 % of the restricted optimum join with the violated ones: a centre joining later costs
# a barrier solve of its own (0.02 -> 0.1: relaxation 82 -> 65 s CPU on an unseen four-span bridge, 52.5 ->
# 43.6 s on the five-span target, the same bounds; 0.25: 71 s)
NEAR = 0.1
# at most this share of the working set's size (or 2 R, or 20) enters per round: with half, the sets grew to
# 800-1,000 candidates in the early rounds (the Newton step costs n n_active m^2) before shrinking to ~250;
# relaxation (CPU s, 0.5 -> 0.2 -> 0.1): unseen four-span 65 -> 19 -> 17.5, unseen six-span 154 -> 68 -> 54,
# five-span target 43.6 -> 23.6 -> 22.8, the same bounds
ENTER_SHARE = 0.1
NEIGHBOURHOOD = 0.1  # a step keeps every centre's slack above this / tau (the central path's is >= 1 / tau)
# The barrier parameter: the first tau is FIRST_TAU n_con; it grows MU-fold per centring up to GENTLE_UP_TO
# n_con, tenfold beyond.  The damped Newton steps of a centring grow with n_con (mu - 1 - log mu) (Boyd &
# Vandenberghe, 11.5), and the first centrings move the weights from near the analytic centre towards a
# sparse optimum: on an unseen four-span bridge (2,991 candidates, working sets of 400-900) tenfold from
# n_con took 150-300 steps for the second centring; this schedule takes at most about 60 (relaxation 131
# -> 82 s CPU, the same bound), while the later, well-behaved centrings keep the tenfold growth (five-span
# target: 2,146 -> 1,756 steps).
FIRST_TAU = 0.1
MU = 3.0
GENTLE_UP_TO = 3.0
STALL = 1e-12  # a step whose predicted decrease (step x decrement) is below this ends the centring (rounding)


class CentreSet:
    """The damage centres whose constraints d^2_c >= t enter the restricted problem.

    All of them up to :data:`~sensorplan.design.criteria.detect.ALL_CENTRES_UP_TO` centres; above, the
    worst ones, and every centre that the restricted solution violates joins (a constraint left out can
    only raise the restricted optimum, so a solution that meets every centre is optimal).
    """

    def __init__(self, n_centres, *values):
        if n_centres <= ALL_CENTRES_UP_TO:
            self.members = set(range(n_centres))
        else:
            self.members = set()
            for f in values:
                if f is not None:
                    self.members |= set(np.argsort(f, kind="stable")[:FIRST_CENTRES].tolist())
        self.n_centres = n_centres

    def index(self):
        return np.array(sorted(self.members))

    def violated(self, f):
        """None if no centre outside the set is below the set's own minimum of ``f``; else the centres
        outside it below that minimum plus NEAR of it, worst first (at most ADDED_CENTRES)."""
        idx = self.index()
        floor = float(f[idx].min())
        outside = np.setdiff1d(np.arange(self.n_centres), idx)
        if not np.any(f[outside] < floor):
            return np.zeros(0, dtype=int)
        near = outside[f[outside] < floor + NEAR * abs(floor)]
        return near[np.argsort(f[near], kind="stable")][:ADDED_CENTRES]

    def add(self, centres):
        self.members |= set(int(c) for c in centres)


@register_fast_method("detect-epigraph")
def solve_detect_epigraph(problem, *, tol=1e-7, start_layout=None, max_rounds=50):
    """Relaxation of the detect criterion with a certified relative gap ``tol`` (see the module docstring)."""
    t0 = time.perf_counter()
    crit = problem.criterion
    c = problem.n_candidates
    uniform = np.full(c, problem.count / c)
    f, x, _ = ridged_parts(crit.packing, problem.precision(uniform), crit.ridge)
    scale = float(f.min()) if f is not None and f.min() > 0 else 1.0
    f_start = None
    if start_layout is not None:
        start = np.zeros(c)
        start[list(start_layout)] = 1.0
        f_start, _, _ = ridged_parts(crit.packing, problem.precision(start), crit.ridge)
        scale = float(f_start.min()) if f_start is not None and f_start.min() > 0 else scale
    centres = CentreSet(crit.packing.n_centres, f, f_start)
    # working set: the best candidates for a soft minimum over the centres at uniform weights
    soft = np.exp(-(f - f.min()) / (0.1 * abs(f.min()) + 1e-300))
    near = np.nonzero(soft > 1e-12)[0]
    grad = gradients(crit.packing, problem.blocks, x[near], near)
    score = grad @ (soft[near] / soft.sum())
    first = set(np.argsort(-score, kind="stable")[:initial_size(c, problem.count, 8)].tolist())
    first |= set(np.argmax(grad, axis=0).tolist())  # the best candidate of the nearly worst centres
    working = WorkingSet(c, first, start_layout=start_layout, enter_share=ENTER_SHARE)
    last, rounds, newton = column_generation(problem, working, partial(_solve_round, problem, scale, centres),
                                             tol=tol, max_rounds=max_rounds)
    stats = {"solver": "epigraph-interior-point+column-generation",
             "status": "optimal" if last.gap <= tol else "gap above tolerance", "rounds": rounds,
             "working_set": len(working), "active_centres": len(centres.members), "newton_iterations": newton,
             "time_s": time.perf_counter() - t0}
    return Relaxation(last.weights, last.utility, max(last.bound, last.utility), "fast", stats)


def _solve_round(problem, scale, centres, working, idx, w_prev, inner):
    """The barrier method on ``idx`` (and the active centres, grown until none is violated) and the LP
    certificate over all candidates."""
    crit = problem.criterion
    iterations = 0
    while True:
        x, nu, it = epigraph_interior_point(problem, idx, centres.index(), scale, w_prev, tol=inner)
        iterations += it
        weights = repair_weights(problem, np.bincount(idx, weights=x, minlength=problem.n_candidates))
        if len(centres.members) == crit.packing.n_centres:
            break
        f, _, _ = ridged_parts(crit.packing, problem.precision(weights), crit.ridge)
        enter = centres.violated(f)
        if enter.size == 0:
            break
        centres.add(enter)
        w_prev = weights
    bound, mu, utility, s = certificate(problem, weights, with_maximiser=True)
    gap = (bound - utility) / max(abs(bound), 1e-300)

    def entry_gradient():  # the mu-weighted gradient of the centres' d^2
        _, xs, _ = ridged_parts(crit.packing, problem.precision(weights), crit.ridge)
        used = np.nonzero(mu > 0.0)[0]
        return gradients(crit.packing, problem.blocks, xs[used], used) @ mu[used]

    return Round(idx=idx, x=x, weights=weights, utility=utility, bound=bound, gap=gap, threshold=nu * scale,
                 maximiser=s, iterations=iterations, entry_gradient=entry_gradient)


class _Barrier:
    """phi(x, t) = -tau t - sum_c log(d^2_c(x) - t) - sum_j log(slack_j(x)) on the working set ``idx``
    and the active ``centres``.

    The packed information is restricted to the working set and the active
    centres and divided by ``scale`` and once more so that the worst centre
    at the start is 1 (d^2 is homogeneous in the blocks and the ridge);
    ``rescale`` is that second factor.
    """

    def __init__(self, problem, idx, centres, scale, w_prev):
        crit = problem.criterion
        full = crit.packing
        self.layout = PackedLayout(centres.size, full.n_nuisance)

        def restrict(q):
            return self.layout.pack(full.rows(q)[..., centres, :], full.nuisance(q)) / scale

        blocks, q0, ridge = restrict(problem.blocks[idx]), restrict(problem.q0), crit.ridge / scale
        self.poly = RestrictedPolytope.for_working_set(problem, idx)
        self.start = self.poly.interior_start(w_prev, idx)
        f, _, _ = ridged_parts(self.layout, q0 + self.start @ blocks, ridge)
        self.rescale = float(f.min()) if f is not None and f.min() > 0 else 1.0
        self.blocks, self.q0, self.ridge = blocks / self.rescale, q0 / self.rescale, ridge / self.rescale
        self.factors = HessianFactors.of(self.layout, self.blocks)

    def evaluate(self, x):
        """(d^2 per centre, the nuisance coefficients x_c, Cholesky factor) at ``x``, or None outside the domain."""
        f, xs, chol = ridged_parts(self.layout, self.q0 + x @ self.blocks, self.ridge)
        return None if f is None else (f, xs, chol)

    def derivatives(self, point):
        """(d^2 per centre, its gradient (m, n_centres), the Hessian roots (n, n_centres, m)) at a
        point of :meth:`evaluate` (only at the points a line search accepts)."""
        f, xs, chol = point
        return f, gradients(self.layout, self.blocks, xs), self.factors.roots(xs, chol)

    @staticmethod
    def phi(f, t, sig, tau):
        """The barrier function (inf outside the domain)."""
        s = f - t
        if np.any(s <= 0) or np.any(sig <= 0):
            return np.inf
        return -tau * t - np.sum(np.log(s)) - np.sum(np.log(sig))

    def newton_step(self, x, t, sig, parts, tau):
        """(dx, dt, nu, decrement) of the Newton step on phi with sum(x) = R, nu its multiplier."""
        f, g, y = parts
        m = x.size
        s = f - t
        z = (y * np.sqrt(2.0 / s)[None, :, None]).reshape(-1, m)
        gs = g / s  # (m, n_centres)
        hxx = self.poly.add_barrier_hessian(z.T @ z + gs @ gs.T, 1.0 / sig**2)
        kkt = np.zeros((m + 2, m + 2))
        kkt[:m, :m] = hxx
        kkt[:m, m] = kkt[m, :m] = -gs @ (1.0 / s)
        kkt[m, m] = np.sum(1.0 / s**2)
        kkt[:m, m + 1] = kkt[m + 1, :m] = 1.0
        grad_x = -gs.sum(axis=1) + self.poly.apply_transpose(1.0 / sig)
        grad_t = -tau + np.sum(1.0 / s)
        sol = solve_kkt(kkt, np.concatenate([-grad_x, [-grad_t], [self.poly.count - x.sum()]]))
        dx, dt, nu = sol[:m], sol[m], sol[m + 1] / tau
        return dx, dt, nu, -(grad_x @ dx + grad_t * dt)

    def line_search(self, x, t, sig, f, step_dir, tau, decrement):
        """(step, parts at the new point): 99 % of the way to the boundary, halved until phi decreases
        by 1 % of the step times the decrement and no centre's slack d^2_c - t falls below
        min(NEIGHBOURHOOD / tau, the smallest slack now) (step <= 1e-14: none does).

        On the central path every slack is at least 1 / tau (the centres' multipliers 1 / (tau s_c) sum
        to 1); a damped step that takes one far below it leaves Newton's method creeping back over
        many full steps (a slack growing a few per cent a step), which the floor prevents.
        """
        dx, dt, gdx = step_dir
        step = min(1.0, 0.99 * boundary_step(sig, -gdx, np.inf))
        p0 = self.phi(f, t, sig, tau)
        floor = min(NEIGHBOURHOOD / tau, float(np.min(f - t)))
        trial = None
        while step > 1e-14:
            trial, t_new = self.evaluate(x + step * dx), t + step * dt
            if trial is not None and np.min(trial[0] - t_new) >= floor and \
                    self.phi(trial[0], t_new, sig - step * gdx, tau) <= p0 - 0.01 * step * decrement:
                break
            step *= 0.5
        return step, trial


def epigraph_interior_point(problem, idx, centres, scale, w_prev, *, tol, max_iter=300):
    """max t s.t. d^2_c(x) >= t, x in the restricted polytope: barrier method (Boyd & Vandenberghe, 11.3).

    Newton steps on phi = -tau t - sum_c log(d^2_c(x) - t) - sum_j log(slack_j(x)) with sum(x) = R,
    backtracking on phi; tau grows (MU-fold, then tenfold) once phi is centred, until the duality gap
    (n_constraints / tau) is below ``tol`` relative.  Returns (x, nu, Newton steps), nu the
    multiplier of sum(x) = R.
    """
    barrier = _Barrier(problem, idx, centres, scale, w_prev)
    x = barrier.start
    parts = barrier.derivatives(barrier.evaluate(x))
    f = parts[0]
    t = float(f.min()) - 0.5
    sig = barrier.poly.slack(x)
    n_con = f.size + barrier.poly.n_ineq
    tau = FIRST_TAU * n_con
    nu, newton = 0.0, 0
    while True:
        for _ in range(max_iter):
            newton += 1
            dx, dt, nu, decrement = barrier.newton_step(x, t, sig, parts, tau)
            if decrement <= 1e-10:
                break
            gdx = barrier.poly.apply(dx)
            step, trial = barrier.line_search(x, t, sig, parts[0], (dx, dt, gdx), tau, decrement)
            if step <= 1e-14:
                break
            x, t, sig = x + step * dx, t + step * dt, sig - step * gdx
            parts = barrier.derivatives(trial)
            if step * decrement <= STALL:  # centred as far as the arithmetic allows
                break
        if n_con / tau <= tol * max(1.0, abs(t)) or newton >= max_iter:
            break
        tau *= MU if tau < GENTLE_UP_TO * n_con else 10.0
    return np.clip(x, 0.0, 1.0), float(nu) * barrier.rescale, newton

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
relative gap is below the tolerance.

Owns: the detect relaxation's fast path.  May import: errors, design.criteria, design.relaxation.
"""

import time
from functools import partial

import numpy as np

from ..criteria.detect import centre_gradients, centre_hessian_roots, certificate, smooth_parts
from .base import Relaxation, repair_weights
from .column_generation import Round, WorkingSet, column_generation, initial_size
from .interior_point import RestrictedPolytope, boundary_step, solve_kkt
from .registry import register_fast_method

__all__ = ["solve_detect_epigraph", "epigraph_interior_point"]


@register_fast_method("detect-epigraph")
def solve_detect_epigraph(problem, *, tol=1e-7, start_layout=None, max_rounds=50):
    """Relaxation of the detect criterion with a certified relative gap ``tol`` (see the module docstring)."""
    t0 = time.perf_counter()
    crit = problem.criterion
    c = problem.n_candidates
    uniform = np.full(c, problem.count / c)
    f, u, _ = smooth_parts(problem.precision(uniform), crit.ridge)
    scale = float(f.min()) if f is not None and f.min() > 0 else 1.0
    if start_layout is not None:
        start = np.zeros(c)
        start[list(start_layout)] = 1.0
        fs, _, _ = smooth_parts(problem.precision(start), crit.ridge)
        scale = float(fs.min()) if fs is not None and fs.min() > 0 else scale
    # working set: the best candidates for a soft minimum over the centres at uniform weights
    soft = np.exp(-(f - f.min()) / (0.1 * abs(f.min()) + 1e-300))
    grad = centre_gradients(problem.blocks, u)
    score = grad @ (soft / soft.sum())
    first = set(np.argsort(-score, kind="stable")[:initial_size(c, problem.count, 8)].tolist())
    first |= set(np.argmax(grad, axis=0).tolist())  # the best candidate of every centre
    working = WorkingSet(c, first, start_layout=start_layout)
    scaled = (problem.blocks / scale, problem.q0 / scale, crit.ridge / scale)
    last, rounds, newton = column_generation(problem, working, partial(_solve_round, problem, scaled, scale),
                                             tol=tol, max_rounds=max_rounds)
    stats = {"solver": "epigraph-interior-point+column-generation",
             "status": "optimal" if last.gap <= tol else "gap above tolerance", "rounds": rounds,
             "working_set": len(working), "newton_iterations": newton, "time_s": time.perf_counter() - t0}
    return Relaxation(last.weights, last.utility, max(last.bound, last.utility), "fast", stats)


def _solve_round(problem, scaled, scale, working, idx, w_prev, inner):
    """The barrier method on ``idx`` and the LP certificate over all candidates."""
    x, nu, it = epigraph_interior_point(problem, idx, scaled, w_prev, tol=inner)
    weights = np.zeros(problem.n_candidates)
    weights[idx] = x
    weights = repair_weights(problem, weights)
    bound, mu, utility, s = certificate(problem, weights, with_maximiser=True)
    gap = (bound - utility) / max(abs(bound), 1e-300)

    def entry_gradient():  # the mu-weighted gradient of the centres' d^2
        _, u, _ = smooth_parts(problem.precision(weights), problem.criterion.ridge)
        return centre_gradients(problem.blocks, u) @ mu

    return Round(idx=idx, x=x, weights=weights, utility=utility, bound=bound, gap=gap, threshold=nu * scale,
                 maximiser=s, iterations=it, entry_gradient=entry_gradient)


class _Barrier:
    """phi(x, t) = -tau t - sum_c log(d^2_c(x) - t) - sum_j log(slack_j(x)) on the working set ``idx``.

    The blocks, prior and ridge of ``scaled`` are divided once more so that
    the worst centre at the start is 1 (d^2 is homogeneous in the blocks and
    the ridge); ``rescale`` is that factor.
    """

    def __init__(self, problem, idx, scaled, w_prev):
        blocks_all, q0, ridge = scaled
        m = idx.size
        blocks = blocks_all[idx]
        self.poly = RestrictedPolytope.for_working_set(problem, idx)
        self.start = self.poly.interior_start(w_prev, idx)
        f, _, _ = smooth_parts(q0 + (self.start @ blocks.reshape(m, -1)).reshape(q0.shape), ridge)
        self.rescale = float(f.min()) if f is not None and f.min() > 0 else 1.0
        self.blocks, self.q0, self.ridge = blocks / self.rescale, q0 / self.rescale, ridge / self.rescale
        self.flat = self.blocks.reshape(m, -1)

    def evaluate(self, x):
        """(d^2 per centre, its gradient (m, n_centres), the nuisance rows R, Cholesky factors), or None."""
        f, u, chol = smooth_parts(self.q0 + (x @ self.flat).reshape(self.q0.shape), self.ridge)
        if f is None:
            return None
        bu = np.einsum("icab,cb->ica", self.blocks, u)
        return f, np.einsum("ica,ca->ic", bu, u), bu[:, :, 1:], chol

    @staticmethod
    def phi(f, t, sig, tau):
        """The barrier function (inf outside the domain)."""
        s = f - t
        if np.any(s <= 0) or np.any(sig <= 0):
            return np.inf
        return -tau * t - np.sum(np.log(s)) - np.sum(np.log(sig))

    def newton_step(self, x, t, sig, parts, tau):
        """(dx, dt, nu, decrement) of the Newton step on phi with sum(x) = R, nu its multiplier."""
        f, g, r, chol = parts
        m = x.size
        s = f - t
        y = centre_hessian_roots(r, chol)
        z = (y * np.sqrt(2.0 / s)[:, None, None]).reshape(-1, m)
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
        by 1 % of the step times the decrement (step <= 1e-14: none does)."""
        dx, dt, gdx = step_dir
        step = min(1.0, 0.99 * boundary_step(sig, -gdx, np.inf))
        p0 = self.phi(f, t, sig, tau)
        trial = None
        while step > 1e-14:
            trial = self.evaluate(x + step * dx)
            if trial is not None and self.phi(trial[0], t + step * dt, sig - step * gdx, tau) \
                    <= p0 - 0.01 * step * decrement:
                break
            step *= 0.5
        return step, trial


def epigraph_interior_point(problem, idx, scaled, w_prev, *, tol, max_iter=300):
    """max t s.t. d^2_c(x) >= t, x in the restricted polytope: barrier method (Boyd & Vandenberghe, 11.3).

    Newton steps on phi = -tau t - sum_c log(d^2_c(x) - t) - sum_j log(slack_j(x)) with sum(x) = R,
    backtracking on phi; tau grows tenfold once phi is centred, until the duality gap
    (n_constraints / tau) is below ``tol`` relative.  Returns (x, nu, Newton steps), nu the
    multiplier of sum(x) = R.
    """
    barrier = _Barrier(problem, idx, scaled, w_prev)
    x = barrier.start
    parts = barrier.evaluate(x)
    f = parts[0]
    t = float(f.min()) - 0.5
    sig = barrier.poly.slack(x)
    n_con = f.size + barrier.poly.n_ineq
    tau = float(n_con)
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
            parts = trial
        if n_con / tau <= tol * max(1.0, abs(t)) or newton >= max_iter:
            break
        tau *= 10.0
    return np.clip(x, 0.0, 1.0), float(nu) * barrier.rescale, newton

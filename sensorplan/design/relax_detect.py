"""Relaxation of the detect criterion: epigraph interior point with column generation.

maximise t  subject to  d^2_c(w) >= t for every damage centre c, and the
placement constraints on w (box, sum w = R, side rows), with d^2_c the
ridged Schur complement of :mod:`.detect_criterion` (smooth and concave).
A primal-dual interior-point method (Boyd & Vandenberghe, Convex
Optimization, 2004, section 11.7, with the nonlinear constraints
t - d^2_c(w) <= 0 and their exact Hessians 2 R_c^T (A_NN + ridge)^-1 R_c,
R_c = the nuisance rows of G_i(c) [1; -x_c]) solves the problem restricted
to a working set of candidates; the multipliers of the centre constraints
are the distribution mu of the certificate.  The certificate over *all*
candidates is :func:`~.detect_criterion.certificate` (one LP over mu);
candidates whose mu-weighted gradient beats the multiplier of the count
constraint, or that the LP's maximiser uses, join the working set until the
certified relative gap is below the tolerance.

Owns: the detect relaxation's fast path.  May import: errors, design.
"""

import time

import numpy as np

from .detect_criterion import (
    centre_gradients,
    centre_hessian_roots,
    certificate,
    smooth_parts,
)
from .relax_ipm import _interior_start, _interior_start_box, _working_rows
from .relaxation import Relaxation, _repair

__all__ = ["solve_detect_epigraph"]


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
    size = min(c, max(4 * problem.count + 20, c // 8))
    working = set(np.argsort(-score, kind="stable")[:size].tolist())
    working |= set(np.argmax(grad, axis=0).tolist())  # the best candidate of every centre
    if start_layout is not None:
        working |= {int(i) for i in start_layout}
    scaled = (problem.blocks / scale, problem.q0 / scale, crit.ridge / scale)
    weights, gap, newton, dropped = None, np.inf, 0, set()
    inner = 1e-3
    for rounds in range(1, max_rounds + 1):
        idx = np.array(sorted(working))
        x, nu, it = _pdip_epigraph(problem, idx, scaled, weights, tol=inner)
        newton += it
        weights = np.zeros(c)
        weights[idx] = x
        weights = _repair(problem, weights)
        bound, mu, utility, s = certificate(problem, weights, with_maximiser=True)
        gap = (bound - utility) / max(abs(bound), 1e-300)
        if gap <= tol or len(working) == c and inner <= 0.1 * tol:
            break
        _, u, _ = smooth_parts(problem.precision(weights), crit.ridge)
        grad = centre_gradients(problem.blocks, u) @ mu
        outside = np.setdiff1d(np.arange(c), idx)
        enter = outside[grad[outside] > nu * scale]
        enter = enter[np.argsort(-grad[enter], kind="stable")][: max(2 * problem.count, 20, idx.size // 2)]
        enter = np.union1d(enter, np.setdiff1d(np.nonzero(s > 1e-9)[0], idx))
        if enter.size == 0:
            if inner <= 0.1 * tol:
                break
            inner = 0.1 * tol
            continue
        inner = max(0.1 * tol, min(inner, 0.1 * gap))
        drop = [i for i in idx[(x < 1e-2) & (grad[idx] < nu * scale)].tolist() if i not in dropped]
        dropped.update(drop)
        working -= set(drop)
        working |= set(enter.tolist())
    stats = {"solver": "epigraph-interior-point+column-generation",
             "status": "optimal" if gap <= tol else "gap above tolerance", "rounds": rounds,
             "working_set": len(working), "newton_iterations": newton, "time_s": time.perf_counter() - t0}
    return Relaxation(weights, utility, max(bound, utility), "fast", stats)


def _pdip_epigraph(problem, idx, scaled, w_prev, *, tol, max_iter=300):
    """max t s.t. d^2_c(x) >= t, x in the restricted polytope: barrier method (Boyd & Vandenberghe, 11.3).

    Newton steps on phi = -tau t - sum_c log(d^2_c(x) - t) - sum_j log(slack_j(x)) with sum(x) = R,
    backtracking on phi; tau grows tenfold once phi is centred, until the duality gap
    (n_constraints / tau) is below ``tol`` relative.  Returns (x, nu, Newton steps), nu the
    multiplier of sum(x) = R.
    """
    blocks_all, q0, ridge = scaled
    m = idx.size
    blocks = blocks_all[idx]
    rows, rhs = _working_rows(problem, idx)
    k = rows.shape[0]
    h_vec = np.concatenate([rhs, np.ones(m), np.zeros(m)])
    count = problem.count
    if w_prev is None or k:
        x = _interior_start(np.vstack([rows, np.eye(m), -np.eye(m)]), h_vec, m, count, w_prev, idx)
    else:
        x = _interior_start_box(m, count, w_prev, idx)
    # rescale so that the worst centre at the start is 1 (d^2 is homogeneous in the blocks and the ridge)
    flat = blocks.reshape(m, -1)
    f, _, _ = smooth_parts(q0 + (x @ flat).reshape(q0.shape), ridge)
    rescale = float(f.min()) if f is not None and f.min() > 0 else 1.0
    blocks, q0, ridge = blocks / rescale, q0 / rescale, ridge / rescale
    flat = blocks.reshape(m, -1)

    def g_dot(v):
        return np.concatenate([rows @ v, v, -v])

    def gt_dot(v):
        return rows.T @ v[:k] + v[k:k + m] - v[k + m:]

    def evaluate(xv):
        f_, u_, chol_ = smooth_parts(q0 + (xv @ flat).reshape(q0.shape), ridge)
        if f_ is None:
            return None
        bu = np.einsum("icab,cb->ica", blocks, u_)
        return f_, np.einsum("ica,ca->ic", bu, u_), bu[:, :, 1:], chol_

    def phi(f_, t_, sig_, tau_):
        s_ = f_ - t_
        if np.any(s_ <= 0) or np.any(sig_ <= 0):
            return np.inf
        return -tau_ * t_ - np.sum(np.log(s_)) - np.sum(np.log(sig_))

    f, g, r, chol = evaluate(x)
    t = float(f.min()) - 0.5
    sig = h_vec - g_dot(x)
    n_con = f.size + h_vec.size
    tau = float(n_con)
    nu, newton = 0.0, 0
    while True:
        for _ in range(max_iter):
            newton += 1
            s = f - t
            y = centre_hessian_roots(r, chol)
            z = (y * np.sqrt(2.0 / s)[:, None, None]).reshape(-1, m)
            gs = g / s  # (m, n_centres)
            hxx = z.T @ z + gs @ gs.T
            d = 1.0 / sig**2
            hxx[np.diag_indices(m)] += d[k:k + m] + d[k + m:]
            if k:
                hxx += (rows.T * d[:k]) @ rows
            kkt = np.zeros((m + 2, m + 2))
            kkt[:m, :m] = hxx
            kkt[:m, m] = kkt[m, :m] = -gs @ (1.0 / s)
            kkt[m, m] = np.sum(1.0 / s**2)
            kkt[:m, m + 1] = kkt[m + 1, :m] = 1.0
            grad_x = -gs.sum(axis=1) + gt_dot(1.0 / sig)
            grad_t = -tau + np.sum(1.0 / s)
            rhs_vec = np.concatenate([-grad_x, [-grad_t], [count - x.sum()]])
            try:
                sol = np.linalg.solve(kkt, rhs_vec)
            except np.linalg.LinAlgError:
                sol = np.linalg.lstsq(kkt, rhs_vec, rcond=None)[0]
            dx, dt, nu = sol[:m], sol[m], sol[m + 1] / tau
            decrement = -(grad_x @ dx + grad_t * dt)
            if decrement <= 1e-10:
                break
            gdx = g_dot(dx)
            step = 1.0
            pos = gdx > 0
            if pos.any():
                step = min(1.0, 0.99 * float(np.min(sig[pos] / gdx[pos])))
            p0 = phi(f, t, sig, tau)
            while step > 1e-14:
                trial = evaluate(x + step * dx)
                if trial is not None:
                    value = phi(trial[0], t + step * dt, sig - step * gdx, tau)
                    if value <= p0 - 0.01 * step * decrement:
                        break
                step *= 0.5
            if step <= 1e-14:
                break
            x, t, sig = x + step * dx, t + step * dt, sig - step * gdx
            f, g, r, chol = trial
        if n_con / tau <= tol * max(1.0, abs(t)) or newton >= max_iter:
            break
        tau *= 10.0
    return np.clip(x, 0.0, 1.0), float(nu) * rescale, newton

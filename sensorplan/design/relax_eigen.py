"""E relaxation by an eigen-subspace cutting-plane method with small LMI interior points.

Owns: the spectral bundle method, the small k x k SDPs (own primal-dual
interior point, Clarabel as fallback).
May import: model, errors, design.relaxation, design.relax_cvxpy.
"""

import time

import numpy as np
import scipy.linalg

from .._errors import SolverError
from .relax_cvxpy import _solve_clarabel
from .relaxation import Relaxation, _repair

__all__ = ["solve_eigen_subspace"]


def solve_eigen_subspace(problem, *, tol, start_layout=None, max_rounds=50, k0=10):
    """E relaxation by an eigen-subspace cutting-plane method (a spectral bundle method).

    For an orthonormal basis V (P x k), lambda_min(V^T Q V) >= lambda_min(Q)
    for every Q, so the small SDP  max_w lambda_min(V^T Q(w) V)  is a relaxation of the
    E problem (a k x k LMI over a working set of candidates, solved by
    :func:`_small_e_sdp`).  Its dual matrix Z_k gives Z = V Z_k V^T, trace one and
    PSD, hence a certified bound over *all* candidates
    (:meth:`ECriterion.bound_from_dual`); the eigenvectors of Q(w) with eigenvalues
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
        bound = min(bound, problem.criterion.bound_from_dual(problem, z))
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

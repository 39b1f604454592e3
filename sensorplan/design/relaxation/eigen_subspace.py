"""E relaxation by an eigen-subspace cutting-plane method with small LMI interior points.

Owns: the spectral bundle method, the small k x k SDPs (own interior point,
:mod:`.lmi`; cvxpy + Clarabel as fallback).
May import: errors, design.relaxation.
"""

import time

import numpy as np

from ..._errors import SolverError
from . import lmi
from .base import Relaxation, repair_weights
from .column_generation import initial_size
from .cvxpy_reference import solve_clarabel
from .registry import register_fast_method

__all__ = ["solve_eigen_subspace"]


@register_fast_method("eigen-subspace")
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
    g = problem.block_dot(basis @ basis.T)
    working = set(np.argsort(-g, kind="stable")[:initial_size(c, r, 4)].tolist())
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
        w = repair_weights(problem, w)
        lam, vec = np.linalg.eigh(problem.precision(w))
        if lam[0] > best[0]:
            best = (float(lam[0]), w)
        z = basis @ z_small @ basis.T
        bound = min(bound, problem.criterion.bound_from_dual(problem, z))
        gap = (bound - best[0]) / max(1.0, abs(bound))
        if gap <= tol:
            break
        grown_set = _grow_working_set(problem, working, idx, (wr, z, nu, small_value), bound, tol)
        basis, grown_basis = _grow_basis(basis, lam, vec, small_value)
        if not (grown_set or grown_basis):
            break
    stats = {"solver": "eigen-subspace+interior-point", "status": "optimal" if gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "subspace": basis.shape[1],
             "sdp_time_s": sdp_time, "clarabel_fallbacks": fallbacks, "time_s": time.perf_counter() - t0}
    return Relaxation(best[1], best[0], max(bound, best[0]), "fast", stats)


def _grow_working_set(problem, working, idx, sdp, bound, tol):
    """Add the candidates that would enter while the working set limits the small SDP; drop those with
    no weight and a gradient well below the threshold (in place).  Returns whether any entered."""
    wr, z, nu, small_value = sdp
    c, r = problem.n_candidates, problem.count
    grown = False
    trace = max(float(np.trace(z)), 1e-300)
    gz = problem.block_dot(z / trace)
    threshold = nu / trace
    if small_value < bound - 0.1 * tol * max(1.0, abs(bound)) and len(working) < c:
        outside = np.setdiff1d(np.arange(c), idx)
        enter = outside[gz[outside] > threshold]
        enter = enter[np.argsort(-gz[enter], kind="stable")][: max(2 * r, 20)]
        working |= set(enter.tolist())
        grown = enter.size > 0
    # (the SDP is solved afresh each round, so a smaller set only saves time)
    working -= set(idx[(wr < 1e-7) & (gz[idx] < threshold - 0.05 * abs(threshold))].tolist())
    return grown


def _grow_basis(basis, lam, vec, small_value):
    """The basis with (up to 8 of) the eigenvectors of Q(w) below the small SDP's value added, and whether
    it grew."""
    sel = np.nonzero(lam < small_value)[0][:8]
    if sel.size:
        new = vec[:, sel] - basis @ (basis.T @ vec[:, sel])
        norms = np.linalg.norm(new, axis=0)
        if np.any(norms > 1e-8):
            return np.linalg.qr(np.hstack([basis, new[:, norms > 1e-8] / norms[norms > 1e-8]]))[0], True
    return basis, False


def _small_e_sdp(problem, idx, basis, *, tol):
    """max t s.t. V^T Q(w) V - t I >= 0 over candidates ``idx``.

    Solved by :func:`~.lmi.lmi_interior_point`; if that does not converge, by cvxpy + Clarabel.
    Returns (value, w, Z_k, nu, time, solver).
    """
    start = time.perf_counter()
    m = idx.size
    b0 = basis.T @ problem.q0 @ basis
    bmat = problem.congruence(basis, idx)
    bmat = 0.5 * (bmat + bmat.transpose(0, 2, 1))
    a_ub, b_ub = problem.inequalities
    rows, rhs = np.zeros((0, m)), np.zeros(0)
    if a_ub.shape[0]:
        rows = a_ub[:, idx]
        keep = np.any(rows != 0, axis=1)
        if np.any(~keep & (b_ub < 0)):
            raise SolverError("The working set cannot satisfy the span minimum counts.")
        rows, rhs = rows[keep], b_ub[keep]
    value, w, z, nu, status, _ = lmi.lmi_interior_point(0.5 * (b0 + b0.T), bmat, rows, rhs, problem.count, tol=tol)
    if status == "optimal":
        return value, np.clip(w, 0.0, 1.0), z, abs(nu), time.perf_counter() - start, "interior-point"
    value, w, z, nu = _small_e_sdp_clarabel(b0, bmat, rows, rhs, problem.count, tol=tol)
    return value, w, z, nu, time.perf_counter() - start, "clarabel"


def _small_e_sdp_clarabel(b0, bmat, rows, rhs, count, *, tol):
    """The small SDP by cvxpy + Clarabel: (value, w, Z_k, nu)."""
    import cvxpy as cp

    m, k, _ = bmat.shape
    w = cp.Variable(m)
    t = cp.Variable()
    mat = b0 + cp.reshape(bmat.reshape(m, -1).T @ w, (k, k), order="C")
    lmi_constraint = 0.5 * (mat + mat.T) - t * np.eye(k) >> 0
    count_eq = cp.sum(w) == count
    constraints = [w >= 0, w <= 1, count_eq, lmi_constraint]
    if rows.shape[0]:
        constraints.append(rows @ w <= rhs)
    prob = cp.Problem(cp.Maximize(t), constraints)
    solve_clarabel(cp, prob, w, tol=tol, what="E relaxation")
    z = lmi_constraint.dual_value
    nu = abs(float(count_eq.dual_value)) if count_eq.dual_value is not None else 0.0
    return float(prob.value), np.clip(w.value, 0.0, 1.0), 0.5 * (z + z.T), nu

"""E relaxation by an eigen-subspace cutting-plane method with small LMI interior points.

Owns: the spectral bundle method, the small k x k SDPs (own interior point,
:mod:`.lmi`; cvxpy + Clarabel as fallback on small SDPs only).
May import: errors, design.relaxation.
"""

import time

import numpy as np
import scipy.linalg

from ..._errors import SolverError
from . import lmi
from .base import Relaxation, repair_weights
from .column_generation import initial_size
from .cvxpy_reference import solve_clarabel
from .registry import register_fast_method

__all__ = ["solve_eigen_subspace"]

K_MAX = 160  # basis size beyond which the directions of least weight in X_V leave the basis (a memory and time
# guard): aggregated into W and kept as cuts (rank-one blocks of the LMI, one linear row each in the small SDP)
SIGNIFICANT = 1e-6  # (directions whose weight exceeds this share of X_V's largest eigenvalue always stay)
N_MIN, N_MAX = 4, 12  # eigenvectors of Q(w) (the lowest) that join the basis each round
CLARABEL_MAX_ENTRIES = 200_000  # m k^2 above which a failed small SDP is not handed to cvxpy + Clarabel
INNER_TOL_MAX = 1e-5  # the small SDPs' tolerance: a tenth of the last certified gap, at most this ...
INNER_TOL_SHARE = 0.01  # ... and at least this share of ``tol`` (the bound is certified from any multiplier)
SDP_MAX_ITER = 80  # interior-point steps per small SDP at most (an unfinished iterate still certifies)
SPREAD = 10  # the first working set also holds every SPREAD-th candidate, ...
SPREAD_GAP = 1e-3  # ... kept in it while the relative gap exceeds this
ENTER_SHARE = 0.1  # candidates enter when they would move the bound by more than this share of the gap over R
ENTER_MAX = 2  # and at most this many times R (and 20) of them per round: the relaxed optimum ties many
# neighbouring candidates, and the small SDP costs m^2 k^2 on m of them
DROP_WEIGHT = 1e-4  # candidates leave when their weight is below this and their gradient below the threshold
DROP_SHARE = 1.0  # by more than this share of the gap over R (ten times the entering margin: no cycling) ...
DROP_FLOOR = 1e-4  # ... and than this share of the threshold (near-ties that leave return the next round)
WARM_SHIFT_FLOOR = 1e-3  # a warm-started SDP's t starts at least this share of the bound below lambda_min; ...
WARM_STALL_STEPS = 25  # ... ten times more (up to WARM_SHIFT_MAX) after a warm-started SDP took more steps than
WARM_SHIFT_MAX = 1e-1  # this: its start's central-path parameter was too small for its primal infeasibility
MAXIMISER_WEIGHT = 1e-9  # with side constraints, candidates above this weight in the bound's maximiser enter


@register_fast_method("eigen-subspace")
def solve_eigen_subspace(problem, *, tol, start_layout=None, max_rounds=50, k0=10):
    """E relaxation by an eigen-subspace cutting-plane method (a spectral bundle method).

    For an orthonormal basis V (P x k), a trace-one PSD aggregate W and unit
    vectors u_j (the cuts), lambda_min(Q) <= min(lambda_min(V^T Q V), <W, Q>,
    u_j^T Q u_j) for every Q, so the small SDP maximising that minimum over
    w (a block-diagonal LMI over a working set of candidates,
    :func:`_small_e_sdp`) is a relaxation of the E problem.  Its multiplier X
    gives Z = V X_V V^T + x_W W + sum_j x_j u_j u_j^T, trace one and PSD,
    hence a certified bound over *all* candidates
    (:meth:`ECriterion.bound_from_dual`) whatever the small SDP's accuracy.
    Each round the lowest eigenvectors of Q(w) join the basis; beyond
    ``K_MAX`` columns the directions of least weight in X_V leave it for W
    and the cuts (Helmberg & Rendl, SIAM J. Optim. 10 (2000) 673-696).
    Candidates whose <Z, I_i> exceeds the count multiplier by a share of the
    gap join the working set, those with no weight well below it leave, until
    the gap is below ``tol`` (many neighbours of a dense grid tie at the
    optimum; only those that move the bound at the present accuracy are
    worth the small SDP's m^2 k^2).  While the gap is large the working set
    also holds candidates spread evenly over the grid (without them the
    small SDP's Z favours directions only the missing regions inform).  The
    small SDPs are solved to a tenth of the last gap, each from the last
    round's weights (about a third fewer interior-point steps), further inside
    after one such start stalled (``WARM_STALL_STEPS``).
    """
    t0 = time.perf_counter()
    c = problem.n_candidates
    basis, agg, cuts = _first_basis(problem, k0)
    working, spread = _first_working_set(problem, basis, start_layout)
    best = (-np.inf, None)
    bound, gap, sdp_time, counts = np.inf, np.inf, 0.0, {"clarabel": 0, "inexact": 0}
    warm = None  # (weights over all candidates, shift): the last round's solution, where the next SDP starts
    shift_floor = WARM_SHIFT_FLOOR
    for rounds in range(1, max_rounds + 1):
        idx = np.array(sorted(working))
        inner = max(INNER_TOL_SHARE * tol, min(INNER_TOL_MAX, 0.1 * gap))
        small_value, wr, x, nu, price, dt, used, steps = _small_e_sdp(
            problem, idx, basis, agg, cuts, tol=inner, warm=None if warm is None else (warm[0][idx], warm[1]))
        sdp_time += dt
        if warm is not None and steps > WARM_STALL_STEPS:
            shift_floor = min(10.0 * shift_floor, WARM_SHIFT_MAX)
        if used != "interior-point":
            counts[used] += 1
        w = np.zeros(c)
        w[idx] = wr
        w = repair_weights(problem, w)
        # the N_MAX lowest eigenpairs, all the next basis can take (LAPACK's dsyevr: a third of the full solve)
        lam, vec = scipy.linalg.eigh(problem.precision(w), subset_by_index=[0, min(N_MAX, problem.n_params) - 1],
                                     driver="evr")
        if lam[0] > best[0]:
            best = (float(lam[0]), w)
        k = basis.shape[1]
        z = basis @ x[:k, :k] @ basis.T + agg.matrix(x[k, k]) + cuts.matrix(np.diag(x)[k + 1:])
        bound_z, maximiser = problem.criterion.bound_and_maximiser(problem, z)
        bound = min(bound, bound_z)
        gap = (bound - best[0]) / max(1.0, abs(bound))
        if gap <= tol:
            break
        # the margins scale with the small SDP's distance to the best weights (not the certified gap, which
        # stays large while outside candidates are violated, and would keep them out)
        model_gap = max(small_value - best[0], 0.1 * tol * max(1.0, abs(bound)))
        # the next SDP starts at these weights, t that far below their lambda_min (floored: a start on the
        # boundary would stall)
        warm = (w, max(small_value - best[0], shift_floor * max(1.0, abs(bound))))
        _grow_working_set(problem, working, idx, (wr, z, nu, price), model_gap, maximiser)
        if gap > SPREAD_GAP:
            working |= spread
        basis, agg, cuts = _next_basis(problem, basis, x, agg, cuts, vec, lam, small_value)
    stats = {"solver": "eigen-subspace+interior-point", "status": "optimal" if gap <= tol else "gap above tolerance",
             "rounds": rounds, "working_set": len(working), "subspace": basis.shape[1], "cuts": cuts.size,
             "sdp_time_s": sdp_time, "clarabel_fallbacks": counts["clarabel"], "inexact_sdps": counts["inexact"],
             "time_s": time.perf_counter() - t0}
    return Relaxation(best[1], best[0], max(bound, best[0]), "fast", stats)


def _first_basis(problem, k0):
    """(basis, aggregate, cuts) to start from: the ``k0`` lowest eigenvectors of Q at uniform weights, the
    next one as W, no cuts."""
    c, p = problem.n_candidates, problem.n_params
    _, vec = np.linalg.eigh(problem.precision(np.full(c, problem.count / c)))
    return vec[:, : min(p, k0)], _Aggregate.start(problem, vec[:, min(p, k0)] if p > k0 else None), _Cuts.empty(problem)


def _first_working_set(problem, basis, start_layout):
    """(working set, spread): the candidates most informative along ``basis``, the start layout, and
    candidates spread evenly over the grid (kept throughout, so that no region is missing from the
    certificates)."""
    c, r = problem.n_candidates, problem.count
    g = problem.block_dot(basis @ basis.T)
    working = set(np.argsort(-g, kind="stable")[:initial_size(c, r, 4, cap=ENTER_MAX * r + 20)].tolist())
    spread = set(np.linspace(0, c - 1, min(c, max(ENTER_MAX * r + 20, c // SPREAD))).astype(int).tolist())
    working |= spread
    if start_layout is not None:
        working |= set(int(i) for i in start_layout)
    return working, spread


class _Aggregate:
    """The aggregate W (trace one, PSD; None before the first aggregation) with <W, Q_0> and <W, I_i>."""

    def __init__(self, mat, q0_dot, dots):
        self.mat, self.q0_dot, self.dots = mat, q0_dot, dots

    @classmethod
    def start(cls, problem, u):
        if u is None:
            return cls(None, 0.0, None)
        return cls.of(problem, np.outer(u, u))

    @classmethod
    def of(cls, problem, mat):
        mat = mat / np.trace(mat)
        return cls(mat, float(np.sum(mat * problem.q0)), problem.block_dot(mat))

    def matrix(self, weight):
        return 0.0 if self.mat is None else weight * self.mat


class _Cuts:
    """Directions u_j that left the basis (unit vectors, P x n) with <u_j u_j^T, Q_0> and <u_j u_j^T, I_i>:
    t <= u_j^T Q(w) u_j holds for every w and t <= lambda_min(Q(w)), so they enter the small SDP as linear
    rows, keeping its memory of past directions at the cost of a row each."""

    def __init__(self, vectors, q0_dots, dots):
        self.vectors, self.q0_dots, self.dots = vectors, q0_dots, dots

    @classmethod
    def empty(cls, problem):
        return cls(np.zeros((problem.n_params, 0)), np.zeros(0), np.zeros((0, problem.n_candidates)))

    @property
    def size(self):
        return self.vectors.shape[1]

    def add(self, problem, vectors):
        """These cuts with the (orthonormal) columns of ``vectors`` added."""
        if not vectors.shape[1]:
            return self
        q0_dots = np.einsum("ij,ij->j", vectors, problem.q0 @ vectors)
        dots = np.array([problem.block_dot(np.outer(u, u)) for u in vectors.T])
        return _Cuts(np.hstack([self.vectors, vectors]), np.concatenate([self.q0_dots, q0_dots]),
                     np.vstack([self.dots, dots]))

    def matrix(self, weights):
        """sum_j weights_j u_j u_j^T."""
        return (self.vectors * np.clip(weights, 0.0, None)) @ self.vectors.T


def _next_basis(problem, basis, x, agg, cuts, vec, lam, small_value):
    """The next basis, aggregate and cuts: the basis keeps its directions up to ``K_MAX`` columns with the
    new ones, beyond that X_V's eigenvectors of most weight (and all those above ``SIGNIFICANT``); the
    other directions become cuts and their weight joins the aggregate W; the eigenvectors of Q(w) (``lam``,
    ``vec``) below the small SDP's value join the basis (at least ``N_MIN``, at most ``N_MAX``, orthogonalised)."""
    k = basis.shape[1]
    n_new = int(np.clip(np.sum(lam < small_value), N_MIN, N_MAX))
    xv, xu = np.linalg.eigh(0.5 * (x[:k, :k] + x[:k, :k].T))
    n_keep = min(k, max(K_MAX - n_new, int(np.sum(xv > SIGNIFICANT * max(xv[-1], 1e-300)))))
    keep = np.arange(k) >= k - n_keep
    weights = np.clip(xv[~keep], 0.0, None)
    agg_weight = max(float(x[k, k]), 0.0) if agg.mat is not None else 0.0
    dropped = basis @ xu[:, ~keep]
    if weights.sum() + agg_weight > 0:
        agg = _Aggregate.of(problem, (dropped * weights) @ dropped.T + agg.matrix(agg_weight))
    cuts = cuts.add(problem, dropped)
    kept = basis @ xu[:, keep]
    new = vec[:, :n_new]
    new = new - kept @ (kept.T @ new)
    new = new - kept @ (kept.T @ new)  # twice: orthogonal to round-off
    q, rr = np.linalg.qr(new)
    return np.hstack([kept, q[:, np.abs(np.diag(rr)) > 1e-6]]), agg, cuts


def _grow_working_set(problem, working, idx, sdp, gap, maximiser=None):
    """Add the candidates that would enter while the working set limits the small SDP by more than
    ``ENTER_SHARE`` of the absolute gap ``gap`` over R (those below it move the bound by less than that
    share of the gap), the best max(ENTER_MAX R, 20, a quarter of the set); drop those with little weight
    and a gradient below the count's multiplier by more than ``DROP_SHARE`` of the gap over R and
    ``DROP_FLOOR`` of the multiplier (in place; the SDP is solved afresh each round, so a smaller set only
    saves time).  The threshold to enter is the count's multiplier plus the candidate's side rows'
    (``price``, from the small SDP's multipliers of the rows with a member: a full span or a neighbour's
    spacing row raises it, a span held to a minimum count lowers it), and the candidates with weight in the
    certificate's maximiser (``maximiser``, the weights that attain the bound over all candidates) enter too.
    (Dropping by the priced threshold as well made the small SDPs of constrained spans take up to 160 steps.)"""
    wr, z, nu, price = sdp
    c, r = problem.n_candidates, problem.count
    trace = max(float(np.trace(z)), 1e-300)
    gz = problem.block_dot(z / trace)
    threshold = (nu + price) / trace
    if len(working) < c:
        outside = np.setdiff1d(np.arange(c), idx)
        enter = outside[gz[outside] > threshold[outside] + ENTER_SHARE * gap / r]
        enter = enter[np.argsort(-(gz - threshold)[enter], kind="stable")][: max(ENTER_MAX * r, 20, len(working) // 4)]
        working |= set(enter.tolist())
    if maximiser is not None and problem.inequalities[0].shape[0]:
        working |= set(np.flatnonzero(maximiser > MAXIMISER_WEIGHT).tolist())
    scale = abs(nu / trace)
    drop = min(max(DROP_SHARE * gap / r, DROP_FLOOR * scale), 0.05 * scale)
    working -= set(idx[(wr < DROP_WEIGHT) & (gz[idx] < nu / trace - drop)].tolist())


def _small_e_sdp(problem, idx, basis, agg, cuts, *, tol, warm=None):
    """max t s.t. V^T Q(w) V - t I >= 0, <W, Q(w)> >= t and u_j^T Q(w) u_j >= t (the cuts) over candidates
    ``idx``.

    Solved by :func:`~.lmi.lmi_interior_point`, from ``warm`` (weights over ``idx``, shift) when given and
    again from its own start if that does not reach the tolerance; an iterate it could not
    take to the tolerance is still used (the bound is certified from any
    multiplier); if it has none, small SDPs go to cvxpy + Clarabel, large
    ones raise SolverError.  Returns (value, w, X, nu, price, time, solver, interior-point steps), price (C,)
    the side rows' multipliers summed over each candidate's rows (sum_r mult_r a_ri, zero without rows).
    """
    start = time.perf_counter()
    m, k = idx.size, basis.shape[1]
    b0 = np.zeros((k + 1, k + 1))
    b0[:k, :k] = basis.T @ problem.q0 @ basis
    bmat = np.zeros((m, k + 1, k + 1))
    bmat[:, :k, :k] = problem.congruence(basis, idx)
    if agg.mat is None:  # no aggregate yet: its diagonal entry is a copy of the first one
        b0[k, k], bmat[:, k, k] = b0[0, 0], bmat[:, 0, 0]
    else:
        b0[k, k], bmat[:, k, k] = agg.q0_dot, agg.dots[idx]
    bmat = 0.5 * (bmat + bmat.transpose(0, 2, 1))
    rows, rhs, kept = _side_rows(problem, idx)
    steps = 0
    for begin in ((warm, None) if warm is not None else (None,)):
        value, w, x, nu, status, it, mult = lmi.lmi_interior_point(
            0.5 * (b0 + b0.T), bmat, rows, rhs, problem.count, cuts=cuts.dots[:, idx], cut_rhs=cuts.q0_dots, tol=tol,
            max_iter=SDP_MAX_ITER, start=begin)
        steps += it
        if status == "optimal":
            break
    if status == "optimal" or w is not None and np.all(np.isfinite(w)) and np.all(np.isfinite(x)):
        return (value, np.clip(w, 0.0, 1.0), x, abs(nu), _price(problem, kept, mult), time.perf_counter() - start,
                "interior-point" if status == "optimal" else "inexact", steps)
    if m * (k + 1) ** 2 > CLARABEL_MAX_ENTRIES:
        raise SolverError(f"The E relaxation's small SDP ({m} candidates, basis {k}) failed; try --solver cvxpy "
                          f"on a coarser candidate grid.")
    value, w, x, nu, mult = _small_e_sdp_clarabel(b0, bmat, rows, rhs, problem.count,
                                                  (cuts.dots[:, idx], cuts.q0_dots), tol=tol)
    return value, w, x, nu, _price(problem, kept, mult), time.perf_counter() - start, "clarabel", steps


def _price(problem, kept, mult):
    """sum_r mult_r a_ri over the side rows ``kept`` (indices into the problem's rows) for every candidate."""
    a_ub = problem.inequalities[0]
    full = np.zeros(a_ub.shape[0])
    if kept.size and mult is not None and np.all(np.isfinite(mult)):
        full[kept] = np.clip(mult, 0.0, None)
    return full @ a_ub  # (the rows without a member have no multiplier; no copy of the kept rows)


def _side_rows(problem, idx):
    """The side constraints restricted to the candidates ``idx`` (rows that do not involve them dropped), and
    the kept rows' indices."""
    a_ub, b_ub = problem.inequalities
    if not a_ub.shape[0]:
        return np.zeros((0, idx.size)), np.zeros(0), np.zeros(0, dtype=int)
    rows = a_ub[:, idx]
    keep = np.any(rows != 0, axis=1)
    if np.any(~keep & (b_ub < 0)):
        raise SolverError("The working set cannot satisfy the span minimum counts.")
    return rows[keep], b_ub[keep], np.flatnonzero(keep)


def _small_e_sdp_clarabel(b0, bmat, rows, rhs, count, cuts, *, tol):
    """The small SDP by cvxpy + Clarabel: (value, w, blockdiag(X, the cuts' multipliers), nu, the rows'
    multipliers)."""
    import cvxpy as cp

    m, k, _ = bmat.shape
    w = cp.Variable(m)
    t = cp.Variable()
    mat = b0 + cp.reshape(bmat.reshape(m, -1).T @ w, (k, k), order="C")
    lmi_constraint = 0.5 * (mat + mat.T) - t * np.eye(k) >> 0
    count_eq = cp.sum(w) == count
    constraints = [w >= 0, w <= 1, count_eq, lmi_constraint]
    row_constraint = rows @ w <= rhs if rows.shape[0] else None
    if row_constraint is not None:
        constraints.append(row_constraint)
    n = cuts[0].shape[0]
    if n:
        cut_constraint = t - cuts[0] @ w <= cuts[1]
        constraints.append(cut_constraint)
    prob = cp.Problem(cp.Maximize(t), constraints)
    solve_clarabel(cp, prob, w, tol=tol, what="E relaxation")
    x = np.zeros((k + n, k + n))
    x[:k, :k] = 0.5 * (lmi_constraint.dual_value + lmi_constraint.dual_value.T)
    if n:
        x[np.arange(k, k + n), np.arange(k, k + n)] = np.clip(cut_constraint.dual_value, 0.0, None)
    nu = abs(float(count_eq.dual_value)) if count_eq.dual_value is not None else 0.0
    mult = None if row_constraint is None else np.atleast_1d(row_constraint.dual_value)
    return float(prob.value), np.clip(w.value, 0.0, 1.0), x, nu, mult

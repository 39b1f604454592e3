"""The ``detect`` criterion: the worst case over damage centres of the detectability d^2.

The "precision" of this criterion is a stack A (n_centres, 1 + n, 1 + n) of
summed per-sensor Gram matrices G_i(c) = [s_i(c) N_i]^T [s_i(c) N_i] of the
whitened exact damage signature s_i(c) of a local loss centred at c and the
whitened nuisance Jacobian N_i (:mod:`sensorplan.detection.signatures`),
times the number of crossings.  For each centre

    d^2_c(A) = A_ss - A_sN A_NN^+ A_Ns = min_x [1; -x]^T A_c [1; -x],

the squared noncentrality of the known-location test exactly as
``sensorplan detectability`` computes it (the same pseudo-inverse cut-off,
:func:`~sensorplan.detection.signatures.schur_d_squared`), and the criterion
is min_c d^2_c: a minimum of functions that are concave in the weights (a
minimum of linear functions of A), hence concave.

Relaxation (:mod:`sensorplan.design.relaxation.detect_epigraph`, and cvxpy + Clarabel with one LMI
[[A_ss - t, A_sN], [A_Ns, A_NN]] >= 0 per centre): d^2_c with a ridge
``RIDGE`` times the mean single-candidate diagonal added to A_NN, a weak
prior on the nuisance that keeps A_NN(w) nonsingular on the whole relaxed
set (layouts that see a nuisance direction only weakly would otherwise make
the pseudo-inverse discontinuous).  The ridged d^2 is >= the exact one, so
the relaxation's optimum still bounds every layout; on the embedded
examples the ridge changes d^2 of the recommended layouts by < 1e-8
relative.  Certificate: for any distribution mu over the centres,

    min_c d^2_c(w) <= sum_c mu_c [d^2_c(w0) + grad d^2_c(w0)^T (w - w0)]

(concavity), so the maximum of the right-hand side over the relaxed
feasible set bounds the relaxation; :func:`certificate` minimises that bound
over mu by one LP (the linear-programming dual of the inner maximum).

Owns: the detect criterion, its exact value, bounds and certificate.
May import: errors, detection, design.criteria.
"""

import math

import numpy as np
import scipy.optimize
from scipy.special import ndtr, ndtri

from ..._errors import ConfigError, SolverError
from ...detection.signatures import schur_d_squared
from .base import Criterion
from .registry import register_criterion

__all__ = ["DetectCriterion", "RIDGE", "centre_d_squared", "centre_solution", "smooth_parts", "centre_gradients",
           "centre_hessian_roots", "certificate"]

RIDGE = 1e-10  # ridge on A_NN in the relaxation, relative to the mean single-candidate diagonal


def _unit_diagonal(stack):
    """The stack scaled to unit diagonal (unseen directions: identity rows) and the scales."""
    diag = np.diagonal(stack, axis1=-2, axis2=-1)
    seen = diag > 0.0
    scale = np.where(seen, 1.0 / np.sqrt(np.where(seen, diag, 1.0)), 0.0)
    scaled = stack * scale[..., :, None] * scale[..., None, :]
    idx = np.arange(diag.shape[-1])
    scaled[..., idx, idx] = 1.0
    return scaled, scale, diag


def centre_d_squared(stack):
    """Exact d^2 per centre of ``stack`` (..., n_centres, m, m), as :func:`schur_d_squared` computes it.

    Fast path: the Cholesky factor of the unit-diagonal matrix with the
    signature ordered last; its last pivot is d^2 / A_ss.  Where a nuisance
    pivot is below 1e-8 (the nuisance block may then have eigenvalues near
    the pseudo-inverse cut-off of 1e-12) or the factorisation fails, the
    value is that of :func:`schur_d_squared` itself (eigen-decomposition,
    cut-off).
    """
    diag = np.diagonal(stack, axis1=-2, axis2=-1)
    m = diag.shape[-1]
    order = np.roll(np.arange(m), -1)  # the signature last
    seen = diag[..., order] > 0.0
    scale = np.where(seen, 1.0 / np.sqrt(np.where(seen, diag[..., order], 1.0)), 0.0)
    full = stack[..., order[:, None], order[None, :]] * scale[..., :, None] * scale[..., None, :]
    full[..., np.arange(m), np.arange(m)] = 1.0
    full[..., m - 1, m - 1] += 1e-13  # keeps d^2 = 0 factorisable; subtracted below
    try:
        piv = np.diagonal(np.linalg.cholesky(full), axis1=-2, axis2=-1) ** 2
    except np.linalg.LinAlgError:
        piv = np.zeros(full.shape[:-1])
    d2 = np.maximum(piv[..., -1] - 1e-13, 0.0) * diag[..., 0]
    bad = np.any(piv[..., :-1] < 1e-8, axis=-1)
    if bad.any():
        d2[bad] = schur_d_squared(stack[bad][None])
    return d2


def centre_solution(stack):
    """(d^2, x) per centre: d^2 as :func:`centre_d_squared`, x the nuisance coefficients with
    d^2 = [1; -x]^T A [1; -x] (pseudo-inverse with the cut-off of :func:`schur_d_squared`)."""
    scaled, scale, _ = _unit_diagonal(stack)
    vals, vecs = np.linalg.eigh(scaled[..., 1:, 1:])
    keep = vals > 1e-12 * vals.max(axis=-1, keepdims=True)
    p = np.einsum("...nm,...n->...m", vecs, stack[..., 1:, 0] * scale[..., 1:])
    coef = np.where(keep, p / np.where(keep, vals, 1.0), 0.0)
    return centre_d_squared(stack), np.einsum("...nm,...m->...n", vecs, coef) * scale[..., 1:]


def smooth_parts(stack, ridge):
    """Ridged d^2 (n_centres,), u = [1; -x] (n_centres, m) and the Cholesky factor of A_NN + ridge."""
    a_nn = stack[:, 1:, 1:] + np.diag(ridge)
    try:
        chol = np.linalg.cholesky(a_nn)
    except np.linalg.LinAlgError:
        return None, None, None
    x = np.linalg.solve(a_nn, stack[:, 1:, 0:1])[..., 0]
    f = stack[:, 0, 0] - np.einsum("cn,cn->c", stack[:, 1:, 0], x)
    u = np.concatenate([np.ones((x.shape[0], 1)), -x], axis=1)
    return f, u, chol


def centre_gradients(blocks, u):
    """d d^2_c / d w_i = u_c^T G_i(c) u_c for every block: (n_blocks, n_centres)."""
    uu = (u[:, :, None] * u[:, None, :]).reshape(u.shape[0], -1)
    return np.einsum("icq,cq->ic", blocks.reshape(blocks.shape[0], u.shape[0], -1), uu)


def centre_hessian_roots(rows, chol):
    """Y (n_centres, n, n_blocks) with d^2 d^2_c / dw_i dw_j = -2 (Y_c^T Y_c)_ij (ridged d^2).

    ``rows`` (n_blocks, n_centres, n): the nuisance rows of G_i(c) u_c; ``chol`` the Cholesky
    factor of A_NN + ridge per centre (from :func:`smooth_parts`).
    """
    return np.linalg.solve(chol, rows.transpose(1, 2, 0))


def certificate(problem, weights, *, with_maximiser=False):
    """(bound, mu, utility[, s]): the best bound of the linearisation at ``weights`` over distributions mu.

    minimise over mu in the simplex: sum_c mu_c (f_c - g_c^T w) + max_{s feasible} (sum_c mu_c g_c)^T s,
    with the inner maximum replaced by its LP dual (y for s <= 1, nu for sum s = R, pi for the side
    constraints): one LP, solved by HiGHS; ``s`` (the inner maximiser) is read from its duals.
    """
    crit = problem.criterion
    w = np.asarray(weights, dtype=float)
    f, u, _ = smooth_parts(problem.precision(w), crit.ridge)
    if f is None:
        raise SolverError("The ridged nuisance block is not positive definite; the relaxation is ill-posed.")
    g = centre_gradients(problem.blocks, u)  # (C, n_centres)
    n_c, c = f.size, problem.n_candidates
    a_ub, b_ub = problem.inequalities
    k = a_ub.shape[0]
    # variables: mu (n_c), y (C), nu (free), pi (k)
    cost = np.concatenate([f - w @ g, np.ones(c), [problem.count], b_ub])
    # g mu - y - nu 1 - A^T pi <= 0
    lhs = np.hstack([g, -np.eye(c), -np.ones((c, 1)), -a_ub.T])
    eq = np.concatenate([np.ones(n_c), np.zeros(c + 1 + k)])[None, :]
    bounds = [(0.0, None)] * (n_c + c) + [(None, None)] + [(0.0, None)] * k
    res = scipy.optimize.linprog(cost, A_ub=lhs, b_ub=np.zeros(c), A_eq=eq, b_eq=[1.0], bounds=bounds,
                                 method="highs")
    if res.status != 0:
        raise SolverError(f"The certificate LP of the detect criterion failed ({res.message}).")
    out = (float(res.fun), np.clip(res.x[:n_c], 0.0, None), float(f.min()))
    return (*out, -res.ineqlin.marginals) if with_maximiser else out


@register_criterion
class DetectCriterion(Criterion):
    """Worst case over damage centres of the detectability d^2 (maximised); see the module docstring.

    Built by :func:`~sensorplan.design.recommend.build_problem` from a case
    (:mod:`sensorplan.design.detect_problem`), not from a number of parameters.
    """

    name = "detect"
    description = "worst-case detectability d^2 of a local loss"
    relaxation = "detect-epigraph"
    information = "detection"
    params_label = "damage centres"
    random_starts = 10  # a minimum over centres has many local optima for single swaps
    batch_size = 16  # one batched Cholesky of 16 candidates costs far less than 16 single ones

    def __init__(self, n_params, *, centres=None, ridge=None, false_alarm=0.05, n_crossings=1, severity=0.25,
                 length=2.0, nuisance="smooth", region=None, step=0.5, nuisance_names=()):
        super().__init__(n_params)
        self.centres = np.zeros(self.n_params) if centres is None else np.asarray(centres, dtype=float)
        self.ridge = np.asarray(ridge, dtype=float) if ridge is not None else None
        self.false_alarm, self.n_crossings, self.severity, self.length = false_alarm, n_crossings, severity, length
        self.nuisance, self.region, self.step, self.nuisance_names = nuisance, region, step, tuple(nuisance_names)
        self.description = (f"worst-case detectability d^2 of a {100 * severity:g} % EI loss over {length:g} m, "
                            f"{n_crossings} crossing(s), nuisance {nuisance}")

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        raise ConfigError("The detect criterion is built from a case by recommend() or build_problem(), "
                          "not by make_criterion().")

    def value(self, q):
        return float(centre_d_squared(q).min())

    def utilities(self, q, blocks):
        return centre_d_squared(q[None] + blocks).min(axis=-1)

    def gradient_matrix(self, q):
        """Supergradient: u u^T at the worst centre, u = [1; -x]."""
        d2, x = centre_solution(q)
        c = int(np.argmin(d2))
        out = np.zeros_like(q)
        u = np.concatenate([[1.0], -x[c]])
        out[c] = np.outer(u, u)
        return out

    def upper_bounds(self, problem, q):
        # d^2_c(A + G) <= u_c^T (A + G) u_c for any u_c = [1; -x]; the minimum over the centres
        d2, x = centre_solution(q)
        u = np.concatenate([np.ones((x.shape[0], 1)), -x], axis=1)
        base = np.einsum("ca,cab,cb->c", u, q, u)
        return float(d2.min()), (base[None, :] + centre_gradients(problem.blocks, u)).min(axis=1)

    def bound(self, problem, w):
        return certificate(problem, w)[0]

    # -- cvxpy: one LMI per centre ------------------------------------------------------------
    def cvxpy_precision(self, cp, problem, w, idx):
        m = problem.q0.shape[1]
        ridge = np.zeros((m, m))
        ridge[1:, 1:] = np.diag(self.ridge)
        out = []
        for c in range(self.n_params):
            flat = problem.blocks[idx, c].reshape(idx.size, m * m).T
            a = problem.q0[c] + ridge + cp.reshape(flat @ w, (m, m), order="C")
            out.append(0.5 * (a + a.T))
        return out

    def cvxpy_objective(self, cp, q_expr, constraints):
        t = cp.Variable()
        e = np.zeros(q_expr[0].shape)
        e[0, 0] = 1.0
        lmis = [a - t * e >> 0 for a in q_expr]
        constraints.extend(lmis)
        return cp.Maximize(t), lmis

    def cvxpy_bound(self, problem, weights, handle):
        return self.bound(problem, weights)

    def relaxed_utility(self, problem, w):
        """min_c of the ridged d^2 at relaxed weights (what the relaxation maximises)."""
        f, _, _ = smooth_parts(problem.precision(w), self.ridge)
        return -math.inf if f is None else float(f.min())

    # -- reporting -------------------------------------------------------------------------------
    def describe(self, q):
        """JSON details and one summary line: worst centre, d, power."""
        d2 = centre_d_squared(q)
        c = int(np.argmin(d2))
        d = math.sqrt(d2[c])
        power = float(ndtr(d + ndtri(self.false_alarm)))  # -ndtri(a): exact for tiny a, unlike ndtri(1 - a)
        details = {"worst_centre_m": float(self.centres[c]), "d2": float(d2[c]), "d": d, "power": power,
                   "false_alarm_rate": self.false_alarm, "n_crossings": self.n_crossings,
                   "severity": self.severity, "length_m": self.length, "nuisance": self.nuisance,
                   "step_m": self.step, "region_m": None if self.region is None else list(self.region),
                   "n_centres": int(self.centres.size), "ridge": RIDGE}
        line = (f"  worst case over {self.centres.size} damage centres: d^2 {d2[c]:.4g} (d {d:.3f}) at "
                f"{self.centres[c]:.2f} m; power {power:.3f} at a {100 * self.false_alarm:g} % false-alarm rate")
        return {"detection": details}, line

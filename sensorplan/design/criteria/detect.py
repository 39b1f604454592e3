"""The ``detect`` criterion: the worst case over damage centres of the detectability d^2.

The "precision" of this criterion sums per-sensor Gram matrices
G_i(c) = [s_i(c) N_i]^T [s_i(c) N_i] of the whitened exact damage signature
s_i(c) of a local loss centred at c and the whitened nuisance Jacobian N_i
(:mod:`sensorplan.detection.signatures`), times the number of crossings,
packed over the centres with their common nuisance block stored once
(:mod:`.detect_algebra`).  For each centre

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

The relaxation's bound can be far above the best layout (a few sensors
cannot see a 2 m zone everywhere, fractional weights spread over many
candidates can); on small problems (up to ``EXACT_UP_TO`` candidates and
sensors) :meth:`DetectCriterion.integer_bound` therefore proves a bound on
the layouts themselves by exhaustive branch and bound
(:mod:`.detect_search`), which also finds a better layout if one exists.

Owns: the detect criterion, its exact value, bounds and certificate.
May import: errors, detection, design.criteria.
"""

import math

import numpy as np
import scipy.optimize
import scipy.sparse
from scipy.special import ndtr, ndtri

from ..._errors import ConfigError, SolverError
from .base import Criterion
from .detect_algebra import PackedLayout, exact_d_squared, exact_solution, gradients, ridged_parts
from .detect_search import certify
from .registry import register_criterion

__all__ = ["DetectCriterion", "RIDGE", "certificate", "ALL_CENTRES_UP_TO"]

RIDGE = 1e-10  # ridge on A_NN in the relaxation, relative to the mean single-candidate diagonal
EXACT_UP_TO = (200, 8)  # candidates and sensors up to which the integer certificate's search is tried
ALL_CENTRES_UP_TO = 120  # more centres: the certificate's distribution uses the nearly binding ones only
NEAR_BINDING = 0.25  # ... those within 25 % of the worst ridged d^2 (any subset gives a valid bound)


def certificate_centres(f):
    """The centres the certificate's distribution may use: all, or the nearly binding ones (see above)."""
    if f.size <= ALL_CENTRES_UP_TO:
        return np.arange(f.size)
    return np.nonzero(f <= f.min() + NEAR_BINDING * abs(f.min()))[0]


def certificate(problem, weights, *, with_maximiser=False):
    """(bound, mu, utility[, s]): the best bound of the linearisation at ``weights`` over distributions mu.

    minimise over mu in the simplex: sum_c mu_c (f_c - g_c^T w) + max_{s feasible} (sum_c mu_c g_c)^T s,
    with the inner maximum replaced by its LP dual (y for s <= 1, nu for sum s = R, pi for the side
    constraints): one sparse LP, solved by HiGHS; ``s`` (the inner maximiser) is read from its duals.
    mu is restricted to :func:`certificate_centres` (a restriction can only raise the bound, so it stays
    valid); ``mu`` is returned over all centres.
    """
    crit = problem.criterion
    w = np.asarray(weights, dtype=float)
    f, x, _ = ridged_parts(crit.packing, problem.precision(w), crit.ridge)
    if f is None:
        raise SolverError("The ridged nuisance block is not positive definite; the relaxation is ill-posed.")
    sub = certificate_centres(f)
    g = gradients(crit.packing, problem.blocks, x[sub], sub)  # (C, n_sub)
    n_c, c = sub.size, problem.n_candidates
    a_ub, b_ub = problem.inequalities
    k = a_ub.shape[0]
    # variables: mu (n_c), y (C), nu (free), pi (k)
    cost = np.concatenate([f[sub] - w @ g, np.ones(c), [problem.count], b_ub])
    # g mu - y - nu 1 - A^T pi <= 0
    lhs = scipy.sparse.hstack([scipy.sparse.csr_matrix(g), -scipy.sparse.identity(c, format="csr"),
                               -np.ones((c, 1)), scipy.sparse.csr_matrix(-a_ub.T)], format="csr")
    eq = np.concatenate([np.ones(n_c), np.zeros(c + 1 + k)])[None, :]
    bounds = [(0.0, None)] * (n_c + c) + [(None, None)] + [(0.0, None)] * k
    res = scipy.optimize.linprog(cost, A_ub=lhs, b_ub=np.zeros(c), A_eq=eq, b_eq=[1.0], bounds=bounds,
                                 method="highs")
    if res.status != 0:
        raise SolverError(f"The certificate LP of the detect criterion failed ({res.message}).")
    mu = np.zeros(f.size)
    mu[sub] = np.clip(res.x[:n_c], 0.0, None)
    out = (float(res.fun), mu, float(f.min()))
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
        self.packing = PackedLayout(self.n_params, len(nuisance_names))
        self.false_alarm, self.n_crossings, self.severity, self.length = false_alarm, n_crossings, severity, length
        self.nuisance, self.region, self.step, self.nuisance_names = nuisance, region, step, tuple(nuisance_names)
        self.description = (f"worst-case detectability d^2 of a {100 * severity:g} % EI loss over {length:g} m, "
                            f"{n_crossings} crossing(s), nuisance {nuisance}")

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        raise ConfigError("The detect criterion is built from a case by recommend() or build_problem(), "
                          "not by make_criterion().")

    def value(self, q):
        return float(exact_d_squared(self.packing, q).min())

    def utilities(self, q, blocks):
        return exact_d_squared(self.packing, q[None] + blocks).min(axis=-1)

    def gradient_matrix(self, q):
        """Supergradient in packed form: u u^T at the worst centre, u = [1; -x] (the a_sN entries once,
        so their coefficient is -2x)."""
        d2, x = exact_solution(self.packing, q)
        c = int(np.argmin(d2))
        rows = np.zeros((self.packing.n_centres, 1 + self.packing.n_nuisance))
        rows[c] = np.concatenate([[1.0], -2.0 * x[c]])
        return self.packing.pack(rows, np.outer(x[c], x[c]))

    def upper_bounds(self, problem, q):
        # d^2_c(A + G) <= u_c^T (A + G) u_c for any u_c = [1; -x]; the minimum over the centres
        d2, x = exact_solution(self.packing, q)
        rows, nn = self.packing.rows(q), self.packing.nuisance(q)
        base = rows[:, 0] - 2.0 * np.einsum("cn,cn->c", rows[:, 1:], x) + np.einsum("cn,nm,cm->c", x, nn, x)
        return float(d2.min()), (base[None, :] + gradients(self.packing, problem.blocks, x)).min(axis=1)

    def bound(self, problem, w):
        return certificate(problem, w)[0]

    def integer_bound(self, problem, layout, utility, *, length):
        """The exhaustive branch and bound of :mod:`.detect_search` on small problems (see EXACT_UP_TO)."""
        if problem.n_candidates > EXACT_UP_TO[0] or problem.count > EXACT_UP_TO[1]:
            return None
        return certify(problem, layout, utility, length=length)

    def information_share(self, q):
        """W (packed) with <W, I_i> = sum_c tr(Q_c^-1 G_i(c)): Effective Independence on the block
        diagonal of the centres' Gram matrices."""
        inv = np.linalg.inv(self.packing.dense(q))
        rows = np.concatenate([inv[:, 0, :1], 2.0 * inv[:, 0, 1:]], axis=1)
        return self.packing.pack(rows, inv[:, 1:, 1:].sum(axis=0))

    # -- cvxpy: one LMI per centre ------------------------------------------------------------
    def cvxpy_precision(self, cp, problem, w, idx):
        m = 1 + self.packing.n_nuisance
        ridge = np.zeros((m, m))
        ridge[1:, 1:] = np.diag(self.ridge)
        q0 = self.packing.dense(problem.q0)
        dense = self.packing.dense(problem.blocks[idx])
        out = []
        for c in range(self.n_params):
            flat = dense[:, c].reshape(idx.size, m * m).T
            a = q0[c] + ridge + cp.reshape(flat @ w, (m, m), order="C")
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
        f, _, _ = ridged_parts(self.packing, problem.precision(w), self.ridge)
        return -math.inf if f is None else float(f.min())

    # -- reporting -------------------------------------------------------------------------------
    def describe(self, q):
        """JSON details and one summary line: worst centre, d, power."""
        d2 = exact_d_squared(self.packing, q)
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

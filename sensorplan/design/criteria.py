"""Optimal-design criteria on the posterior precision Q(w) = Q_0 + sum_i w_i I_i.

Every criterion is one class behind one protocol (:class:`Criterion`): its
value, the utility that is maximised (``value`` or ``-value``), the gradient
matrix G with d utility / d w_i = <G, I_i>, the Hessian in the weights of a
working set, upper bounds on the utility of adding one candidate (for
pruned greedy and exchange), the certified bound of a relaxed point, the
cvxpy objective, and the efficiency of a value against a bound.  The
defaults of the base class need only ``value``, ``gradient_matrix`` and
``cvxpy_objective`` of a concave utility; the built-in criteria override
the rest with exact, faster forms.  :func:`register_criterion` makes a new
criterion available to :func:`recommend`, greedy, exchange, both
relaxation solvers and the command line.

Definitions (Q is the posterior precision in log-EI parameters, optionally
with spring log-stiffnesses appended):

* D  = log det Q
* Ds = log det of the Schur complement of the spring block, i.e. the log
  determinant of the precision of log EI with the springs marginalised
* A  = trace(C Q^{-1} C^T): C = identity (all parameters), rows selecting
  the elements of a region of interest, or given linear functionals
* E  = lambda_min(Q)

Owns: criteria and their registry.  May import: errors.
"""

import math
from typing import ClassVar

import numpy as np
import scipy.linalg

from .._errors import ConfigError
from .linalg import (
    _chol,
    _eigen_split,
    _gram_sym,
    _inv,
    _logdet,
    _sym,
    _whitened_blocks,
)

__all__ = ["Criterion", "DCriterion", "DsCriterion", "ACriterion", "ECriterion", "CRITERIA",
           "register_criterion", "make_criterion", "criterion_class"]

CRITERIA: dict[str, type] = {}


def register_criterion(cls):
    """Class decorator: make ``cls`` available under ``cls.name``."""
    CRITERIA[cls.name] = cls
    return cls


class Criterion:
    """The protocol of a design criterion (a concave utility of the weights).

    Subclasses set ``name`` and ``description`` and implement ``value``,
    ``gradient_matrix`` and ``cvxpy_objective``; everything else has a
    correct default for any concave utility.  ``n_params``: dimension of Q.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    maximise: ClassVar[bool] = True
    submodular: ClassVar[bool] = False  # gains only shrink as sensors are added: lazy greedy is exact
    relaxation: ClassVar[str] = "interior-point"  # fast solver: "interior-point", "eigen-subspace", ...
    information: ClassVar[str] = "fisher"  # what a sensor adds: Fisher blocks, or "detection" Gram stacks
    params_label: ClassVar[str] = "parameters"  # what n_effective counts, for summaries
    random_starts: ClassVar[int] = 0  # randomised roundings of the relaxation tried as exchange starts
    batch_size: ClassVar[int] = 1  # candidates exchange evaluates together (``utilities``)

    def __init__(self, n_params):
        self.n_params = int(n_params)

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        """Build the criterion from the options of :func:`make_criterion`."""
        if region is not None or functionals is not None:
            raise ConfigError(f"A region of interest or functionals apply to the A criterion only, "
                              f"not to {cls.name}.")
        return cls(n_params)

    @property
    def n_effective(self):  # dimension used by a per-parameter efficiency
        return self.n_params

    # -- value and derivatives ---------------------------------------------------------
    def value(self, q):
        raise NotImplementedError

    def utility(self, q):
        v = self.value(q)
        return v if self.maximise else -v

    def utilities(self, q, blocks):
        """utility(Q + I_i) for each block of ``blocks`` (overridden where a batch is cheaper)."""
        return [self.utility(q + b) for b in blocks]

    def gradient_matrix(self, q):
        """Symmetric G with d utility / d w_i = <G, I_i> (a supergradient if not smooth)."""
        raise NotImplementedError

    def hessian(self, q, chol, blocks):
        """Hessian of the utility in the weights of ``blocks`` (m, P, P); default: central
        differences of the gradient along each block (exact forms override it)."""
        m = blocks.shape[0]
        flat = blocks.reshape(m, -1).astype(float)
        h = np.empty((m, m))
        for j in range(m):
            step = 1e-4 * max(1.0, float(np.abs(q).max())) / max(1.0, float(np.abs(flat[j]).max()))
            plus = self.gradient_matrix(q + step * blocks[j])
            minus = self.gradient_matrix(q - step * blocks[j])
            h[:, j] = flat @ ((plus - minus) / (2.0 * step)).ravel()
        return 0.5 * (h + h.T)

    # -- bounds and certificates ---------------------------------------------------------
    def upper_bounds(self, problem, q):
        """(utility(Q), b) with b_i >= utility(Q + I_i) for every candidate (concavity)."""
        u = self.utility(q)
        return u, u + problem.flat_blocks @ self.gradient_matrix(q).ravel()

    def bound(self, problem, w):
        """Certified bound on the relaxed optimum of the utility, from weights ``w``.

        For a concave utility f: f* <= f(w) + max_s g(w)^T (s - w) over the
        relaxed feasible set (the Frank-Wolfe gap).
        """
        q = problem.precision(w)
        g = problem.flat_blocks @ self.gradient_matrix(q).ravel()
        best, _ = problem.linear_max(g)
        return self.utility(q) + max(0.0, best - float(g @ w))

    # -- cvxpy -----------------------------------------------------------------------------
    def cvxpy_precision(self, cp, problem, w, idx):
        """Q(w) as a cvxpy expression (weights ``w`` on the candidates ``idx``)."""
        p = problem.n_params
        q = problem.q0 + cp.reshape(problem.flat_blocks[idx].T @ w, (p, p), order="C")
        return 0.5 * (q + q.T)

    def cvxpy_objective(self, cp, q_expr, constraints):
        """(objective, handle) of the relaxation; ``constraints`` may be extended."""
        raise NotImplementedError

    def cvxpy_bound(self, problem, weights, handle):
        """Certified bound from a cvxpy solution (default: :meth:`bound` at the weights)."""
        return self.bound(problem, weights)

    def relaxed_utility(self, problem, w):  # what the relaxation maximises, at relaxed weights
        return self.utility(problem.precision(w))

    def describe(self, q):
        """(JSON details, summary line) of a layout's Q beyond the value (none by default)."""
        return {}, ""

    # -- comparing values --------------------------------------------------------------------
    def efficiency(self, value, bound):
        """Certified lower bound on the efficiency of ``value`` against ``bound`` (in [0, 1])."""
        if self.maximise:
            return float(min(1.0, value / bound)) if bound > 0 and value > 0 else 0.0
        return float(min(1.0, bound / value)) if value > 0 else 0.0

    def relative(self, value, reference):
        """Efficiency of ``value`` relative to ``reference`` (1 = as good)."""
        if self.maximise:
            return value / reference if reference != 0 else math.nan
        return reference / value if value != 0 else math.nan


@register_criterion
class DCriterion(Criterion):
    """D-optimality: log det Q (submodular gains; exact Hessian)."""

    name = "D"
    description = "log det of the posterior precision"
    submodular = True

    def value(self, q):
        return _logdet(q)

    def gradient_matrix(self, q):
        return _inv(_sym(q))

    def hessian(self, q, chol, blocks):
        # H_ij = -<A_i, A_j>, A_i = L^-1 I_i L^-T (Q = L L^T), symmetric: a Gram
        # matrix on the upper triangles (off-diagonals scaled by sqrt 2)
        return -_gram_sym(_whitened_blocks(chol, blocks))

    def upper_bounds(self, problem, q):
        # Fischer's inequality on V (k smallest eigenvectors), concavity of log det on W
        lam, v, w, small = _eigen_split(problem, q)
        k = v.shape[1]
        logdet = 2.0 * np.log(np.diagonal(np.linalg.cholesky(small), axis1=1, axis2=2)).sum(axis=1)
        first = problem.flat_blocks @ ((w / lam[k:]) @ w.T).ravel()
        return float(np.sum(np.log(lam))), logdet + float(np.sum(np.log(lam[k:]))) + first

    def cvxpy_objective(self, cp, q_expr, constraints):
        return cp.Maximize(cp.log_det(q_expr)), None

    def efficiency(self, value, bound):
        return float(math.exp(min(0.0, (value - bound) / self.n_effective)))

    def relative(self, value, reference):
        return math.exp((value - reference) / self.n_effective)


@register_criterion
class DsCriterion(DCriterion):
    """Ds-optimality: log det of the precision of the first ``n_keep`` parameters (the rest marginalised)."""

    name = "Ds"
    description = "log det of the posterior precision of log EI, springs marginalised"
    submodular = False

    def __init__(self, n_params, n_keep=None):
        super().__init__(n_params)
        self.n_keep = self.n_params if n_keep is None else int(n_keep)

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        if region is not None or functionals is not None:
            raise ConfigError("A region of interest or functionals apply to the A criterion only, not to Ds.")
        return cls(n_params, n_params if n_elements is None else n_elements)

    @property
    def n_effective(self):
        return self.n_keep

    def value(self, q):
        q = _sym(q)
        k = self.n_keep
        return _logdet(q) - _logdet(q[k:, k:]) if k < q.shape[0] else _logdet(q)

    def gradient_matrix(self, q):
        q = _sym(q)
        g = _inv(q)
        k = self.n_keep
        if k < q.shape[0]:
            g[k:, k:] -= _inv(q[k:, k:])
        return g

    def hessian(self, q, chol, blocks):
        h = super().hessian(q, chol, blocks)
        k = self.n_keep
        if k < q.shape[0]:
            ls = np.linalg.inv(np.linalg.cholesky(_sym(q)[k:, k:])).astype(blocks.dtype)
            h = h + _gram_sym(np.matmul(ls, np.matmul(blocks[:, k:, k:], ls.T)))
        return h

    def upper_bounds(self, problem, q):
        return Criterion.upper_bounds(self, problem, q)

    def cvxpy_objective(self, cp, q_expr, constraints):
        k = self.n_keep
        if k == self.n_params:
            return cp.Maximize(cp.log_det(q_expr)), None
        s = cp.Variable((k, k), symmetric=True)
        block = cp.bmat([[q_expr[:k, :k] - s, q_expr[:k, k:]], [q_expr[k:, :k], q_expr[k:, k:]]])
        constraints.append(0.5 * (block + block.T) >> 0)
        return cp.Maximize(cp.log_det(s)), None


@register_criterion
class ACriterion(Criterion):
    """A-optimality: trace(C Q^-1 C^T), minimised (all parameters, a region or functionals)."""

    name = "A"
    description = "trace of the posterior covariance"
    maximise = False

    def __init__(self, n_params, targets=None):
        super().__init__(n_params)
        self.targets = np.eye(self.n_params) if targets is None else np.asarray(targets, dtype=float)
        p = self.n_params
        self.all_parameters = self.targets.shape == (p, p) and np.array_equal(self.targets, np.eye(p))

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        n_elements = n_params if n_elements is None else n_elements
        if region is not None and functionals is not None:
            raise ConfigError("Give either a region of interest or functionals, not both.")
        if region is not None:
            a, b = float(region[0]), float(region[1])
            if edges is None or not b > a:
                raise ConfigError(f"The region of interest must be (start, stop) with stop > start. Got {region!r}.")
            inside = (edges[1:] > a) & (edges[:-1] < b)
            if not inside.any():
                raise ConfigError(f"The 'region' {a:g}:{b:g} m contains no element; give a 'region' on the bridge.")
            targets = np.zeros((int(inside.sum()), n_params))
            targets[np.arange(targets.shape[0]), np.nonzero(inside)[0]] = 1.0
            return cls(n_params, targets)
        if functionals is not None:
            f = np.atleast_2d(np.asarray(functionals, dtype=float))
            if f.shape[1] != n_elements:
                raise ConfigError(f"Functionals must have {n_elements} columns (one per element). Got {f.shape}.")
            targets = np.zeros((f.shape[0], n_params))
            targets[:, :n_elements] = f
            return cls(n_params, targets)
        return cls(n_params)

    def value(self, q):
        chol = _chol(_sym(q))
        if self.all_parameters:
            # trace(Q^-1) = ||L^-1||_F^2 (triangular inverse, a third of the cost of a solve)
            z, info = scipy.linalg.lapack.dtrtri(chol, lower=1)
            if info == 0:
                return float(np.sum(z * z))
        z = scipy.linalg.solve_triangular(chol, self.targets.T, lower=True, check_finite=False)
        return float(np.sum(z * z))

    def gradient_matrix(self, q):
        qi_ct = scipy.linalg.cho_solve((_chol(_sym(q)), True), self.targets.T)
        return qi_ct @ qi_ct.T

    def hessian(self, q, chol, blocks):
        # utility -tr(C Q^-1 C^T): H_ij = -2 tr(M I_i Q^-1 I_j), M = N N^T, N = Q^-1 C^T,
        # so H_ij = -2 <B_i, B_j> with B_i = L^-1 I_i N
        m, p, _ = blocks.shape
        dtype = blocks.dtype
        n = scipy.linalg.cho_solve((chol, True), self.targets.T)
        nt = n.shape[1]
        li = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True)
        y = (blocks.reshape(m * p, p) @ n.astype(dtype)).reshape(m, p, nt).transpose(0, 2, 1).reshape(m * nt, p)
        b = (y @ li.T.astype(dtype)).reshape(m, -1)
        return -2.0 * (b @ b.T).astype(float)

    def upper_bounds(self, problem, q):
        if not self.all_parameters:
            return Criterion.upper_bounds(self, problem, q)
        # tr(M^-1) >= tr(V^T M V)^-1 + tr(W^T M W)^-1, then convexity of tr X^-1 on W
        lam, v, w, small = _eigen_split(problem, q)
        k = v.shape[1]
        trace = np.trace(np.linalg.inv(small), axis1=1, axis2=2)
        first = problem.flat_blocks @ ((w / lam[k:] ** 2) @ w.T).ravel()
        return -float(np.sum(1.0 / lam)), -(trace + float(np.sum(1.0 / lam[k:])) - first)

    def cvxpy_objective(self, cp, q_expr, constraints):
        return cp.Minimize(cp.matrix_frac(self.targets.T, q_expr)), None


@register_criterion
class ECriterion(Criterion):
    """E-optimality: lambda_min(Q) (not smooth: eigen-subspace relaxation, trace-one certificates)."""

    name = "E"
    description = "smallest eigenvalue of the posterior precision"
    relaxation = "eigen-subspace"

    def value(self, q):
        return float(np.linalg.eigvalsh(_sym(q))[0])

    def gradient_matrix(self, q):
        _, vecs = np.linalg.eigh(_sym(q))
        u = vecs[:, 0]
        return np.outer(u, u)

    def upper_bounds(self, problem, q):
        # Cauchy interlacing: lambda_min(Q + I_i) <= lambda_min(V^T (Q + I_i) V)
        lam, _, _, small = _eigen_split(problem, q)
        return float(lam[0]), np.linalg.eigvalsh(small)[:, 0]

    def bound(self, problem, w):
        return self.bound_from_dual(problem, self.gradient_matrix(problem.precision(w)))

    def bound_from_dual(self, problem, z):
        """lambda_min(Q) <= <Z, Q> for every Z >= 0 with trace 1, so
        E* <= <Z, Q_0> + max_s sum_i s_i <Z, I_i> (``z`` is projected onto that set)."""
        vals, vecs = np.linalg.eigh(_sym(z))
        vals = np.clip(vals, 0.0, None)
        if vals.sum() <= 0:
            return np.inf
        z = (vecs * (vals / vals.sum())) @ vecs.T
        best, _ = problem.linear_max(problem.flat_blocks @ z.ravel())
        return float(np.sum(z * problem.q0)) + best

    def cvxpy_objective(self, cp, q_expr, constraints):
        # maximise t s.t. Q(w) - t I >= 0: the PSD constraint's dual is the Z of the bound
        t = cp.Variable()
        lmi = q_expr - t * np.eye(self.n_params) >> 0
        constraints.append(lmi)
        return cp.Maximize(t), lmi

    def cvxpy_bound(self, problem, weights, handle):
        dual = handle.dual_value
        return self.bound_from_dual(problem, dual) if dual is not None else self.bound(problem, weights)


def criterion_class(name):
    """The registered criterion class called ``name`` (ConfigError if there is none)."""
    if name not in CRITERIA:
        raise ConfigError(f"The 'criterion' parameter must be one of {', '.join(CRITERIA)}. Got {name!r} instead.")
    return CRITERIA[name]


def make_criterion(name, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
    """Build a registered criterion.

    Parameters
    ----------
    name : str
        A key of ``CRITERIA`` ("D", "A", "E", "Ds" or a registered one).
    n_params : int
        Dimension of Q.
    n_elements : int
        Number of log-EI parameters (the leading ones); needed for Ds and
        for targeted A.
    edges : ndarray
        Element edges [m] (for ``region``).
    region : (float, float), optional
        A-criterion restricted to the elements overlapping [a, b] m.
    functionals : ndarray (m, n_elements), optional
        A-criterion on linear functionals of log EI (e.g. zone means).
    """
    return criterion_class(name).from_options(n_params, n_elements=n_elements, edges=edges, region=region,
                                       functionals=functionals)


from . import detect_criterion  # noqa: E402,F401  (registers "detect"; it builds on the protocol above)

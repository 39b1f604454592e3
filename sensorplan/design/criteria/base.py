"""The protocol every design criterion follows: :class:`Criterion`.

A criterion is a concave utility of the relaxed weights w (C,) of the
candidates, evaluated on the "precision" Q(w) = Q_0 + sum_i w_i I_i of a
placement problem (:class:`~sensorplan.design.problem.DesignProblem`).

Owns: the Criterion base class and its defaults, ProductRows.  May import: errors.
"""

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import partial
from typing import ClassVar

import numpy as np

from ..._errors import ConfigError

__all__ = ["Criterion", "ProductRows"]


@dataclass(frozen=True)
class ProductRows:
    """Rows B_i = U_i^T V_i of a Hessian factor given by their factors ``u`` (m, r, a) and ``v`` (m, r, b) (None:
    ``v`` is ``u``): <B_i, B_j> = <U_i U_j^T, V_i V_j^T>_F, from m r (a + b) numbers instead of m a b (the
    Gram of blocks' low-rank roots, r small)."""

    u: np.ndarray
    v: np.ndarray | None = None

    def __len__(self):
        return self.u.shape[0]

    def gram(self, rows=slice(None), *, chunk=64):
        """<B_i, B_j> for the rows ``rows`` (a slice) against all, (len(rows), m) in double precision."""
        m, r, a = self.u.shape
        every = self.u.reshape(m * r, a)
        other = None if self.v is None else self.v.reshape(m * r, -1)
        picked = np.arange(m)[rows]
        out = np.empty((picked.size, m))
        for s in range(0, picked.size, chunk):  # (chunk r, m r) products at a time
            part = picked[s:s + chunk]
            g = self.u[part].reshape(-1, a) @ every.T
            g *= g if other is None else self.v[part].reshape(part.size * r, -1) @ other.T
            out[s:s + part.size] = g.reshape(part.size, r, m, r).sum(axis=(1, 3))
        return out


class Criterion(ABC):
    """The protocol of a design criterion (a concave utility of the weights).

    Contract
    --------
    A subclass sets the class attributes ``name`` (its registry key, also
    the ``--criterion`` choice) and ``description``, and implements three
    methods:

    * ``value(q) -> float``: the criterion of a precision Q (P, P);
    * ``gradient_matrix(q) -> ndarray (P, P)``: a symmetric G with
      d utility / d w_i = <G, I_i> (a supergradient where not smooth);
    * ``cvxpy_objective(cp, q_expr, constraints) -> (objective, handle)``: the
      cvxpy objective of the relaxation on the expression Q(w) (it may append
      to ``constraints``; ``handle`` is passed back to :meth:`cvxpy_bound`).

    The utility that is maximised is ``value`` if ``maximise`` else
    ``-value``, and it must be concave in the weights: every certificate
    (:meth:`bound`, :meth:`upper_bounds`) relies on that.  Everything else
    has a correct default for any concave utility (central-difference
    Hessian, first-order upper bounds, the Frank-Wolfe bound, a Newton
    step's derivatives and the preconditioner's factors one by one), which
    the built-in criteria override with exact, faster forms.  Class attributes
    that tune the search: ``submodular`` (lazy greedy is exact),
    ``relaxation`` (the fast relaxation method registered under that name,
    :mod:`sensorplan.design.relaxation`), ``information`` (what a sensor adds:
    ``"fisher"`` blocks, or ``"detection"`` Gram stacks built by
    :mod:`~sensorplan.design.detect_problem`), ``params_label`` (what
    :attr:`n_effective` counts, for summaries), ``random_starts`` (randomised
    roundings tried as exchange starts), ``batch_size`` (candidates
    :meth:`utilities` evaluates together) and ``enter_share`` (how fast the
    working set of the structured relaxation may grow per round: fewer
    rounds against more preconditioner rows).

    A criterion becomes available to :func:`~sensorplan.design.recommend.recommend`,
    greedy, exchange, both relaxation solvers and the command line once its
    class is registered with
    :func:`~sensorplan.design.criteria.registry.register_criterion`.

    Parameters
    ----------
    n_params : int
        Dimension of Q.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    maximise: ClassVar[bool] = True
    submodular: ClassVar[bool] = False  # gains only shrink as sensors are added: lazy greedy is exact
    relaxation: ClassVar[str] = "interior-point"  # fast solver: "interior-point", "eigen-subspace", ...
    relaxation_tol: ClassVar[float] = 1e-7  # relative duality gap at which the fast relaxation stops by default
    swap_gain: ClassVar[float] = 0.0  # share of the utility a swap must gain for exchange to take it (0: round-off)
    smallest_eigenvectors_only: ClassVar[bool] = False  # subset_bounds needs Q's k smallest eigenpairs only
    information: ClassVar[str] = "fisher"  # what a sensor adds: Fisher blocks, or "detection" Gram stacks
    params_label: ClassVar[str] = "parameters"  # what n_effective counts, for summaries
    random_starts: ClassVar[int] = 0  # randomised roundings of the relaxation tried as exchange starts
    batch_size: ClassVar[int] = 1  # candidates exchange evaluates together (``utilities``)
    enter_share: ClassVar[float] = 0.5  # share of the working set that may join it per round of column generation

    def __init__(self, n_params):
        self.n_params = int(n_params)

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        """Build the criterion from the options of :func:`~sensorplan.design.criteria.registry.make_criterion`."""
        if region is not None or functionals is not None:
            raise ConfigError(f"A region of interest or functionals apply to the A criterion only, "
                              f"not to {cls.name}.")
        return cls(n_params)

    @property
    def n_effective(self):
        """Dimension used by a per-parameter efficiency."""
        return self.n_params

    # -- value and derivatives ---------------------------------------------------------
    @abstractmethod
    def value(self, q):
        """The criterion of the precision ``q``."""

    def utility(self, q):
        """What is maximised: ``value`` or ``-value``."""
        v = self.value(q)
        return v if self.maximise else -v

    def utilities(self, q, blocks):
        """utility(Q + I_i) for each block of ``blocks`` (overridden where a batch is cheaper)."""
        return [self.utility(q + b) for b in blocks]

    def utilities_above(self, q, blocks, threshold):
        """utility(Q + I_i) for each block where it exceeds ``threshold``; elsewhere any number not above it
        (a search for the best candidate needs only the values that can win; overridden where a test is
        cheaper than the value)."""
        return self.utilities(q, blocks)

    @abstractmethod
    def gradient_matrix(self, q):
        """Symmetric G with d utility / d w_i = <G, I_i> (a supergradient if not smooth)."""

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

    def hessian_factors(self, q, chol, blocks):
        """(N, M) with Hessian = M M^T - N N^T (M may be None), one row per block of ``blocks``, rows computed
        for different blocks at the same ``q`` combining into the Hessian of all of them; None where the
        criterion has no such form (default)."""
        return None

    def hessian_factors_of_roots(self, q, chol, roots):
        """:meth:`hessian_factors` of the blocks R_i R_i^T given by their roots ``roots`` (m, P, r): low-rank
        forms of the blocks, cheaper where a criterion overrides it (m P^2 r instead of m P^3); default: the
        blocks formed."""
        return self.hessian_factors(q, chol, np.matmul(roots, np.swapaxes(roots, 1, 2)))

    def hessian_factors_at(self, q, chol, *, rank=None):
        """The function roots -> (N, M) of :meth:`hessian_factors_of_roots` at ``q`` (what it needs of ``q``
        computed once: rows added at one point over many calls), each factor None, rows (m, w) or
        :class:`ProductRows` (cheaper where the roots are narrow).  ``rank``: where the Hessian weights the
        blocks by a matrix (A's N N^T), only its ``rank`` leading directions are kept, an approximation from
        below (the factors' Gram B_k B_k^T <= B B^T) that a preconditioner can use; default: exact rows,
        ``rank`` ignored."""
        return partial(self.hessian_factors_of_roots, q, chol)

    def hessian_product(self, q, chol, s):
        """Symmetric G with (H v)_i = <G, I_i>, where S = sum_j v_j I_j: the Hessian of the utility in the
        weights applied to ``v`` without the per-candidate blocks (``chol`` the lower Cholesky factor of
        ``q``).  Same as ``hessian_operator(q, chol)(s)``."""
        return self.hessian_operator(q, chol)(s)

    def hessian_operator(self, q, chol, *, dtype=np.float64):
        """The function S -> G of :meth:`hessian_product` at ``q`` (what it needs of ``q`` computed once, for
        many products at the same point), computed in ``dtype`` where the form allows; default: central
        differences of ``gradient_matrix`` along S in double precision (exact forms override it)."""
        scale = max(1.0, float(np.abs(q).max()))

        def product(s):
            step = 1e-4 * scale / max(1e-300, float(np.abs(s).max()))
            g = (self.gradient_matrix(q + step * s) - self.gradient_matrix(q - step * s)) / (2.0 * step)
            return 0.5 * (g + g.T)

        return product

    def point_derivatives(self, q, chol, *, dtype=np.float64):
        """(utility, gradient matrix, Hessian operator) at ``q`` (``chol`` its lower Cholesky factor): what a
        Newton step of the relaxation needs at one point, the operator's products in ``dtype``; default:
        :meth:`utility`, :meth:`gradient_matrix` and :meth:`hessian_operator` (overridden where they share
        their work, e.g. one inverse of Q)."""
        return self.utility(q), self.gradient_matrix(q), self.hessian_operator(q, chol, dtype=dtype)

    # -- bounds and certificates ---------------------------------------------------------
    def upper_bounds(self, problem, q):
        """(utility(Q), b) with b_i >= utility(Q + I_i) for every candidate (concavity)."""
        u = self.utility(q)
        return u, u + problem.block_dot(self.gradient_matrix(q))

    def bound(self, problem, w):
        """Certified bound on the relaxed optimum of the utility, from weights ``w``.

        For a concave utility f: f* <= f(w) + max_s g(w)^T (s - w) over the
        relaxed feasible set (the Frank-Wolfe gap).
        """
        q = problem.precision(w)
        g = problem.block_dot(self.gradient_matrix(q))
        best, _ = problem.linear_max(g)
        return self.utility(q) + max(0.0, best - float(g @ w))

    def integer_bound(self, problem, layout, utility, *, length):
        """A bound on the integer layouts tighter than the relaxation's, for ``layout`` of ``utility`` on a
        bridge of ``length`` [m]: an object with ``layout`` and ``value`` (the best layout met, perhaps
        better), ``bound`` and ``method`` (how it was proven), or None (the default: no such proof)."""
        return None

    def linearisation(self, problem, w):
        """(constant, g) with utility* <= constant + g^T s for every relaxed-feasible s of *any* count
        (concavity at the relaxed weights ``w``): the relaxed optimum for count r is at most
        constant + max g^T s over sum s = r, a concave function of r."""
        q = problem.precision(w)
        g = problem.block_dot(self.gradient_matrix(q))
        return self.utility(q) - float(g @ w), g

    # -- cvxpy -----------------------------------------------------------------------------
    def cvxpy_precision(self, cp, problem, w, idx):
        """Q(w) as a cvxpy expression (weights ``w`` on the candidates ``idx``)."""
        p = problem.n_params
        q = problem.q0 + cp.reshape(np.asarray(problem.blocks[idx]).reshape(len(idx), -1).T @ w, (p, p), order="C")
        return 0.5 * (q + q.T)

    @abstractmethod
    def cvxpy_objective(self, cp, q_expr, constraints):
        """(objective, handle) of the relaxation; ``constraints`` may be extended."""

    def cvxpy_bound(self, problem, weights, handle):
        """Certified bound from a cvxpy solution (default: :meth:`bound` at the weights)."""
        return self.bound(problem, weights)

    def relaxed_utility(self, problem, w):
        """What the relaxation maximises, at relaxed weights ``w`` (default: the utility)."""
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

"""The determinant criteria: D (log det Q) and Ds (log det of the Schur complement of the nuisance block).

* D  = log det Q
* Ds = log det of the Schur complement of the spring block, i.e. the log
  determinant of the precision of log EI with the springs marginalised

Owns: DCriterion, DsCriterion.  May import: errors, design.criteria.
"""

import math

import numpy as np
import scipy.linalg

from ..._errors import ConfigError
from .base import Criterion, ProductRows
from .linalg import (congruence, eigen_split, factor_inverse, inverse, inverse_from_cholesky, log_det, log_dets,
                     lower_factor, packed_upper, scaled_gram, symmetrise, whitened_blocks)
from .registry import register_criterion

__all__ = ["DCriterion", "DsCriterion"]


@register_criterion
class DCriterion(Criterion):
    """D-optimality: log det Q (submodular gains; exact Hessian)."""

    name = "D"
    description = "log det of the posterior precision"
    submodular = True
    # the eigen-split levels of the searches (selection; the first, every candidate's first bounds): with k = 32
    # first, fewer candidates reach the split bounds, whose cost grows with their number
    refine_levels = ((32, 40), (64, 64), (128, 96))
    enter_share = 1.0  # its preconditioner rows are narrow product rows: fewer rounds pay

    def value(self, q):
        return log_det(q)

    def gradient_matrix(self, q):
        return inverse(symmetrise(q))

    def utilities(self, q, blocks):
        # Q and the blocks are symmetric, so Q + I_i is (no symmetrised copy; the factor reads one triangle)
        return [2.0 * float(np.sum(np.log(np.diag(lower_factor(q + b))))) for b in blocks]

    def hessian(self, q, chol, blocks):
        # H_ij = -<A_i, A_j>, A_i = L^-1 I_i L^-T (Q = L L^T), symmetric: a Gram
        # matrix on the upper triangles (off-diagonals scaled by sqrt 2)
        negative, _ = self.hessian_factors(q, chol, blocks)
        return -(negative @ negative.T).astype(float)

    def hessian_factors(self, q, chol, blocks):
        """(N, None): H = -N N^T, row i of N the packed upper triangle of L^-1 I_i L^-T (in the blocks'
        precision), so that rows computed at one ``q`` for different blocks combine into one Hessian."""
        return packed_upper(whitened_blocks(chol, blocks)), None

    def hessian_factors_at(self, q, chol, *, rank=None):
        """The factor of :meth:`hessian_factors_of_roots` as :class:`ProductRows`: Z_i Z_i^T with U_i = V_i =
        Z_i^T = (L^-1 R_i)^T, m r P numbers (<Z_i Z_i^T, Z_j Z_j^T> = ||Z_i^T Z_j||_F^2); ``rank`` ignored."""
        p = chol.shape[0]
        linv = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True)

        def factors(roots):
            m, _, r = roots.shape
            flat = np.swapaxes(roots, 0, 1).reshape(p, m * r)
            z = (linv.astype(roots.dtype) @ flat).reshape(p, m, r).transpose(1, 2, 0)
            return ProductRows(np.ascontiguousarray(z)), None

        return factors

    def hessian_operator(self, q, chol, *, dtype=np.float64):
        # (H v)_i = -tr(Q^-1 I_i Q^-1 S): G = -Q^-1 S Q^-1
        w = inverse_from_cholesky(chol).astype(dtype)
        return lambda s: -congruence(w, np.asarray(s, dtype=dtype))

    def point_derivatives(self, q, chol, *, dtype=np.float64):
        """From one inverse W = Q^-1 (LAPACK dpotri on ``chol``): the utility 2 sum log diag L, the gradient
        matrix W and the products of :meth:`hessian_operator` with W."""
        w = factor_inverse(chol)
        wd = w.astype(dtype)
        return 2.0 * float(np.sum(np.log(np.diag(chol)))), w, lambda s: -congruence(wd, np.asarray(s, dtype=dtype))

    def upper_bounds(self, problem, q):
        eig = np.linalg.eigh(symmetrise(q))
        return float(np.sum(np.log(eig[0]))), self.subset_bounds(problem, q, eig=eig)

    def subset_bounds(self, problem, q, index=None, *, k=16, eig=None):
        """b_i >= utility(Q + I_i) for the candidates at ``index`` (all if None), from the eigen-split with
        the ``k`` smallest eigenvectors of Q (``eig``: its eigendecomposition if known): Fischer's inequality
        on V, concavity of log det on W.  A larger k gives tighter bounds (k = P: the exact values)."""
        lam, v, w, small = eigen_split(problem, q, k, index=index, eig=eig)
        k = v.shape[1]
        logdet = log_dets(small)
        first = problem.block_dot(scaled_gram(w, 1.0 / lam[k:]), index)
        return logdet + float(np.sum(np.log(lam[k:]))) + first

    def split_bounds(self, problem, q, index, *, basis, chol):
        """b_i >= utility(Q + I_i) from the whitened split: with B_i = L^-1 I_i L^-T and [U W] orthonormal
        (U = ``basis``), log det(I + B_i) <= log det(I + U^T B_i U) + log det(I + W^T B_i W) (Fischer) and
        log det(I + X) <= tr X, where tr W^T B_i W = <Q^-1, I_i> - tr U^T B_i U.  Tight when U spans B_i."""
        v = scipy.linalg.solve_triangular(chol, basis, lower=True, trans="T", check_finite=False)  # L^-T U
        small = problem.congruence(v, index)  # U^T B_i U
        k = small.shape[1]
        inside = np.trace(small, axis1=1, axis2=2)
        small[:, np.arange(k), np.arange(k)] += 1.0
        logdet = log_dets(small)
        rest = np.maximum(problem.block_dot(factor_inverse(chol), index) - inside, 0.0)
        return 2.0 * float(np.sum(np.log(np.diag(chol)))) + logdet + rest

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
    utilities = Criterion.utilities  # not D's: the value is a difference of two log determinants
    point_derivatives = Criterion.point_derivatives  # D's utility and gradient are not Ds's

    def __init__(self, n_params, *, n_keep=None):
        super().__init__(n_params)
        self.n_keep = self.n_params if n_keep is None else int(n_keep)

    @classmethod
    def from_options(cls, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
        if region is not None or functionals is not None:
            raise ConfigError("A region of interest or functionals apply to the A criterion only, not to Ds.")
        n_keep = n_params if n_elements is None else n_elements
        if n_keep >= n_params:  # nothing to marginalise (no spring parameters): Ds is D, with D's bounds and paths
            return _DsWithoutNuisance(n_params)
        return cls(n_params, n_keep=n_keep)

    @property
    def n_effective(self):
        return self.n_keep

    def value(self, q):
        q = symmetrise(q)
        k = self.n_keep
        return log_det(q) - log_det(q[k:, k:]) if k < q.shape[0] else log_det(q)

    def gradient_matrix(self, q):
        q = symmetrise(q)
        g = inverse(q)
        k = self.n_keep
        if k < q.shape[0]:
            g[k:, k:] -= inverse(q[k:, k:])
        return g

    def hessian(self, q, chol, blocks):
        negative, positive = self.hessian_factors(q, chol, blocks)
        h = -(negative @ negative.T).astype(float)
        return h if positive is None else h + (positive @ positive.T).astype(float)

    def hessian_factors(self, q, chol, blocks):
        """(N, M): H = M M^T - N N^T, N as D's, M (None without nuisance) the packed upper triangles of
        L22^-1 I_i,22 L22^-T (the Hessian of -log det Q22)."""
        negative, _ = super().hessian_factors(q, chol, blocks)
        k = self.n_keep
        if k == q.shape[0]:
            return negative, None
        ls = np.linalg.inv(np.linalg.cholesky(symmetrise(q)[k:, k:])).astype(blocks.dtype)
        return negative, packed_upper(np.matmul(ls, np.matmul(blocks[:, k:, k:], ls.T)))

    def hessian_factors_at(self, q, chol, *, rank=None):
        """D's product rows (L^-1 R_i, the -N N^T part) and, for the +M M^T part (the Hessian of
        -log det Q_22), product rows of L_22^-1 R_i,22 (s x r per candidate) from the roots' marginalised
        rows, without forming the blocks; ``rank`` ignored."""
        negative_at = super().hessian_factors_at(q, chol, rank=rank)
        k = self.n_keep
        if k == q.shape[0]:
            return negative_at
        l22 = scipy.linalg.solve_triangular(np.linalg.cholesky(symmetrise(q)[k:, k:]), np.eye(q.shape[0] - k),
                                            lower=True)

        def factors(roots):
            negative, _ = negative_at(roots)
            z = np.matmul(l22.astype(roots.dtype), roots[:, k:, :])  # (m, s, r)
            return negative, ProductRows(np.ascontiguousarray(np.swapaxes(z, 1, 2)))

        return factors

    def hessian_operator(self, q, chol, *, dtype=np.float64):
        # D's product plus Q22^-1 S22 Q22^-1 on the nuisance block (the Hessian of -log det Q22)
        full = super().hessian_operator(q, chol, dtype=dtype)
        k = self.n_keep
        if k == q.shape[0]:
            return full
        w22 = inverse(symmetrise(q)[k:, k:]).astype(dtype)

        def product(s):
            g = full(s)
            g[k:, k:] += congruence(w22, np.asarray(s, dtype=dtype)[k:, k:])
            return g

        return product

    # Ds(Q + I_i) = log det(Q + I_i) - log det(Q_22 + I_i,22): D's bounds on the first term less the second,
    # exact and cheap (Q_22 is the s x s block of the s marginalised parameters; I_i,22 from a congruence)

    def upper_bounds(self, problem, q):
        """(utility(Q), b): the smaller of the first-order (concavity) bounds and D's eigen-split bounds on
        log det(Q + I_i) less log det(Q_22 + I_i,22)."""
        value, first = Criterion.upper_bounds(self, problem, q)
        return value, np.minimum(first, self.subset_bounds(problem, q, eig=np.linalg.eigh(symmetrise(q))))

    def subset_bounds(self, problem, q, index=None, *, k=16, eig=None):
        """b_i >= utility(Q + I_i): D's eigen-split bound on log det(Q + I_i) less log det(Q_22 + I_i,22)."""
        return super().subset_bounds(problem, q, index, k=k, eig=eig) - self._marginalised(problem, q, index)

    def split_bounds(self, problem, q, index, *, basis, chol):
        """b_i >= utility(Q + I_i): D's whitened split bound on log det(Q + I_i) less log det(Q_22 + I_i,22)."""
        return super().split_bounds(problem, q, index, basis=basis, chol=chol) - self._marginalised(problem, q, index)

    def _marginalised(self, problem, q, index):
        """log det(Q_22 + I_i,22) for the candidates at ``index`` (all if None)."""
        k = self.n_keep
        p = q.shape[0]
        corner = np.zeros((p, p - k))
        corner[k:] = np.eye(p - k)
        small = problem.congruence(corner, index)
        small += symmetrise(q)[k:, k:]
        return log_dets(small)

    def cvxpy_objective(self, cp, q_expr, constraints):
        k = self.n_keep
        if k == self.n_params:
            return cp.Maximize(cp.log_det(q_expr)), None
        s = cp.Variable((k, k), symmetric=True)
        block = cp.bmat([[q_expr[:k, :k] - s, q_expr[:k, k:]], [q_expr[k:, :k], q_expr[k:, k:]]])
        constraints.append(0.5 * (block + block.T) >> 0)
        return cp.Maximize(cp.log_det(s)), None


class _DsWithoutNuisance(DCriterion):
    """Ds when no parameter is marginalised (the springs are not estimated): D itself under Ds's name.

    log det Q - log det Q_22 with an empty Q_22 is log det Q, so D's exact
    evaluations, split and eigen-split bounds, greedy's lazy evaluation and the
    relaxation's structured derivatives all hold (Ds's own paths, written for a
    difference of two log determinants, are about three times slower).
    """

    name = DsCriterion.name
    description = DsCriterion.description

    @property
    def n_keep(self):
        return self.n_params

"""The covariance criterion A = trace(C Q^-1 C^T), minimised.

C is the identity (all parameters), rows selecting the elements of a region
of interest, or given linear functionals of log EI.

Owns: ACriterion.  May import: errors, design.criteria.
"""

from functools import cached_property

import numpy as np
import scipy.linalg

from ..._errors import ConfigError
from .base import Criterion, ProductRows
from .linalg import (cholesky, eigen_split, factor_inverse, inverse_from_cholesky, inverse_traces, lower_factor,
                     lower_inverse, scaled_gram, symmetrise)
from .registry import register_criterion

__all__ = ["ACriterion"]

# relative margin by which the blocked inverse's value must lie below a search's threshold to be settled without
# dtrtri: both inversions are backward stable, their values agree to round-off (~1e-15 relative) far below this
LOSER_MARGIN = 1e-9


@register_criterion
class ACriterion(Criterion):
    """A-optimality: trace(C Q^-1 C^T), minimised (all parameters, a region or functionals)."""

    name = "A"
    description = "trace of the posterior covariance"
    maximise = False
    # the eigen-split levels of the searches (selection; the first, every candidate's first bounds): an exact A
    # evaluation (a factor and a triangular inverse) costs more than D's, so tighter bounds pay sooner
    refine_levels = ((32, 16), (64, 16), (128, 24))
    # the relaxed A optimum spreads over hundreds of candidates: sets that may double per round take fewer rounds
    # (each a dozen Newton steps), and the preconditioner rows of the members that enter are narrow (WEIGHT_RANK)
    enter_share = 1.0

    def __init__(self, n_params, *, targets=None):
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
            return cls(n_params, targets=region_targets(region, edges, n_params))
        if functionals is not None:
            f = np.atleast_2d(np.asarray(functionals, dtype=float))
            if f.shape[1] != n_elements:
                raise ConfigError(f"Functionals must have {n_elements} columns (one per element). Got {f.shape}.")
            targets = np.zeros((f.shape[0], n_params))
            targets[:, :n_elements] = f
            return cls(n_params, targets=targets)
        return cls(n_params)

    def value(self, q):
        chol = cholesky(symmetrise(q))
        if self.all_parameters:
            # trace(Q^-1) = ||L^-1||_F^2 (triangular inverse, a third of the cost of a solve)
            z, info = scipy.linalg.lapack.dtrtri(chol, lower=1)
            if info == 0:
                return float(np.sum(z * z))
        z = scipy.linalg.solve_triangular(chol, self.targets.T, lower=True, check_finite=False)
        return float(np.sum(z * z))

    def utilities(self, q, blocks):
        if not self.all_parameters:
            return super().utilities(q, blocks)
        out = []
        for b in blocks:  # -||L^-1||_F^2 (Q and the blocks are symmetric: the factor reads one triangle)
            z, info = scipy.linalg.lapack.dtrtri(lower_factor(q + b), lower=1)
            out.append(-float(np.sum(np.tril(z) ** 2)) if info == 0 else self.utility(q + b))
        return out

    def utilities_above(self, q, blocks, threshold):
        """As :meth:`utilities` where utility(Q + I_i) may reach ``threshold``; elsewhere -||L^-1||_F^2 from the
        blocked triangular inverse (:func:`~sensorplan.design.criteria.linalg.lower_inverse`), which is below the
        threshold by more than its round-off (``LOSER_MARGIN``): a search's losers, most of its evaluations,
        skip dtrtri, and the values that can win are the ones of :meth:`utilities`."""
        if not self.all_parameters:
            return self.utilities(q, blocks)
        cut = threshold - LOSER_MARGIN * max(1.0, abs(threshold)) if np.isfinite(threshold) else threshold
        out = []
        for b in blocks:
            factor = lower_factor(q + b)
            z = lower_inverse(factor)
            fast = -float(np.sum(z * z))
            if fast < cut:
                out.append(fast)
                continue
            z, info = scipy.linalg.lapack.dtrtri(factor, lower=1)
            out.append(-float(np.sum(np.tril(z) ** 2)) if info == 0 else self.utility(q + b))
        return out

    def gradient_matrix(self, q):
        qi_ct = scipy.linalg.cho_solve((cholesky(symmetrise(q)), True), self.targets.T)
        return qi_ct @ qi_ct.T

    def hessian(self, q, chol, blocks):
        negative, _ = self.hessian_factors(q, chol, blocks)
        return -(negative @ negative.T).astype(float)

    def hessian_factors(self, q, chol, blocks):
        """(sqrt 2 B, None): H = -2 B B^T (utility -tr(C Q^-1 C^T): H_ij = -2 tr(M I_i Q^-1 I_j),
        M = N N^T, N = Q^-1 C^T, so H_ij = -2 <B_i, B_j> with B_i = L^-1 I_i N), row i of B the flattened B_i
        in the blocks' precision."""
        m, p, _ = blocks.shape
        dtype = blocks.dtype
        n = scipy.linalg.cho_solve((chol, True), self.targets.T)
        nt = n.shape[1]
        li = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True)
        y = (blocks.reshape(m * p, p) @ n.astype(dtype)).reshape(m, p, nt).transpose(0, 2, 1).reshape(m * nt, p)
        b = (y @ (np.sqrt(2.0) * li.T).astype(dtype)).reshape(m, -1)
        return b, None

    def hessian_factors_at(self, q, chol, *, rank=None):
        """The factors of :meth:`hessian_factors_of_roots` as :class:`ProductRows`: B_i = U_i^T V_i with
        U_i = sqrt 2 (L^-1 R_i)^T and V_i = R_i^T N, m r (P + nt) numbers; with ``rank``, N replaced by
        N_k = U_k S_k of its ``rank`` leading singular triplets (N = U S V^T), whose Gram is below the exact
        one (N_k N_k^T <= N N^T)."""
        p = chol.shape[0]
        n = scipy.linalg.cho_solve((chol, True), self.targets.T)
        if rank is not None and rank < min(n.shape):
            u, s, _ = np.linalg.svd(n, full_matrices=False)
            n = u[:, :rank] * s[:rank]
        li = np.sqrt(2.0) * scipy.linalg.solve_triangular(chol, np.eye(p), lower=True)

        def factors(roots):
            m, _, r = roots.shape
            dtype = roots.dtype
            flat = np.swapaxes(roots, 0, 1).reshape(p, m * r)
            z = (li.astype(dtype) @ flat).reshape(p, m, r).transpose(1, 2, 0)  # (L^-1 R_i)^T, scaled
            y = (n.T.astype(dtype) @ flat).reshape(-1, m, r).transpose(1, 2, 0)  # R_i^T N
            return ProductRows(np.ascontiguousarray(z), np.ascontiguousarray(y)), None

        return factors

    def hessian_operator(self, q, chol, *, dtype=np.float64):
        # (H v)_i = -2 tr(M I_i Q^-1 S), M = N N^T, N = Q^-1 C^T: G = -(Q^-1 S M + M S Q^-1)
        w = inverse_from_cholesky(chol)
        n = w @ self.targets.T
        return _product(w, n @ n.T, dtype)

    def point_derivatives(self, q, chol, *, dtype=np.float64):
        """From one inverse W = Q^-1 (LAPACK dpotri on ``chol``): N = W C^T, the utility -tr(C W C^T), the
        gradient matrix N N^T and the products of :meth:`hessian_operator` with W and M = N N^T."""
        w = factor_inverse(chol)
        if self.all_parameters:
            n, utility = w, -float(np.trace(w))
        else:
            n = w @ self.targets.T
            utility = -float(np.einsum("ij,ji->", self.targets, n))
        g = n @ n.T
        return utility, g, _product(w, g, dtype)

    def upper_bounds(self, problem, q):
        if not self.all_parameters:
            return Criterion.upper_bounds(self, problem, q)
        eig = np.linalg.eigh(symmetrise(q))
        return -float(np.sum(1.0 / eig[0])), self.subset_bounds(problem, q, eig=eig)

    def subset_bounds(self, problem, q, index=None, *, k=16, eig=None):
        """b_i >= utility(Q + I_i) for the candidates at ``index`` (all if None) from the eigen-split with
        the ``k`` smallest eigenvectors of Q, tighter for larger k; None unless C is the identity.
        tr(M^-1) >= tr(V^T M V)^-1 + tr(W^T M W)^-1, then convexity of tr X^-1 on W."""
        if not self.all_parameters:
            return None
        lam, v, w, small = eigen_split(problem, q, k, index=index, eig=eig)
        k = v.shape[1]
        trace = inverse_traces(small)
        first = problem.block_dot(scaled_gram(w, lam[k:] ** -2.0), index)
        return -(trace + float(np.sum(1.0 / lam[k:])) - first)

    def split_bounds(self, problem, q, index, *, basis, chol):
        """b_i >= utility(Q + I_i) from the whitened split: with B_i = L^-1 I_i L^-T and H = L^-1 C^T C L^-T,
        utility(Q + I_i) = -tr H + f(B_i), f(B) = tr H - tr (I + B)^-1 H concave (the inverse is operator convex),
        bounded by its tangent at U C_i U^T (U = ``basis``, C_i = U^T B_i U):
        f(U C U^T) = tr D S with D = C (I + C)^-1, S = U^T H U, and the gradient there
        (I - U D U^T) H (I - U D U^T).  Exact when U spans B_i."""
        k = basis.shape[1]
        y = scipy.linalg.solve_triangular(chol, basis, lower=True, trans="T", check_finite=False)  # L^-T U
        q_inv = factor_inverse(chol)
        if self.all_parameters:  # C^T C = I
            my, n, trace = y, q_inv, np.trace(q_inv)
        else:
            n = q_inv @ self.targets.T
            my, trace = self._gram @ y, np.einsum("ij,ji->", self.targets, n)  # tr(C Q^-1 C^T)
        both = problem.congruence(np.hstack([q_inv @ my, y]), index)
        cross, small = both[:, :k, k:], both[:, k:, k:]  # U^T H B_i U and C_i
        s = y.T @ my
        d = np.eye(k) - np.linalg.inv(np.eye(k)[None] + small)
        ds = d @ s
        linear = problem.block_dot(n @ n.T, index)  # tr H B_i (Q^-1 C^T C Q^-1, a symmetric product)
        tangent = (np.trace(ds, axis1=1, axis2=2) - 2.0 * np.einsum("cij,cji->c", d, cross)
                   - np.einsum("ij,cji->c", s, small) + 2.0 * np.einsum("cij,cji->c", ds, small))
        return -float(trace) + linear + tangent

    @cached_property
    def _gram(self):
        """C^T C."""
        return self.targets.T @ self.targets

    def cvxpy_objective(self, cp, q_expr, constraints):
        return cp.Minimize(cp.matrix_frac(self.targets.T, q_expr)), None


def _product(w, m, dtype):
    """S -> -(W S M + M S W) for symmetric S, in ``dtype`` (A's Hessian operator with W = Q^-1, M = N N^T)."""
    w, m = w.astype(dtype), m.astype(dtype)

    def product(s):
        s = np.asarray(s, dtype=dtype)
        x = w @ (0.5 * (s + s.T)) @ m
        return -(x + x.T)

    return product


def region_targets(region, edges, n_params):
    """Rows of C selecting the elements that overlap ``region`` (start, stop) [m] of the element ``edges``."""
    a, b = float(region[0]), float(region[1])
    if edges is None or not b > a:
        raise ConfigError(f"The region of interest must be (start, stop) with stop > start. Got {region!r}.")
    inside = (edges[1:] > a) & (edges[:-1] < b)
    if not inside.any():
        raise ConfigError(f"The 'region' {a:g}:{b:g} m contains no element; give a 'region' on the bridge.")
    targets = np.zeros((int(inside.sum()), n_params))
    targets[np.arange(targets.shape[0]), np.nonzero(inside)[0]] = 1.0
    return targets

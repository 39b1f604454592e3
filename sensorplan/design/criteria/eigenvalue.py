"""The eigenvalue criterion E = lambda_min(Q).

Not smooth: its relaxation is the eigen-subspace method
(:mod:`sensorplan.design.relaxation.eigen_subspace`), certified by trace-one
dual matrices (:meth:`ECriterion.bound_from_dual`).

Owns: ECriterion.  May import: errors, design.criteria.
"""

import numpy as np
import scipy.linalg

from .base import Criterion
from .linalg import eigen_split, symmetrise
from .registry import register_criterion

__all__ = ["ECriterion"]


@register_criterion
class ECriterion(Criterion):
    """E-optimality: lambda_min(Q) (not smooth: eigen-subspace relaxation, trace-one certificates)."""

    name = "E"
    description = "smallest eigenvalue of the posterior precision"
    relaxation = "eigen-subspace"

    def value(self, q):
        return float(np.linalg.eigvalsh(symmetrise(q))[0])

    def utilities_above(self, q, blocks, threshold):
        """utility(Q + I_i) for each block, exact (``value``) where it exceeds ``threshold``; elsewhere
        any number not above ``threshold`` (here ``-inf``).

        lambda_min(Q + I_i) > v exactly when Q + I_i - v I is positive definite, so
        one Cholesky factorisation (a third of the cost of the eigenvalues)
        settles most candidates; it is tried at v = threshold - margin
        (``margin`` above the factorisation's round-off, Demmel's bound
        P eps ||A||), so that no candidate above ``threshold`` is missed, and
        those that pass get the exact value.
        """
        if not np.isfinite(threshold):
            return self.utilities(q, blocks)
        p = q.shape[0]
        out = []
        for block in blocks:
            a = q + block
            diagonal = np.diagonal(a)
            # ||A||'s largest entry: on the diagonal of a positive definite matrix (the only kind that passes)
            size = float(diagonal.max()) if diagonal.min() > 0 else float(np.abs(symmetrise(a)).max())
            margin = 1e-9 * max(1.0, abs(threshold)) + 8.0 * p * np.finfo(float).eps * size
            a.flat[::p + 1] -= threshold - margin
            # the transpose is Fortran-ordered (no copy); its lower triangle differs from the symmetric part's
            # by round-off only, far inside the margin
            _, info = scipy.linalg.lapack.dpotrf(a.T, lower=1, clean=0, overwrite_a=1)
            out.append(self.value(q + block) if info == 0 else -np.inf)
        return out

    def gradient_matrix(self, q):
        _, vecs = np.linalg.eigh(symmetrise(q))
        u = vecs[:, 0]
        return np.outer(u, u)

    def upper_bounds(self, problem, q):
        eig = np.linalg.eigh(symmetrise(q))
        return float(eig[0][0]), self.subset_bounds(problem, q, eig=eig)

    def subset_bounds(self, problem, q, index=None, *, k=16, eig=None):
        """b_i >= lambda_min(Q + I_i) for the candidates at ``index`` (all if None), by Cauchy interlacing:
        lambda_min(Q + I_i) <= lambda_min(V^T (Q + I_i) V), V the ``k`` smallest eigenvectors of Q (tighter
        for larger k)."""
        _, _, _, small = eigen_split(problem, q, k, index=index, eig=eig)
        return np.linalg.eigvalsh(small)[:, 0]

    def bound(self, problem, w):
        return self.bound_from_dual(problem, self.gradient_matrix(problem.precision(w)))

    def linearisation(self, problem, w):
        """(<Z, Q_0>, <Z, I_i>) of the trace-one Z at ``w`` (see :meth:`bound_from_dual`): valid for every count."""
        z = self.gradient_matrix(problem.precision(w))
        return float(np.sum(z * problem.q0)), problem.block_dot(z)

    def bound_from_dual(self, problem, z):
        """lambda_min(Q) <= <Z, Q> for every Z >= 0 with trace 1, so
        E* <= <Z, Q_0> + max_s sum_i s_i <Z, I_i> (``z`` is projected onto that set)."""
        vals, vecs = np.linalg.eigh(symmetrise(z))
        vals = np.clip(vals, 0.0, None)
        if vals.sum() <= 0:
            return np.inf
        z = (vecs * (vals / vals.sum())) @ vecs.T
        best, _ = problem.linear_max(problem.block_dot(z))
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

"""The eigenvalue criterion E = lambda_min(Q).

Not smooth: its relaxation is the eigen-subspace method
(:mod:`sensorplan.design.relaxation.eigen_subspace`), certified by trace-one
dual matrices (:meth:`ECriterion.bound_from_dual`).

Owns: ECriterion, smallest_eigenvalue, lowest_eigenvalue.  May import: errors, _cache, design.criteria.
"""

import numpy as np
import scipy.linalg

from ..._cache import Cache
from .base import Criterion
from .linalg import eigen_split, symmetrise
from .registry import register_criterion

__all__ = ["ECriterion", "smallest_eigenvalue", "lowest_eigenvalue"]


@register_criterion
class ECriterion(Criterion):
    """E-optimality: lambda_min(Q) (not smooth: eigen-subspace relaxation, trace-one certificates)."""

    name = "E"
    description = "smallest eigenvalue of the posterior precision"
    relaxation = "eigen-subspace"
    # E's relaxed optimum is flat (lambda_min of multiplicity 3-4, hundreds of fractional weights): the
    # eigen-subspace method's last digit costs the most rounds, and rounding loses far more than 1e-6
    relaxation_tol = 1e-6
    # swaps along a dense grid raise lambda_min by tiny steps (a sensor moved 6 cm, then the next): the
    # exchange takes a swap only when it gains more than this share of lambda_min
    swap_gain = 1e-6

    def value(self, q):
        return lowest_eigenvalue(symmetrise(q))

    def utilities_above(self, q, blocks, threshold):
        """utility(Q + I_i) for each block, exact (``value``) where it exceeds ``threshold``; elsewhere
        any number not above ``threshold`` (here ``-inf``).

        lambda_min(Q + I_i) > v exactly when Q + I_i - v I is positive definite, so
        one Cholesky factorisation (a third of the cost of the eigenvalues)
        settles most candidates; it is tried at v = threshold - margin
        (``margin`` above the factorisation's round-off, Demmel's bound
        P eps ||A||), so that no candidate above ``threshold`` is missed, and
        those that pass get the exact value from that factor
        (:func:`smallest_eigenvalue`, equal to ``value`` to round-off; ``value`` itself within
        ``NEAR_THRESHOLD`` of the threshold).  Without a threshold (-inf) every block needs its value: the test
        is then made just below lambda_min(Q), which no lambda_min(Q + I_i) is below (I_i >= 0).
        """
        every = not np.isfinite(threshold)
        if every:
            floor = self.value(q)
            threshold = floor - BELOW_FLOOR * max(1.0, abs(floor))
        p = q.shape[0]
        total, a, shifted = np.empty((p, p)), np.empty((p, p)), np.empty((p, p))
        out = []
        for block in blocks:
            # a = symmetrise(q + block) and a - v I, written into held arrays (the same numbers, fewer passes)
            np.add(q, block, out=total)
            np.add(total, total.T, out=a)
            a *= 0.5
            margin = 1e-9 * max(1.0, abs(threshold)) + 8.0 * p * np.finfo(float).eps * max(a.max(), -a.min())
            np.copyto(shifted, a)
            shifted.flat[::p + 1] -= threshold - margin
            # a is exactly symmetric: its transpose is the same matrix in Fortran order (no copy for LAPACK)
            factor, info = scipy.linalg.lapack.dpotrf(shifted.T, lower=1, clean=0, overwrite_a=1)
            if info != 0:
                out.append(self.value(a) if every else -np.inf)
                continue
            value = self._settled(a, smallest_eigenvalue(a, factor, threshold - margin, shifted), threshold)
            out.append(self.value(a) if every and value == -np.inf else value)
        return out

    @staticmethod
    def _settled(a, theta, threshold):
        """The value of ``a`` for :meth:`utilities_above` from its certified Ritz value ``theta``
        (lambda_min <= theta, never far below): below the threshold by more than CERTIFY_TOL, any number not
        above it (-inf; the many swaps that leave lambda_min where it was land there); within
        ``NEAR_THRESHOLD`` above it, the full solver's (what ``value`` gives: nothing at or below the
        threshold is ever reported above it); above, theta."""
        scale = max(1.0, abs(threshold))
        if theta < threshold - CERTIFY_TOL * scale:
            return -np.inf
        if theta <= threshold + NEAR_THRESHOLD * scale:
            return lowest_eigenvalue(a)
        return theta

    def gradient_matrix(self, q):
        # the eigenvector of the smallest eigenvalue alone (LAPACK's dsyevr: a quarter of the full solve)
        _, vecs = scipy.linalg.eigh(symmetrise(q), subset_by_index=[0, 0], driver="evr")
        u = vecs[:, 0]
        return np.outer(u, u)

    def upper_bounds(self, problem, q):
        eig = np.linalg.eigh(symmetrise(q))
        return float(eig[0][0]), self.subset_bounds(problem, q, eig=eig)

    smallest_eigenvectors_only = True  # subset_bounds needs only Q's k smallest eigenpairs (not all of them)

    def subset_bounds(self, problem, q, index=None, *, k=16, eig=None):
        """b_i >= lambda_min(Q + I_i) for the candidates at ``index`` (all if None), by Cauchy interlacing:
        lambda_min(Q + I_i) <= lambda_min(V^T (Q + I_i) V), V the ``k`` smallest eigenvectors of Q (tighter
        for larger k; without ``eig`` only those are computed, by LAPACK's dsyevx)."""
        if eig is None:
            k = min(k, q.shape[0])
            eig = scipy.linalg.eigh(symmetrise(q), subset_by_index=[0, k - 1], driver="evx", check_finite=False)
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
        return self.bound_and_maximiser(problem, z)[0]

    def bound_and_maximiser(self, problem, z):
        """(the bound of :meth:`bound_from_dual`, the weights s that attain its maximum, None if Z is zero):
        the candidates Z favours under the constraints (those outside a working set enter it)."""
        vals, vecs = np.linalg.eigh(symmetrise(z))
        vals = np.clip(vals, 0.0, None)
        if vals.sum() <= 0:
            return np.inf, None
        z = (vecs * (vals / vals.sum())) @ vecs.T
        best, s = problem.linear_max(problem.block_dot(z))
        return float(np.sum(z * problem.q0)) + best, s

    def cvxpy_objective(self, cp, q_expr, constraints):
        # maximise t s.t. Q(w) - t I >= 0: the PSD constraint's dual is the Z of the bound
        t = cp.Variable()
        lmi = q_expr - t * np.eye(self.n_params) >> 0
        constraints.append(lmi)
        return cp.Maximize(t), lmi

    def cvxpy_bound(self, problem, weights, handle):
        dual = handle.dual_value
        return self.bound_from_dual(problem, dual) if dual is not None else self.bound(problem, weights)


BELOW_FLOOR = 1e-9  # relative: without a threshold, the test is made this far below lambda_min(Q)
NEAR_THRESHOLD = 1e-11  # relative: closer to the threshold than this, the full eigenvalue solver decides
LANCZOS_STEPS = 60  # at most; shift-and-invert converges in 4-8 steps on the design problems (P = 400)
LANCZOS_TOL = 1e-14  # relative residual of the largest Ritz value of (A - s I)^-1 at which it is taken
CERTIFY_TOL = 1e-13  # relative distance below the Ritz value at which the factorisation certifies it smallest


def smallest_eigenvalue(a, factor, shift, work=None):
    """lambda_min(A) of a symmetric A with every eigenvalue above ``shift``, from the lower Cholesky factor
    ``factor`` of A - shift I (as LAPACK's dpotrf leaves it, the upper triangle not cleared).

    Lanczos on (A - shift I)^-1 (two triangular solves a step, full
    reorthogonalisation): its largest eigenvalue 1 / (lambda_min - shift) is
    the first to converge, in a few steps when lambda_min is near ``shift``,
    as it is for the candidates a search evaluates.  The Ritz value theta is
    never below lambda_min; a factorisation of A - (1 - ``CERTIFY_TOL``)
    theta I certifies that none lies further below (it fails if Lanczos
    missed the smallest eigenvalue), else the eigenvalues are computed.
    Agrees with :func:`lowest_eigenvalue` to its round-off (~1e-14 relative).  ``work`` (P, P) is overwritten if
    given.
    """
    p = a.shape[0]
    solve = scipy.linalg.lapack.dtrtrs
    basis = np.empty((LANCZOS_STEPS, p))
    v = _start(p)
    alphas, betas, theta = [], [], None
    for j in range(LANCZOS_STEPS):
        basis[j] = v
        half, _ = solve(factor, v, lower=1)
        u, _ = solve(factor, half, lower=1, trans=1)
        alphas.append(float(v @ u))
        u -= basis[:j + 1].T @ (basis[:j + 1] @ u)  # full reorthogonalisation (also removes alpha v, beta v_prev)
        beta = float(np.linalg.norm(u))
        ritz, vec = scipy.linalg.eigh_tridiagonal(np.array(alphas), np.array(betas), select="i",
                                                  select_range=(j, j))
        if beta * abs(vec[-1, 0]) <= LANCZOS_TOL * ritz[0] or beta == 0.0:
            theta = shift + 1.0 / ritz[0]
            break
        betas.append(beta)
        v = u / beta
    if theta is not None:
        work = np.empty((p, p)) if work is None else work
        np.copyto(work, a)
        work.flat[::p + 1] -= theta - CERTIFY_TOL * max(1.0, abs(theta))
        _, info = scipy.linalg.lapack.dpotrf(work.T, lower=1, clean=0, overwrite_a=1)
        if info == 0:
            return theta
    return lowest_eigenvalue(a)


def lowest_eigenvalue(a):
    """lambda_min of a symmetric ``a`` alone (LAPACK's dsyevr: the same tridiagonal reduction as the full
    spectrum, then one eigenvalue instead of all; ECriterion's value wherever the criterion decides)."""
    return float(scipy.linalg.eigh(a, subset_by_index=[0, 0], eigvals_only=True, driver="evr")[0])


_STARTS = Cache(maxsize=8)  # the Lanczos start vectors by size


def _start(p):
    """The Lanczos start vector of size ``p``: fixed, with every component nonzero and no symmetry (a bridge's
    symmetric layouts have antisymmetric eigenvectors a constant vector would miss)."""
    return _STARTS.get((int(p),), lambda: _start_vector(int(p)))


def _start_vector(p):
    v = np.cos(np.arange(1, p + 1) * np.sqrt(2.0)) + 1.5
    v /= np.linalg.norm(v)
    v.flags.writeable = False
    return v

"""Small dense linear algebra shared by the criteria: Cholesky, log det, Gram matrices, eigen-splits.

Owns: the dense kernels of the criteria.  May import: errors.
"""

import numpy as np
import scipy.linalg

from ..._errors import ConfigError

__all__ = ["symmetrise", "cholesky", "lower_factor", "log_det", "log_dets", "inverse", "whitened_blocks", "packed_upper",
           "inverse_from_cholesky", "congruence", "eigen_split", "lower_inverse",
           "factor_inverse", "scaled_gram", "inverse_traces"]

INVERSE_LEAF = 128  # lower_inverse: triangles up to this size are inverted by LAPACK's dtrtri directly


def symmetrise(q):
    """(Q + Q^T) / 2: the symmetric part, removing round-off asymmetry."""
    return 0.5 * (q + q.T)


def cholesky(q):
    """Lower Cholesky factor L of Q = L L^T; ConfigError if Q is not positive definite."""
    try:
        return np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        raise ConfigError("The posterior precision is not positive definite; the prior must be proper.") from None


def lower_factor(q):
    """The lower triangle of Q's Cholesky factor by LAPACK's dpotrf (the other triangle is not cleared): what
    the searches' many exact evaluations use, about three times faster than numpy's routine for P = 400; the
    same factor up to round-off.  ConfigError if Q is not positive definite."""
    factor, info = scipy.linalg.lapack.dpotrf(q, lower=1, clean=0)
    if info != 0:
        raise ConfigError("The posterior precision is not positive definite; the prior must be proper.")
    return factor


def lower_inverse(factor):
    """L^-1 (zeros above the diagonal) from the lower triangle of ``factor`` (the other triangle is not read).

    The halves are inverted (recursively) and the off-diagonal block is
    -L22^-1 L21 L11^-1, two triangular matrix products: BLAS-3 throughout,
    several times faster than dtrtri on one thread for P = 400; the same
    inverse up to round-off.
    """
    n = factor.shape[0]
    if n <= INVERSE_LEAF:
        z, info = scipy.linalg.lapack.dtrtri(factor, lower=1)
        if info != 0:
            raise ConfigError("The posterior precision is not positive definite; the prior must be proper.")
        return np.tril(z)
    h = n // 2
    out = np.zeros((n, n), order="F")
    out[:h, :h] = lower_inverse(factor[:h, :h])
    out[h:, h:] = lower_inverse(factor[h:, h:])
    half = scipy.linalg.blas.dtrmm(1.0, out[:h, :h], factor[h:, :h], side=1, lower=1)  # L21 L11^-1
    out[h:, :h] = scipy.linalg.blas.dtrmm(-1.0, out[h:, h:], half, lower=1)
    return out


def inverse_traces(mats):
    """tr(S^-1) of each positive definite matrix of the stack ``mats`` (n, k, k) (only their lower triangles are
    read), by LAPACK's dpotrf and dpotri one matrix at a time: about half the time of numpy's batched inverse,
    which solves against the identity by LU.  ConfigError if one is not positive definite."""
    out = np.empty(mats.shape[0])
    potrf, potri = scipy.linalg.lapack.dpotrf, scipy.linalg.lapack.dpotri
    for i, m in enumerate(mats):
        factor, info = potrf(m, lower=1, clean=0)
        if info == 0:
            factor, info = potri(factor, lower=1)
        if info != 0:
            raise ConfigError("The posterior precision is not positive definite; the prior must be proper.")
        out[i] = np.trace(factor)
    return out


def log_dets(mats):
    """log det of each positive definite matrix of the stack ``mats`` (n, k, k), from their Cholesky factors."""
    return 2.0 * np.log(np.diagonal(np.linalg.cholesky(mats), axis1=1, axis2=2)).sum(axis=1)


def log_det(q):
    """log det Q of a positive definite Q (from the Cholesky factor of its symmetric part)."""
    return float(2.0 * np.sum(np.log(np.diag(cholesky(symmetrise(q))))))


def inverse(q):
    """Q^-1 of a positive definite Q, by its Cholesky factor."""
    return scipy.linalg.cho_solve((cholesky(q), True), np.eye(q.shape[0]))


def whitened_blocks(chol, blocks):
    """A_i = L^-1 I_i L^-T for all blocks (m, P, P): one tall product I_i L^-T, then L^-1 times each (no
    transposed copy of the stack)."""
    m, p, _ = blocks.shape
    linv = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True).astype(blocks.dtype)
    y = (blocks.reshape(m * p, p) @ linv.T).reshape(m, p, p)
    return np.matmul(linv, y)


def inverse_from_cholesky(chol):
    """Q^-1 (symmetric) from the lower Cholesky factor of Q."""
    w = scipy.linalg.cho_solve((chol, True), np.eye(chol.shape[0]), check_finite=False)
    return symmetrise(w)


def factor_inverse(chol):
    """Q^-1 (symmetric) from the lower Cholesky factor of Q by LAPACK's dpotri (a triangular inverse and its
    product with its transpose: a third of the flops of two solves against the identity); what the bounds use,
    equal to :func:`inverse_from_cholesky` up to round-off."""
    w, info = scipy.linalg.lapack.dpotri(chol, lower=1)
    if info != 0:
        raise ConfigError("The posterior precision is not positive definite; the prior must be proper.")
    lower = np.tril(w)
    return lower + np.tril(w, -1).T


def scaled_gram(w, scale):
    """W diag(scale) W^T for positive ``scale`` as one symmetric rank-k product (X X^T with X = W diag(scale)^1/2,
    half the flops of a general product)."""
    x = w * np.sqrt(scale)
    return x @ x.T


def congruence(w, s):
    """W S W for symmetric W and S (symmetric, by construction)."""
    return symmetrise(w @ symmetrise(s) @ w)


def packed_upper(a):
    """The upper triangles of symmetric A (m, P, P) as rows, off-diagonals scaled by sqrt 2, so that
    <A_i, A_j>_F is the dot product of rows i and j."""
    p = a.shape[1]
    iu = np.triu_indices(p)
    scale = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0)).astype(a.dtype)
    return a[:, iu[0], iu[1]] * scale


def eigen_split(problem, q, k=16, *, index=None, eig=None):
    """Eigen-split of Q for the upper bounds: R^P = V (k smallest eigenvectors) + W.

    Returns (lambda, V, W, S) with S_i = V^T (Q + I_i) V = Lambda_V + V^T I_i V
    for every candidate of ``problem`` (or those at ``index``; two tall products).
    ``eig``, the (eigenvalues, eigenvectors) of Q when already computed, saves
    the eigendecomposition (several k on one Q: a larger k gives tighter bounds).
    """
    p = q.shape[0]
    k = min(p, k)
    lam, vec = np.linalg.eigh(symmetrise(q)) if eig is None else eig
    v, w = vec[:, :k], vec[:, k:]
    small = problem.congruence(v, index)
    small[:, np.arange(k), np.arange(k)] += lam[:k]
    return lam, v, w, small

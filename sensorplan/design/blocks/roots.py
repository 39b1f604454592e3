"""Low-rank roots of dense positive semidefinite blocks (what the relaxation's preconditioner is built from).

Owns: low_rank_roots.  May import: nothing of the package.
"""

import numpy as np

__all__ = ["low_rank_roots"]


def low_rank_roots(blocks, rank, *, oversample=8, seed=0):
    """R (k, P, r) with R_i R_i^T close to the positive semidefinite blocks (k, P, P): their ``rank`` largest
    eigenpairs by a randomised range finder with ``oversample`` extra directions (Halko, Martinsson & Tropp,
    SIAM Review 53 (2011), algorithms 4.1 and 5.3), one Gaussian sketch drawn from ``seed`` for all blocks;
    the exact roots (r = P) when the sketch would not be smaller than P.  In the blocks' precision."""
    k, p, _ = blocks.shape
    if rank + oversample >= p:
        lam, vec = np.linalg.eigh(blocks)
        return (vec * np.sqrt(np.maximum(lam, 0.0))[:, None, :]).astype(blocks.dtype)
    sketch = np.random.default_rng(seed).standard_normal((p, rank + oversample)).astype(blocks.dtype)
    basis = np.linalg.qr(np.matmul(blocks, sketch))[0]  # (k, P, rank + oversample), orthonormal columns
    lam, vec = np.linalg.eigh(np.matmul(np.swapaxes(basis, 1, 2), np.matmul(blocks, basis)))
    lam, vec = lam[:, oversample:], vec[:, :, oversample:]  # ascending: the largest ``rank``
    return np.matmul(basis, vec * np.sqrt(np.maximum(lam, 0.0))[:, None, :]).astype(blocks.dtype)

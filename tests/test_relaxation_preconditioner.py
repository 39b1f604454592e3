"""The Newton-CG preconditioner's pieces: low-rank roots of the blocks, Hessian factors from roots, the row store.

References: numpy's symmetric eigendecomposition (the exact truncated roots,
an independent computation of what the randomised range finder
approximates), the criteria's own Hessian factors and exact Hessians on the
blocks R_i R_i^T formed densely (the identity the roots' forms rely on),
and plain concatenation of the rows.
"""

import pathlib
import sys

import numpy as np
import pytest

from sensorplan.design.blocks import low_rank_roots

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_relaxation_newton_cg import point, problem_for  # noqa: E402  (the shared small problems)


def decaying_blocks(rng, k, p, decay):
    """k random positive semidefinite (p, p) blocks with eigenvalues decay**j."""
    out = np.empty((k, p, p))
    for n in range(k):
        basis = np.linalg.qr(rng.standard_normal((p, p)))[0]
        out[n] = (basis * decay ** np.arange(p)) @ basis.T
    return 0.5 * (out + np.swapaxes(out, 1, 2))


def test_low_rank_roots_approach_the_truncated_eigendecomposition():
    rng = np.random.default_rng(0)
    blocks = decaying_blocks(rng, 5, 60, 0.5)
    for rank in (4, 8, 16):
        roots = low_rank_roots(blocks, rank)
        assert roots.shape == (5, 60, rank)
        approx = np.matmul(roots, np.swapaxes(roots, 1, 2))
        for b, a in zip(blocks, approx):
            lam, vec = np.linalg.eigh(b)
            best = (vec[:, -rank:] * lam[-rank:]) @ vec[:, -rank:].T  # the best rank-r approximation
            best_err = np.linalg.norm(b - best, 2)
            # Halko, Martinsson & Tropp (2011), eq. (1.9): within a modest factor of the best, with 8 extra samples
            assert np.linalg.norm(b - a, 2) <= 30.0 * best_err + 1e-12
            assert best_err <= 0.5**rank * 1.01  # the spectrum: sigma_{r+1} = 0.5^r
        assert np.all(np.linalg.eigvalsh(approx) >= -1e-12)  # positive semidefinite, as the blocks


def test_low_rank_roots_are_exact_when_the_sketch_covers_the_space():
    rng = np.random.default_rng(1)
    blocks = decaying_blocks(rng, 3, 12, 0.7)
    roots = low_rank_roots(blocks, 8)  # 8 + 8 extra >= 12: the exact roots
    assert roots.shape == (3, 12, 12)
    np.testing.assert_allclose(np.matmul(roots, np.swapaxes(roots, 1, 2)), blocks, rtol=0, atol=1e-12)
    single = low_rank_roots(blocks.astype(np.float32), 2)
    assert single.dtype == np.float32


@pytest.mark.parametrize("criterion", ["D", "Ds", "A", "A-region"])
def test_hessian_factors_of_roots_equal_the_factors_of_the_formed_blocks(criterion):
    options = {"region": (3.0, 9.0)} if criterion == "A-region" else {}
    problem = problem_for(criterion.split("-")[0], **options)
    crit = problem.criterion
    rng, _, q = point(problem, 2)
    chol = np.linalg.cholesky(q)
    p = problem.n_params
    roots = rng.standard_normal((problem.n_candidates, p, 3)) * np.sqrt(np.abs(problem.blocks).max())
    formed = np.matmul(roots, np.swapaxes(roots, 1, 2))
    ref = crit.hessian(q, chol, formed)  # the criterion's exact Hessian of the formed blocks
    factors = crit.hessian_factors_of_roots(q, chol, roots)
    if factors is None:
        assert crit.hessian_factors(q, chol, formed) is None
        return
    negative, positive = factors
    h = -(negative @ negative.T) + (0.0 if positive is None else positive @ positive.T)
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_row_store_keeps_rows_in_order_and_appends_new_ones():
    from sensorplan.design.relaxation.preconditioner import _RowStore

    rng = np.random.default_rng(3)
    first = rng.standard_normal((6, 4))
    store = _RowStore((first.copy(), None))
    reference = first
    for n_new in (3, 0, 5, 2):
        stay = rng.uniform(size=store.count) < 0.6
        new = rng.standard_normal((n_new, 4))
        store.replace(stay, (new, None))
        reference = np.concatenate([reference[stay], new])  # the plain concatenation
        negative, positive = store.factors
        np.testing.assert_array_equal(negative, reference)
        assert positive is None


def test_unsymmetrised_single_precision_blocks_equal_the_dense_blocks(monkeypatch):
    # reference: the symmetrised double-precision dense blocks (StructuredBlocks indexing, cached path)
    from test_relaxation_newton_cg import structured_problem

    problem, dense = structured_problem(monkeypatch, "D")
    index = np.arange(0, problem.n_candidates, 3)
    ref = dense.blocks[index]
    for dtype, tol in ((np.float64, 1e-12), (np.float32, 1e-4)):
        got = problem.blocks.unsymmetrised(index, dtype=dtype)
        assert got.dtype == dtype
        scale = np.abs(ref).max(axis=(1, 2), keepdims=True)
        assert np.all(np.abs(got - ref) <= tol * scale)

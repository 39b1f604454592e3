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


def random_roots(problem, rng, rank=3):
    """Random roots R_i (C, P, rank) on the scale of the problem's blocks, and the blocks R_i R_i^T they form."""
    roots = rng.standard_normal((problem.n_candidates, problem.n_params, rank)) * np.sqrt(np.abs(problem.blocks).max())
    return roots, np.matmul(roots, np.swapaxes(roots, 1, 2))


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
    problem = problem_for(criterion)
    crit = problem.criterion
    rng, _, q = point(problem, 2)
    chol = np.linalg.cholesky(q)
    roots, formed = random_roots(problem, rng)
    ref = crit.hessian(q, chol, formed)  # the criterion's exact Hessian of the formed blocks
    factors = crit.hessian_factors_of_roots(q, chol, roots)
    if factors is None:
        assert crit.hessian_factors(q, chol, formed) is None
        return
    negative, positive = factors
    h = -(negative @ negative.T) + (0.0 if positive is None else positive @ positive.T)
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_row_store_keeps_product_rows_in_order_and_appends_new_ones():
    from sensorplan.design.criteria.base import ProductRows
    from sensorplan.design.relaxation.preconditioner import _RowStore

    rng = np.random.default_rng(5)
    u, v = rng.standard_normal((6, 2, 4)), rng.standard_normal((6, 2, 3))
    store = _RowStore((ProductRows(u.copy(), v.copy()), ProductRows(u.copy())))
    for n_new in (3, 0, 5):
        stay = rng.uniform(size=store.count) < 0.6
        nu, nv = rng.standard_normal((n_new, 2, 4)), rng.standard_normal((n_new, 2, 3))
        store.replace(stay, (ProductRows(nu, nv), ProductRows(nu)))
        u, v = np.concatenate([u[stay], nu]), np.concatenate([v[stay], nv])  # the plain concatenation
        first, second = store.factors
        np.testing.assert_array_equal(first.u, u)
        np.testing.assert_array_equal(first.v, v)
        np.testing.assert_array_equal(second.u, u)
        assert second.v is None


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


@pytest.mark.parametrize("criterion", ["A", "A-region"])
def test_hessian_factors_at_a_rank_keep_the_leading_directions_of_the_weighting(criterion):
    # reference: H_ij = -2 tr(M_k I_i Q^-1 I_j) with M_k the k leading eigenpairs of M = N N^T (numpy's symmetric
    # eigendecomposition of M, not the SVD of N the factors use), contracted over the formed blocks R_i R_i^T
    problem = problem_for(criterion)
    crit = problem.criterion
    rng, _, q = point(problem, 6)
    chol = np.linalg.cholesky(q)
    roots, formed = random_roots(problem, rng)
    exact = crit.hessian(q, chol, formed)
    n = np.linalg.solve(q, crit.targets.T)
    lam, vec = np.linalg.eigh(n @ n.T)
    q_inv = np.linalg.inv(q)
    for rank in (1, 2):
        m_k = (vec[:, -rank:] * lam[-rank:]) @ vec[:, -rank:].T
        ref = -2.0 * np.einsum("ab,ibc,cd,jda->ij", m_k, formed, q_inv, formed)
        negative, positive = crit.hessian_factors_at(q, chol, rank=rank)(roots)
        assert positive is None and negative.v.shape == (problem.n_candidates, 3, min(rank, n.shape[1]))
        h = -negative.gram()
        np.testing.assert_allclose(h, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
        # below the exact Hessian's magnitude: H_k - H positive semidefinite (M_k <= M)
        assert np.linalg.eigvalsh(h - exact).min() >= -1e-9 * np.abs(exact).max()
    # a rank at least N's, or none: the exact factors
    for rank in (problem.n_params, None):
        full, _ = crit.hessian_factors_at(q, chol, rank=rank)(roots)
        np.testing.assert_allclose(-full.gram(), exact, rtol=0, atol=1e-9 * np.abs(exact).max())


@pytest.mark.parametrize("criterion", ["D", "Ds", "A"])
def test_hessian_factors_at_give_the_exact_hessian_of_the_formed_blocks(criterion):
    # reference: the criterion's exact Hessian (closed form) of the blocks R_i R_i^T formed densely
    from sensorplan.design.relaxation.preconditioner import _gram

    problem = problem_for(criterion)
    crit = problem.criterion
    rng, _, q = point(problem, 9)
    chol = np.linalg.cholesky(q)
    roots = rng.standard_normal((problem.n_candidates, problem.n_params, 2)) * np.sqrt(np.abs(problem.blocks).max())
    ref = crit.hessian(q, chol, np.matmul(roots, np.swapaxes(roots, 1, 2)))
    factors = crit.hessian_factors_at(q, chol)(roots)
    np.testing.assert_allclose(_gram(factors), ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    # the rows from the fifth on against all: the same rows of the Hessian
    np.testing.assert_allclose(_gram(factors, rows=slice(4, None)), ref[4:], rtol=0, atol=1e-9 * np.abs(ref).max())


def test_product_rows_gram_equals_the_gram_of_the_formed_rows():
    # reference: B_i = U_i^T V_i formed and flattened, their plain Gram
    from sensorplan.design.criteria.base import ProductRows

    rng = np.random.default_rng(4)
    u, v = rng.standard_normal((150, 3, 7)), rng.standard_normal((150, 3, 5))
    for rows in (ProductRows(u, v), ProductRows(u)):
        other = u if rows.v is None else v
        flat = np.matmul(np.swapaxes(u, 1, 2), other).reshape(150, -1)
        ref = flat @ flat.T
        np.testing.assert_allclose(rows.gram(), ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(rows.gram(slice(70, None), chunk=16), ref[70:], rtol=1e-12,
                                   atol=1e-12 * np.abs(ref).max())
        assert len(rows) == 150


@pytest.mark.parametrize("criterion", ["D", "Ds", "A", "A-region", "logdiag"])
def test_point_derivatives_equal_the_criterion_methods(criterion):
    # reference: utility, gradient_matrix and hessian_operator called one by one (each checked against finite
    # differences in tests/test_conformance.py and tests/test_relaxation_newton_cg.py)
    import dataclasses

    from criterion_checks import LogDiagonal

    problem = problem_for("D" if criterion == "logdiag" else criterion)
    if criterion == "logdiag":  # the protocol's default
        problem = dataclasses.replace(problem, criterion=LogDiagonal(problem.n_params))
    crit = problem.criterion
    rng, _, q = point(problem, 7)
    chol = np.linalg.cholesky(q)
    utility, gradient, product = crit.point_derivatives(q, chol)
    assert utility == pytest.approx(crit.utility(q), rel=1e-12)
    ref = crit.gradient_matrix(q)
    np.testing.assert_allclose(gradient, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    s = np.einsum("c,cij->ij", rng.standard_normal(problem.n_candidates), problem.blocks)
    ref = crit.hessian_operator(q, chol)(s)
    np.testing.assert_allclose(product(s), ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    single = crit.point_derivatives(q, chol, dtype=np.float32)[2](s)
    assert single.dtype == (np.float64 if criterion == "logdiag" else np.float32)  # the default: double only
    np.testing.assert_allclose(single, ref, rtol=0, atol=1e-4 * np.abs(ref).max())


@pytest.mark.parametrize("kinds", [("rotation",), ("rotation", "deflection")])
def test_structured_roots_approach_the_truncated_eigendecomposition_of_the_dense_blocks(monkeypatch, kinds):
    # reference: the dense blocks (BlockFamily.dense, formed element by element) and numpy's symmetric
    # eigendecomposition of each (the best rank-r approximation the Nyström roots approach)
    import sensorplan as sp
    from sensorplan.design import recommend as module
    from sensorplan.design.recommend import build_problem
    from sensorplan.design.relaxation.structured_roots import StructuredRoots
    from sensorplan.io.config import example_case

    monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)
    noise = {"noise_std": {"rotation": 5e-6, "deflection": 1e-4}} if len(kinds) > 1 else {}
    problem = build_problem(example_case("three-span"), 4, "D", grid=sp.CandidateGrid(spacing=1.0, kinds=kinds),
                            **noise)
    assert problem.structured and len(problem.blocks.families) == len(kinds)
    dense = problem.blocks[np.arange(problem.n_candidates)]
    scale = np.abs(dense).max()  # single-precision sketches: absolute round-off against the largest block
    p = problem.n_params
    index = np.arange(problem.n_candidates)[::-1]  # any order
    sketches = StructuredRoots(problem.blocks, 4)
    ref = np.matmul(dense[index], sketches.omega.astype(float))  # the sketch of the formed blocks
    np.testing.assert_allclose(sketches.sketch(index), ref, rtol=0, atol=1e-5 * np.abs(ref).max())
    for rank in (4, 8):
        roots = StructuredRoots(problem.blocks, rank)(index)
        assert roots.shape == (index.size, p, rank) and roots.dtype == np.float32
        approx = np.matmul(roots.astype(float), np.swapaxes(roots, 1, 2).astype(float))
        for b, a in zip(dense[index], approx):
            lam = np.linalg.eigvalsh(b)
            assert np.linalg.norm(b - a, 2) <= 3.0 * lam[-rank - 1] + 1e-4 * scale  # the best rank-r error

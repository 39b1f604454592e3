"""The E relaxation's cut rows: the small LMI with cuts t <= cut_rhs + cuts w against cvxpy + Clarabel, and
the eigen-subspace method's certificate when the basis sheds directions as cuts."""

import sys
from pathlib import Path

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan.design.relaxation import eigen_subspace, lmi, solve_relaxation
from sensorplan.design.relaxation.lmi import lmi_interior_point

sys.path.insert(0, str(Path(__file__).resolve().parent))
from design_problems import random_e_problem  # noqa: E402


def random_lmi(seed, *, k=6, m=25, n_cuts=4):
    """Random PSD blocks B_i (rank 3), a positive definite B0, and cuts of rank-one directions of random
    P x P data (so that they are as binding as the LMI)."""
    rng = np.random.default_rng(seed)
    f = rng.normal(size=(m, k, 3))
    bmat = np.einsum("mpr,mqr->mpq", f, f) * rng.uniform(0.5, 5.0, m)[:, None, None]
    a0 = rng.normal(size=(k, k))
    b0 = a0 @ a0.T * 0.05 + 0.2 * np.eye(k)
    cuts = np.einsum("mpr,mpr->m", f[:, :1], f[:, :1])[None, :] * rng.uniform(0.3, 1.5, (n_cuts, m))
    cut_rhs = rng.uniform(0.05, 0.3, n_cuts)
    return b0, bmat, cuts, cut_rhs


@pytest.mark.parametrize("single_gap", [lmi.SINGLE_GAP, 0.0, np.inf])
@pytest.mark.parametrize("seed", range(4))
def test_small_lmi_with_cuts_matches_clarabel(seed, single_gap, monkeypatch):
    # Reference: the same SDP (LMI block, cut rows, box, sum) by cvxpy + Clarabel, an independent conic
    # solver.  Same optimum; the block-diagonal multiplier is PSD with trace one and the cuts' multipliers
    # match Clarabel's duals; the weights are feasible and meet every cut at the value.  Whatever the gap
    # below which the Schur complement is formed in double (0: single precision wherever it stays positive
    # definite, inf: never), and single precision is used when allowed.
    monkeypatch.setattr(lmi, "SINGLE_GAP", single_gap)
    dtypes, schur = [], lmi._Newton._schur

    def spy(self, lzi, xz, dtype):
        dtypes.append(dtype)
        return schur(self, lzi, xz, dtype)

    monkeypatch.setattr(lmi._Newton, "_schur", spy)
    b0, bmat, cuts, cut_rhs = random_lmi(seed)
    m, k, _ = bmat.shape
    count = 5
    value, w, x, nu, status, _, _ = lmi_interior_point(b0, bmat, np.zeros((0, m)), np.zeros(0), count, cuts=cuts,
                                                    cut_rhs=cut_rhs, tol=1e-9)
    wv, t = cp.Variable(m), cp.Variable()
    mat = b0 + cp.reshape(bmat.reshape(m, -1).T @ wv, (k, k), order="C")
    cut_rows = t - cuts @ wv <= cut_rhs
    cons = [wv >= 0, wv <= 1, cp.sum(wv) == count, 0.5 * (mat + mat.T) - t * np.eye(k) >> 0, cut_rows]
    ref = cp.Problem(cp.Maximize(t), cons)
    ref.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    assert status == "optimal"
    scale = max(1.0, abs(ref.value))
    assert abs(value - ref.value) <= 1e-8 * scale
    assert x.shape == (k + cuts.shape[0],) * 2
    assert np.linalg.eigvalsh(x)[0] >= -1e-9 and abs(np.trace(x) - 1.0) <= 1e-8
    assert np.allclose(np.diag(x)[k:], cut_rows.dual_value, atol=1e-5)
    assert w.min() >= -1e-9 and w.max() <= 1 + 1e-9 and abs(w.sum() - count) <= 1e-8
    s_w = b0 + (w @ bmat.reshape(m, -1)).reshape(k, k)
    assert np.linalg.eigvalsh(s_w)[0] >= value - 1e-7 * scale
    assert np.all(cut_rhs + cuts @ w >= value - 1e-7 * scale)
    assert (np.float32 in dtypes) == (single_gap < np.inf)
    if single_gap > 0:  # the last steps are within any positive gap threshold: double precision
        assert dtypes[-1] == np.float64


def test_the_schur_complement_holds_if_blas_returns_a_copy(monkeypatch):
    # The Schur complement's triangular products are written in place by BLAS; were a SciPy/BLAS build to
    # return a copy instead, the products are copied back: the same iterates to the last bit.
    import scipy.linalg.blas

    b0, bmat, cuts, cut_rhs = random_lmi(0)
    m = bmat.shape[0]
    args = (b0, bmat, np.zeros((0, m)), np.zeros(0), 5)
    expected = lmi_interior_point(*args, cuts=cuts, cut_rhs=cut_rhs, tol=1e-9)
    copies = []
    for name in ("dtrmm", "strmm"):
        def copying(*a, _f=getattr(scipy.linalg.blas, name), _name=name, **k):
            copies.append(_name)
            return np.array(_f(*a, **k), order="F", copy=True)

        monkeypatch.setattr(scipy.linalg.blas, name, copying)
    got = lmi_interior_point(*args, cuts=cuts, cut_rhs=cut_rhs, tol=1e-9)
    assert {"dtrmm", "strmm"} <= set(copies)
    assert got[0] == expected[0] and np.array_equal(got[1], expected[1]) and np.array_equal(got[2], expected[2])


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), c=st.integers(10, 30), p=st.integers(12, 20), count=st.integers(1, 5))
def test_a_basis_shedding_cuts_still_certifies(seed, c, p, count):
    # Basis capped at 5 columns (directions beyond become cuts; the first basis has 10): reference the
    # relaxed E problem by cvxpy + Clarabel.  The bound is never below lambda_min at Clarabel's weights (numpy's eigvalsh), the
    # utility is eigvalsh at the fast method's weights and never above Clarabel's bound.
    problem = random_e_problem(seed, c=c, p=p, count=count)
    reference = solve_relaxation(problem, "cvxpy")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(eigen_subspace, "K_MAX", 5)
        patch.setattr(eigen_subspace, "N_MIN", 2)
        patch.setattr(eigen_subspace, "N_MAX", 3)
        rel = solve_relaxation(problem, "fast")
    scale = max(1.0, abs(reference.bound))
    assert rel.stats["rounds"] == 1 or rel.stats["cuts"] > 0  # (the first basis has 10 columns)
    assert rel.bound >= np.linalg.eigvalsh(problem.precision(reference.weights))[0] - 1e-9 * scale
    assert rel.utility <= reference.bound + 1e-9 * scale
    assert abs(rel.utility - np.linalg.eigvalsh(problem.precision(rel.weights))[0]) <= 1e-9 * scale

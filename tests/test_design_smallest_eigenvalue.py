"""The E criterion's exact evaluations: the smallest eigenvalue from a shifted Cholesky factor (Lanczos on
the inverse, certified by a second factorisation) against LAPACK's full eigenvalue solver (numpy's eigvalsh,
a different algorithm: Householder tridiagonalisation), and the screening test of ``utilities_above``."""

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings, strategies as st

from sensorplan.design.criteria.eigenvalue import ECriterion, smallest_eigenvalue


def _factor(a, shift):
    factor, info = scipy.linalg.lapack.dpotrf(a - shift * np.eye(a.shape[0]), lower=1, clean=0)
    assert info == 0
    return factor


def _spd(rng, p, spread):
    """A random symmetric positive definite matrix with eigenvalues over ``spread`` decades."""
    q, _ = np.linalg.qr(rng.standard_normal((p, p)))
    vals = np.logspace(0.0, spread, p)
    return (q * vals) @ q.T


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), p=st.integers(2, 60), spread=st.floats(0.0, 6.0),
       gap=st.floats(1e-6, 0.9))
def test_smallest_eigenvalue_equals_the_full_solver(seed, p, spread, gap):
    a = _spd(np.random.default_rng(seed), p, spread)
    exact = np.linalg.eigvalsh(a)[0]  # reference: LAPACK dsyevd through numpy
    shift = exact * (1.0 - gap)  # below the smallest eigenvalue, as the screening test leaves it
    got = smallest_eigenvalue(a, _factor(a, shift), shift)
    assert got == pytest.approx(exact, rel=1e-11, abs=1e-12 * np.abs(a).max())


def test_a_smallest_eigenvector_the_start_misses_is_still_found():
    # the smallest eigenvector orthogonal to Lanczos's start vector: Lanczos sees only the others, the
    # certifying factorisation fails and the full solver answers
    from sensorplan.design.criteria import eigenvalue

    p = 30
    start = eigenvalue._start(p)
    rng = np.random.default_rng(3)
    basis, _ = np.linalg.qr(np.column_stack([start, rng.standard_normal((p, p - 1))]))
    vals = np.linspace(2.0, 10.0, p)
    vals[1] = 1.0  # the smallest eigenvalue's vector basis[:, 1] is orthogonal to the start
    a = (basis * vals) @ basis.T
    a = 0.5 * (a + a.T)
    got = smallest_eigenvalue(a, _factor(a, 0.9), 0.9)
    assert got == pytest.approx(1.0, rel=1e-12)


def test_repeated_smallest_eigenvalue_of_a_symmetric_structure():
    # a mirror-symmetric precision (a symmetric bridge and layout): the smallest eigenvalue doubled
    p = 40
    rng = np.random.default_rng(5)
    half = _spd(rng, p // 2, 2.0)
    a = np.block([[half, np.zeros((p // 2, p // 2))], [np.zeros((p // 2, p // 2)), half[::-1, ::-1]]])
    exact = np.linalg.eigvalsh(a)[0]
    got = smallest_eigenvalue(a, _factor(a, 0.5 * exact), 0.5 * exact)
    assert got == pytest.approx(exact, rel=1e-12)


def test_utilities_above_screens_and_evaluates_exactly():
    rng = np.random.default_rng(11)
    p = 25
    q = _spd(rng, p, 1.0)
    blocks = [np.outer(x, x) for x in rng.standard_normal((12, p))]
    exact = np.array([np.linalg.eigvalsh(q + b)[0] for b in blocks])  # reference: the full solver
    threshold = float(np.median(exact))
    got = np.array(ECriterion(p).utilities_above(q, blocks, threshold))
    above = exact > threshold
    assert np.all(np.isneginf(got[~above]))
    np.testing.assert_allclose(got[above], exact[above], rtol=1e-12)

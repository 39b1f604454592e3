"""The exact evaluations of the searches: the blocked triangular inverse and A's settled losers.

References: numpy's general inverse of the lower triangle (LU, no shared code with the blocked recursion) and
the A criterion's own ``utilities`` (potrf then dtrtri), which the values that can win must equal bit for bit.
"""

import numpy as np
import pytest

from sensorplan.design.criteria.covariance import LOSER_MARGIN, ACriterion
from sensorplan.design.criteria.linalg import lower_factor, lower_inverse


def _spd(rng, p, m):
    a = rng.standard_normal((p, m))
    return a @ a.T / m + 1e-2 * np.eye(p)


@pytest.mark.parametrize("p", [1, 7, 128, 129, 300, 400])
def test_lower_inverse_equals_the_inverse_of_the_lower_triangle(p):
    rng = np.random.default_rng(p)
    factor = lower_factor(_spd(rng, p, 2 * p))  # the upper triangle holds the matrix, not zeros: never read
    inverse = lower_inverse(factor)
    reference = np.linalg.inv(np.tril(factor))
    assert np.all(np.triu(inverse, 1) == 0.0)
    assert np.allclose(inverse, reference, rtol=0.0, atol=1e-12 * np.abs(reference).max())


def test_a_values_that_can_win_are_the_exact_ones_and_the_others_lie_below():
    rng = np.random.default_rng(3)
    p = 300
    crit = ACriterion(p)
    q = _spd(rng, p, 2 * p)
    blocks = np.array([(lambda j: j @ j.T / 40)(rng.standard_normal((p, 30))) for _ in range(12)])
    exact = crit.utilities(q, blocks)
    assert exact == pytest.approx([crit.utility(q + b) for b in blocks], rel=1e-12)
    for threshold in sorted(exact) + [-np.inf, np.inf, exact[0] + 0.5 * LOSER_MARGIN * abs(exact[0])]:
        values = crit.utilities_above(q, blocks, threshold)
        for u, v in zip(exact, values):
            if u >= threshold:  # could win (or tie): the same number as utilities gives
                assert v == u
            else:  # any number not above the threshold
                assert v < threshold or v == u
        if threshold == np.inf:  # nothing can win: every value settled by the blocked inverse
            assert values == pytest.approx(exact, rel=1e-12)


def test_a_with_targets_keeps_its_utilities():
    rng = np.random.default_rng(4)
    p = 20
    crit = ACriterion(p, targets=np.eye(p)[:5])
    q = _spd(rng, p, 40)
    blocks = np.array([(lambda j: j @ j.T)(rng.standard_normal((p, 3))) for _ in range(4)])
    assert crit.utilities_above(q, blocks, 0.0) == crit.utilities(q, blocks)

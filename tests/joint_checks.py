"""The checks both binning test files (AR(1) and the noise model in time) make of the binned diagnosis.

References: J^T J, J^T r and r^T r of the Jacobian formed row by row (JointProblem.rows), on training masks
that drop bins (seeded) and a whole crossing; the same diagnosis with binning switched off.
"""

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import GMRFPrior
from sensorplan.diagnosis.effects import make_effect
from sensorplan.diagnosis.joint.problem import JointProblem


def check_factored_normal_equations(b_case, b_data, names, *, rr_rtol, rtol, atol):
    """Assert that the evaluated normal equations equal the row-by-row ones (``atol`` relative to the largest
    entry); returns (problem, theta, evaluation) for further checks."""
    rng = np.random.default_rng(9)
    masks = [rng.random(c.n_loads) < 0.7 for c in b_data]
    masks[2][:] = False
    problem = JointProblem(b_case, b_data, [make_effect(n) for n in names], GMRFPrior(), masks=masks)
    theta = problem.theta0 + 0.1 * rng.standard_normal(problem.n_params) * np.sqrt(1.0 / np.diag(problem.fixed))
    lin = problem.evaluate(theta)
    r, jac, cross, load, _ = problem.rows(theta)
    keep = np.array([masks[c][k] for c, k in zip(cross, load)])
    r, jac = r[keep], jac[keep]
    assert lin.rr == pytest.approx(r @ r, rel=rr_rtol)
    np.testing.assert_allclose(lin.jtj, jac.T @ jac, rtol=rtol, atol=atol * np.abs(jac.T @ jac).max())
    np.testing.assert_allclose(lin.jtr, jac.T @ r, rtol=rtol, atol=atol * np.abs(jac.T @ r).max())
    return problem, theta, lin


def check_binned_diagnosis_equals_rows(monkeypatch, case, data, cause):
    """Assert that the binned diagnosis of ``data`` agrees with the row-by-row one (every reading a row:
    binning switched off) within what the bins' <= 5 % loss of information on EI allows."""
    binned = sp.diagnose(case, data)
    monkeypatch.setattr("sensorplan.diagnosis.diagnose.choose_size", lambda *args: 1)
    rows = sp.diagnose(case, data)
    assert binned.binning.size > 1 and not rows.binning
    assert binned.causes == rows.causes == (cause,)
    assert binned.heldout_ratio_after == pytest.approx(rows.heldout_ratio_after, rel=0.05)
    assert binned.heldout_ratio_before == pytest.approx(rows.heldout_ratio_before, rel=0.1)
    for name in case.sensors.names:
        assert binned.shrinkage[name].rms_after == pytest.approx(rows.shrinkage[name].rms_after, rel=0.02)
    np.testing.assert_allclose(binned.ei_final, rows.ei_final, rtol=0.05)

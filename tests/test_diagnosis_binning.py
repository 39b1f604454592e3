"""Dense records fitted in whitened bins (sensorplan/diagnosis/joint/binning.py).

References: the dense noise covariance exp(-|x_i - x_j| / l) (no whitening
code), the unbinned model at the readings, finite differences, and the same
diagnosis run row by row.
"""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg

import sensorplan as sp
from sensorplan import GMRFPrior, example_case, simulate_crossings
from sensorplan.diagnosis.joint import binning
from sensorplan.diagnosis.joint.binning import BinnedCrossing, bin_crossings, choose_size
from sensorplan.diagnosis.effects import make_effect
from sensorplan.diagnosis.joint.problem import JointProblem
from sensorplan.model.forward import influence_lines

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies" / "diagnosis"))
from effects_data import generate  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from joint_checks import check_binned_diagnosis_equals_rows, check_factored_normal_equations  # noqa: E402


def dense_case(step=0.1, correlation=0.0, n_elements=8):
    case = example_case("openlab-like")
    case = case.with_mesh(sp.Mesh.uniform(case.bridge, n_elements))
    return replace(case, sweep=sp.LoadSweep.from_range(0.0, 32.0, step),
                   noise=sp.NoiseModel(case.noise.std, correlation))


@pytest.mark.parametrize("correlation", [0.0, 0.3, 2.0])
def test_bins_are_independent_unit_normals_under_the_dense_covariance(correlation):
    # reference: the covariance of the readings written out densely, std_s^2 exp(-|x_i - x_j| / l) (the
    # definition of the noise model, sensorplan/model/noise.py), on unequally spaced positions; the bins'
    # covariance M Gamma M^T must be the identity, whatever the spacing and correlation
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(0.03, 0.08, 60))
    noise = sp.NoiseModel([2e-6, 5e-4], correlation)
    crossing = BinnedCrossing("a", x[:60:4], np.zeros((2, 15)), np.ones(15), x, np.zeros((2, 60)), np.ones(60),
                              noise, 4)
    gamma = np.eye(60) if correlation == 0 else np.exp(-np.abs(x[:, None] - x[None, :]) / correlation)
    for s in range(2):
        # the map of sensor s: the bins of a unit reading at every row
        unit = np.zeros((2, 60, 60))
        unit[s] = np.eye(60)
        m = crossing.to_bins(unit)[s]  # (bins, readings)
        np.testing.assert_allclose(m @ (noise.std[s] ** 2 * gamma) @ m.T, np.eye(15), atol=1e-10)


@pytest.mark.parametrize("names", [
    ("thermal_drift", "position_offset", "sensor_gain", "vertical_support_spring"),
    ("sensor_gain", "vertical_support_spring", "sensor_position", "axle_loads"),  # no shifts: shared lines
    ("load_dependent_stiffness", "position_offset"),  # a crossing's own EI factor: lines of two interpolants
])
def test_binned_problem_is_the_unbinned_model_mapped_onto_the_bins(names):
    # reference: the unbinned problem's predictions and Jacobian at the readings (every effect that reads the
    # load positions: drift, shifts with the entry ramp, gain, axle loads), mapped with the bins' matrix
    case = dense_case(0.25, correlation=0.6)
    data = simulate_crossings(case, 3, noise=True, rng=4)
    # two crossings at one load level (they share the mapped log-EI block), one at another (it must not)
    data = sp.Crossings(data.sensor_names, tuple(replace(c, load_factor=c.load_factor * f)
                                                 for c, f in zip(data.crossings, (1.0, 1.0, 1.4))))
    b_case, b_data = bin_crossings(case, data, 3)
    row = JointProblem(case, data, [make_effect(n) for n in names], GMRFPrior())
    binned = JointProblem(b_case, b_data, [make_effect(n) for n in names], GMRFPrior())
    assert binned.n_params == row.n_params
    np.testing.assert_allclose(binned.offset_scale, row.offset_scale)
    rng = np.random.default_rng(5)
    theta = row.theta0 + 0.1 * rng.standard_normal(row.n_params) * np.sqrt(1.0 / np.diag(row.fixed))
    reference = row.predict(theta)
    if "position_offset" not in names:  # global parameters only: each crossing alone, so that nothing is shared
        reference = [JointProblem(case, sp.Crossings(data.sensor_names, (one,)), [make_effect(n) for n in names],
                                  GMRFPrior()).predict(theta)[0] for one in data]
    for c, ((y, jac), (yb, jb)) in enumerate(zip(reference, binned.predict(theta))):
        n = b_data[c].raw_positions.size
        eye = np.zeros((y.shape[0], n, n))
        for s in range(y.shape[0]):
            eye[s] = np.eye(n)
        m = b_data[c].to_bins(eye)  # (S, bins, readings): sensor s's map
        want_y = np.einsum("sbk,sk->sb", m, y[:, :n])
        want_j = np.einsum("sbk,skp->sbp", m, jac[:, :n])
        np.testing.assert_allclose(yb, want_y, rtol=1e-10, atol=1e-10 * np.abs(want_y).max())
        np.testing.assert_allclose(jb, want_j, rtol=1e-9, atol=1e-9 * np.abs(want_j).max())
        # the data are binned with the same map
        np.testing.assert_allclose(b_data[c].values, np.einsum("sbk,sk->sb", m, data[c].values[:, :n]),
                                   rtol=1e-10, atol=1e-10 * np.abs(b_data[c].values).max())


def test_binned_normal_equations_equal_finite_differences_of_the_misfit():
    # J^T r of the binned fit against central differences of -|r|^2 / 2 (no shared Jacobian code)
    case = dense_case(0.2, correlation=0.4)
    data = simulate_crossings(case, 2, noise=True, rng=6)
    b_case, b_data = bin_crossings(case, data, 4)
    problem = JointProblem(b_case, b_data, [make_effect("thermal_drift"), make_effect("position_offset")],
                           GMRFPrior())
    theta = problem.theta0 + 0.02
    lin = problem.evaluate(theta)
    for k in (0, 3, problem.n_elements, problem.n_params - 1):
        h = 1e-5
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        fd = -(problem.evaluate(up, jacobian=False).rr - problem.evaluate(down, jacobian=False).rr) / (4 * h)
        assert lin.jtr[k] == pytest.approx(fd, rel=1e-4, abs=1e-6 * np.abs(lin.jtr).max())


@pytest.mark.parametrize("names, odd_noise", [
    (("position_offset", "sensor_gain"), False),  # moved loads, a factor per sensor
    (("dynamic_amplification", "thermal_drift"), False),  # a factor per crossing, columns of one crossing
    (("load_dependent_stiffness",), False),  # a crossing's own EI factor: two interpolants, two tables
    (("support_rotational_spring", "sensor_gain"), True),  # one crossing's noise unlike the others': no
])  # common factor of the crossings' scales, so J^T J is summed crossing by crossing
def test_factored_normal_equations_equal_the_formed_jacobian(names, odd_noise):
    # reference: J^T J, J^T r and r^T r of the Jacobian formed explicitly, row by row (JointProblem.rows, whose
    # blocks are checked against the unbinned model above); evaluate never forms the log-EI block of binned
    # crossings (LogEIFactor) -- on training masks that drop bins and a whole crossing
    case = dense_case(0.25, correlation=0.6)
    data = simulate_crossings(case, 4, noise=True, rng=8)
    data = sp.Crossings(data.sensor_names, tuple(replace(c, load_factor=c.load_factor * f)
                                                 for c, f in zip(data.crossings, (1.0, 1.3, 1.0, 0.8))))
    b_case, b_data = bin_crossings(case, data, 3)
    if odd_noise:
        odd = replace(b_data[1], noise=sp.NoiseModel(b_data[1].noise.std * np.array([1.0, 3.0]), 0.6))
        b_data = sp.Crossings(b_data.sensor_names, (b_data[0], odd) + tuple(b_data.crossings[2:]))
    check_factored_normal_equations(b_case, b_data, names, rr_rtol=1e-12, rtol=1e-9, atol=1e-12)


def _information(case, data, size, prior):
    # reference: Fisher information of log EI with the dense inverse covariance (rows) or the bins' dense map
    lines = influence_lines(case.bridge, case.mesh, case.ei, case.sensors, case.vehicle, data[0].positions)
    jac = lines.jacobian("log_ei")
    x = data[0].positions
    n = x.size // size * size
    corr = case.noise.correlation_length
    gamma = np.exp(-np.abs(x[:n, None] - x[None, :n]) / corr) if corr > 0 else np.eye(n)
    info = prior.precision(case.mesh.n_elements).copy()
    for s in range(case.sensors.n_sensors):
        cov = case.noise.std[s] ** 2 * gamma
        j = jac[s, :n]
        if size == 1:
            info += len(data) * j.T @ np.linalg.solve(cov, j)
        else:  # the bins' map M (M Gamma M^T = I: test above), information J^T M^T M J
            crossing = bin_crossings(case, data, size)[1][0]
            unit = np.zeros((case.sensors.n_sensors, n, n))
            unit[s] = np.eye(n)
            m = crossing.to_bins(unit)[s]
            info += len(data) * (m @ j).T @ (m @ j)
    return info


@pytest.mark.parametrize("correlation", [0.0, 0.5])
def test_bin_size_keeps_the_stated_information_on_ei(correlation):
    # the chosen size keeps >= KEEP of the posterior precision of log EI in every direction (dense reference
    # above); one size more either loses more or leaves fewer than MIN_BINS bins
    case = dense_case(0.1, correlation, n_elements=16)
    data = simulate_crossings(case, 2, noise=True, rng=7)
    prior = GMRFPrior()
    size = choose_size(case, data, prior)
    assert size > 1
    full = _information(case, data, 1, prior)
    kept = linalg.eigh(_information(case, data, size, prior), full, eigvals_only=True)
    assert binning.KEEP <= kept.min() <= kept.max() <= 1.0 + 1e-9
    n_rows = data[0].n_loads
    if n_rows // (size + 1) >= binning.MIN_BINS:
        nxt = linalg.eigh(_information(case, data, size + 1, prior), full, eigvals_only=True)
        assert nxt.min() < binning.KEEP


def test_sparse_records_are_fitted_row_by_row():
    case = dense_case(1.0)
    data = simulate_crossings(case, 2, noise=True, rng=8)
    assert data[0].n_loads < binning.MIN_ROWS
    assert choose_size(case, data, GMRFPrior()) == 1


def test_dense_diagnosis_names_the_cause_and_reports_the_readings():
    # a settled bearing on a record every 0.05 m (a data logger's density): the same verdict as row by row,
    # the gap reported on the readings themselves (rms at the configured noise after the fix), the binning
    # stated in the summary
    case = dense_case(0.05, n_elements=16)
    rng = np.random.SeedSequence(11)
    data = generate(case, "vertical_support_spring", rng, 8)
    d = sp.diagnose(case, data)
    assert d.binning.size > 1 and d.binning.rows == sum(c.n_loads for c in data) - sum(
        c.n_loads % d.binning.size for c in data)
    assert d.causes == ("vertical_support_spring",)
    assert f"{d.binning.size} consecutive readings" in d.summary()
    for name, s in d.shrinkage.items():
        std = case.noise.std[case.sensors.names.index(name)]
        assert s.rms_after == pytest.approx(std, rel=0.1)  # the readings' own noise, not the bins'
    assert d.gap.significant and not d.gap_after.significant
    assert d.heldout_ratio_after == pytest.approx(1.0, abs=0.2)


def test_binned_diagnosis_agrees_with_the_row_by_row_one(monkeypatch):
    # reference: the same diagnosis with binning switched off (every reading a row of the fit); thermal drift
    # under AR(1) noise, whose per-crossing parameters make the held-out predictions uncertain, so that the
    # held-out rms per reading (converted from the bins) is tested where it differs from the bins' own
    case = dense_case(0.1, correlation=0.5, n_elements=16)
    data = generate(case, "thermal_drift", np.random.SeedSequence(12), 8)
    check_binned_diagnosis_equals_rows(monkeypatch, case, data, "thermal_drift")


def test_a_fit_crawling_in_a_flat_direction_counts_as_converged():
    # studies/diagnosis/validation.py, three-span (AR(1) noise, elastic interior bearings), its left interior
    # bearing settled (seed 0): the screening refit of vertical_support_spring frees the bearings the base fit
    # already estimates, and on the bins Levenberg-Marquardt crawled (decrements 0.02-0.04 with gains of
    # 0.0002-0.001 per step for ten steps) to its 15-step limit and was flagged not converged; the stall rule
    # of solve_map (three steps gaining < 0.01 together) accepts it
    import validation

    case = validation.make_case("three-span")
    data = generate(case, "vertical_support_spring",
                    validation.seed_sequence("three-span", "vertical_support_spring", 0), validation.N_CROSSINGS)
    d = sp.diagnose(case, data)
    assert d.binning.size > 1
    entry = {e.name: e for e in d.effects}["vertical_support_spring"]
    assert entry.converged and entry.heldout_rms_after is not None


def test_binned_problem_survives_pickling():
    # worker processes receive and return binned problems (the bins' sparse map travels with each crossing)
    import pickle

    case = dense_case(0.25, correlation=0.6)
    data = simulate_crossings(case, 2, noise=True, rng=9)
    b_case, b_data = bin_crossings(case, data, 3)
    problem = JointProblem(b_case, b_data, [make_effect("thermal_drift")], GMRFPrior())
    theta = problem.theta0 + 0.01
    there = pickle.loads(pickle.dumps(problem)).evaluate(theta)  # before any evaluation: nothing cached
    assert there.rr == pytest.approx(problem.evaluate(theta).rr, rel=1e-12)

"""Dense records fitted in whitened bins under the noise model in time (sensorplan/diagnosis/joint/binning.py).

References: the covariance of the readings written out densely from the
noise model's definition (white + Ornstein-Uhlenbeck + a random walk started
at the first reading, sensorplan/model/statespace.py's docstring) and its
Cholesky factor from numpy (no filter code); the offset marginalised by the
restricted likelihood (Sigma^{-1} - Sigma^{-1} 1 1^T Sigma^{-1} / 1^T Sigma^{-1} 1);
the unbinned model at the readings; the formed Jacobian row by row; the same
diagnosis run row by row.
"""

import pickle
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg

import sensorplan as sp
from sensorplan import GMRFPrior, example_case, simulate_crossings
from sensorplan.diagnosis.effects import make_effect
from sensorplan.diagnosis.joint import binning
from sensorplan.diagnosis.joint.binning import BinnedCrossing, bin_crossings, choose_size
from sensorplan.diagnosis.joint.problem import JointProblem
from sensorplan.model.forward import influence_lines

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies" / "diagnosis"))
from effects_data import generate  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from joint_checks import check_binned_diagnosis_equals_rows, check_factored_normal_equations  # noqa: E402


def timed_noise(std, *, speed=1.0, tau=3.0):
    """The Munich inclinometer's proportions (issue 36) scaled to ``std``, as bench_noise_time.py uses them."""
    std = np.asarray(std, dtype=float)
    return sp.NoiseModel(std, correlated_std=std * 9 / 21, correlation_time_s=tau, random_walk=std * 2.5 / 21,
                         speed=speed)


def unlike_noise(std, *, speed=1.0):
    """Sensors whose noise has different shapes (one map each): OU of other proportions and times, the first
    sensor wandering, the others not."""
    std = np.asarray(std, dtype=float)
    n = std.size
    return sp.NoiseModel(std * np.linspace(1.0, 1.5, n), correlated_std=std * np.linspace(0.3, 0.6, n),
                         correlation_time_s=np.linspace(0.5, 3.0, n), random_walk=std * (np.arange(n) == 0) * 0.12,
                         speed=speed)


NOISES = {"like": timed_noise, "unlike": unlike_noise}


def dense_case(step=0.1, n_elements=8, speed=1.0, noise="like"):
    case = example_case("openlab-like")
    case = case.with_mesh(sp.Mesh.uniform(case.bridge, n_elements))
    return replace(case, sweep=sp.LoadSweep.from_range(0.0, 32.0, step),
                   noise=NOISES[noise](case.noise.std, speed=speed))


def dense_covariance(noise, s, t):
    """Sigma of sensor s at times t from the model's definition: white, stationary OU, walk from t[0] (dense)."""
    dt = np.abs(t[:, None] - t[None, :])
    walk = np.minimum(t[:, None], t[None, :]) - t[0]
    tau = noise.correlation_time_s[s]
    ou = noise.correlated_std[s] ** 2 * np.exp(-dt / tau) if tau > 0 else 0.0
    return noise.std[s] ** 2 * np.eye(t.size) + ou + noise.random_walk[s] ** 2 * walk


def reference_map(noise, s, t, size):
    """P_u B L^{-1} with L numpy's Cholesky factor of the dense covariance, u = B L^{-1} 1; and log |u|^2
    (B L^{-1} and 0 without wander)."""
    linv = linalg.solve_triangular(np.linalg.cholesky(dense_covariance(noise, s, t)), np.eye(t.size), lower=True)
    bins = linv.reshape(t.size // size, size, t.size).sum(axis=1) / np.sqrt(size)
    if noise.random_walk[s] == 0:
        return bins, 0.0
    u = bins.sum(axis=1)
    return bins - np.outer(u, u @ bins) / (u @ u), float(np.log(u @ u))


def sensor_map(crossing, s):
    """The bins of a unit reading at every row of sensor ``s`` (the map the fit applies), (bins, readings)."""
    n = crossing.raw_positions.size
    unit = np.zeros((crossing.noise.n_sensors, n, n))
    unit[s] = np.eye(n)
    return crossing.to_bins(unit)[s]


@pytest.mark.parametrize("times, unlike", [(False, False), (True, False), (True, True)])
def test_bins_in_time_are_the_dense_restricted_likelihood(times, unlike):
    # each sensor's map equals P_u B L^{-1} built from the dense covariance's Cholesky factor (unequal sensors,
    # unequally spaced readings, recorded times or positions / speed, one shape or one per sensor); the bins'
    # covariance is the projector of rank bins - 1 and the constant is annihilated (the offset marginalised);
    # one offset per wandering sensor (without wander: B L^{-1}, the bins independent unit normals)
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(0.03, 0.08, 60))
    noise = unlike_noise([2e-6, 5e-4], speed=0.7) if unlike else timed_noise([2e-6, 5e-4], speed=0.7, tau=0.5)
    t = x / 0.7 + 0.1 * np.sin(x) if times else (x - x[0]) / 0.7
    crossing = BinnedCrossing("a", x[:60:4], np.zeros((2, 15)), np.ones(15), x, np.zeros((2, 60)), np.ones(60),
                              noise, 4, raw_times=t if times else None)
    log_det = 0.0
    assert crossing.shared != unlike
    for s in range(2):
        m = sensor_map(crossing, s)
        want, log_u = reference_map(noise, s, t, 4)
        np.testing.assert_allclose(m, want, rtol=1e-8, atol=1e-8 * np.abs(want).max())
        cov = m @ dense_covariance(noise, s, t) @ m.T
        wander = noise.random_walk[s] > 0
        if wander:
            np.testing.assert_allclose(cov @ cov, cov, atol=1e-8)
            np.testing.assert_allclose(m @ np.ones(60), 0.0, atol=1e-8 * np.abs(m).sum())
        else:
            np.testing.assert_allclose(cov, np.eye(15), atol=1e-8)
        assert np.trace(cov) == pytest.approx(15.0 - wander, rel=1e-8)
        log_det += log_u
    assert crossing.n_offsets == (1 if unlike else 2)
    assert crossing.offset_log_det == pytest.approx(log_det, rel=1e-10)


def test_noise_without_wander_projects_nothing():
    # OU alone: no offset; the bins of L^{-1} are independent unit normals under the dense covariance
    x = np.linspace(0.0, 6.0, 48)
    noise = sp.NoiseModel([3e-6], correlated_std=2e-6, correlation_time_s=0.8, speed=2.0)
    crossing = BinnedCrossing("a", x[::3], np.zeros((1, 16)), np.ones(16), x, np.zeros((1, 48)), np.ones(48), noise, 3)
    m = sensor_map(crossing, 0)
    sigma = dense_covariance(noise, 0, x / 2.0)
    np.testing.assert_allclose(m @ sigma @ m.T, np.eye(16), atol=1e-9)
    assert crossing.n_offsets == 0 and crossing.offset_log_det == 0.0


@pytest.mark.parametrize("noise", ["like", "unlike"])
def test_problem_counts_the_offsets_of_the_bins(noise):
    # the restricted likelihood of the bins: bins x sensors - one offset per wandering sensor and crossing with
    # rows, log det: sum over those sensors of log |B L_s^{-1} 1|^2 (dense reference above)
    case = dense_case(0.25, noise=noise)
    data = simulate_crossings(case, 3, noise=True, rng=3)
    b_case, b_data = bin_crossings(case, data, 4)
    masks = [np.ones(c.n_loads, bool) for c in b_data]
    masks[1][:] = False
    problem = JointProblem(b_case, b_data, [], GMRFPrior(), masks=masks)
    s_count = case.sensors.n_sensors
    wandering = int(np.sum(case.noise.random_walk > 0))
    assert problem.n_data == 2 * (b_data[0].n_loads * s_count - wandering)
    t = (b_data[0].raw_positions - b_data[0].raw_positions[0]) / case.noise.speed
    want = sum(reference_map(case.noise, s, t, 4)[1] for s in range(s_count))
    assert problem.log_det_noise == pytest.approx(2 * want, rel=1e-9)


@pytest.mark.parametrize("names, noise", [
    (("thermal_drift", "position_offset", "sensor_gain", "vertical_support_spring"), "like"),
    (("sensor_gain", "vertical_support_spring", "sensor_position", "axle_loads"), "like"),
    (("thermal_drift", "position_offset", "sensor_gain", "vertical_support_spring"), "unlike"),
])
def test_binned_problem_in_time_is_the_unbinned_model_mapped_onto_the_bins(names, noise):
    # reference: the unbinned problem's predictions and Jacobian at the readings, mapped with each sensor's map
    # (itself checked against the dense reference above): the dense-map paths of the assembly
    case = dense_case(0.25, noise=noise)
    data = simulate_crossings(case, 3, noise=True, rng=4)
    data = sp.Crossings(data.sensor_names, tuple(replace(c, load_factor=c.load_factor * f)
                                                 for c, f in zip(data.crossings, (1.0, 1.0, 1.4))))
    b_case, b_data = bin_crossings(case, data, 3)
    row = JointProblem(case, data, [make_effect(n) for n in names], GMRFPrior())
    binned = JointProblem(b_case, b_data, [make_effect(n) for n in names], GMRFPrior())
    rng = np.random.default_rng(5)
    theta = row.theta0 + 0.1 * rng.standard_normal(row.n_params) * np.sqrt(1.0 / np.diag(row.fixed))
    for c, ((y, jac), (yb, jb)) in enumerate(zip(row.predict(theta), binned.predict(theta))):
        n = b_data[c].raw_positions.size
        m = np.stack([sensor_map(b_data[c], s) for s in range(y.shape[0])])
        want_y = np.einsum("sbk,sk->sb", m, y[:, :n])
        want_j = np.einsum("sbk,skp->sbp", m, jac[:, :n])
        np.testing.assert_allclose(yb, want_y, rtol=1e-9, atol=1e-9 * np.abs(want_y).max())
        np.testing.assert_allclose(jb, want_j, rtol=1e-8, atol=1e-9 * np.abs(want_j).max())


@pytest.mark.parametrize("names, noise", [(("position_offset", "sensor_gain"), "like"),
                                         (("support_rotational_spring",), "like"),
                                         (("support_rotational_spring", "sensor_gain"), "unlike")])
def test_factored_normal_equations_in_time_equal_the_formed_jacobian(names, noise):
    # reference: J^T J, J^T r, r^T r of the Jacobian formed row by row (JointProblem.rows); evaluate keeps the
    # log-EI block factored with one dense map for all sensors (a map per sensor: formed on the bins) -- on
    # training masks that drop bins and a whole crossing
    case = dense_case(0.25, noise=noise)
    data = simulate_crossings(case, 3, noise=True, rng=8)
    b_case, b_data = bin_crossings(case, data, 3)
    problem, theta, lin = check_factored_normal_equations(b_case, b_data, names, rr_rtol=1e-10, rtol=1e-8, atol=1e-11)
    there = pickle.loads(pickle.dumps(problem)).evaluate(theta)  # worker processes receive binned problems
    assert there.rr == pytest.approx(lin.rr, rel=1e-12)


def _information(case, data, size, prior):
    # reference: the restricted Fisher information of log EI with the dense covariance (rows), or of the bins
    # through the dense reference map
    x = data[0].positions
    n = x.size // size * size
    lines = influence_lines(case.bridge, case.mesh, case.ei, case.sensors, case.vehicle, x)
    jac = lines.jacobian("log_ei")
    t = (x[:n] - x[0]) / case.noise.speed
    info = prior.precision(case.mesh.n_elements).copy()
    for s in range(case.sensors.n_sensors):
        j = jac[s, :n]
        if size == 1:
            inv = np.linalg.inv(dense_covariance(case.noise, s, t))
            ones = inv @ np.ones(n)
            info += len(data) * j.T @ (inv - np.outer(ones, ones) / ones.sum()) @ j
        else:
            m = reference_map(case.noise, s, t, size)[0]
            info += len(data) * (m @ j).T @ (m @ j)
    return info


def test_bin_size_in_time_keeps_the_stated_information_on_ei(monkeypatch):
    # the chosen size keeps >= KEEP of the posterior precision of log EI in every direction (dense reference);
    # one size more loses more. The least number of bins lowered, so that the information decides the size
    # (on this record it would otherwise stop at 40 bins, every size up to it keeping >= KEEP)
    monkeypatch.setattr(binning, "MIN_BINS", 2)
    case = dense_case(0.1, n_elements=16)
    data = simulate_crossings(case, 2, noise=True, rng=7)
    prior = GMRFPrior()
    size = choose_size(case, data, prior)
    assert 1 < size < data[0].n_loads // 3
    full = _information(case, data, 1, prior)
    kept = linalg.eigh(_information(case, data, size, prior), full, eigvals_only=True)
    assert binning.KEEP <= kept.min() <= kept.max() <= 1.0 + 1e-9
    nxt = linalg.eigh(_information(case, data, size + 1, prior), full, eigvals_only=True)
    assert nxt.min() < binning.KEEP


def test_sensors_of_unlike_noise_get_a_map_each():
    # one bin map serves every sensor only when their noise has one shape
    for noise, shared in (("like", True), ("unlike", False)):
        case = dense_case(0.1, noise=noise)
        data = simulate_crossings(case, 2, noise=True, rng=8)
        size = choose_size(case, data, GMRFPrior())
        assert size > 1
        assert bin_crossings(case, data, size)[1][0].shared == shared


@pytest.mark.parametrize("noise", ["like", "unlike"])
def test_binned_diagnosis_in_time_agrees_with_the_row_by_row_one(monkeypatch, noise):
    # reference: the same diagnosis with binning switched off (every reading a row of the time model's fit); a
    # settled bearing on a dense record under white + OU + wander (one map for all sensors, or one each).
    # Tolerances as for AR(1) noise (test_diagnosis_binning.py): the bins lose <= 5 % of the information on EI
    case = dense_case(0.1, n_elements=16, noise=noise)
    data = generate(case, "vertical_support_spring", np.random.SeedSequence(12), 8)
    check_binned_diagnosis_equals_rows(monkeypatch, case, data, "vertical_support_spring")


@pytest.mark.parametrize("names, noise", [(("thermal_drift", "sensor_gain"), "like"),
                                         (("vertical_support_spring", "position_offset"), "like"),
                                         (("vertical_support_spring", "sensor_gain"), "unlike")])
def test_bins_of_one_reading_are_the_unbinned_time_model_fit(names, noise):
    # the reduction with nothing lost: bins of one reading, P_u L^{-1}, give the unbinned problem's normal
    # equations (its Kalman filter and offset projection, model/statespace.py) and degrees of freedom; the noise
    # determinants differ by log det Sigma (the bins are whitened: their covariance is I), a constant
    case = dense_case(0.25, noise=noise)
    data = simulate_crossings(case, 3, noise=True, rng=11)
    ones = []
    for c in data:
        one = BinnedCrossing(c.label, c.positions, np.zeros_like(c.values), c.load_factor, c.positions, c.values,
                             c.load_factor, case.noise, 1)
        ones.append(replace(one, values=one.to_bins(one.raw_values)))
    unit = replace(case, noise=sp.NoiseModel(np.ones(case.sensors.n_sensors), 0.0))
    binned = JointProblem(unit, sp.Crossings(data.sensor_names, tuple(ones)), [make_effect(n) for n in names],
                          GMRFPrior())
    rows = JointProblem(case, data, [make_effect(n) for n in names], GMRFPrior())
    rng = np.random.default_rng(12)
    theta = rows.theta0 + 0.1 * rng.standard_normal(rows.n_params) * np.sqrt(1.0 / np.diag(rows.fixed))
    a, b = binned.evaluate(theta), rows.evaluate(theta)
    assert a.rr == pytest.approx(b.rr, rel=1e-9)
    np.testing.assert_allclose(a.jtj, b.jtj, rtol=1e-8, atol=1e-10 * np.abs(b.jtj).max())
    np.testing.assert_allclose(a.jtr, b.jtr, rtol=1e-8, atol=1e-10 * np.abs(b.jtr).max())
    assert binned.n_data == rows.n_data
    t = (data[0].positions - data[0].positions[0]) / case.noise.speed
    log_det_sigma = sum(np.linalg.slogdet(dense_covariance(case.noise, s, t))[1]
                        for s in range(case.sensors.n_sensors))
    assert rows.log_det_noise - binned.log_det_noise == pytest.approx(len(data) * log_det_sigma, rel=1e-9)


def test_long_records_build_the_map_without_the_whole_inverse(monkeypatch):
    # beyond statespace.DENSE_ROWS readings the map is built a block of columns at a time by the filter's
    # recursion (no n x n matrix): the same dense reference as above, limits lowered so that 60 readings are long
    from sensorplan.model import statespace

    monkeypatch.setattr(statespace, "DENSE_ROWS", 10)
    monkeypatch.setattr(binning, "DENSE_ROWS", 10)
    monkeypatch.setattr(binning, "BLOCK", 7)  # blocks that do not divide the record
    x = np.linspace(0.0, 9.0, 60)
    noise = timed_noise([2e-6, 5e-4], speed=0.9, tau=0.7)
    crossing = BinnedCrossing("long", x[::5], np.zeros((2, 12)), np.ones(12), x, np.zeros((2, 60)), np.ones(60),
                              noise, 5)
    for s in range(2):
        want = reference_map(noise, s, x / 0.9, 5)[0]
        np.testing.assert_allclose(sensor_map(crossing, s), want, rtol=1e-8, atol=1e-8 * np.abs(want).max())

"""Fisher information: the paper's findings, scaling laws and properties."""

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

import sensorplan as sp
from sensorplan import Case, GMRFPrior, NoiseModel, example_case, fisher_blocks, identifiability


def dense_gamma(positions, corr_length):
    """The AR(1) correlation matrix exp(-|z_k - z_l| / l), formed densely (the reference)."""
    positions = np.asarray(positions, dtype=float)
    if corr_length == 0.0:
        return np.eye(positions.size)
    return np.exp(-np.abs(positions[:, None] - positions[None, :]) / corr_length)


def fd_jacobian(case, springs=False, step=1e-5):
    """d predictions / d (log EI per element[, log k per elastic spring]) by central differences."""
    log_ei = np.log(case.ei)
    log_k = np.log(case.bridge.spring_stiffness()) if springs else np.zeros(0)
    jac = np.empty((case.sensors.n_sensors, case.sweep.n_loads, log_ei.size + log_k.size))
    for j in range(log_ei.size):
        up, down = log_ei.copy(), log_ei.copy()
        up[j] += step
        down[j] -= step
        jac[:, :, j] = (case.influence_lines(np.exp(up)).predictions
                        - case.influence_lines(np.exp(down)).predictions) / (2 * step)
    for s in range(log_k.size):
        up, down = log_k.copy(), log_k.copy()
        up[s] += step
        down[s] -= step
        jac[:, :, log_ei.size + s] = (
            case.influence_lines(bridge=case.bridge.with_spring_stiffness(np.exp(up))).predictions
            - case.influence_lines(bridge=case.bridge.with_spring_stiffness(np.exp(down))).predictions) / (2 * step)
    return jac


def assert_columns_close(actual, reference, rtol, label=""):
    """Column by column, relative to each reference column's norm (a flipped weak column cannot pass)."""
    for j in range(reference.shape[-1]):
        ref = np.linalg.norm(reference[..., j])
        assert ref > 0.0, f"{label}: column {j} of the reference is zero"
        err = np.linalg.norm(actual[..., j] - reference[..., j])
        assert err <= rtol * ref, f"{label}: column {j} differs by {err / ref:.2e} of its norm"


def simple_case(n_elements=30, load=1e5, sigma=1e-6, length=20.0, step=0.05, ei=1e10):
    bridge = sp.Bridge((length,))
    sweep = sp.LoadSweep.from_range(0.0, length, step)
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), ei, sp.Vehicle.point_load(load),
                sp.SensorLayout([length / 4], noise_std=sigma), sweep=sweep)


def test_paper_single_span_quarter_point_sensor():
    # Paper, Fig. FisherInformation: the curve of a sensor at x/L = 1/4 is low
    # left of the sensor, jumps at the sensor and peaks to its right.
    case = simple_case(40)  # the sensor at 5 m sits on an element edge
    blocks = fisher_blocks(case, parameterisation="ei")
    curve = blocks.curves[0]
    mid = case.mesh.midpoints / 20.0
    left, right = curve[mid < 0.25], curve[mid > 0.25]
    assert curve.argmax() == np.argmax(np.where(mid > 0.25, curve, -1))
    assert left.max() < 0.5 * right.max()
    j = case.mesh.element_of(5.0)  # first element right of the sensor
    assert curve[j] > 2.0 * curve[j - 1]


@pytest.mark.parametrize("n_elements", [20, 30, 45])
def test_paper_maxima_near_thirds(n_elements):
    # Paper, section Fisher information: maxima near x/L = 1/3 for sensors at
    # x/L < 1/3 and near 2/3 for sensors at x/L > 2/3 (within one element).
    case = simple_case(n_elements)
    xs = np.array([0.0, 0.05, 0.1, 0.2, 0.25, 0.3, 0.32, 0.68, 0.7, 0.8, 0.9, 0.95, 1.0]) * 20.0
    blocks = fisher_blocks(case, sensors=sp.SensorLayout.candidates(xs, noise_std=1e-6),
                           parameterisation="ei")
    h = 20.0 / n_elements
    for x, peak in zip(xs, blocks.peaks()):
        target = 20.0 / 3 if x < 20.0 / 3 else 40.0 / 3
        assert abs(peak - target) <= h, (x, peak)


def test_information_scales_with_load_noise_and_element_length():
    base = fisher_blocks(simple_case(), parameterisation="ei").curves
    scaled = fisher_blocks(simple_case(load=3e5, sigma=2e-6), parameterisation="ei").curves
    np.testing.assert_allclose(scaled, base * 9.0 / 4.0, rtol=1e-12)
    # (Delta s)^2 for a fixed span: the element integrals scale with the
    # element width, so doubling the element count quarters the information
    # (compared at element midpoints of equal position, where the kernel is
    # smooth: elements not containing the sensor).
    coarse = fisher_blocks(simple_case(20), parameterisation="ei").curves[0]
    fine = fisher_blocks(simple_case(40), parameterisation="ei").curves[0]
    fine_pairs = 0.5 * (fine[0::2] + fine[1::2])
    ratio = coarse / fine_pairs
    # (exact only where the kernel is nearly constant over an element: away
    # from the supports, where it vanishes quadratically)
    np.testing.assert_allclose(ratio[3:13], 4.0, rtol=0.02)


def two_span_case(n_elements=40):
    bridge = sp.Bridge((15.0, 15.0))
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([5.0], noise_std=1e-6),
                sweep=sp.LoadSweep.from_range(0.0, 30.0, 0.1))


def test_paper_two_span_coupling():
    # Paper, Fig. FisherInformationTwoSpan.
    case = two_span_case()
    xs = np.arange(0.0, 1.01, 0.1) * 15.0
    span1 = fisher_blocks(case, sensors=sp.SensorLayout.candidates(xs, noise_std=1e-6),
                          parameterisation="ei").curves
    mid = case.mesh.midpoints
    in2 = mid > 15.0
    for x, curve in zip(xs, span1):
        if 0.0 < x < 15.0:
            # diminishing but non-zero information beyond the interior support
            assert np.all(curve[in2] > 0.0)
            assert curve[in2].max() < curve[~in2].max()
            # largest right after the support, fading towards the far support
            assert np.argmax(curve[in2]) == 0
            tail = curve[in2][int(0.6 * in2.sum()):]
            assert np.all(np.diff(tail) < 0.0)
            assert tail[-1] < 1e-3 * curve[in2][0]
    right_of_support = fisher_blocks(
        case, sensors=sp.SensorLayout.candidates([15.5], noise_std=1e-6), parameterisation="ei").curves[0]
    start2 = (mid > 16.0) & (mid < 20.0)  # first third of span 2, right of the sensor's element
    assert np.all(right_of_support[start2] > span1[:, start2].max(axis=0))


def test_blocks_equal_the_dense_ar1_formula_and_add_up():
    # Reference: I^(i) = n J_i^T Gamma^-1 J_i / sigma_i^2 with J from central
    # differences of the forward map and Gamma the dense AR(1) correlation
    # matrix, applied through its Cholesky factor (Gamma = C C^T, whitened
    # Jacobian C^-1 J / sigma).  Three-span example: AR(1) noise, two
    # elastic bearings as extra parameters, three crossings.
    case = example_case("three-span")
    blocks = fisher_blocks(case, springs=True, n_crossings=3)
    assert blocks.n_springs == 2 and blocks.n_params == case.n_elements + 2
    # step 1e-4: with 1e-5 the round-off of the differences (eps |y| / h) reaches 2e-6 of the
    # weakest columns' norm on some numpy builds; at 1e-4 the error is 6e-8 (measured; 3e-8 at 3e-4)
    jac = fd_jacobian(case, springs=True, step=1e-4)
    chol = np.linalg.cholesky(dense_gamma(case.sweep.positions, case.noise.correlation_length))
    reference = []
    for i, sigma in enumerate(case.noise.std):
        white = scipy.linalg.solve_triangular(chol, jac[i], lower=True) / sigma
        reference.append(3 * white.T @ white)
        assert_columns_close(blocks.blocks[i], reference[-1], 2e-6, f"sensor {i}")
        # PSD (not implied by the code's symmetrisation): no eigenvalue below round-off
        assert np.linalg.eigvalsh(blocks.blocks[i]).min() >= -1e-9 * np.abs(reference[-1]).max()
    # blocks add across sensors: the joint information of all sensors is the sum
    np.testing.assert_allclose(blocks.total(), sum(reference), rtol=1e-6, atol=1e-9 * np.abs(sum(reference)).max())
    np.testing.assert_allclose(blocks.total([1, 0, 1]), blocks.blocks[0] + blocks.blocks[2])


def test_crossings_scale_information():
    case = example_case("openlab-like")
    one = fisher_blocks(case).blocks
    ten = fisher_blocks(case, n_crossings=10).blocks
    np.testing.assert_allclose(ten, 10 * one, rtol=1e-12)


@pytest.mark.parametrize("parameterisation", ["ei", "log_ei"])
def test_parameterisations_equal_finite_differences(parameterisation):
    # Reference: I = J^T J / sigma^2 (independent noise) with J from central
    # differences of the forward map, compared column by column.
    case = example_case("openlab-like")
    sigma = case.noise.std
    blocks = fisher_blocks(case, parameterisation=parameterisation).blocks
    jac = fd_jacobian(case)  # d / d log EI
    if parameterisation == "ei":
        jac = jac / case.ei  # chain rule: d / d EI = (d / d log EI) / EI
    for i in range(case.sensors.n_sensors):
        ref = jac[i].T @ jac[i] / sigma[i] ** 2
        assert_columns_close(blocks[i], ref, 2e-6, f"sensor {i}")


@settings(max_examples=25)
@given(st.floats(0.05, 5.0), st.integers(3, 25), st.integers(0, 1000))
def test_ar1_whitening_is_the_inverse_cholesky_factor(corr_length, n_loads, seed):
    # Reference: the dense correlation matrix Gamma = C C^T (numpy Cholesky);
    # whitening must be C^-1 y / sigma, and log det Gamma = 2 sum log diag C.
    rng = np.random.default_rng(seed)
    positions = np.sort(rng.uniform(0.0, 10.0, n_loads))
    positions = positions[np.concatenate([[True], np.diff(positions) > 1e-3])]
    noise = NoiseModel([2e-6, 5e-6], corr_length)
    jac = rng.normal(size=(2, positions.size, 4))
    white = noise.whiten(jac, positions)
    chol = np.linalg.cholesky(dense_gamma(positions, corr_length))
    for i in range(2):
        ref = scipy.linalg.solve_triangular(chol, jac[i], lower=True) / noise.std[i]
        np.testing.assert_allclose(white[i], ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    assert noise.log_det_gamma(positions) == pytest.approx(2 * np.sum(np.log(np.diag(chol))), rel=1e-8, abs=1e-10)


def test_ar1_samples_have_the_dense_covariance():
    # Reference: the dense covariance sigma^2 Gamma; 40000 draws give the sample
    # covariance to about 0.01 (4 / sqrt(n) covers every entry).
    positions = np.array([0.0, 0.2, 0.5, 0.55, 1.3, 2.0])
    noise = NoiseModel([2.0, 0.5], 0.4)
    draws = noise.sample(positions, rng=7, n_crossings=40000)
    for i, sigma in enumerate(noise.std):
        sample_cov = np.cov(draws[:, i, :] / sigma, rowvar=False)
        np.testing.assert_allclose(sample_cov, dense_gamma(positions, 0.4), atol=4 / np.sqrt(40000))


def test_identifiability_eigen_analysis_and_prior_split():
    case = example_case("openlab-like")
    blocks = fisher_blocks(case, n_crossings=10)
    prior = GMRFPrior(order=2).precision(case.n_elements)
    ident = identifiability(blocks, prior_precision=prior, threshold=1e-3)
    total = blocks.total()
    # eigen-decomposition reproduces the matrix, values descending
    recon = ident.eigenvectors @ np.diag(ident.eigenvalues) @ ident.eigenvectors.T
    np.testing.assert_allclose(recon, total, atol=1e-9 * np.abs(total).max())
    # reference: numpy's symmetric eigensolver, sorted descending (values clipped at 0)
    np.testing.assert_allclose(ident.eigenvalues, np.clip(np.linalg.eigvalsh(total)[::-1], 0.0, None),
                               rtol=1e-8, atol=1e-12 * ident.eigenvalues[0])
    # two tiltmeters: the data inform only a few directions of 30 elements
    assert 1 <= ident.effective_rank < case.n_elements
    # precision split: data + prior = posterior diagonal
    np.testing.assert_allclose(ident.data_precision + ident.prior_precision, np.diag(total + prior))
    # parameters determined by the data: tr(I (I + Q_prior)^-1), formed densely
    assert ident.data_dof == pytest.approx(np.trace(total @ np.linalg.inv(total + prior)), rel=1e-8)
    assert 0.0 < ident.data_dof < case.n_elements
    share = ident.data_share
    # elements at the sensors are data dominated, those at the far zero-moment end less so
    j_sensor = case.mesh.element_of(11.0)
    assert share[j_sensor] > share[-1]


def test_new_sensors_take_the_noise_of_the_case_sensors_of_their_kind():
    # Reference: the documented default for new sensors (Case.noise_std_for), the median noise of the
    # case's sensors of the same kind: 2 urad for tiltmeters and 0.05 mm for deflection sensors here,
    # not the median over both kinds (which would use a level in m for a tiltmeter or vice versa).
    bridge = sp.Bridge((20.0,))
    case = Case(bridge, sp.Mesh.uniform(bridge, 10), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([5.0, 10.0, 15.0], kinds=["rotation", "deflection", "rotation"],
                                noise_std=[2e-6, 5e-5, 2e-6]),
                sweep=sp.LoadSweep.from_range(0.0, 20.0, 0.5))
    new = sp.SensorLayout([4.0, 12.0], kinds=["deflection", "rotation"])
    default = fisher_blocks(case, sensors=new).blocks
    explicit = fisher_blocks(case, sensors=sp.SensorLayout([4.0, 12.0], kinds=["deflection", "rotation"],
                                                           noise_std=[5e-5, 2e-6])).blocks
    np.testing.assert_allclose(default, explicit, rtol=1e-12)

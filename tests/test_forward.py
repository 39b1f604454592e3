"""Forward model against closed forms, an independent FE solve and identities."""
import sys, pathlib
sys.path.insert(0, str(pathlib.Path(__file__).parent))

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

import sensorplan as sp
from fe_reference import fe_response
from sensorplan.model.forward import readings

P = 1.0e5
EI = 1.0e10


def ss_slope(x, a, L, P=P, EI=EI):
    # Simply supported beam, point load P at a (b = L - a), w downward.
    # w(x) = P b x (L^2 - b^2 - x^2) / (6 L EI) for x <= a (Gere & Goodno,
    # Mechanics of Materials, Table G-2 case 5); theta = dw/dx, mirrored for x > a.
    b = L - a
    if x <= a:
        return P * b * (L**2 - b**2 - 3 * x**2) / (6 * L * EI)
    xp = L - x
    return -P * a * (L**2 - a**2 - 3 * xp**2) / (6 * L * EI)


def ss_deflection(x, a, L, P=P, EI=EI):
    # Same source, deflection (positive downward).
    b = L - a
    if x <= a:
        return P * b * x * (L**2 - b**2 - x**2) / (6 * L * EI)
    xp = L - x
    return P * a * xp * (L**2 - a**2 - xp**2) / (6 * L * EI)


def point_lines(bridge, ei, positions, kinds, loads, n_elements=12):
    mesh = sp.Mesh.uniform(bridge, n_elements)
    sensors = sp.SensorLayout(positions, kinds)
    return sp.influence_lines(bridge, mesh, ei, sensors, sp.Vehicle.point_load(P), loads)


@pytest.mark.parametrize("x", [0.0, 2.5, 5.0, 7.3, 10.0, 13.9, 20.0])
def test_simply_supported_slope_and_deflection(x):
    L = 20.0
    loads = np.array([0.0, 1.0, 4.9, 10.0, 13.9, 15.5, 20.0])
    bridge = sp.Bridge((L,))
    lines = point_lines(bridge, EI, [x, x], ["rotation", "deflection"], loads, n_elements=7)
    slope = [ss_slope(x, a, L) for a in loads]
    defl = [ss_deflection(x, a, L) for a in loads]
    np.testing.assert_allclose(lines.predictions[0], slope, rtol=1e-12, atol=1e-12 * np.abs(slope).max())
    np.testing.assert_allclose(lines.predictions[1], defl, rtol=1e-12, atol=1e-12 * np.abs(defl).max())


def test_sign_convention():
    # DEVELOPERS brief: w downward, theta = dw/dx, x from the left end; under a
    # sagging load a tiltmeter near a span's left support reads positive.
    bridge = sp.Bridge((15.0, 15.0))
    lines = point_lines(bridge, EI, [1.0, 14.0, 16.0, 29.0, 7.5],
                        ["rotation"] * 4 + ["deflection"], [7.5, 22.5])
    assert lines.predictions[0, 0] > 0  # near left support of loaded span 1
    assert lines.predictions[1, 0] < 0  # near its right support
    assert lines.predictions[2, 1] > 0  # near left support of loaded span 2
    assert lines.predictions[3, 1] < 0
    assert lines.predictions[4, 0] > 0  # loaded span deflects downwards
    assert lines.predictions[4, 1] < 0  # the other span lifts


def test_propped_cantilever_end_moment():
    # Fixed at x = L, pinned at x = 0, load at distance a from the pinned end:
    # M_fixed = -P a b (a + L) / (2 L^2) (hogging), AISC Steel Construction
    # Manual, Beam Diagrams and Formulas, case 13.
    L = 10.0
    bridge = sp.Bridge((L,), rotational_springs=(0.0, math.inf))
    mesh = sp.Mesh.uniform(bridge, 5)
    for a in (2.0, 3.7, 8.0):
        b = L - a
        m = sp.bending_moments(bridge, mesh, EI, sp.Vehicle.point_load(P), [a], [L])
        assert m[0, 0] == pytest.approx(-P * a * b * (a + L) / (2 * L**2), rel=1e-12)


def test_fixed_fixed_end_moments():
    # M_A = -P a b^2 / L^2, M_B = -P a^2 b / L^2 (Roark's Formulas, Table 8.1 case 1e).
    L = 12.0
    bridge = sp.Bridge((L,), rotational_springs=(math.inf, math.inf))
    mesh = sp.Mesh.uniform(bridge, 6)
    a = 4.5
    b = L - a
    m = sp.bending_moments(bridge, mesh, EI, sp.Vehicle.point_load(P), [a], [0.0, L - 1e-12])
    np.testing.assert_allclose(m[0], [-P * a * b**2 / L**2, -P * a**2 * b / L**2], rtol=1e-9)


def test_two_equal_spans_three_moment_equation():
    # Clapeyron: 4 M_B L = -P a (L^2 - a^2) / L for a load at a in span 1.
    L = 15.0
    bridge = sp.Bridge((L, L))
    mesh = sp.Mesh.uniform(bridge, 10)
    for a in (3.0, 7.5, 11.0):
        m = sp.bending_moments(bridge, mesh, EI, sp.Vehicle.point_load(P), [a], [L])
        assert m[0, 0] == pytest.approx(-P * a * (L**2 - a**2) / (4 * L**2), rel=1e-12)


def test_rotational_spring_limits():
    L = 10.0
    loads = np.linspace(0.5, 9.5, 7)
    kwargs = dict(positions=[0.5, 3.0, 9.0], kinds=["rotation"] * 3, loads=loads)
    pin = point_lines(sp.Bridge((L,), (0.0, 0.0)), EI, **kwargs).predictions
    clamp = point_lines(sp.Bridge((L,), (math.inf, math.inf)), EI, **kwargs).predictions
    soft = point_lines(sp.Bridge((L,), (1e-6 * EI / L,) * 2), EI, **kwargs).predictions
    stiff = point_lines(sp.Bridge((L,), (1e9 * EI / L,) * 2), EI, **kwargs).predictions
    scale = np.abs(pin).max()
    np.testing.assert_allclose(soft, pin, atol=1e-6 * scale)
    np.testing.assert_allclose(stiff, clamp, atol=1e-7 * scale)
    assert not np.allclose(pin, clamp, atol=1e-2 * scale)


def test_vertical_springs_closed_form_and_limits():
    # A simple span on end springs k0, k1: the rigid-support line plus the
    # rigid-body motion of the settlements R_i / k_i (superposition).
    L, k0, k1 = 20.0, 3e7, 8e7
    loads = np.array([2.0, 9.0, 15.0])
    x = np.array([0.0, 6.0, 14.0])
    lines = point_lines(sp.Bridge((L,), vertical_springs=(k0, k1)), EI, list(x) + list(x),
                        ["rotation"] * 3 + ["deflection"] * 3, loads, n_elements=4)
    for k, a in enumerate(loads):
        d0, d1 = P * (L - a) / L / k0, P * a / L / k1
        for i, xi in enumerate(x):
            assert lines.predictions[i, k] == pytest.approx(ss_slope(xi, a, L) + (d1 - d0) / L, rel=1e-12)
            w = ss_deflection(xi, a, L) + d0 + (d1 - d0) * xi / L
            assert lines.predictions[3 + i, k] == pytest.approx(w, rel=1e-12)
    rigid = point_lines(sp.Bridge((L,)), EI, x, ["rotation"] * 3, loads).predictions
    stiff = point_lines(sp.Bridge((L,), vertical_springs=(1e14, 1e14)), EI, x, ["rotation"] * 3,
                        loads).predictions
    np.testing.assert_allclose(stiff, rigid, atol=1e-5 * np.abs(rigid).max())


def test_kernel_equals_paper_integrals_on_simple_span():
    # theta(r; z) = int m_r(s) M(s; z) v(s) ds with the paper's closed-form
    # m_r(s) = -s/L + H(s - r) and M(s; z) (eq. mrM), integrated element by
    # element with scipy.integrate.quad (adaptive, split at the kinks).
    L = 20.0
    bridge = sp.Bridge((L,))
    mesh = sp.Mesh.uniform(bridge, 8)
    r, z = 5.7, 12.3
    lines = sp.influence_lines(bridge, mesh, EI, sp.SensorLayout([r]), sp.Vehicle.point_load(P), [z])

    def m_r(s):
        return -s / L + (1.0 if s > r else 0.0)

    def moment(s):
        return P * ((L - z) / L * s if s <= z else z * (1 - s / L))

    for j, (a, b) in enumerate(zip(mesh.edges[:-1], mesh.edges[1:])):
        pts = [p for p in (r, z) if a < p < b]
        ref, _ = integrate.quad(lambda s: m_r(s) * moment(s), a, b, points=pts or None,
                                epsabs=0, epsrel=1e-13)
        assert lines.kernel[0, 0, j] == pytest.approx(ref, rel=1e-10, abs=1e-8 * P)
    assert lines.predictions[0, 0] == pytest.approx(lines.kernel[0, 0].sum() / EI, rel=1e-13)


def test_linear_in_compliance_for_determinate_bridge():
    rng = np.random.default_rng(3)
    bridge = sp.Bridge((18.0,))
    mesh = sp.Mesh.uniform(bridge, 9)
    sensors = sp.SensorLayout([3.0, 9.5, 17.0], ["rotation", "deflection", "rotation"])
    v1, v2 = rng.uniform(5e-11, 2e-10, (2, 9))
    veh = sp.Vehicle((0.0, 2.0), (5e4, 3e4))
    z = np.linspace(0, 20, 11)

    def pred(v):
        return sp.influence_lines(bridge, mesh, 1.0 / v, sensors, veh, z).predictions

    np.testing.assert_allclose(pred(v1 + v2), pred(v1) + pred(v2), rtol=1e-12)


def random_indeterminate(rng):
    bridge = sp.Bridge((11.0, 14.0), rotational_springs=(rng.uniform(1e8, 1e10), 0.0, 4e9),
                       vertical_springs=(math.inf, rng.uniform(1e8, 1e9), 5e8))
    mesh = sp.Mesh.uniform(bridge, 10)
    ei = rng.uniform(5e9, 2e10, mesh.n_elements)
    sensors = sp.SensorLayout([0.0, 4.3, 11.0, 18.2, 7.0], ["rotation"] * 4 + ["deflection"])
    veh = sp.Vehicle((0.0, 1.7, 4.1), (5e4, 4e4, 2e4))
    return bridge, mesh, ei, sensors, veh, np.linspace(0.0, 29.0, 13)


def test_homogeneous_in_compliances_for_indeterminate_bridge():
    bridge, mesh, ei, sensors, veh, z = random_indeterminate(np.random.default_rng(5))
    base = sp.influence_lines(bridge, mesh, ei, sensors, veh, z).predictions
    alpha = 1.7
    scaled = bridge.with_spring_stiffness(bridge.spring_stiffness() / alpha)
    scaled_pred = sp.influence_lines(scaled, mesh, ei / alpha, sensors, veh, z).predictions
    scale = np.abs(base).max()
    np.testing.assert_allclose(scaled_pred, alpha * base, rtol=1e-11, atol=1e-13 * scale)
    # Euler's theorem for degree-1 homogeneity: y = A v + sum dy/dc c.
    lines = sp.influence_lines(bridge, mesh, ei, sensors, veh, z)
    euler = lines.kernel @ (1 / ei) + lines.spring_kernel @ (1 / bridge.spring_stiffness())
    np.testing.assert_allclose(euler, base, rtol=1e-11, atol=1e-13 * scale)


def test_maxwell_betti_reciprocity():
    bridge, mesh, ei, _, _, _ = random_indeterminate(np.random.default_rng(7))
    x = np.array([1.3, 6.0, 12.4, 20.9, 24.0])
    lines = sp.influence_lines(bridge, mesh, ei, sp.SensorLayout(x, "deflection"),
                               sp.Vehicle.point_load(1.0), x)
    np.testing.assert_allclose(lines.predictions, lines.predictions.T, rtol=1e-11)


def assert_columns_match(jac, fd, rtol, label):
    """Each Jacobian column against its finite difference, relative to that column's own norm.

    A tolerance relative to the largest reading would let a sign error
    through on weakly sensitive columns (elements far from every sensor,
    soft springs); relative to the column's norm a flipped column misses by
    a factor of 2.
    """
    for j in range(fd.shape[-1]):
        ref = np.linalg.norm(fd[..., j])
        assert ref > 0.0, f"{label}: column {j} has no sensitivity, the check would be empty"
        err = np.linalg.norm(jac[..., j] - fd[..., j])
        assert err <= rtol * ref, f"{label}: column {j} differs by {err / ref:.2e} of its norm"


@pytest.mark.parametrize("parameterisation", ["compliance", "ei", "log_ei"])
def test_jacobians_equal_finite_differences(parameterisation):
    # Reference: central differences of the forward map (step 1e-6 relative);
    # observed agreement is ~1e-7 of each column's norm or better.
    bridge, mesh, ei, sensors, veh, z = random_indeterminate(np.random.default_rng(11))
    lines = sp.influence_lines(bridge, mesh, ei, sensors, veh, z)
    jac = lines.jacobian(parameterisation, springs=True)
    to_param = {"compliance": lambda e: 1 / e, "ei": lambda e: e, "log_ei": np.log}[parameterisation]
    from_param = {"compliance": lambda p: 1 / p, "ei": lambda p: p, "log_ei": np.exp}[parameterisation]
    theta = to_param(ei)
    fd = np.empty_like(jac)
    for j in range(mesh.n_elements):
        h = 1e-6 * abs(theta[j])
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        fd[:, :, j] = (sp.influence_lines(bridge, mesh, from_param(up), sensors, veh, z).predictions
                       - sp.influence_lines(bridge, mesh, from_param(down), sensors, veh, z).predictions) / (2 * h)
    logk = np.log(bridge.spring_stiffness())
    for s in range(logk.size):
        up, down = logk.copy(), logk.copy()
        up[s] += 1e-6
        down[s] -= 1e-6
        fd[:, :, mesh.n_elements + s] = (
            sp.influence_lines(bridge.with_spring_stiffness(np.exp(up)), mesh, ei, sensors, veh, z).predictions
            - sp.influence_lines(bridge.with_spring_stiffness(np.exp(down)), mesh, ei, sensors, veh,
                                 z).predictions) / 2e-6
    assert_columns_match(jac, fd, 1e-6, parameterisation)
    # the check can fail: one flipped column (the weakest) is caught
    weakest = int(np.argmin(np.linalg.norm(fd.reshape(-1, fd.shape[-1]), axis=0)))
    flipped = jac.copy()
    flipped[..., weakest] *= -1.0
    with pytest.raises(AssertionError):
        assert_columns_match(flipped, fd, 1e-6, parameterisation)


def test_axles_superpose_and_off_bridge_axles_vanish():
    bridge, mesh, ei, sensors, veh, z = random_indeterminate(np.random.default_rng(13))
    z = np.array([-3.0, 0.5, 3.0, 12.0, 26.0, 28.0, 31.0])
    total = sp.influence_lines(bridge, mesh, ei, sensors, veh, z).predictions
    parts = sum(
        sp.influence_lines(bridge, mesh, ei, sensors, sp.Vehicle.point_load(p), z - d).predictions
        for d, p in zip(veh.axle_offsets, veh.axle_loads))
    np.testing.assert_allclose(total, parts, rtol=1e-12, atol=1e-25)
    assert np.all(total[:, 0] == 0.0)  # the whole vehicle is off the bridge


def _off_edges(x, edges, gap=0.02):
    # Snap each point onto an edge or an earlier point closer than ``gap``.
    x = np.array(x, dtype=float)
    for i, xi in enumerate(x):
        nodes = np.concatenate([edges, x[:i]])
        d = np.abs(nodes - xi)
        j = np.argmin(d)
        if 0 < d[j] < gap:
            x[i] = nodes[j]
    return x


def _clear_of(z, offsets, nodes, gap=0.02):
    # Shift a whole vehicle until every axle is >= gap from every node.
    for shift in np.arange(0.0, 2.0, 0.0371):
        axles = z + shift - offsets
        if np.all(np.abs(axles[:, None] - nodes[None, :]) >= gap):
            return z + shift
    return z


@st.composite
def random_bridges(draw):
    n_spans = draw(st.integers(1, 3))
    spans = [draw(st.floats(4.0, 25.0)) for _ in range(n_spans)]
    rot_choice = st.sampled_from([0.0, math.inf, "elastic"])
    rot = []
    for _ in range(n_spans + 1):
        c = draw(rot_choice)
        rot.append(draw(st.floats(1e7, 1e11)) if c == "elastic" else c)
    vert = [math.inf if draw(st.booleans()) else draw(st.floats(1e7, 1e10))
            for _ in range(n_spans + 1)]
    if n_spans == 1 and not any(math.isinf(v) for v in vert) and rot == [0.0, 0.0]:
        vert[0] = math.inf
    return spans, rot, vert


@settings(max_examples=150)
@given(random_bridges(), st.integers(0, 2**32 - 1))
def test_kernel_matches_independent_fe_solve(geometry, seed):
    spans, rot, vert = geometry
    rng = np.random.default_rng(seed)
    bridge = sp.Bridge(spans, rot, vert)
    mesh = sp.Mesh.uniform(bridge, int(rng.integers(bridge.n_spans, 4 * bridge.n_spans + 8)))
    ei = rng.uniform(1e9, 3e10, mesh.n_elements)
    n_axles = int(rng.integers(1, 4))
    veh = sp.Vehicle(np.concatenate([[0.0], np.sort(rng.uniform(0.5, 6.0, n_axles - 1))]),
                     rng.uniform(1e4, 1e5, n_axles))
    length = bridge.length
    # Keep sensors and axles >= 2 cm from element edges (or on them): the FE
    # reference's stiffness grows like 1/h^3, and near-zero elements next to
    # soft springs would make it, not the kernel, lose digits.
    sensors = sp.SensorLayout(_off_edges(rng.uniform(0, length, 4), mesh.edges),
                              [str(k) for k in rng.choice(["rotation", "deflection"], 4)],
                              names=["a", "b", "c", "d"])
    z = np.sort(rng.uniform(-1.0, length + 6.0, 4))
    nodes = np.concatenate([mesh.edges, sensors.positions])
    z = np.array([_clear_of(zk, np.asarray(veh.axle_offsets), nodes) for zk in z])
    lines = sp.influence_lines(bridge, mesh, ei, sensors, veh, z)
    ref = np.zeros((4, z.size))
    for k, zk in enumerate(z):
        loads = [(zk - d, p) for d, p in zip(veh.axle_offsets, veh.axle_loads) if 0 <= zk - d <= length]
        ref[:, k] = fe_response(spans, mesh.edges, ei, rot, vert, loads,
                                list(zip(sensors.positions, sensors.kinds)))
    # Relative to the response scale of the case (rotation ~ P L^2 / EI).
    scale = max(np.abs(ref).max(), veh.total_load * length**2 / ei.max())
    np.testing.assert_allclose(lines.predictions, ref, rtol=0, atol=1e-9 * scale)
    # the readings alone (element sums as matrix products, no kernel) against the same reference
    np.testing.assert_allclose(readings(bridge, mesh, ei, sensors, veh, z), ref, rtol=0, atol=1e-9 * scale)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_moment_diagram_algebra_against_direct_evaluation_and_quadrature(seed):
    # The diagram algebra under the force method, checked against references that share no code with
    # it: each free-body diagram evaluated directly as sum w (s - p)_+ (ramps) or w H(s - p) (steps), and
    # the compliance-weighted products integrated by Gauss-Legendre quadrature between breakpoints
    # (exact for the piecewise-quadratic integrands).
    from sensorplan.model.diagrams import RAMP, point_actions, weighted_products

    rng = np.random.default_rng(seed)
    n_el = int(rng.integers(1, 9))
    edges = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 3.0, n_el))])

    def family():
        n_funcs, n_actions = int(rng.integers(1, 6)), int(rng.integers(1, 4))
        pos = rng.uniform(-0.5, edges[-1] + 0.5, (n_funcs, n_actions))
        pos[:, 0] = np.where(rng.random(n_funcs) < 0.5, rng.choice(edges, n_funcs), pos[:, 0])  # some on edges
        weights = np.where(rng.random((n_funcs, n_actions)) < 0.2, 0.0, rng.normal(size=(n_funcs, n_actions)))
        return pos, weights, rng.integers(0, 2, (n_funcs, n_actions))

    def direct(pos, weights, kinds, s):
        d = s[None, None, :] - pos[:, :, None]
        atom = np.where((kinds == RAMP)[:, :, None], np.maximum(d, 0.0), (d >= 0.0).astype(float))
        return np.einsum("fa,fas->fs", weights, atom)

    first, second = family(), family()
    d1, d2 = point_actions(edges, *first), point_actions(edges, *second)
    s = np.sort(np.concatenate([rng.uniform(0.0, edges[-1], 50), edges[1:-1] + 1e-9]))
    np.testing.assert_allclose(d1.evaluate(edges, s), direct(*first, s), atol=1e-12 * edges[-1])
    v = rng.uniform(0.5, 2.0, n_el)
    breaks = np.unique(np.concatenate([edges, first[0].ravel(), second[0].ravel()]))
    breaks = breaks[(breaks >= 0.0) & (breaks <= edges[-1])]
    nodes, gl_weights = np.polynomial.legendre.leggauss(3)
    mid, half = 0.5 * (breaks[1:] + breaks[:-1]), 0.5 * np.diff(breaks)
    x = (mid[:, None] + half[:, None] * nodes[None, :]).ravel()
    wq = (half[:, None] * gl_weights[None, :]).ravel() * v[np.clip(np.searchsorted(edges, x) - 1, 0, n_el - 1)]
    reference = (direct(*first, x) * wq) @ direct(*second, x).T
    scale = np.abs(reference).max() + 1e-12
    np.testing.assert_allclose(weighted_products(edges, d1, d2, v) / scale, reference / scale, atol=1e-12)

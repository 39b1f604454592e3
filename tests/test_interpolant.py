"""The piecewise-cubic line interpolant against the independent FE solve, the force method and differences."""
import sys, pathlib
sys.path.insert(0, str(pathlib.Path(__file__).parent))

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import sensorplan as sp
from fe_reference import fe_response
from sensorplan.model.interpolant import LineInterpolant
from test_forward import _clear_of, _off_edges, random_bridges


def _setup(geometry, seed):
    spans, rot, vert = geometry
    rng = np.random.default_rng(seed)
    bridge = sp.Bridge(spans, rot, vert)
    mesh = sp.Mesh.uniform(bridge, int(rng.integers(bridge.n_spans, 4 * bridge.n_spans + 8)))
    ei = rng.uniform(1e9, 3e10, mesh.n_elements)
    sensors = sp.SensorLayout(_off_edges(rng.uniform(0, bridge.length, 4), mesh.edges),
                              [str(k) for k in rng.choice(["rotation", "deflection"], 4)])
    return rng, bridge, mesh, ei, sensors


def _assert_lines_equal(got, ref, vehicle, length):
    """(predictions, kernel, spring kernel) of the interpolant against influence_lines' ``ref``."""
    for mine, theirs in zip(got[:2], (ref.predictions, ref.kernel)):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-11 * np.abs(theirs).max(initial=1e-300))
    # dy/dc of the springs' compliances: sensor reactions (1 or 1/m per unit action) times load reactions (N,
    # N m); a spring that carries no reaction (a vertical spring beside a clamped support) has a column of
    # round-off, ~1e-12 on both sides, where a tolerance relative to that column tests noise against noise:
    # 1e-14 of the loads' scale is the floor
    floor = 1e-14 * sum(vehicle.axle_loads) * length
    np.testing.assert_allclose(got[2], ref.spring_kernel, rtol=0,
                               atol=max(1e-11 * np.abs(ref.spring_kernel).max(initial=0.0), floor))


@settings(max_examples=60, deadline=None)
@given(random_bridges(), st.integers(0, 2**32 - 1))
def test_unit_lines_match_the_independent_fe_solve(geometry, seed):
    # reference: tests/fe_reference.py (Hermite beam elements refined around every load and sensor; shares no
    # code with the force method or the interpolant)
    rng, bridge, mesh, ei, sensors = _setup(geometry, seed)
    nodes = np.concatenate([mesh.edges, sensors.positions])
    x = np.array([_clear_of(z, np.zeros(1), nodes) for z in rng.uniform(0.0, bridge.length - 2.1, 5)])
    predictions, _, _ = LineInterpolant(bridge, mesh, ei, sensors).unit(x)
    ref = np.column_stack([fe_response(geometry[0], mesh.edges, ei, geometry[1], geometry[2], [(z, 1.0)],
                                       list(zip(sensors.positions, sensors.kinds))) for z in x])
    scale = max(np.abs(ref).max(), bridge.length**2 / ei.max())
    np.testing.assert_allclose(predictions, ref, rtol=0, atol=1e-9 * scale)


@settings(max_examples=60, deadline=None)
@given(random_bridges(), st.integers(0, 2**32 - 1))
def test_lines_kernels_and_slopes_equal_the_force_method(geometry, seed):
    # reference: influence_lines (one force-method solve per load position; matches the FE solve above) at
    # arbitrary positions, on element edges, on the sensors and off the bridge; the x-derivative against
    # central differences of it (exact for the cubic pieces up to h^2 w''' / 6)
    rng, bridge, mesh, ei, sensors = _setup(geometry, seed)
    length = bridge.length
    x = np.concatenate([rng.uniform(-2.0, length + 2.0, 30), mesh.edges, sensors.positions, [0.0, length]])
    interpolant = LineInterpolant(bridge, mesh, ei, sensors)
    vehicle = sp.Vehicle((0.0, 1.7), (6e4, 4e4))
    got = interpolant.lines(interpolant.weights(x, vehicle.axle_offsets, vehicle.axle_loads))
    ref = sp.influence_lines(bridge, mesh, ei, sensors, vehicle, x)
    _assert_lines_equal(got, ref, vehicle, length)
    nodes = np.concatenate([mesh.edges, sensors.positions, mesh.edges + 1.7])
    h = 1e-4
    z = np.array([_clear_of(zk, np.zeros(1), nodes) for zk in rng.uniform(0.1, length - 2.2, 10)])
    fd = (sp.influence_lines(bridge, mesh, ei, sensors, vehicle, z + h).predictions
          - sp.influence_lines(bridge, mesh, ei, sensors, vehicle, z - h).predictions) / (2 * h)
    slopes = interpolant.readings(interpolant.weights(z, vehicle.axle_offsets, vehicle.axle_loads,
                                                      derivative=True))
    np.testing.assert_allclose(slopes, fd, rtol=0, atol=1e-6 * np.abs(fd).max())


@settings(max_examples=40, deadline=None)
@given(random_bridges(), st.integers(0, 2**32 - 1), st.floats(0.2, 5.0))
def test_a_uniform_ei_factor_without_elastic_springs_needs_no_solve(geometry, seed, factor):
    # reference: influence_lines at EI x factor (its own force-method solve).  With an elastic spring the
    # diagrams change with the factor, and scaled() must refuse (None) rather than answer wrongly.
    spans, rot, vert = geometry
    rng, bridge, mesh, ei, sensors = _setup(geometry, seed)
    assert (LineInterpolant(bridge, mesh, ei, sensors).scaled(factor) is None) == bool(bridge.spring_parameters)
    rigid = sp.Bridge(spans, [k if k in (0.0, math.inf) else math.inf for k in rot], [math.inf] * len(vert))
    scaled = LineInterpolant(rigid, mesh, ei, sensors).scaled(factor)
    x = np.concatenate([rng.uniform(-1.0, rigid.length + 1.0, 20), mesh.edges, sensors.positions])
    vehicle = sp.Vehicle((0.0, 1.3), (5e4, 7e4))
    got = scaled.lines(scaled.weights(x, vehicle.axle_offsets, vehicle.axle_loads))
    ref = sp.influence_lines(rigid, mesh, ei * factor, sensors, vehicle, x)
    for mine, theirs in zip(got[:2], (ref.predictions, ref.kernel)):
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-11 * np.abs(theirs).max(initial=1e-300))


@settings(max_examples=30, deadline=None)
@given(random_bridges(), st.integers(0, 2**32 - 1))
def test_kept_tables_serve_a_new_ei_and_new_spring_stiffnesses(geometry, seed):
    # the EI-independent tables are kept per support layout, mesh and sensors; an interpolant formed after
    # another one at a different EI and different (elastic) stiffnesses must still equal influence_lines there
    spans, rot, vert = geometry
    rng, bridge, mesh, ei, sensors = _setup(geometry, seed)
    LineInterpolant(bridge, mesh, ei, sensors)  # fills the tables
    soften = lambda k: k * rng.uniform(0.3, 3.0) if 0.0 < k < math.inf else k  # noqa: E731
    other = sp.Bridge(spans, [soften(k) for k in rot], [soften(k) for k in vert])
    ei2 = ei * rng.uniform(0.5, 2.0, ei.size)
    interpolant = LineInterpolant(other, mesh, ei2, sensors)
    x = np.concatenate([rng.uniform(0.0, other.length, 15), sensors.positions])
    vehicle = sp.Vehicle((0.0, 2.1), (4e4, 9e4))
    got = interpolant.lines(interpolant.weights(x, vehicle.axle_offsets, vehicle.axle_loads))
    ref = sp.influence_lines(other, mesh, ei2, sensors, vehicle, x)
    _assert_lines_equal(got, ref, vehicle, other.length)

"""The verification's faster paths give the results of the direct ones (issue 38: verify throughput).

* :class:`~sensorplan.inference.fixed_lines.FixedLines` (the forward model
  with its EI-independent element integrals kept) against
  :func:`~sensorplan.model.forward.influence_lines` (the integrals of the
  actual diagrams formed at every EI), a closed form and finite differences;
* the detector's zone posteriors, now computed when first asked for;
* a whole verification through the fast forward against the same run
  through ``influence_lines``: verdicts, detections and false alarms equal,
  every number within ``RTOL``;
* a Dask LocalCluster of two workers against one process.
"""

import json
import math
import pickle

import numpy as np
import pytest

from sensorplan import Bridge, Mesh, SensorLayout, Vehicle
from sensorplan import invert
from sensorplan.inference.detector import detect_damage
from sensorplan.inference.fixed_lines import FixedLines
from sensorplan.io.config import example_case
from sensorplan.model.forward import influence_lines
from sensorplan.model.simulate import simulate_crossings
from sensorplan.verification.verify import plan_verification, run_pilot, run_scenario, verify_layouts

# The hyper-posterior's grid step comes from a finite-difference curvature (step 0.1) of log weights of size
# ~1e3-1e4, which turns the forward model's rounding (1e-14) into up to ~1e-5 of the step: the undamaged
# posterior's mean moves by ~1e-10 of itself (POSTERIOR_RTOL bounds it).  The damage hypotheses then keep
# the components that make up 99.9 % of the weight: a component at the cut can enter or leave, which moves a
# scenario's rmse (a small difference of means) by up to ~1e-6 of itself (RTOL).  Verdicts and counts are equal.
POSTERIOR_RTOL = 1e-8
RTOL = 1e-5


def _perturbed(case, seed):
    rng = np.random.default_rng(seed)
    ei = case.ei * np.exp(0.2 * rng.standard_normal(case.ei.size))
    bridge = case.bridge
    if bridge.spring_names:
        factors = np.exp(0.3 * rng.standard_normal(len(bridge.spring_names)))
        bridge = bridge.with_spring_stiffness(bridge.spring_stiffness() * factors)
    return ei, bridge


@pytest.mark.parametrize("name", ["openlab-like", "three-span", "simply-supported"])
def test_fixed_lines_equal_the_forward_model(name):
    case = example_case(name)
    lines = FixedLines(case.bridge, case.mesh, case.sensors, case.vehicle, case.sweep.positions)
    for seed in (0, 1):  # two EI and stiffness states from one FixedLines
        ei, bridge = _perturbed(case, seed)
        direct = influence_lines(bridge, case.mesh, ei, case.sensors, case.vehicle, case.sweep.positions)
        fast = lines.at(bridge, ei)
        for field in ("predictions", "kernel", "spring_kernel"):
            a, b = getattr(direct, field), getattr(fast, field)
            assert a.shape == b.shape
            if a.size:
                assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), field


def test_fixed_lines_closed_form_and_finite_differences():
    bridge = Bridge(spans=(20.0,))
    mesh = Mesh.uniform(bridge, 10)
    sensors = SensorLayout([0.0])
    lines = FixedLines(bridge, mesh, sensors, Vehicle.point_load(1e5), [10.0, 5.0])
    # closed form: rotation at the pinned end of a simple span under a central load, P L^2 / (16 EI)
    assert lines.at(bridge, 2e10).predictions[0, 0] == pytest.approx(1e5 * 20.0**2 / (16 * 2e10), rel=1e-13)
    # a two-span beam with EI varying along it: the kernel is dy/dv (v = 1 / EI), checked by central differences
    case = example_case("openlab-like")
    ei, bridge = _perturbed(case, 3)
    fixed = FixedLines(case.bridge, case.mesh, case.sensors, case.vehicle, case.sweep.positions)
    at = fixed.at(bridge, ei)
    for e in (0, 7, 22):
        h = 1e-6 / ei[e]
        v_plus, v_minus = 1.0 / ei, 1.0 / ei
        v_plus[e] += h
        v_minus[e] -= h
        numeric = (fixed.at(bridge, 1.0 / v_plus).predictions - fixed.at(bridge, 1.0 / v_minus).predictions) / (2 * h)
        assert np.max(np.abs(numeric - at.kernel[..., e])) <= 1e-6 * np.max(np.abs(at.kernel[..., e]))


def test_zone_posteriors_computed_on_demand():
    case = example_case("simply-supported")
    ei = case.ei.copy()
    ei[(case.mesh.midpoints > 5.0) & (case.mesh.midpoints < 7.0)] *= 0.5
    data = simulate_crossings(case, 10, noise=True, rng=2, ei=ei)
    detection = detect_damage(case, data, rng=3)
    assert detection.detected
    copy = pickle.loads(pickle.dumps(detection))  # the lazy part travels (to a Dask worker, say)
    weights, loss = detection.weights, detection.posterior_loss
    assert weights.shape == (len(detection.zones),) and loss.shape == (len(detection.zones), 2)
    assert weights.sum() == pytest.approx(1.0, abs=1e-12) and np.all(weights >= 0.0)
    assert np.all((loss[:, 0] > 0.0) & (loss[:, 0] < 1.0)) and np.all(loss[:, 1] >= 0.0)
    np.testing.assert_array_equal(copy.weights, weights)
    np.testing.assert_array_equal(copy.posterior_loss, loss)
    # the most probable zone overlaps the damaged stretch
    start, stop = detection.zones[int(np.argmax(weights))]
    assert start < 7.0 and stop > 5.0


def _assert_same_records(one, other):
    assert len(one) == len(other)
    for a, b in zip(one, other):
        assert set(a) == set(b)
        for key in a:
            x, y = a[key], b[key]
            if isinstance(x, float) and isinstance(y, float) and math.isfinite(x) and math.isfinite(y):
                assert y == pytest.approx(x, rel=RTOL, abs=1e-300), key
            else:
                assert x == y, key


def test_inversion_through_the_fast_forward_model_equals_the_direct_one(monkeypatch):
    case = example_case("simply-supported")
    ei = case.ei.copy()
    ei[(case.mesh.midpoints > 5.0) & (case.mesh.midpoints < 7.0)] *= 0.7
    data = simulate_crossings(case, 6, noise=True, rng=5, ei=ei)
    fast = invert(case, data, rng=1)

    def direct(self, bridge, ei):
        return influence_lines(bridge, self.mesh, ei, self.sensors, self.vehicle, self.positions)

    monkeypatch.setattr(FixedLines, "at", direct)
    reference = invert(case, data, rng=1)
    np.testing.assert_allclose(fast.ei_mean, reference.ei_mean, rtol=POSTERIOR_RTOL)
    np.testing.assert_allclose(fast.credible_interval(0.95), reference.credible_interval(0.95), rtol=POSTERIOR_RTOL)
    assert fast.noise_scale == pytest.approx(reference.noise_scale, rel=POSTERIOR_RTOL)
    assert fast.damage.detected == reference.damage.detected and fast.damage.threshold == reference.damage.threshold
    assert fast.verdict.status == reference.verdict.status


def _records(case, layout, **options):
    """Every scenario's record of a verification, run in process step by step (as verify_layouts does)."""
    plan = plan_verification(case, [layout], **options)
    starts = [run_pilot(task) for task in plan.pilots()]
    return [run_scenario(task).to_dict() for task in plan.tasks(starts)]


@pytest.mark.slow
def test_verification_equals_the_run_through_the_direct_forward_model(monkeypatch):
    case = example_case("simply-supported")
    options = dict(n_locations=6, n_controls=3, seed=1)
    fast = _records(case, [4.0, 16.0], **options)

    def direct(self, bridge, ei):
        return influence_lines(bridge, self.mesh, ei, self.sensors, self.vehicle, self.positions)

    monkeypatch.setattr(FixedLines, "at", direct)
    reference = _records(case, [4.0, 16.0], **options)
    assert len(reference) == 10
    _assert_same_records(reference, fast)
    assert any(r.get("detected") for r in reference)  # the comparison covers a detection's numbers


def _has_dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.slow
@pytest.mark.skipif(not _has_dask(), reason="the dask extra is not installed")
def test_verification_on_a_local_cluster_of_two_workers_equals_one_process():
    case = example_case("openlab-like")
    options = dict(n_locations=3, n_controls=2, n_crossings=4, seed=7)
    one = verify_layouts(case, [[11.0, 19.0], [6.0, 24.0]], **options).to_dict()
    two = verify_layouts(case, [[11.0, 19.0], [6.0, 24.0]], workers=2, scheduler="local", **options).to_dict()
    assert json.dumps(two, sort_keys=True) == json.dumps(one, sort_keys=True)

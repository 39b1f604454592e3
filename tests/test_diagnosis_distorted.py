"""Diagnosis at the edges found on random bridges (studies/diagnosis/unseen.py), never tuned on.

The datasets are written out here with their parameters; the truth is
computed on a finer mesh than the case's (no inverse crime) and the withheld
values are the references: the diagnosis must name the effect and bracket
them.  A settled bearing the base EI twists to mimic (before the nominal
start of the support-spring fits and the third pass: sensor offsets and a
significant gap; with the third pass alone: named late, slowly); a
flipped sensor beside it (before the look-ahead: unexplained); six moved
sensors on precise data (before the third pass: the fit crawled past 55
iterations and was not used; unexplained).
"""

from dataclasses import replace

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.model.crossings import Crossing, Crossings
from sensorplan.verification.verify import truth_mesh


def _data(case, truth_bridge, n_crossings, gain, seed, sensors=None):
    truth = replace(case.with_mesh(truth_mesh(case)), bridge=truth_bridge)
    if sensors is not None:
        truth = replace(truth, sensors=sensors)
    x = case.sweep.positions
    clean = truth.influence_lines(truth.ei, positions=x).predictions
    noise = case.noise.sample(x, np.random.default_rng(seed), n_crossings)
    return Crossings(case.sensors.names, tuple(
        Crossing(str(c + 1), x, gain[:, None] * clean + noise[c], np.ones(x.size)) for c in range(n_crossings)))


def _case(bridge, ei, vehicle, positions, std, correlation_length, step, n_elements=60):
    names = tuple(f"T{i + 1}" for i in range(len(positions)))
    sensors = sp.SensorLayout(positions, "rotation", names, [std] * len(positions))
    return sp.Case(bridge, sp.Mesh.uniform(bridge, n_elements), ei, vehicle, sensors,
                   sp.NoiseModel([std] * len(positions), correlation_length),
                   sweep=sp.LoadSweep.from_range(0.0, bridge.length + vehicle.length, step))


def _settled(d, support):
    # the settled support's finding: its value and 95 % interval in N/m
    where = f"support {support} "
    found = [f for f in d.findings.get("vertical_support_spring", ()) if where in f.where]
    assert found, d.findings
    return found[0]


@pytest.mark.slow
def test_a_settled_bearing_that_distorts_the_base_fit_is_named():
    # three spans with elastic end restraints and an elastic first bearing; the second interior bearing, rigid in
    # the case, settles to 2 x 48 EI / L^3 of its span (2.06e8 N/m): the base fit's noise scale is about 40 and
    # its EI spans five orders of magnitude
    bridge = sp.Bridge((23.1, 19.8, 23.3), (2.8e9, 0.0, 0.0, 1.56e9), (np.inf, 6.49e9, np.inf, np.inf))
    case = _case(bridge, [2.47e10, 3.08e10, 2.71e10], sp.Vehicle((0.0, 3.3, 6.63), (70.4e3, 114.6e3, 54.3e3)),
                 [8.1, 9.79, 23.87, 38.17], 6.2e-7, 0.0, 0.1)
    k = 2.06e8
    truth = sp.Bridge(bridge.spans, bridge.rotational_springs, (np.inf, 6.49e9, k, np.inf))
    d = sp.diagnose(case, _data(case, truth, 9, np.ones(4), seed=5))
    assert d.causes == ("vertical_support_spring",) and not d.unexplained
    # found by the screening itself, from the nominal start; without it the bearing's fit from the base MAP
    # crawls, sensor offsets and axle loads are picked first, and the bearing arrives only in the third
    # selection step through a third pass (the same verdict in about four times the time)
    assert d.effects[0].name == "vertical_support_spring" and d.effects[0].converged
    f = _settled(d, 2)
    assert f.low <= k <= f.high


@pytest.mark.slow
def test_a_flipped_sensor_next_to_a_settled_bearing_needs_both_to_be_named():
    # one 25.4 m span, its left end elastically restrained; the left bearing settles (6.6e7 N/m) and T4 is
    # mounted the wrong way round; AR(1) noise
    bridge = sp.Bridge((25.4,), (1.1e9, 0.0), (np.inf, np.inf))
    case = _case(bridge, [1.13e10], sp.Vehicle((0.0, 1.35), (43.3e3, 92.3e3)), [1.48, 5.24, 7.43, 11.46, 18.44],
                 2.9e-6, 0.88, 0.25)
    k = 6.6e7
    truth = sp.Bridge(bridge.spans, bridge.rotational_springs, (k, np.inf))
    data = _data(case, truth, 12, np.array([1.0, 1.0, 1.0, -1.0, 1.0]), seed=5)
    with pytest.warns(sp.SensorplanWarning, match="'T4' is anti-correlated"):
        d = sp.diagnose(case, data)
    assert set(d.causes) == {"sensor_gain", "vertical_support_spring"} and not d.unexplained
    f = _settled(d, 0)
    assert f.low <= k <= f.high
    assert d.heldout_ratio_after < 1.2


@pytest.mark.slow
def test_six_moved_sensors_on_precise_data_are_named_after_a_longer_fit():
    # two spans on an elastic bearing, six tiltmeters each mounted 0.4-0.7 m from where the case says, noise
    # 0.2 micro-radians (a precise instrument): the position fit is strongly nonlinear and needs ~60 steps
    bridge = sp.Bridge((21.2, 17.7), (0.0, 0.0, 6.6e9), (np.inf, 9.4e9, np.inf))
    positions = np.array([8.45, 11.48, 16.59, 27.96, 30.82, 31.97])
    case = _case(bridge, [3.71e10, 2.74e10], sp.Vehicle((0.0, 4.13), (58.2e3, 49.2e3)), positions, 2e-7, 0.0,
                 0.25, n_elements=49)
    moves = np.array([-0.53, -0.60, -0.69, 0.53, 0.57, -0.40])
    moved = sp.SensorLayout(positions + moves, "rotation", case.sensors.names, [2e-7] * 6)
    d = sp.diagnose(case, _data(case, bridge, 8, np.ones(6), seed=1, sensors=moved))
    assert d.causes == ("sensor_position",) and not d.unexplained
    found = {f.where.split()[2]: f for f in d.findings["sensor_position"]}
    for name, move in zip(case.sensors.names, moves):
        assert found[name].low <= move <= found[name].high, (name, found[name].text)


@pytest.mark.parametrize("alpha, starts", [(5.0, 2), (1.5, 1)])
def test_the_nominal_start_follows_the_noise_scale_of_the_model_a_fit_starts_from(monkeypatch, alpha, starts):
    # A support-spring fit that does not converge is fitted again from the nominal EI only while the model it
    # starts from is grossly distorted (noise scale above the policy's ``distorted``).  After picks that explain
    # most of the gap the noise scale is re-estimated below it and the second start is skipped.  The fits are
    # replaced by a stub that never converges; what is counted is the starts.
    from types import SimpleNamespace

    from sensorplan.diagnosis.effects import make_effect
    from sensorplan.diagnosis.selection import context
    from sensorplan.diagnosis.selection.policy import DEFAULT_POLICY

    assert 1.5 < DEFAULT_POLICY.distorted < 5.0
    case = sp.example_case("openlab-like")
    case = case.with_mesh(sp.Mesh.uniform(case.bridge, 8))
    data = sp.simulate_crossings(case, 2, noise=True, rng=0)
    calls = []

    def stub(problem, theta, *args, **kwargs):
        calls.append(theta.copy())
        return SimpleNamespace(converged=False, abandoned=False, log_evidence=0.0, problem=problem, theta=theta)

    monkeypatch.setattr(context, "quick_fit", stub)
    blocks = {"log_ei": np.log(np.broadcast_to(case.ei, (case.mesh.n_elements,))) + 0.5}  # a distorted base EI
    ctx = context.DiagnosisContext(case, data, prior=sp.GMRFPrior(), effects={"vertical_support_spring": make_effect(
        "vertical_support_spring")}, estimate_springs=True, noise_scale=alpha, tau=1.0, blocks=blocks, test_masks=[],
        predictions=[])
    ctx.fit(["vertical_support_spring"])
    assert len(calls) == starts
    if starts == 2:  # the second start: the nominal EI
        nominal = np.log(np.broadcast_to(case.ei, (case.mesh.n_elements,)))
        np.testing.assert_allclose(calls[1][:case.mesh.n_elements], nominal)

"""Gap diagnosis: effect Jacobians, linearised held-out folds, and a seeded small version of the validation study.

A diagnosis of the openLAB-like case takes a few seconds (warm-started
screening, linearised folds); the withheld-effect runs carry the ``slow``
marker.
"""

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import GMRFPrior, diagnose, example_case, simulate_crossings
from sensorplan.diagnosis.effects import EFFECTS, make_effect
from sensorplan.diagnosis.joint.problem import JointProblem

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies" / "diagnosis"))
from effects_data import generate  # noqa: E402


def small_case():
    case = example_case("openlab-like")
    case = case.with_mesh(sp.Mesh.uniform(case.bridge, 8))
    return replace(case, sweep=sp.LoadSweep.from_range(0.0, 32.0, 1.0))


def _rigid(case):
    """``case`` with every elastic support made rigid (pins stay pins): no spring parameters."""
    b = case.bridge
    rot = [k if k in (0.0, math.inf) else math.inf for k in b.rotational_springs]
    return replace(case, bridge=sp.Bridge(b.spans, rot, [math.inf] * len(b.vertical_springs)))


@pytest.mark.parametrize("name", list(EFFECTS) + ["load_dependent_stiffness/rigid"])
def test_effect_jacobian_equals_finite_differences(name):
    # "/rigid": on a bridge without elastic springs, where a crossing's own EI factor rescales the lines
    # without a solve (LineInterpolant.scaled)
    name, _, variant = name.partition("/")
    case = small_case() if not variant else _rigid(small_case())
    data = simulate_crossings(case, 2, noise=True, rng=0)
    # two load levels, so that load-dependent stiffness acts (its Jacobian is not zero)
    data = sp.Crossings(data.sensor_names, tuple(replace(c, load_factor=c.load_factor * f)
                                                 for c, f in zip(data.crossings, (0.7, 1.3))))
    problem = JointProblem(case, data, [make_effect(name)], GMRFPrior())
    assert ("case_springs" in [b.name for b in problem.blocks]) == (name != "support_rotational_spring"
                                                                      and not variant)
    rng = np.random.default_rng(1)
    theta = problem.theta0 + 0.05 * rng.standard_normal(problem.n_params) * np.sqrt(
        1.0 / np.diag(problem.fixed))
    preds = problem.predict(theta)
    for k in range(problem.n_params):
        h = 1e-6 * max(1.0, abs(theta[k])) if k < problem.n_elements else 1e-4 * np.sqrt(1 / problem.fixed[k, k])
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        pu, pd = problem.predict(up), problem.predict(down)
        for c, (y, jac) in enumerate(preds):
            fd = (pu[c][0] - pd[c][0]) / (2 * h)
            scale = max(np.abs(fd).max(), np.abs(jac[:, :, k]).max(), 1e-30)
            np.testing.assert_allclose(jac[:, :, k], fd, atol=2e-4 * scale, err_msg=problem.param_names[k])


def test_vehicle_lines_summed_from_axle_lines_equal_the_vehicle_solve():
    # with axle loads in the model, the lines come from unit point loads at every axle position; reference: the
    # direct solve for the whole vehicle (a separate force-method call with every axle as one load case)
    case = small_case()
    data = simulate_crossings(case, 2, noise=True, rng=0)
    effects = [make_effect("axle_loads"), make_effect("position_offset")]
    problem = JointProblem(case, data, effects, GMRFPrior())
    theta = problem.theta0 + 0.1 * np.random.default_rng(2).standard_normal(problem.n_params) * np.sqrt(
        1.0 / np.diag(problem.fixed))
    summed = problem.predict(theta, jacobian=True)
    state = problem.state_at(theta)
    problem.clear_cache()
    for c, (y, _) in enumerate(summed):
        direct = problem.lines(state, c)  # one vehicle solve (nothing cached)
        np.testing.assert_allclose(y, direct.predictions * problem.load_factor(c)[None, :],
                                   rtol=1e-12, atol=1e-12 * np.abs(y).max())
    problem.clear_cache()
    unsummed = problem.predict(theta, jacobian=False)
    for (y, _), (y0, _) in zip(summed, unsummed):
        np.testing.assert_allclose(y, y0, rtol=1e-12, atol=1e-12 * np.abs(y).max())


@pytest.fixture(scope="module")
def case():
    return example_case("openlab-like")


@pytest.mark.slow
def test_effect_free_data_are_adequate(case):
    d = diagnose(case, generate(case, None, rng=3))
    assert d.causes == () and not d.unexplained
    assert "adequate" in d.statement and d.verdict.status == "no_change"


@pytest.mark.slow
@pytest.mark.parametrize("effect,seed", [("sensor_offset", 1), ("vertical_support_spring", 1),
                                         ("position_offset", 2), ("thermal_drift", 4)])
def test_withheld_effect_is_found(case, effect, seed):
    data = generate(case, effect, rng=seed)
    d = diagnose(case, data)
    assert d.causes and d.causes[0] == effect
    assert d.effects[0].name == effect
    entry = d.effects[0]
    assert entry.log_bayes_factor > 3 and entry.heldout_score_gain > 0
    # the held-out residual shrinks to near the noise level of the data
    assert entry.heldout_rms_after < 1.2 * float(np.median(case.noise.std)) * 1.05
    # thermal drift holds the sensor offsets (an offset per sensor and crossing) as a special case: said, not named
    if effect == "thermal_drift":
        assert d.includes == {"thermal_drift": ("sensor_offset",)} and "sensor_offset" not in d.causes
        assert "includes sensor_offset as a special case" in d.summary()
        assert d.to_dict()["includes"] == {"thermal_drift": ["sensor_offset"]}
    else:
        assert d.includes == {}


@pytest.mark.slow
def test_out_of_library_effect_is_unexplained(case):
    d = diagnose(case, generate(case, "vibration", rng=0))
    assert d.unexplained and "unexplained" in d.statement and d.causes == ()
    assert d.verdict.status == "model_error" and "unexplained" in d.verdict.summary


@pytest.mark.slow
def test_genuine_ei_change_is_not_blamed_on_an_effect(case):
    # 30 % softer over 5-9 m: part of the model (EI), not a gap
    def ei(x):
        base = np.where(x < 15.0, 7.5e9, 1.0e10)
        return np.where((x > 5.0) & (x < 9.0), 0.7 * base, base)

    d = diagnose(case, generate(case, None, rng=5, ei=ei))
    assert d.causes == () and not d.unexplained
    # the one verdict: EI departs from nominal (never "no change"), where the loss is
    assert d.verdict.status == "departure"
    a, b = d.verdict.location_m
    assert a < 9.0 and b > 5.0 and d.verdict.loss > 0


@pytest.mark.slow
def test_diagnosis_json_holds_the_computed_values(case):
    data = generate(case, "dynamic_amplification", rng=2)
    d = diagnose(case, data, estimate_springs=False)
    j = json.loads(json.dumps(d.to_dict()))  # what `sensorplan diagnose` writes
    # the gap: the base model's residuals, recomputed here from the forward model at the
    # base EI with the configured springs (reference independent of the diagnosis code)
    residuals = [c.values - c.load_factor * case.influence_lines(d.ei_base, positions=c.positions).predictions
                 for c in data]
    flat = np.concatenate([r.ravel() for r in residuals])
    assert d.gap.rms_residual == pytest.approx(np.sqrt(np.mean(flat**2)), rel=1e-9)
    for i, name in enumerate(case.sensors.names):
        sensor = np.concatenate([r[i] for r in residuals])
        assert d.gap.by_sensor[name].rms_residual == pytest.approx(np.sqrt(np.mean(sensor**2)), rel=1e-9)
    # the JSON carries the result object's numbers, not just its keys
    gap = j["gap"]
    assert (gap["rms_residual"], gap["systematic_rms"], gap["noise_rms"], gap["p_value"], gap["significant"]) == (
        d.gap.rms_residual, d.gap.systematic_rms, d.gap.noise_rms, d.gap.p_value, d.gap.significant)
    assert gap["worst_positions_m"] == list(d.gap.worst_positions_m)
    assert gap["by_sensor"] == {k: v.to_dict() for k, v in d.gap.by_sensor.items()}
    assert [e["name"] for e in j["effects"]] == [e.name for e in d.effects]
    for entry, effect in zip(j["effects"], d.effects):
        assert entry["log_bayes_factor"] == effect.log_bayes_factor
        assert entry["heldout_score_gain"] == effect.heldout_score_gain
        assert entry["rms_after"] == effect.rms_after and entry["heldout_rms_after"] == effect.heldout_rms_after
        assert entry["ei_shift"] == list(effect.ei_shift) and entry["max_ei_shift"] == effect.max_ei_shift
        assert entry["parameters"] == effect.parameters
    # effects are ranked by their Bayes factor
    assert [e.log_bayes_factor for e in d.effects] == sorted((e.log_bayes_factor for e in d.effects), reverse=True)
    assert j["causes"] == list(d.causes) and j["unexplained"] is d.unexplained and j["statement"] == d.statement
    assert j["verdict"] == json.loads(json.dumps(d.verdict.to_dict())) and j["verdict"]["status"] == d.verdict.status
    np.testing.assert_array_equal(j["ei_edges_m"], case.mesh.edges)
    np.testing.assert_array_equal(j["ei_base"], d.ei_base)
    np.testing.assert_array_equal(j["ei_final"], d.ei_final)


def test_linearised_folds_match_refits_on_the_training_rows():
    # reference: brute force, the base model refitted on each fold's training rows (masked problem,
    # Levenberg-Marquardt to convergence), and the Gaussian predictive density of the held-out whitened
    # rows evaluated with scipy.stats (not the Woodbury form of selection.heldout.heldout)
    from scipy import stats

    from sensorplan.diagnosis.selection.heldout import fold_rows, heldout, make_folds
    from sensorplan.diagnosis.selection.refit import quick_fit
    from sensorplan.inference.engine import solve_map

    case = small_case()
    data = simulate_crossings(case, 3, noise=True, rng=4)
    prior = GMRFPrior()
    problem = JointProblem(case, data, [], prior)
    fit = quick_fit(problem, problem.theta0, 1.0, 1.0)
    folds = make_folds(data, 4)
    r, jac, cross, load, _ = problem.rows(fit.theta)
    masks = fold_rows(data, folds, cross, load)
    scores = heldout(fit, masks).log_density
    q = problem.rough + problem.fixed
    for (train, test), mask, score in zip(folds, masks, scores):
        a2 = float(np.sum(r[~mask] ** 2)) / int((~mask).sum())
        sub = JointProblem(case, data, [], prior, masks=train)
        theta, lin, _, ok = solve_map(sub, fit.theta, np.sqrt(a2), q, sub.theta0, max_iter=100, tol=1e-12)
        assert ok
        rf, jf, *_ = problem.rows(theta)
        cov = a2 * np.eye(int(mask.sum())) + jf[mask] @ np.linalg.inv(lin.jtj / a2 + q) @ jf[mask].T
        reference = stats.multivariate_normal(np.zeros(int(mask.sum())), cov).logpdf(rf[mask])
        # the leave-fold-out step is one Newton step from the full-data MAP: second-order error only
        assert score == pytest.approx(reference, abs=0.2)


def test_static_load_steps_do_not_offer_dynamic_effects():
    case = small_case()
    sim = simulate_crossings(case, 3, noise=True, rng=2)
    steps = sp.Crossings(sim.sensor_names, tuple(sp.Crossing(c.label, c.positions[10:11], c.values[:, 10:11],
                                                             c.load_factor[10:11]) for c in sim.crossings))
    d = diagnose(case, steps, effects=["dynamic_amplification", "thermal_drift", "sensor_offset", "axle_loads"])
    assert set(d.not_offered) == {"dynamic_amplification", "thermal_drift", "sensor_offset"}
    assert [e.name for e in d.effects] == ["axle_loads"]


def test_sign_flipped_sensor_is_named_quickly():
    case = small_case()
    data = simulate_crossings(case, 4, noise=True, rng=3)
    flipped = sp.Crossings(data.sensor_names, tuple(replace(c, values=c.values * np.array([[1.0], [-1.0]]))
                                                    for c in data.crossings))
    # the input screening warns first (anti-correlated channel); the diagnosis then names the effect.
    # (How fast this is, is measured in studies/benchmarks/bench_diagnose.py, not asserted here.)
    with pytest.warns(sp.SensorplanWarning, match="PE2.*anti-correlated"):
        d = diagnose(case, flipped)
    assert d.causes[0] == "sensor_gain"
    texts = [f.text for f in d.findings["sensor_gain"]]
    assert len(texts) == 1 and "PE2" in texts[0] and "wrong way round" in texts[0]
    gain = d.findings["sensor_gain"][0]
    assert gain.low < -1.0 < gain.high


@pytest.mark.slow
def test_written_case_brings_invert_back_to_the_truth(tmp_path, capsys):
    # issue 17, acceptance 2: the middle bearing of the openLAB-like bridge settles (k = 3e8 N/m) while
    # the case says rigid; `diagnose --write-case` then `invert` on the written case must give a noise
    # scale of 1 +- 0.1 and bands that hold the true EI (the example's nominal 7.5e9 / 1e10 N m^2,
    # simulated on the truth mesh of the public forward model with the spring in place)
    import math
    import warnings
    from importlib import resources

    from sensorplan.cli import main

    text = resources.files("sensorplan.examples").joinpath("openlab-like.toml").read_text()
    truth = text.replace("vertical_springs = [inf, inf, inf]", "vertical_springs = [inf, 3.0e8, inf]")
    assert truth != text
    (tmp_path / "truth.toml").write_text(truth)
    data, written = tmp_path / "d.csv", tmp_path / "fixed.toml"
    assert main(["simulate", "--config", str(tmp_path / "truth.toml"), "--crossings", "4", "--noise", "--seed", "7",
                 "--out", str(data), "--quiet"]) == 0
    assert main(["diagnose", "--example", "openlab-like", "--data", str(data), "--out", str(tmp_path),
                 "--write-case", str(written)]) == 0
    assert "corrected case written to" in capsys.readouterr().out
    fixed = sp.load_case(written)
    # the bearing written in, the other supports as they were
    assert math.isinf(fixed.bridge.vertical_springs[0]) and math.isinf(fixed.bridge.vertical_springs[2])
    assert 2.0e8 < fixed.bridge.vertical_springs[1] < 4.5e8
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sp.SensorplanWarning)
        post = sp.invert(fixed, sp.read_crossings(data, fixed.sensors))
    assert abs(post.noise_scale - 1.0) < 0.1
    band = post.credible_interval(0.95)
    true_ei = example_case("openlab-like").ei
    assert np.all((band[:, 0] <= true_ei) & (true_ei <= band[:, 1]))


def test_moved_loads_roll_onto_an_elastic_end_bearing_continuously():
    # With the left bearing elastic (as the vertical-spring effect makes every support), a point load steps
    # from nothing to the bearing's response as it crosses x = 0: the lines jumped when a position offset
    # moved an axle over the end, and the fits crawled along that jump.  With a position effect the entry
    # is a ramp over ENTRY: the predictions change by O(step) across the end.
    from sensorplan.diagnosis.joint.problem import ENTRY

    case = small_case()
    data = simulate_crossings(case, 1, noise=False, rng=0)
    problem = JointProblem(case, data, [make_effect("vertical_support_spring"), make_effect("position_offset")],
                           GMRFPrior())
    assert problem.entry == ENTRY
    _, sl = problem.block("position_offset")
    rear = max(case.vehicle.axle_offsets)
    recorded = data.crossings[0].positions
    k = int(np.argmin(np.abs(recorded - rear - 1.0)))  # the rear axle 1 m into the bridge
    crossing = recorded[k] - rear  # the shift that puts the rear axle exactly on x = 0

    def rear_reading(shift):
        theta = problem.theta0.copy()
        theta[sl.start] = -crossing + shift
        return problem.predict(theta, jacobian=False)[0][0][:, k]

    on, off = rear_reading(1e-7), rear_reading(-1e-7)
    assert np.all(np.abs(on - off) < 1e-5 * np.abs(on).max())
    # and off the right end (an elastic bearing there too): the front axle leaves over the same ramp
    front = min(case.vehicle.axle_offsets)
    k = int(np.argmin(np.abs(recorded - front - (case.bridge.length - 1.0))))  # the front axle 1 m before L
    leaving = recorded[k] - front - case.bridge.length  # the shift that puts it exactly on x = L

    def front_reading(shift):
        theta = problem.theta0.copy()
        theta[sl.start] = -leaving + shift
        return problem.predict(theta, jacobian=False)[0][0][:, k]

    on, off = front_reading(-1e-7), front_reading(1e-7)
    assert np.all(np.abs(on - off) < 1e-5 * np.abs(on).max())
    # a point-load model jumps there by the bearing's response: the ramp is what removes it
    plain = JointProblem(case, data, [make_effect("vertical_support_spring")], GMRFPrior())
    assert plain.entry == 0.0
    # the ramp is centred on the end: half the load is on at the end, and over [-ENTRY, ENTRY] it carries as
    # much load as a point load stepping on at the end (the jump is not moved; reference: that step's
    # integral ENTRY, against the trapezoidal rule on a fine grid; a ramp wholly outside gives 1.5 ENTRY)
    from scipy.integrate import trapezoid

    from sensorplan.diagnosis.joint.entry import entry_ramp

    u = np.linspace(-ENTRY, ENTRY, 4001)
    state = problem.state_at(problem.theta0)  # elastic ends (the spring effect's prior means)
    vertical = state.bridge.vertical_springs
    assert np.isfinite(vertical[0]) and np.isfinite(vertical[-1])
    g, _ = entry_ramp(u[None, :], state.bridge.length, ENTRY, (True, True))
    assert g[0, 2000] == pytest.approx(0.5)
    assert trapezoid(g[0], u) == pytest.approx(ENTRY, rel=1e-6)
    # inside the ramp the Jacobian (shift, springs, EI) still equals finite differences of the predictions,
    # with the rear axle just outside the end and just on the bridge
    for where in (-0.25 * ENTRY, 0.25 * ENTRY):
        theta = problem.theta0.copy()
        theta[sl.start] = -crossing + where
        _, jac = problem.predict(theta)[0]
        for j in [sl.start] + list(range(problem.n_elements, sl.start)) + [0, problem.n_elements - 1]:
            h = 1e-6 if j < problem.n_elements or j == sl.start else 1e-4
            up, down = theta.copy(), theta.copy()
            up[j] += h
            down[j] -= h
            fd = (problem.predict(up, jacobian=False)[0][0] - problem.predict(down, jacobian=False)[0][0]) / (2 * h)
            scale = max(np.abs(fd).max(), np.abs(jac[:, :, j]).max(), 1e-30)
            np.testing.assert_allclose(jac[:, :, j], fd, atol=2e-4 * scale, err_msg=problem.param_names[j])


def test_gains_act_on_the_response_and_drift_is_added_whatever_the_order():
    # a gain selected after a drift must not scale the drift (it then shrank the drift's prior cost and was
    # named as a false second cause): reading = gain * response + offset + slope * t, in either order
    case = small_case()
    data = simulate_crossings(case, 2, noise=True, rng=4)
    first = JointProblem(case, data, [make_effect("thermal_drift"), make_effect("sensor_gain")], GMRFPrior())
    second = JointProblem(case, data, [make_effect("sensor_gain"), make_effect("thermal_drift")], GMRFPrior())
    rng = np.random.default_rng(3)
    blocks = {n: 0.3 * rng.standard_normal(first.block(n)[1].stop - first.block(n)[1].start)
              for n in ("thermal_drift", "sensor_gain")}
    thetas = []
    for problem in (first, second):
        theta = problem.theta0.copy()
        for name, value in blocks.items():
            theta[problem.block(name)[1]] += value * (1e-6 if name == "thermal_drift" else 1.0)
        thetas.append(theta)
    (y1, _), (y2, _) = first.predict(thetas[0])[0], second.predict(thetas[1])[0]
    np.testing.assert_allclose(y1, y2, rtol=1e-12, atol=1e-18)
    # and the drift is not scaled: reading = gain * (response of the nominal model) + drift
    block, sl = first.block("sensor_gain")
    gain = block.detail * np.exp(thetas[0][sl])
    base = JointProblem(case, data, [], GMRFPrior())
    response = base.predict(base.theta0, jacobian=False)[0][0]
    x = data.crossings[0].positions
    t = (x - 0.5 * (x[0] + x[-1])) / (x[-1] - x[0])
    drift = thetas[0][first.block("thermal_drift")[1]][:2 * case.sensors.n_sensors].reshape(-1, 2)
    np.testing.assert_allclose(y1, gain[:, None] * response + drift[:, :1] + drift[:, 1:] * t[None, :],
                               rtol=1e-12, atol=1e-18)


def test_noise_rescale_reaches_the_evidence_maximum_in_the_noise_scale():
    # reference: the Laplace log evidence maximised over the noise scale directly (bounded scalar search,
    # a converged refit at each trial scale), not MacKay's fixed point that DiagnosisContext.rescaled iterates.  The data
    # carry twice the case's noise and a settled bearing the model lacks, and the search starts at 8x:
    # one fixed-point step from there stops short of the maximum
    from scipy.optimize import minimize_scalar

    from sensorplan.diagnosis.selection.candidate import Candidate
    from sensorplan.diagnosis.selection.context import DiagnosisContext
    from sensorplan.diagnosis.selection.refit import quick_fit

    case = small_case()
    truth = replace(case, noise=sp.NoiseModel(2.0 * case.noise.std, case.noise.correlation_length))
    vert = list(truth.bridge.vertical_springs)
    vert[1] = 2.0 * 48 * float(np.median(case.ei)) / case.bridge.spans[0] ** 3
    truth = replace(truth, bridge=sp.Bridge(truth.bridge.spans, truth.bridge.rotational_springs, tuple(vert)))
    data = simulate_crossings(truth, 4, noise=True, rng=7)
    prior = GMRFPrior()
    problem = JointProblem(case, data, [make_effect("sensor_offset")], prior)
    tau = 1.0
    start = quick_fit(problem, problem.theta0, 8.0 * 2.0, tau, max_iter=200)
    assert start.converged
    ctx = DiagnosisContext(case, data, prior=prior, effects={}, estimate_springs=True, noise_scale=16.0, tau=tau,
                           blocks={}, test_masks=[], predictions=[])
    ctx, rescaled = ctx.rescaled(Candidate(start))
    assert rescaled is None  # without folds the refit is not scored: the selection keeps its fit, at the new scale
    fit = quick_fit(problem, start.theta, ctx.noise_scale, tau, max_iter=200)

    def minus_evidence(log_alpha):
        f = quick_fit(problem, fit.theta, math.exp(log_alpha), tau, max_iter=200)
        assert f.converged
        return -f.log_evidence

    best = minimize_scalar(minus_evidence, bounds=(math.log(0.5), math.log(16.0)), method="bounded",
                           options={"xatol": 1e-4})
    assert ctx.noise_scale == pytest.approx(math.exp(best.x), rel=0.005)  # one fixed-point step: 2 % off
    assert fit.log_evidence == pytest.approx(-best.fun, abs=0.5)


def test_normal_equations_on_each_crossings_columns_equal_the_full_jacobian():
    # reference: J^T J, J^T r and |r|^2 from the full whitened rows (every column of every crossing,
    # JointProblem.rows) against evaluate, which forms each crossing's Jacobian on its own columns only;
    # AR(1) noise so that whitening mixes the rows, and effects with per-crossing parameters
    case = small_case()
    case = replace(case, noise=sp.NoiseModel(case.noise.std, 1.5))
    data = simulate_crossings(case, 3, noise=True, rng=2)
    effects = [make_effect(n) for n in ("thermal_drift", "position_offset", "dynamic_amplification", "sensor_gain")]
    problem = JointProblem(case, data, effects, GMRFPrior())
    rng = np.random.default_rng(3)
    theta = problem.theta0 + 0.05 * rng.standard_normal(problem.n_params) * np.sqrt(1.0 / np.diag(problem.fixed))
    r, jac, *_ = problem.rows(theta)
    lin = problem.evaluate(theta)
    assert sum(c.size for c in problem.columns) < problem.n_crossings * problem.n_params
    np.testing.assert_allclose(lin.jtj, jac.T @ jac, rtol=1e-10, atol=1e-10 * np.abs(jac.T @ jac).max())
    np.testing.assert_allclose(lin.jtr, jac.T @ r, rtol=1e-10, atol=1e-10 * np.abs(jac.T @ r).max())
    assert lin.rr == pytest.approx(float(r @ r), rel=1e-12)


def test_a_problem_sent_to_another_process_evaluates_the_same():
    # the screening and selection refits run in worker processes (--workers, Dask) and come back pickled; the
    # per-crossing column places were keyed by the effects' id(), which unpickling changes (KeyError in the
    # selection's noise-scale refit with --workers 2); reference: the problem that never left this process
    import pickle

    case = small_case()
    data = simulate_crossings(case, 2, noise=True, rng=4)
    effects = [make_effect(n) for n in ("thermal_drift", "position_offset", "sensor_gain")]
    problem = JointProblem(case, data, effects, GMRFPrior())
    theta = problem.theta0 + 0.01
    sent = pickle.dumps(problem)  # before any evaluation: nothing cached travels with it
    here = problem.evaluate(theta)
    there = pickle.loads(sent).evaluate(theta)
    assert there.rr == pytest.approx(here.rr, rel=1e-12)
    np.testing.assert_allclose(there.jtj, here.jtj, rtol=1e-12, atol=1e-12 * np.abs(here.jtj).max())

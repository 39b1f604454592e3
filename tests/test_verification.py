"""Verification of layouts by full Bayesian inversion of synthetic damage."""

import json
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import CandidateGrid, Case, example_case, recommend, verify_layouts
from sensorplan.verification.scenarios import element_average_ei, make_scenarios, truth_mesh


def two_span():
    bridge = sp.Bridge((15.0, 15.0))
    return Case(bridge, sp.Mesh.uniform(bridge, 30), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([5.0], noise_std=2e-6), sweep=sp.LoadSweep.from_range(0.0, 30.0, 0.25))


def test_crowded_layout_scores_worse_than_d_optimal():
    case = two_span()
    design = recommend(case, 3, 'D', curve_max=0, n_random=10, grid=CandidateGrid(spacing=0.5))
    crowded = [27.5, 28.5, 29.5]  # all sensors near the far end support
    result = verify_layouts(case, [design.layout_m, crowded], n_locations=12, severity=0.3, seed=3)
    best, worst = result.layouts
    m_best, se_best = best.metrics["detection_rate"]
    m_worst, se_worst = worst.metrics["detection_rate"]
    assert m_best - m_worst > math.hypot(se_best, se_worst), (best.metrics, worst.metrics)
    # the detector's centre of the losses it finds is close to the truth (the loss spans 2 m)
    assert best.metrics["localisation_error_m"].mean < 1.0


def test_control_coverage_and_false_alarm_reported():
    case = example_case("simply-supported")
    result = verify_layouts(case, [[0.0, 10.0, 20.0]], n_locations=2, n_controls=12, seed=5)
    score = result.layouts[0]
    coverage, se = score.metrics["control_coverage95"]
    assert 0.85 <= coverage <= 1.0
    false_alarm, _ = score.metrics["false_alarm_rate"]
    assert 0.0 <= false_alarm <= 0.2
    # the per-scenario records: 2 local losses, 1 span softening, 12 controls; every metric is the
    # mean over its scenarios with the standard error std(ddof=1) / sqrt(n)
    records = score.records
    assert [r.kind for r in records].count("control") == 12 and len(records) == score.n_scenarios == 15
    controls = [r for r in records if r.kind == "control"]
    damaged = [r for r in records if r.kind != "control"]
    for name, values in (("control_coverage95", [r.coverage95 for r in controls]),
                         ("false_alarm_rate", [r.false_alarm for r in controls]),
                         ("detection_rate", [r.detected for r in damaged if r.kind == "local"]),
                         ("rmse", [r.rmse for r in records])):
        assert score.metrics[name].mean == pytest.approx(np.mean(values), rel=1e-12)
        assert score.metrics[name].se == pytest.approx(np.std(values, ddof=1) / math.sqrt(len(values)), rel=1e-12)
    # the JSON form carries those numbers
    d = json.loads(json.dumps(result.to_dict()))["layouts"][0]
    assert d["layout_m"] == [0.0, 10.0, 20.0] and d["n_scenarios"] == 15
    for key in ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width",
                "control_coverage95"):
        metric = score.metrics[key]
        assert (d[key], d[key + "_se"]) == pytest.approx((metric.mean, metric.se), nan_ok=True)


def test_identical_results_for_one_or_two_workers():
    case = example_case("openlab-like")
    kwargs = dict(n_locations=3, n_controls=2, seed=11)
    one = verify_layouts(case, [[11.0, 19.0]], workers=1, **kwargs).to_dict()
    two = verify_layouts(case, [[11.0, 19.0]], workers=2, **kwargs).to_dict()
    assert one == two
    with ThreadPoolExecutor(2) as pool:  # any concurrent.futures executor
        other = verify_layouts(case, [[11.0, 19.0]], executor=pool, **kwargs).to_dict()
    assert other == one


def test_truth_mesh_is_finer_and_differently_aligned():
    case = example_case("three-span")
    fine = truth_mesh(case)
    assert fine.n_elements > 4 * case.n_elements
    inner_coarse = set(np.round(case.mesh.edges, 9)) - set(np.round(case.bridge.support_positions, 9))
    assert not inner_coarse & set(np.round(fine.edges, 9))
    # element averages of a uniform field are that field
    ei = np.full(fine.n_elements, 2e10)
    np.testing.assert_allclose(element_average_ei(fine, ei, case.mesh), 2e10, rtol=1e-12)
    # of any field, the compliance average EI_j = length_j / sum(overlap / EI_fine), from the overlaps
    ei = np.random.default_rng(0).uniform(1e10, 3e10, fine.n_elements)
    lo = np.maximum(fine.edges[None, :-1], case.mesh.edges[:-1, None])
    hi = np.minimum(fine.edges[None, 1:], case.mesh.edges[1:, None])
    overlap = np.clip(hi - lo, 0.0, None)
    np.testing.assert_allclose(element_average_ei(fine, ei, case.mesh), case.mesh.lengths / (overlap @ (1.0 / ei)),
                               rtol=1e-12)
    scen = make_scenarios(case, 5)
    local = [s for s in scen if s.kind == "local"]
    edges = case.mesh.edges
    for s in local:  # damage edges fall inside inversion elements
        assert np.min(np.abs(edges - s.start)) > 1e-6 and np.min(np.abs(edges - s.stop)) > 1e-6


def mixed_case():
    """A tiltmeter (2 urad) and a deflection sensor (0.05 mm) on a simple span."""
    bridge = sp.Bridge((20.0,))
    sensors = sp.SensorLayout([5.0, 10.0], kinds=["rotation", "deflection"], noise_std=[2e-6, 5e-5])
    return Case(bridge, sp.Mesh.uniform(bridge, 10), 1e10, sp.Vehicle.point_load(1e5), sensors,
                sweep=sp.LoadSweep.from_range(0.0, 20.0, 0.5))


def test_layout_sensors_take_the_noise_of_the_case_sensors_of_their_kind():
    # Reference: the documented default (Case.noise_std_for), the median noise of the case's sensors
    # of the same kind, here 5e-5 m for deflection sensors; not the median over both kinds,
    # which would use a noise level in rad as one in m.
    case = mixed_case()
    kwargs = dict(kind="deflection", n_locations=1, n_controls=1, n_crossings=2, seed=0)
    default = verify_layouts(case, [[6.0, 14.0]], **kwargs).to_dict()
    explicit = verify_layouts(case, [[6.0, 14.0]], noise_std=5e-5, **kwargs).to_dict()
    assert json.dumps(default) == json.dumps(explicit)  # (NaN standard errors compare equal as text)

"""Verification of layouts by full Bayesian inversion of synthetic damage."""

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import sensorplan as sp
from sensorplan.model.case import Case
from sensorplan.io.config import example_case
from sensorplan import CandidateGrid, recommend
from sensorplan.verification.verify import element_average_ei, make_scenarios, truth_mesh, verify_layouts


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
    d = result.to_dict()["layouts"][0]
    for key in ("layout_m", "n_scenarios", "rmse", "localisation_error_m", "detection_rate",
                "false_alarm_rate", "coverage95", "band_width"):
        assert key in d
        if key not in ("layout_m", "n_scenarios"):
            assert key + "_se" in d


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
    # element averages of a uniform field are that field; compliance averages exactly
    ei = np.full(fine.n_elements, 2e10)
    np.testing.assert_allclose(element_average_ei(fine, ei, case.mesh), 2e10, rtol=1e-12)
    scen = make_scenarios(case, 5)
    local = [s for s in scen if s.kind == "local"]
    edges = case.mesh.edges
    for s in local:  # damage edges fall inside inversion elements
        assert np.min(np.abs(edges - s.start)) > 1e-6 and np.min(np.abs(edges - s.stop)) > 1e-6

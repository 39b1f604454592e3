"""Design to a requirement (``recommend --target-power``) against independent checks.

* The worst-case power of the layout returned is recomputed here with
  ``detectability`` (the numbers ``sensorplan detectability`` prints).
* Minimality: every layout with one sensor fewer on the same candidate grid
  is enumerated here and evaluated with ``detectability``; none may reach
  the power.
* With the count capped below what is needed, ``crossings_needed`` is
  checked with ``detectability`` at that number (reaches the power) and at
  one fewer (does not).
* The exact search against plain enumeration of every layout.
"""

import itertools
import json
import math

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.design.exact import estimate_nodes, exact_search
from sensorplan.design.recommend import build_problem
from sensorplan.design.target_levels import levels
from sensorplan.detection.detectability import detectability
from sensorplan.io.config import example_case

POWER = 0.8
# (example, candidate spacing [m], centre step [m], crossings, count needed): coarse grids so that the
# brute force over one sensor fewer stays short; the counts were measured (and are checked below)
CASES = [("simply-supported", 1.0, 1.0, 1, 2), ("openlab-like", 2.0, 1.0, 400, 3), ("three-span", 4.0, 1.0, 1000, 3)]


def worst_power(case, layout, *, step, crossings, region=None):
    """Minimum over the zone centres (inside ``region``) of the power detectability reports."""
    m = detectability(case, layout=list(layout), step=step, n_crossings=crossings)
    inside = np.ones(m.n_centres, dtype=bool) if region is None else (
        (m.centres_m >= region[0] - 1e-9) & (m.centres_m <= region[1] + 1e-9))
    return float(m.power[inside].min())


def grid(case, spacing):
    return np.round(np.arange(0.0, case.bridge.length + 1e-9, spacing), 9)


def design(example, spacing, step, crossings, **options):
    return sp.design_for_target(example_case(example), power=POWER, n_crossings=crossings,
                                grid=sp.CandidateGrid(spacing=spacing), target=sp.DetectionTarget(step=step),
                                n_random=20, **options)


def check_minimal(example, spacing, step, crossings, needed):
    case = example_case(example)
    result = design(example, spacing, step, crossings)
    answer = result.answer
    assert answer.met and answer.count == needed and result.design.count == needed
    # the power claimed is what detectability computes for the layout
    independent = worst_power(case, result.design.layout_m, step=step, crossings=crossings)
    assert independent >= POWER - 0.01 and independent == pytest.approx(answer.worst_case_power, abs=1e-9)
    np.testing.assert_array_equal(result.design.candidates_m, grid(case, spacing))
    # no layout with one sensor fewer on the same grid reaches the power
    best = max(worst_power(case, layout, step=step, crossings=crossings)
               for layout in itertools.combinations(grid(case, spacing), needed - 1))
    assert best < POWER
    assert answer.minimality in ("relaxation bound", "exhaustive")
    assert answer.crossings_needed is None
    return result


def test_minimal_count_simply_supported():
    result = check_minimal(*CASES[0])
    assert [t.outcome for t in result.trials] == ["exhaustive", "reached"]
    assert result.headline().startswith("Sufficient: 2 rotation sensor(s) reach a worst-case power of 0.875 >= 0.8 "
                                        "for a 25 % EI loss over 2 m anywhere on the bridge")


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES[1:], ids=[c[0] for c in CASES[1:]])
def test_minimal_count_two_and_three_spans(case):
    check_minimal(*case)


@pytest.mark.parametrize("example,spacing,step,crossings,needed", CASES, ids=[c[0] for c in CASES])
def test_capped_count_reports_the_crossings_needed(example, spacing, step, crossings, needed):
    case = example_case(example)
    result = design(example, spacing, step, crossings, max_count=needed - 1)
    answer = result.answer
    assert not answer.met and answer.count == needed - 1
    layout = result.design.layout_m
    assert worst_power(case, layout, step=step, crossings=crossings) == pytest.approx(answer.worst_case_power,
                                                                                       abs=1e-9)
    n = answer.crossings_needed
    assert n > crossings
    assert worst_power(case, layout, step=step, crossings=n) >= POWER
    assert worst_power(case, layout, step=step, crossings=n - 1) < POWER
    assert result.headline().startswith(f"Not sufficient: with the cap of {needed - 1} rotation sensor(s) the "
                                        "worst-case power is ")
    assert f"{n} crossings would reach 0.8 with that layout" in result.headline()


def test_region_and_a_larger_loss():
    case = example_case("openlab-like")
    result = sp.design_for_target(case, power=0.9, n_crossings=20, region=(16.0, 29.0), grid=sp.CandidateGrid(
        spacing=1.0), target=sp.DetectionTarget(severity=0.5, length=3.0, step=1.0), n_random=10)
    answer = result.answer
    m = detectability(case, layout=list(result.design.layout_m), severity=0.5, length=3.0, step=1.0,
                      n_crossings=20)
    inside = (m.centres_m >= 16.0) & (m.centres_m <= 29.0)
    assert answer.met and float(m.power[inside].min()) == pytest.approx(answer.worst_case_power, abs=1e-9)
    assert answer.worst_case_power >= 0.9 and float(m.power.min()) < answer.worst_case_power
    assert "centred anywhere in 16-29 m" in result.headline()
    assert result.design.details["detection"]["region_m"] == [16.0, 29.0]


# ----------------------------------------------------------------------------------------------
# the exact search against enumeration

EXACT = {
    "none": ("openlab-like", 1.0, 3, {}),
    "min_spacing": ("three-span", 2.0, 3, {"min_spacing": 4.0}),
    "span_counts": ("three-span", 2.0, 3, {"min_spacing": 3.0, "span_max": (1, 1, 2)}),
    "budget": ("simply-supported", 1.0, 3, {"costs": np.linspace(1.0, 2.0, 21), "budget": 4.0}),
    "fixed": ("simply-supported", 1.0, 2, {"fixed": (10.0,)}),
}


@pytest.mark.parametrize("name", sorted(EXACT))
def test_exact_search_finds_every_layout_above_the_threshold(name):
    example, spacing, count, options = EXACT[name]
    case = example_case(example)
    problem = build_problem(case, count, "detect", grid=sp.CandidateGrid(spacing=spacing),
                            constraints=sp.Constraints(**options))
    layouts = [s for s in itertools.combinations(range(problem.n_candidates), count) if problem.feasible(s)]
    values = np.array([problem.value_of(s) for s in layouts])
    order = np.argsort(-values)
    for threshold in (values[order[0]] * (1 + 1e-9), values[order[0]] * (1 - 1e-9),
                      0.5 * (values[order[4]] + values[order[5]])):
        result = exact_search(problem, threshold, length=case.bridge.length, max_found=100)
        expected = {layouts[i] for i in np.nonzero(values >= threshold)[0]}
        assert result.complete and set(result.layouts) == expected, threshold
        assert list(result.values) == sorted(result.values, reverse=True)
    stopped = exact_search(problem, values[order[0]] * 2, length=case.bridge.length, max_nodes=10)
    assert not stopped.complete and stopped.layouts == ()


def test_node_estimate_tells_feasible_from_hopeless():
    case = example_case("openlab-like")
    problem = build_problem(case, 4, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=100)
    threshold = 6.0
    actual = exact_search(problem, threshold, length=case.bridge.length, max_nodes=10**7).nodes
    estimate = estimate_nodes(problem, threshold, length=case.bridge.length)
    assert actual / 5 <= estimate <= actual * 5
    assert estimate <= sum(math.comb(problem.n_candidates, r) for r in range(1, 5))


def test_a_search_over_its_limit_is_not_a_proof():
    result = design(*CASES[1][:4], max_nodes=5)
    answer = result.answer
    assert answer.met and answer.count == 3 and answer.minimality == "not proven"
    assert [t.outcome for t in result.trials] == ["not proven", "not proven", "reached"]
    assert result.trials[1].note.startswith("exact search not started: about ")
    assert result.headline().endswith("; whether fewer sensors could is not proven (the bound is not conclusive "
                                      "and an exhaustive search too long).")


def test_levels_cheapest_first_with_costs_per_kind():
    case = example_case("simply-supported")
    problem = build_problem(case, 1, "D", grid=sp.CandidateGrid(spacing=5.0, kinds=("rotation", "deflection")),
                            noise_std={"deflection": 1e-4}, constraints=sp.Constraints(
                                costs={"rotation": 1.0, "deflection": 3.0}, budget=4.0))
    assert levels(problem, 1, 3) == [(1, 1.0), (2, 2.0), (1, 3.0), (3, 3.0), (2, 4.0)]
    uniform = build_problem(case, 1, "D", grid=sp.CandidateGrid(spacing=5.0), constraints=sp.Constraints(
        costs=2.0, budget=5.0))
    assert levels(uniform, 1, 4) == [(1, 5.0), (2, 5.0)]


def test_cheapest_layout_with_costs_per_kind():
    case = example_case("simply-supported")
    result = sp.design_for_target(case, power=0.8, kind=("rotation", "deflection"),
                                  noise_std={"deflection": 2e-5},
                                  grid=sp.CandidateGrid(spacing=2.0, kinds=("rotation", "deflection")),
                                  constraints=sp.Constraints(costs={"rotation": 3.0, "deflection": 1.0}, budget=6.0),
                                  target=sp.DetectionTarget(step=1.0), n_random=10, max_count=3)
    answer = result.answer
    assert answer.met and answer.cost is not None and answer.cost == result.design.cost
    trials = result.trials
    assert [t.budget for t in trials] == sorted(t.budget for t in trials)  # cheapest level first
    assert all(t.outcome in ("relaxation bound", "exhaustive", "infeasible") for t in trials[:-1])
    assert trials[-1].outcome == "reached" and answer.cost <= trials[-1].budget
    # measured: one or two deflection sensors (cost 1, 2), ... up to three (cost 5) cannot; two tiltmeters can
    assert len(trials) == 7 and answer.cost == 6.0 and result.design.layout_kind == ("rotation", "rotation")
    assert result.headline().startswith("Sufficient: 2 rotation sensor(s) (cost 6) reach")
    assert result.headline().endswith("; a cheaper layout cannot (exhaustive search over every layout).")


# ----------------------------------------------------------------------------------------------
# command line

def test_cli_target_power_json_summary_and_progress(tmp_path, capsys):
    path = tmp_path / "design.json"
    code = main(["recommend", "--example", "simply-supported", "--target-power", "0.8", "--spacing", "1",
                 "--step", "1", "--json", str(path), "--out", str(tmp_path / "out")])
    assert code == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("Sufficient: 2 rotation sensor(s) reach a worst-case power of ")
    progress = [line for line in captured.err.splitlines() if "target power 0.8" in line]
    assert len(progress) >= 2 and all(line.startswith("sensorplan recommend: ") for line in progress)
    data = json.loads(path.read_text())
    target = data["target"]
    assert {k: target[k] for k in ("power", "met", "count", "crossings_needed")} == {
        "power": 0.8, "met": True, "count": 2, "crossings_needed": None}
    assert target["minimality"] == "exhaustive" and data["criterion"] == "detect" and data["count"] == 2
    case = example_case("simply-supported")
    assert worst_power(case, data["layout_m"], step=1.0, crossings=1) == pytest.approx(target["worst_case_power"],
                                                                                        abs=1e-12)
    code = main(["recommend", "--example", "simply-supported", "--target-power", "0.8", "--spacing", "1",
                 "--step", "1", "--count", "1", "--quiet", "--json", str(path), "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code == 0 and captured.err == "" and captured.out == ""
    target = json.loads(path.read_text())["target"]
    assert target["met"] is False and target["count"] == 1
    layout = json.loads(path.read_text())["layout_m"]
    n = target["crossings_needed"]
    assert worst_power(case, layout, step=1.0, crossings=n) >= 0.8 > worst_power(case, layout, step=1.0,
                                                                                   crossings=n - 1)


@pytest.mark.parametrize("argv,needle", [
    (["--target-power", "1.5"], "--target-power"),
    (["--target-power", "0.8", "--criterion", "A"], "--target-power designs detect-optimal layouts"),
    (["--target-power", "0.8", "--springs"], "drop --springs"),
    (["--target-power", "0.8", "--support-margin", "11"], "--support-margin"),
])
def test_cli_target_errors_are_one_line(tmp_path, capsys, argv, needle):
    code = main(["recommend", "--example", "simply-supported", "--spacing", "2", "--out", str(tmp_path)] + argv)
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and needle in err, err
    assert not (tmp_path / "design.json").exists()


def test_power_and_cap_errors_name_the_parameter():
    case = example_case("simply-supported")
    with pytest.raises(sp.ConfigError, match="'power'"):
        sp.design_for_target(case, power=1.0)
    with pytest.raises(sp.ConfigError, match="'max_count'"):
        sp.design_for_target(case, power=0.8, max_count=0)


@pytest.mark.parametrize("example,spacing,step,crossings,needed", CASES, ids=[c[0] for c in CASES])
def test_cli_capped_below_the_need(tmp_path, capsys, example, spacing, step, crossings, needed):
    path = tmp_path / "design.json"
    code = main(["recommend", "--example", example, "--target-power", "0.8", "--spacing", str(spacing), "--step",
                 str(step), "--crossings", str(crossings), "--count", str(needed - 1), "--seed", "1",
                 "--json", str(path), "--out", str(tmp_path / "out")])
    assert code == 0 and capsys.readouterr().out.startswith("Not sufficient: with the cap of ")
    data = json.loads(path.read_text())
    target, layout, case = data["target"], data["layout_m"], example_case(example)
    assert target["met"] is False and target["count"] == needed - 1 == len(layout)
    n = target["crossings_needed"]
    assert worst_power(case, layout, step=step, crossings=crossings) == pytest.approx(target["worst_case_power"],
                                                                                       abs=1e-12)
    assert worst_power(case, layout, step=step, crossings=n) >= 0.8 > worst_power(case, layout, step=step,
                                                                                   crossings=n - 1)

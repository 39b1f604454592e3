"""CLI: several sensor kinds, per-kind noise and cost, budgets, per-span counts, existing sensors; the ranking."""

import json
import math

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import CandidateGrid, Constraints, example_case, recommend
from sensorplan.cli import main
from sensorplan.verification.ranking import rank_layouts
from sensorplan.verification.results import LayoutScore, Metric, ScenarioRecord, VerificationResult

MIXED = ["--kind", "rotation,deflection", "--noise-std", "deflection=2e-6", "--cost", "rotation=1,deflection=2",
         "--budget", "5", "--per-span-min", "1,1", "--per-span-max", "2,2", "--keep-case-sensors", "--spacing", "1"]


def test_recommend_mixed_kinds_budget_and_existing_sensors(tmp_path, capsys):
    js = tmp_path / "d.json"
    assert main(["recommend", "--example", "openlab-like", "--count", "3", *MIXED, "--json", str(js),
                 "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    # reference: the Python API with the same options
    case = example_case("openlab-like")
    ref = recommend(case, 3, "D", grid=CandidateGrid(spacing=1.0, kinds=("rotation", "deflection")),
                    noise_std={"deflection": 2e-6},
                    constraints=Constraints(fixed=case.sensors, costs={"rotation": 1, "deflection": 2}, budget=5,
                                            span_min=(1, 1), span_max=(2, 2)))
    assert d["layout_m"] == list(ref.layout_m) and d["layout_kind"] == list(ref.layout_kind)
    assert d["value"] == pytest.approx(ref.value, rel=1e-9)
    assert len(d["layout_kind"]) == len(d["layout_m"]) == 3 and set(d["layout_kind"]) <= {"rotation", "deflection"}
    assert d["fixed_m"] == [11.0, 19.0] and d["fixed_kind"] == ["rotation", "rotation"]
    assert d["noise_std"] == {"rotation": 5e-6, "deflection": 2e-6} and d["budget"] == 5.0
    cost = sum({"rotation": 1, "deflection": 2}[k] for k in d["layout_kind"])
    assert d["cost"] == pytest.approx(cost) and cost <= 5
    spans = np.bincount(np.asarray(d["layout_m"]) >= 15.0, minlength=2)
    assert np.all(spans >= 1) and np.all(spans <= 2)
    assert all(abs(x - f) > 1e-9 or k != "rotation" for x, k in zip(d["layout_m"], d["layout_kind"])
               for f in (11.0, 19.0))
    for b in d["baselines"].values():
        if b is not None:
            assert len(b["layout_kind"]) == len(b["layout_m"]) and b["cost"] <= 5 + 1e-9
    printed = capsys.readouterr().out.splitlines()
    assert "  positions [m]: " + ", ".join(f"{x:.2f} ({k})" for x, k in zip(d["layout_m"], d["layout_kind"])) \
        in printed
    assert "  existing sensors [m]: 11.00 (rotation), 19.00 (rotation)" in printed
    assert f"  cost {cost:g} of a budget of 5" in printed


def test_recommend_existing_sensor_of_another_kind_takes_the_given_noise(tmp_path):
    js = tmp_path / "d.json"
    assert main(["recommend", "--example", "openlab-like", "--count", "2", "--fixed", "11:deflection,19",
                 "--noise-std", "deflection=1e-5", "--spacing", "2", "--json", str(js), "--out", str(tmp_path),
                 "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert d["fixed_kind"] == ["deflection", "rotation"] and d["fixed_noise_std"] == [1e-5, 5e-6]
    case = example_case("openlab-like")
    fixed = sp.SensorLayout([11.0, 19.0], ["deflection", "rotation"], noise_std=[1e-5, 5e-6])
    ref = recommend(case, 2, "D", grid=CandidateGrid(spacing=2.0), constraints=Constraints(fixed=fixed))
    assert d["layout_m"] == list(ref.layout_m) and d["value"] == pytest.approx(ref.value, rel=1e-9)
    # the existing deflection sensor's information counts: without it the criterion is lower
    alone = recommend(case, 2, "D", grid=CandidateGrid(spacing=2.0), constraints=Constraints(fixed=(19.0,)))
    assert d["value"] > alone.value


@pytest.mark.parametrize("extra, flag", [
    (["--kind", "rotation,strain"], "--kind"),
    (["--kind", "rotation,rotation"], "--kind"),
    (["--kind", "rotation,deflection"], "--noise-std"),  # the case has no deflection sensor to take it from
    (["--kind", "rotation,deflection", "--noise-std", "5e-6"], "--noise-std"),  # one value for two kinds
    (["--kind", "rotation", "--noise-std", "deflection=1e-4"], "--noise-std"),
    (["--cost", "rotation=-1", "--budget", "3"], "--cost"),
    (["--cost", "rotation=1"], "--cost"),  # a cost without a budget
    (["--cost", "rotation=2", "--budget", "3"], "--budget"),  # two sensors cost 4 at least
    (["--per-span-min", "1,1,1"], "--per-span-min"),
    (["--per-span-max", "1,x"], "--per-span-max"),
    (["--per-span-min", "2,1"], "--per-span-min"),  # more than the count
    (["--fixed", "11:strain"], "--fixed"),
    (["--fixed", "11:deflection"], "--fixed"),  # no noise known for an existing deflection sensor
])
def test_recommend_bad_kind_noise_cost_and_budget_input(tmp_path, capsys, extra, flag):
    argv = ["recommend", "--example", "openlab-like", "--count", "2", "--spacing", "2", *extra,
            "--out", str(tmp_path / "out")]
    assert main(argv) == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and flag in err[0] and "Traceback" not in captured.err, err
    assert not (tmp_path / "out").exists()  # nothing written


def _score(layout, detected, limit, loc=0.5, cov=0.95):
    common = dict(rmse=0.1, coverage95=cov, band_width=0.2, converged=1.0, statistic=0.0, threshold=1.0)
    records = [ScenarioRecord(kind="local", centre_m=0.0, detected=float(d), localisation_error_m=loc if d else None,
                              **common) for d in detected]
    records += [ScenarioRecord(kind="control", centre_m=0.0, false_alarm=0.0, **common)]
    return LayoutScore.from_records(layout, records, detection_limit=limit)


def test_ranking_by_verification_names_a_baseline_that_verifies_better():
    rec = _score([1.0, 2.0], [1, 0, 0, 0], 0.30)
    base = _score([5.0, 9.0], [1, 1, 1, 0], 0.70)
    tie = _score([3.0, 4.0], [1, 0, 0, 0], 0.30)  # equal to the recommended layout: not ranked above it
    result = VerificationResult((tie, rec, base), (), n_crossings=10, seed=0, severity=0.25, length=2.0,
                                names=("tie", "recommended", "even"))
    ranking = rank_layouts(result, criterion="D", values={"recommended": 10.0, "even": 9.0, "tie": 8.0})
    assert [e.name for e in ranking.entries] == ["even", "recommended", "tie"]
    assert ranking.verifies_better == ("even",)
    even = ranking.entries[0]
    # paired differences over the 4 local losses: (0, 1, 1, 0) -> mean 0.5, s.e. std(ddof=1)/2 = 0.57735/2
    assert even.detection_rate_diff == pytest.approx(0.5)
    assert even.detection_rate_diff_se == pytest.approx(np.std([0, 1, 1, 0], ddof=1) / 2)
    assert "detection_limit" in even.better_on and even.criterion == 9.0
    d = ranking.to_dict()
    assert d["baseline_verifies_better"] == ["even"] and d["verification_ranking"][0]["name"] == "even"
    text = ranking.summary()
    assert "NOTE: baseline even verifies better than the D-optimal layout" in text
    assert Metric.of([1, 0, 0, 0]).mean == pytest.approx(ranking.entries[1].detection_rate)
    # when the recommended layout is best, the summary says so and the list is empty
    alone = rank_layouts(VerificationResult((rec, tie), (), n_crossings=10, seed=0, severity=0.25, length=2.0,
                                            names=("recommended", "tie")), criterion="A")
    assert alone.verifies_better == () and "the A-optimal layout (recommended) verifies best." in alone.summary()
    # unnamed layouts are labelled by position, deflection sensors marked in a layout of mixed kinds
    mixed = LayoutScore.from_records([2.0, 13.0, 28.5], rec.records, detection_limit=0.3,
                                     layout_kind=("rotation", "deflection", "rotation"))
    assert mixed.label == "2, 13:deflection, 28.5" and rec.label == "1, 2"


@pytest.mark.slow
def test_verify_mixed_kind_layouts_match_the_python_api(tmp_path):
    js = tmp_path / "v.json"
    assert main(["verify", "--example", "openlab-like", "--layout", "2,13:deflection,28.5", "--layout", "11,19",
                 "--noise-std", "rotation=5e-6,deflection=2e-5", "--scenarios", "1", "--verify-crossings", "3",
                 "--seed", "2", "--json", str(js), "--out", str(tmp_path), "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert d["layouts"][0]["layout_kind"] == ["rotation", "deflection", "rotation"]
    assert d["layouts"][1]["layout_kind"] == ["rotation", "rotation"]
    case = example_case("openlab-like")
    mixed = sp.SensorLayout([2.0, 13.0, 28.5], ["rotation", "deflection", "rotation"], noise_std=[5e-6, 2e-5, 5e-6])
    ref = sp.verify_layouts(case, [mixed, [11.0, 19.0]], n_locations=1, n_crossings=3, seed=2).to_dict()
    for got, want in zip(d["layouts"], ref["layouts"]):
        for key in ("rmse", "coverage95", "detection_limit", "band_width"):
            assert got[key] == pytest.approx(want[key], rel=1e-12), key
    # the deflection sensor adds information: the mixed layout's detection limit exceeds that of its tiltmeters alone
    tilts = sp.verify_layouts(case, [[2.0, 28.5]], n_locations=1, n_crossings=3, seed=2).layouts[0]
    assert d["layouts"][0]["detection_limit"] > tilts.detection_limit
    assert math.isfinite(d["layouts"][0]["rmse"])


@pytest.mark.slow
def test_recommend_verify_ranks_by_verification(tmp_path, capsys):
    js = tmp_path / "d.json"
    assert main(["recommend", "--example", "simply-supported", "--count", "2", "--spacing", "2", "--verify",
                 "--scenarios", "2", "--verify-crossings", "3", "--json", str(js), "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    ranking = d["verification_ranking"]
    names = [e["name"] for e in d["verification"]["layouts"]]
    assert sorted(e["name"] for e in ranking) == sorted(names) and [e["rank"] for e in ranking] == list(
        range(1, len(names) + 1))
    # ordered by detection rate, then detection limit (from the verification's own numbers)
    by_name = {e["name"]: e for e in d["verification"]["layouts"]}
    keys = [(-by_name[e["name"]]["detection_rate"], -by_name[e["name"]]["detection_limit"]) for e in ranking]
    assert keys == sorted(keys)
    above = [e["name"] for e in ranking[:[e["name"] for e in ranking].index("recommended")]]
    assert d["baseline_verifies_better"] == above
    printed = capsys.readouterr().out
    for name in above:
        assert f"NOTE: baseline {name} verifies better than the D-optimal layout" in printed
    if not above:
        assert "the D-optimal layout (recommended) verifies best." in printed

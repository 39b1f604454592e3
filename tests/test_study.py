"""Design studies: recommend + verify over several cases, one table, wherever the work runs.

References: ``recommend`` and ``verify_layouts`` called one by one with the
same options and seed (what the study must reproduce row by row); the D
criterion's efficiency in closed form exp((value - bound) / n_params)
(design/criteria.py docstring, Atkinson & Donev 2007, ch. 10); a second copy
of a case under another name must give identical rows (cases do not share
noise draws with each other's work).
"""

import csv
import io
import json
import math
from dataclasses import replace

import pytest

import sensorplan as sp
from sensorplan import CandidateGrid, ConfigError, design_study, example_case, recommend, verify_layouts

OPTIONS = dict(criteria=["D"], counts=2, baselines=["equally_spaced"], n_scenarios=2, n_controls=1, n_crossings=3,
               spacing=2.0, seed=5)


@pytest.fixture(scope="module")
def study():
    case = example_case("simply-supported")
    return design_study([case, replace(case, name="copy")], **OPTIONS)


def test_rows_reproduce_recommend_and_verify_layouts(study):
    case = example_case("simply-supported")
    design = recommend(case, 2, "D", grid=CandidateGrid(spacing=2.0), kind=case.default_kind, rng=5, curve_max=0)
    even = design.baseline("equally_spaced")
    rows = [r for r in study.rows if r.case == "simply-supported"]
    assert [(r.layout, r.criterion, r.count) for r in rows] == [("recommended", "D", 2), ("equally_spaced", "D", 2)]
    assert rows[0].layout_m == design.layout_m and rows[1].layout_m == even.layout_m
    assert rows[0].value == pytest.approx(design.value) and rows[1].value == pytest.approx(even.value)
    assert rows[0].efficiency == pytest.approx(design.efficiency)
    # closed form of the D efficiency against the relaxation bound
    assert rows[1].efficiency == pytest.approx(math.exp(min(0.0, (even.value - design.bound) / design.n_params)))
    reference = verify_layouts(case, [design.layout_m, even.layout_m], n_locations=2, n_controls=1,
                               n_crossings=3, seed=5)
    for row, score in zip(rows, reference.layouts):
        m = score.metrics
        assert (row.detection_rate, row.detection_rate_se) == pytest.approx(tuple(m["detection_rate"]), nan_ok=True)
        assert (row.localisation_error_m, row.localisation_error_m_se) == pytest.approx(
            tuple(m["localisation_error_m"]), nan_ok=True)
        assert (row.coverage95, row.coverage95_se) == pytest.approx(tuple(m["coverage95"]), nan_ok=True)
        assert (row.false_alarm_rate, row.false_alarm_rate_se) == pytest.approx(tuple(m["false_alarm_rate"]),
                                                                              nan_ok=True)
        assert row.detection_limit == pytest.approx(score.detection_limit)
        assert row.n_scenarios == score.n_scenarios == 2 + 1 + 1


def test_cases_do_not_interfere(study):
    first = [r for r in study.rows if r.case == "simply-supported"]
    copy = [replace(r, case="simply-supported") for r in study.rows if r.case == "copy"]
    assert json.dumps([r.__dict__ for r in copy], sort_keys=True, default=list) == \
        json.dumps([r.__dict__ for r in first], sort_keys=True, default=list)


def test_table_as_columns_and_csv(study, tmp_path):
    cols = study.columns()
    assert list(cols) == list(sp.DesignStudy.COLUMNS) and all(len(v) == len(study.rows) for v in cols.values())
    path = tmp_path / "study.csv"
    text = study.to_csv(path)
    assert path.read_text(encoding="utf-8") == text
    parsed = list(csv.DictReader(io.StringIO(text)))
    assert len(parsed) == len(study.rows)
    for line, row in zip(parsed, study.rows):
        assert line["case"] == row.case and line["layout"] == row.layout
        assert [float(x) for x in line["layout_m"].split(";")] == list(row.layout_m)
        assert float(line["detection_rate"]) == pytest.approx(row.detection_rate, rel=1e-12)
    assert json.loads(json.dumps(study.to_dict()))["rows"][0]["layout_m"] == list(study.rows[0].layout_m)
    assert "Design study: 2 case(s), 4 rows" in study.summary()


@pytest.mark.slow
def test_local_cluster_gives_the_table_of_one_worker(study):
    pytest.importorskip("distributed")
    case = example_case("simply-supported")
    cluster = design_study([case, replace(case, name="copy")], workers=2, scheduler="local", **OPTIONS)
    assert cluster.to_csv() == study.to_csv()


@pytest.mark.parametrize("kwargs, field", [
    (dict(criteria=["Q"]), "criteria"),
    (dict(counts=0), "counts"),
    (dict(counts=[2, 1.5]), "counts"),
    (dict(cases=[]), "cases"),
    (dict(cases=[42]), "cases"),
    (dict(cases=["simply-supported", "simply-supported"]), "cases"),
])
def test_bad_input_names_the_field(kwargs, field):
    args = dict(cases=["simply-supported"], **OPTIONS)
    args.update(kwargs)
    with pytest.raises(ConfigError, match=f"'{field}'"):
        design_study(args.pop("cases"), **args)


def test_unknown_baseline_name_lists_the_choices():
    with pytest.raises(ConfigError, match="'baselines'.*equally_spaced"):
        design_study(["simply-supported"], **dict(OPTIONS, baselines=["evenly"]))

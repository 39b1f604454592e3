"""Rates a reader can trust: counts, Wilson intervals, "no detections", the false-alarm caveat.

References: scipy.stats.binomtest(k, n).proportion_ci(method="wilson") for the Wilson score interval
(Wilson 1927); the caveat's wording is that of issue 37 ("5 controls: a false-alarm rate of 0.20, 95 %
interval 0.04-0.62, cannot be told from the nominal 0.05").
"""

import dataclasses
import json
import math

import matplotlib
import pytest
from scipy import stats

from sensorplan.verification.ranking import rank_layouts
from sensorplan.verification.results import (
    LayoutScore,
    Metric,
    ScenarioRecord,
    VerificationResult,
    false_alarm_caveat,
    wilson_interval,
)
from sensorplan.verification.scenarios import Scenario

COMMON = dict(rmse=0.1, coverage95=0.95, band_width=0.2, converged=1.0, statistic=0.5, threshold=1.0)


@pytest.mark.parametrize("count, n", [(0, 1), (0, 5), (1, 5), (5, 5), (3, 17), (40, 100), (0, 200)])
def test_wilson_interval_is_scipys(count, n):
    want = stats.binomtest(count, n).proportion_ci(0.95, method="wilson")
    assert wilson_interval(count, n) == pytest.approx((want.low, want.high), abs=1e-12)


def test_a_rate_carries_its_count_and_interval():
    rate = Metric.rate([1.0, 0.0, None, 0.0, 0.0, 0.0])
    assert (rate.count, rate.n, rate.mean) == (1, 5, pytest.approx(0.2))
    assert rate.ci95 == pytest.approx(wilson_interval(1, 5))
    assert rate.text() == "0.20 (1/5; 95 % 0.04-0.62)"
    assert Metric.rate([0.0, 0.0]).text() == "0.00 (0/2; 95 % 0.00-0.66)"  # never 0.00 ± 0.00
    empty = Metric.rate([]).to_dict()
    assert (empty["n"], empty["count"], empty["ci95"]) == (0, 0, None) and math.isnan(empty["mean"])
    assert Metric.of([]).text(empty="no detections") == "no detections"
    assert "ci95" not in Metric.of([0.1, 0.2]).to_dict()


def _result(local, controls, *, names=("recommended",), localisation=None):
    """A verification of len(names) layouts: local losses detected as ``local`` (0/1), controls alarming as
    ``controls``."""
    records = [ScenarioRecord(kind="local", centre_m=5.0 + k, detected=float(d),
                              localisation_error_m=(localisation if d else None), **COMMON)
               for k, d in enumerate(local)]
    records += [ScenarioRecord(kind="control", centre_m=0.0, false_alarm=float(f), **COMMON) for f in controls]
    scenarios = tuple(Scenario("local", 4.0 + k, 6.0 + k, 0.25) for k in range(len(local))) + tuple(
        Scenario("control", 0.0, 0.0, 0.0) for _ in controls)
    scores = tuple(LayoutScore.from_records([2.0 + i, 9.0], records, detection_limit=0.4) for i in range(len(names)))
    return VerificationResult(scores, scenarios, n_crossings=10, seed=0, severity=0.25, length=2.0, names=names)


def test_summary_json_and_ranking_show_counts_and_intervals_never_nan():
    result = _result([0, 0], [1, 0, 0, 0, 0], names=("recommended", "even"))
    text = result.summary()
    assert "nan" not in text and "0.000±0.000" not in text and "0.00 ± 0.00" not in text
    row = next(line for line in text.splitlines() if line.startswith("  recommended "))
    assert "no detections" in row and "0.00 (0/2; 0.00-0.66)" in row and "0.20 (1/5; 0.04-0.62)" in row
    # the caveat of issue 37, once for both layouts
    caveats = [line for line in text.splitlines() if line.startswith("  caveat: ")]
    assert caveats == ["  caveat: 5 controls: a false-alarm rate of 0.20, 95 % interval 0.04-0.62, cannot be told "
                       "from the nominal 0.05 (more controls would narrow it)"]
    layout = json.loads(json.dumps(result.to_dict()))
    first = layout["layouts"][0]
    assert first["false_alarm_rate"] == pytest.approx(0.2) and first["false_alarm_rate_se"] is not None  # kept
    assert (first["false_alarm_rate_count"], first["false_alarm_rate_n"]) == (1, 5)
    assert first["false_alarm_rate_ci95"] == pytest.approx(list(wilson_interval(1, 5)))
    assert first["detection_rate_ci95"] == pytest.approx(list(wilson_interval(0, 2)))
    assert first["localisation_error_m"] is None and first["localisation_error_m_n"] == 0
    assert first["false_alarm_caveat"].startswith("5 controls: a false-alarm rate of 0.20")
    ranking = rank_layouts(result)
    assert "0.00 (0/2; 95 % 0.00-0.66)" in ranking.summary() and "nan" not in ranking.summary()
    assert ranking.to_dict()["verification_ranking"][0]["detection_rate_ci95"] == pytest.approx(
        list(wilson_interval(0, 2)))


@pytest.mark.parametrize("alarms, n, expected", [
    (0, 60, None),  # 95 % interval 0.00-0.06: tells a rate from 0.05 well enough
    (1, 5, "cannot be told from the nominal 0.05"),
    (0, 12, "cannot be told"),  # fewer than 20 controls
    (6, 60, "cannot be told"),  # 20+ controls but the interval reaches 0.20 > 3 x 0.05
    (10, 20, "above the nominal 0.05"),  # interval 0.30-0.70: the detector fires too often
])
def test_false_alarm_caveat(alarms, n, expected):
    text = false_alarm_caveat(Metric.rate([1.0] * alarms + [0.0] * (n - alarms)), 0.05)
    if expected is None:
        assert text is None
    else:
        assert expected in text and text.startswith(f"{n} controls: a false-alarm rate of {alarms / n:.2f}, 95 % "
                                                    "interval ")


def test_caveats_name_the_layouts_they_apply_to():
    result = _result([1], [0] * 30, names=("a", "b"))
    scores = list(result.layouts)
    noisy = LayoutScore.from_records(scores[1].layout_m, [r if r.kind == "local" else
                                                          dataclasses.replace(r, false_alarm=1.0)
                                                          for r in scores[1].records], detection_limit=0.4)
    mixed = dataclasses.replace(result, layouts=(scores[0], noisy))
    caveats = mixed.false_alarm_caveats()
    assert caveats == ["b: 30 controls: a false-alarm rate of 1.00, 95 % interval 0.89-1.00, above the nominal "
                       "0.05: the detector fires on undamaged bridges more often than calibrated"]


def test_empty_verification_panel_says_why():
    matplotlib.use("Agg")
    from sensorplan.plotting import plot_verification

    axes = plot_verification(_result([0, 0], [0] * 5))
    assert [t.get_text() for t in axes[1].texts] == [
        "no detections: no layout detected any of the local losses\n(every scan statistic above is below its "
        "threshold)"]
    assert len(plot_verification(_result([1, 0], [0] * 5, localisation=0.3))[1].texts) == 0


def test_a_ranking_note_on_identical_detections_says_so_not_plus_minus_zero():
    result = _result([1, 1], [0] * 5, names=("recommended", "random"))
    first, second = result.layouts
    closer = LayoutScore.from_records(second.layout_m, [dataclasses.replace(r, localisation_error_m=0.1)
                                                        if r.kind == "local" else r for r in second.records],
                                      detection_limit=0.4)  # ranks first by a smaller localisation error
    text = rank_layouts(dataclasses.replace(result, layouts=(first, closer))).summary()
    assert "detection rate the same, loss by loss" in text and "0.000 ± 0.000" not in text

"""The one verdict: its rules on constructed inputs whose answer is known by hand."""

import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import special

from sensorplan.verdict import STATUSES, Verdict, band_departures, inversion_verdict

EDGES = np.linspace(0.0, 30.0, 31)
NOMINAL = np.full(30, np.log(1e10))
STD = np.full(30, 0.05)
# Bonferroni quantile over 30 elements at a simultaneous 95 %: ndtri(1 - 0.025 / 30) = 3.14 (scipy)
Z30 = special.ndtri(1 - 0.025 / 30)


def _detection(detected, *, centre=20.5, length=2.0, loss=0.4):
    d = {"detected": detected, "false_alarm_rate": 0.05}
    return SimpleNamespace(detected=detected, centre_m=centre, length_m=length, loss=loss, loss_ci95=(0.3, 0.5),
                           false_alarm_rate=0.05, to_dict=lambda: d)


def _verdict(mean=NOMINAL, p=(0.5, 0.5), detection=None, noise_scale=1.0, probability=0.9):
    return inversion_verdict(edges=EDGES, log_mean=mean, log_std=STD, log_nominal=NOMINAL, residual_p=p,
                             residual_level=1e-3, sensor_names=("A", "B"), noise_scale=noise_scale,
                             noise_configured=True, detection=detection, damage_probability=probability)


def test_band_departure_found_where_the_nominal_leaves_the_band():
    mean = NOMINAL.copy()
    mean[20:22] += np.log(0.6)  # a 40 % loss over 20-22 m: z = log(0.6) / 0.05 = -10
    mean[5] += (Z30 - 0.1) * 0.05  # just inside the simultaneous band: not a departure
    out = band_departures(EDGES, mean, STD, NOMINAL)
    assert len(out) == 1
    assert out[0]["start"] == 20.0 and out[0]["stop"] == 22.0
    assert out[0]["loss"] == pytest.approx(0.4)


def test_precedence_model_error_over_damage_over_departure():
    mean = NOMINAL.copy()
    mean[20:22] += np.log(0.6)
    assert _verdict(mean, p=(1e-9, 0.5), detection=_detection(True)).status == "model_error"
    assert _verdict(mean, noise_scale=3.0, detection=_detection(True)).status == "model_error"
    v = _verdict(mean, detection=_detection(True))
    assert v.status == "local_damage" and v.location_m == (19.5, 21.5) and v.loss == 0.4
    v = _verdict(mean, detection=_detection(False))
    assert v.status == "departure" and v.location_m == (20.0, 22.0)
    assert _verdict(detection=_detection(False)).status == "no_change"
    assert _verdict(detection=None).status == "insufficient_data"
    # the detector fires but the posterior does not favour a loss: no damage headline
    doubted = _verdict(detection=_detection(True), probability=0.3)
    assert doubted.status == "no_change" and "0.30" in doubted.summary


def test_residuals_flagged_only_below_the_bonferroni_level():
    # level 1e-3 over two sensors (Bonferroni): a sensor is flagged below 5e-4
    assert _verdict(p=(4e-4, 0.5), detection=_detection(False)).status == "model_error"
    assert _verdict(p=(6e-4, np.nan), detection=_detection(False)).status == "no_change"


def test_verdict_is_json_and_rejects_unknown_status():
    v = _verdict(detection=_detection(False))
    assert v.status in STATUSES
    text = json.dumps(v.to_dict())
    assert json.loads(text)["status"] == "no_change"
    with pytest.raises(ValueError, match="status"):
        Verdict("damaged", "x")


def test_headline_agrees_with_status():
    mean = NOMINAL.copy()
    mean[20:22] += np.log(0.6)
    assert "local loss" in _verdict(mean, detection=_detection(True)).headline
    assert "no change" in _verdict(detection=_detection(False)).headline
    assert "model error" in _verdict(p=(1e-9, 1.0), detection=_detection(True)).headline


def test_without_the_detector_no_loss_is_concluded_and_data_are_not_called_insufficient():
    v = inversion_verdict(edges=EDGES, log_mean=NOMINAL, log_std=STD, log_nominal=NOMINAL, residual_p=(0.5, 0.5),
                          residual_level=1e-3, sensor_names=("A", "B"), noise_scale=1.0, noise_configured=True,
                          detection=None, detector_run=False)
    assert v.status == "no_change" and "not run" in v.summary

"""The inversion's verdict on simulated records of the embedded two-span bridge (issue 37's acceptance).

Truth from a finer mesh (0.2 m elements, the loss edges not on the
inversion's 1 m elements: no inverse crime), four tiltmeters, ten crossings,
the configured 5 µrad noise.  The expected statuses follow from what was
simulated: a 40 % loss over 20-22 m is a local loss; a settled middle
support (3e8 N/m) and a sensor logged with reversed sign are errors of the
model that no EI field explains; undamaged records show no change (the
detector's false-alarm rate is 5 %, the verdict's at most that).
"""

import dataclasses
import warnings

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.model.crossings import Crossing, Crossings
from sensorplan.model.sensors import SensorLayout
from sensorplan.model.structure import Mesh

CASE = sp.example_case("openlab-like").with_sensors(SensorLayout(
    np.array([4.0, 11.0, 19.0, 26.0]), kinds=("rotation",) * 4, names=("T1", "T2", "T3", "T4"), noise_std=5e-6))
FINE = CASE.with_mesh(Mesh.uniform(CASE.bridge, 150))
INVERT = CASE.with_mesh(Mesh.uniform(CASE.bridge, 30))


def _truth(loss=0.0, start=20.1, stop=22.1):
    ei = np.asarray(FINE.ei_at(FINE.mesh.midpoints), float).copy()
    ei[(FINE.mesh.midpoints > start) & (FINE.mesh.midpoints < stop)] *= 1.0 - loss
    return ei


def _verdict(data, *, warns=False):
    if not warns:
        return sp.invert(INVERT, data, rng=0).verdict
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", sp.SensorplanWarning)
        verdict = sp.invert(INVERT, data, rng=0).verdict
    assert any("systematic residuals" in str(w.message) for w in caught)  # the warning agrees with the verdict
    return verdict


def test_local_loss_is_found_where_it_is():
    v = _verdict(sp.simulate_crossings(FINE, 10, noise=True, rng=1, ei=_truth(0.4)))
    assert v.status in ("local_damage", "departure")
    centre = 0.5 * (v.location_m[0] + v.location_m[1])
    assert abs(centre - 21.1) <= 2.0


def test_settled_support_is_a_model_error():
    settled = dataclasses.replace(FINE.bridge, vertical_springs=(np.inf, 3e8, np.inf))
    v = _verdict(sp.simulate_crossings(FINE, 10, noise=True, rng=2, ei=_truth(), bridge=settled), warns=True)
    assert v.status == "model_error"
    assert v.next_step and "diagnose" in v.next_step


def test_reversed_sensor_is_a_model_error():
    data = sp.simulate_crossings(FINE, 10, noise=True, rng=3, ei=_truth())
    flip = np.array([1.0, -1.0, 1.0, 1.0])[:, None]
    data = Crossings(data.sensor_names, tuple(
        Crossing(c.label, c.positions, c.values * flip, c.load_factor) for c in data.crossings))
    assert _verdict(data, warns=True).status == "model_error"


@pytest.mark.slow
def test_undamaged_records_show_no_change():
    statuses = [_verdict(sp.simulate_crossings(FINE, 10, noise=True, rng=100 + k, ei=_truth())).status
                for k in range(20)]
    assert statuses.count("no_change") >= 18, statuses


def test_cli_invert_without_the_detector(tmp_path):
    import json

    from sensorplan.cli import main
    from sensorplan.io.csvio import write_crossings

    data = tmp_path / "d.csv"
    write_crossings(data, sp.simulate_crossings(sp.example_case("openlab-like"), 4, noise=True, rng=7))
    out = tmp_path / "p.json"
    assert main(["invert", "--example", "openlab-like", "--data", str(data), "--no-detect", "--json", str(out),
                 "--out", str(tmp_path), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["damage"] is None and result["verdict"]["status"] in ("no_change", "departure")
    assert "not run" in result["verdict"]["summary"] or result["verdict"]["status"] == "departure"

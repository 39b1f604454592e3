"""Sensors and supports: the support margin of the candidate grid, and the note on a sensor that sits on one."""

import json
import math

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.design.supports import keep_off_supports, support_notes
from sensorplan.io.config import example_case


def test_support_margin_keeps_every_candidate_off_the_supports():
    case = example_case("openlab-like")
    supports = case.bridge.support_positions
    grid = sp.CandidateGrid(spacing=0.5, support_margin=1.2)
    x = grid.candidates(case.bridge)
    assert np.abs(x[:, None] - supports[None, :]).min() >= 1.2 - 1e-9
    # exactly the grid points closer than 1.2 m to a support are gone: 0, 0.5, 1; 14-16; 29-30
    full = sp.CandidateGrid(spacing=0.5).candidates(case.bridge)
    assert full.size - x.size == 3 + 5 + 3
    result = sp.recommend(case, 3, "D", grid=grid, curve_max=0, n_random=5)
    assert np.abs(np.array(result.layout_m)[:, None] - supports[None, :]).min() >= 1.2 - 1e-9
    assert result.support_margin_m == 1.2 and result.to_dict()["support_margin_m"] == 1.2
    assert "candidates kept at least 1.2 m from every support" in result.summary()
    assert result.support_notes == ()
    default = sp.recommend(case, 3, "D", curve_max=0, n_random=5)
    assert "support_margin_m" not in default.to_dict() and "kept at least" not in default.summary()


def test_support_margin_applies_to_explicit_positions_and_is_checked():
    case = example_case("simply-supported")
    grid = sp.CandidateGrid(positions=(0.0, 0.5, 5.0, 19.5, 20.0), support_margin=1.0)
    np.testing.assert_array_equal(grid.candidates(case.bridge), [5.0])
    for bad in (-1.0, math.nan, "x"):
        with pytest.raises(sp.ConfigError, match="'support_margin'"):
            keep_off_supports([1.0, 2.0], [0.0], bad)
    with pytest.raises(sp.ConfigError, match="'support_margin' of 10.5 m removes every candidate"):
        sp.CandidateGrid(support_margin=10.5).candidates(case.bridge)


def test_what_a_sensor_on_a_support_reads():
    bridge = sp.Bridge(spans=(10.0, 10.0, 10.0), rotational_springs=(0.0, math.inf, 5e8, 0.0),
                       vertical_springs=(math.inf, 2e9, math.inf, math.inf))
    notes = support_notes(bridge, [0.0, 10.02, 10.0, 20.0, 0.03, 25.0], ["rotation", "rotation", "deflection",
                                                                         "rotation", "deflection", "rotation"])
    assert len(notes) == 5  # the sensor at 25 m is on no support
    pin, clamp, spring, rotational, rigid = notes
    assert pin.startswith("sensor at 0.00 m sits on the support at 0.00 m: a tiltmeter there still reads the "
                          "rotation")
    assert clamp.startswith("sensor at 10.02 m sits on the support at 10.00 m: a tiltmeter there reads nothing")
    assert "compression of the elastic bearing (2e+09 N/m)" in spring
    assert "rotational spring (5e+08 N·m/rad)" in rotational
    assert rigid.startswith("sensor at 0.03 m sits on the support at 0.00 m: a deflection sensor there reads "
                            "nothing (the rigid support does not move)")


def test_recommend_says_a_sensor_sits_on_a_support(tmp_path, capsys):
    case = example_case("simply-supported")
    result = sp.recommend(case, 2, "detect", grid=sp.CandidateGrid(spacing=1.0), n_crossings=10, curve_max=0,
                          n_random=5)
    assert result.layout_m == (0.0, 20.0)
    assert len(result.support_notes) == 2 and all(n in result.summary() for n in result.support_notes)
    assert "support_notes" not in result.to_dict()
    code = main(["recommend", "--example", "simply-supported", "--count", "2", "--criterion", "detect",
                 "--crossings", "10", "--spacing", "1", "--support-margin", "1.5", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0 and "sits on the support" not in out
    data = json.loads((tmp_path / "design.json").read_text())
    assert data["support_margin_m"] == 1.5
    assert min(abs(x - s) for x in data["layout_m"] for s in (0.0, 20.0)) >= 1.5

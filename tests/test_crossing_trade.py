"""What slower or more crossings buy: the crossing trade against an independent computation, and the CLI.

Reference (no sensorplan forward model or whitening): the Jacobian of the
readings in log EI by central finite differences of the independent
finite-element solve (tests/fe_reference.py), the noise covariance written
from the definitions of the time model (white std / sqrt(rate * dt) for a
reading that stands for the mean of the logger samples between readings, an
Ornstein-Uhlenbeck part, a random walk whose level at the start is
marginalised by the restricted precision of tests/test_noise_time.py), the
posterior covariance (Q + n F)^-1 inverted by numpy.
"""

import json
import math
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from fe_reference import fe_response
from test_noise_time import dense_covariance, restricted_precision

from sensorplan._errors import ConfigError
from sensorplan.cli import main
from sensorplan.design.crossing_trade import crossing_trade
from sensorplan.io.config import case_from_toml
from sensorplan.model.prior import GMRFPrior

SPAN, EI, N_EL = 12.0, 2e10, 6
WHITE, OU, TAU, WALK, RATE = 20e-6, 8e-6, 3.0, 2.5e-6, 50.0
CASE = f"""
[case]
name = "trade"
[bridge]
spans = [{SPAN}]
ei = {EI}
elements = {N_EL}
[vehicle]
axle_offsets = [0.0]
axle_loads = [100e3]
[sensors]
names = ["T1", "T2"]
positions = [1.0, 7.5]
kinds = ["rotation", "rotation"]
noise_std = [{WHITE}, {WHITE}]
[noise]
correlated_std = {OU}
correlation_time_s = {TAU}
random_walk = {WALK}
speed = 1.5
sample_rate = {RATE}
[loads]
start = 0.0
stop = {SPAN}
step = 0.4
"""


def reference_information(case, speed):
    """Sum over both sensors of J^T P J, J by central differences of the FE solve in log EI."""
    edges = case.mesh.edges
    x = case.sweep.positions
    sensors = [(p, "rotation") for p in case.sensors.positions]

    def readings(log_ei):
        out = np.zeros((len(sensors), x.size))
        for k, z in enumerate(x):
            if 0.0 <= z <= SPAN:
                out[:, k] = fe_response([SPAN], edges, np.exp(log_ei), [0.0, 0.0], [math.inf, math.inf],
                                        [(z, 100e3)], sensors)
        return out

    h = 1e-4
    base = np.full(N_EL, math.log(EI))
    jac = np.stack([(readings(base + h * e) - readings(base - h * e)) / (2 * h) for e in np.eye(N_EL)], axis=-1)
    t = (x - x[0]) / speed
    white = WHITE / math.sqrt(max(1.0, RATE * float(np.median(np.diff(t)))))
    prec = restricted_precision(dense_covariance(t, white, OU, TAU, WALK), True)
    return sum(j.T @ prec @ j for j in jac)


def test_posterior_std_equals_the_independent_computation():
    case = case_from_toml(CASE)
    speeds, counts = (0.5, 1.5, 4.0), (1, 3, 20)
    trade = crossing_trade(case, case.sensors, speeds=speeds, crossings=counts)
    q = GMRFPrior().precision(N_EL, 0)
    traces = []
    for i, v in enumerate(speeds):
        info = reference_information(case, v)
        traces.append(np.trace(info))
        for j, n in enumerate(counts):
            want = np.mean(np.sqrt(np.diag(np.linalg.inv(q + n * info))))
            assert trade.posterior_std[i, j] == pytest.approx(want, rel=1e-6)
    ref = np.trace(reference_information(case, 1.5))
    np.testing.assert_allclose(trade.information, np.array(traces) / ref, rtol=1e-6)
    assert trade.prior_std == pytest.approx(np.mean(np.sqrt(np.diag(np.linalg.inv(q)))), rel=1e-10)
    # more crossings never hurt
    assert np.all(np.diff(trade.posterior_std, axis=1) < 0)


def test_the_wander_caps_what_slower_crossings_buy():
    case = case_from_toml(CASE)
    trade = crossing_trade(case, case.sensors, speeds=np.geomspace(0.02, 20.0, 13))
    # white noise averages (the gain grows as the speed falls) until the walk over the longer crossing wins
    assert trade.capped and trade.speeds[0] < trade.best_speed < trade.speeds[-1]
    peak = int(np.argmax(trade.information))
    assert trade.information[0] < trade.information[peak] > trade.information[-1]
    quiet = case_from_toml(CASE.replace(f"random_walk = {WALK}", "random_walk = 0.0"))
    assert not crossing_trade(quiet, quiet.sensors, speeds=np.geomspace(0.02, 20.0, 13)).capped
    text = trade.summary()
    assert "most information at" in text and "<- case" not in text
    assert json.loads(json.dumps(trade.to_dict()))["capped_by_wander"] is True


def test_without_a_time_model_it_says_so():
    case = case_from_toml(CASE.split("[noise]")[0] + "[loads]" + CASE.split("[loads]")[1])
    with pytest.raises(ConfigError, match="noise model in time"):
        crossing_trade(case, case.sensors)


def test_recommend_and_verify_take_the_speed(tmp_path, capsys):
    config = tmp_path / "case.toml"
    config.write_text(CASE)
    values = {}
    for speed in ("0.5", "1.5", None):
        out = tmp_path / f"r{speed}.json"
        argv = ["recommend", "--config", str(config), "--count", "2", "--spacing", "1.0", "--json", str(out),
                "--out", str(tmp_path), "--quiet"]
        assert main(argv + ([] if speed is None else ["--speed", speed])) == 0
        values[speed] = json.loads(out.read_text())
    # the default is the case's speed; another speed is another design problem, and the JSON says which
    assert values[None]["value"] == values["1.5"]["value"] != values["0.5"]["value"]
    assert values["0.5"]["crossing_trade"]["speed_m_s"] == 0.5
    assert values[None]["crossing_trade"]["speed_m_s"] == 1.5
    out = tmp_path / "v.json"
    assert main(["verify", "--config", str(config), "--layout", "1,7.5", "--scenarios", "2", "--speed", "0.5",
                 "--json", str(out), "--out", str(tmp_path), "--quiet"]) == 0
    assert out.exists()
    white = tmp_path / "white.toml"
    white.write_text(CASE.split("[noise]")[0] + "[loads]" + CASE.split("[loads]")[1])
    capsys.readouterr()
    assert main(["recommend", "--config", str(white), "--count", "2", "--speed", "0.5", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert "--speed" in err and "\n" not in err

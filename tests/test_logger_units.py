"""Logger units and time bases (io/logger.py, io/logger_checks.py) and ``sensorplan noise`` through ``main``.

Records come from the independent simulator tests/logger_sim.py, written in
the unit under test; the reader must give back the simulator's SI values.
"""

import json
import math
import pathlib
import sys
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from logger_sim import Channel, record, write_csv  # noqa: E402
from sensorplan._errors import ConfigError, DataError  # noqa: E402
from sensorplan.cli import main  # noqa: E402
from sensorplan.io.config import case_from_toml, load_case, load_logger_format  # noqa: E402
from sensorplan.io.logger import read_timeseries  # noqa: E402

CASE = """
[bridge]
spans = [20.0]
ei = 2.0e9
[vehicle]
axle_offsets = [0.0]
axle_loads = [1.0e5]
[sensors]
names = ["INC01", "LVDT"]
positions = [5.0, 10.0]
kinds = ["rotation", "deflection"]
noise_std = [2.0e-5, 1.0e-5]
"""
TILT = Channel("INC01", 5.0)
DEFLECTION = Channel("LVDT", 10.0, kind="deflection", white=1e-5, correlated=4e-6, tau=2.0, walk=2e-7)
DEG = math.pi / 180.0


def _case(tmp_path, logger=""):
    path = tmp_path / "case.toml"
    path.write_text(CASE + ("[logger]\n" + logger if logger else ""))
    return path


def _read(tmp_path, log, logger=""):
    path = _case(tmp_path, logger)
    return read_timeseries(log, load_case(path).sensors, load_logger_format(path))


@pytest.fixture(scope="module")
def sim():
    time, values, _ = record(30.0, 100.0, [TILT, DEFLECTION], rng=5)
    return time, values


@pytest.mark.parametrize("unit, factor", [("deg", DEG), ("mdeg", DEG * 1e-3), ("mm/m", 1e-3), ("urad", 1e-6),
                                          ("rad", 1.0)])
def test_tilt_units_convert_to_rad(tmp_path, sim, unit, factor):
    time, values = sim
    scaled = values / np.array([[factor], [1e-3]])  # the deflection in mm
    write_csv(tmp_path / "log.csv", time, [TILT, DEFLECTION], scaled)
    series = _read(tmp_path, tmp_path / "log.csv", f'tilt_unit = "{unit}"\ndeflection_unit = "mm"\n')
    assert np.allclose(series.values, values, rtol=1e-12, atol=0.0)
    assert np.allclose(series.time, time)


def test_milliseconds_by_column_name_or_time_unit(tmp_path, sim):
    time, values = sim
    write_csv(tmp_path / "log.csv", time, [TILT, DEFLECTION], values, time_scale=1e-3)
    text = (tmp_path / "log.csv").read_text()
    (tmp_path / "ms.csv").write_text(text.replace("time_s,", "time_ms,", 1))
    assert np.allclose(_read(tmp_path, tmp_path / "ms.csv").time, time)
    assert np.allclose(_read(tmp_path, tmp_path / "log.csv", 'time_unit = "ms"\n').time, time)
    with pytest.raises(DataError, match="'time_ms' but \\[logger\\] time_unit is \"s\""):
        _read(tmp_path, tmp_path / "ms.csv", 'time_unit = "s"\n')


def _iso_log(path, time, values, stamp):
    rows = ["time_s,INC01,LVDT"] + [f"{stamp(float(t))},{float(a)!r},{float(b)!r}" for t, a, b in zip(time, *values)]
    path.write_text("\n".join(rows) + "\n")


def test_iso_timestamps_naive_and_aware(tmp_path, sim):
    time, values = sim
    start = datetime(2022, 3, 7, 16, 35, 15, 600000)
    _iso_log(tmp_path / "naive.csv", time, values, lambda t: (start + timedelta(seconds=t)).isoformat(sep=" "))
    series = _read(tmp_path, tmp_path / "naive.csv")
    assert np.allclose(series.time, time, atol=1e-6) and series.start == "2022-03-07T16:35:15.600000"
    # aware, crossing a change of offset (a DST switch written as local time with its offset): elapsed time counts
    utc = datetime(2022, 3, 27, 0, 59, 50, tzinfo=timezone.utc)

    def local(t):
        moment = utc + timedelta(seconds=t)
        offset = timezone(timedelta(hours=1 if moment.hour < 1 else 2))
        return moment.astimezone(offset).isoformat()

    _iso_log(tmp_path / "aware.csv", time, values, local)
    assert np.allclose(_read(tmp_path, tmp_path / "aware.csv").time, time, atol=1e-6)
    lines = (tmp_path / "aware.csv").read_text().splitlines()
    lines[5] = lines[5].replace("+01:00", "")  # file line 6
    (tmp_path / "mixed.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match="row 6, column 'time_s' mixes timestamps with and without a time zone"):
        _read(tmp_path, tmp_path / "mixed.csv")


def test_a_time_column_named_time(tmp_path, sim):
    time, values = sim
    start = datetime(2022, 3, 7, 16, 35, 15, 600000)
    _iso_log(tmp_path / "iso.csv", time, values, lambda t: (start + timedelta(seconds=t)).isoformat())
    text = (tmp_path / "iso.csv").read_text().replace("time_s,", "time,", 1)
    (tmp_path / "iso.csv").write_text(text)
    assert np.allclose(_read(tmp_path, tmp_path / "iso.csv").time, time, atol=1e-6)
    write_csv(tmp_path / "num.csv", time, [TILT, DEFLECTION], values, time_scale=1e-3)
    (tmp_path / "num.csv").write_text((tmp_path / "num.csv").read_text().replace("time_s,", "time,", 1))
    assert np.allclose(_read(tmp_path, tmp_path / "num.csv", 'time_unit = "ms"\n').time, time)
    with pytest.raises(DataError, match="column 'time' holds numbers without a unit; name it time_s or time_ms"):
        _read(tmp_path, tmp_path / "num.csv")


def test_a_time_column_in_ms_declared_as_s_is_caught(tmp_path, sim):
    time, values = sim
    write_csv(tmp_path / "log.csv", time, [TILT, DEFLECTION], values, time_scale=1e-3)
    with pytest.raises(DataError, match="median sample interval of 10 s.*name the column time_ms or set "
                                        "\\[logger\\] time_unit = \"ms\""):
        _read(tmp_path, tmp_path / "log.csv")
    write_csv(tmp_path / "s.csv", time, [TILT, DEFLECTION], values)  # seconds declared as ms: 100 kHz
    with pytest.raises(DataError, match="time_unit = \"s\""):
        _read(tmp_path, tmp_path / "s.csv", 'time_unit = "ms"\n')


def test_degrees_declared_as_rad_are_caught(tmp_path, sim):
    time, values = sim
    write_csv(tmp_path / "log.csv", time, [TILT, DEFLECTION], values / np.array([[DEG], [1.0]]))
    with pytest.raises(DataError, match="column 'INC01' read in 'rad' has a sample-to-sample noise of 0.001[0-9]* rad.*"
                                        "tilt_unit .*\"deg\""):
        _read(tmp_path, tmp_path / "log.csv")
    write_csv(tmp_path / "mm.csv", time, [TILT, DEFLECTION], values / np.array([[1.0], [1e-3]]))
    with pytest.raises(DataError, match="column 'LVDT' read in 'm'.*deflection_unit .*\"mm\""):
        _read(tmp_path, tmp_path / "mm.csv")


def test_logger_section_keys():
    with pytest.raises(ConfigError, match="time_unit"):
        case_from_toml(CASE + '[logger]\ntime_unit = "min"\n')
    with pytest.raises(ConfigError, match="tilt_unit"):
        case_from_toml(CASE + '[logger]\ntilt_unit = "gon"\n')


# ---- sensorplan noise through main ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def degree_log(tmp_path_factory):
    """Five minutes at 20 Hz, the tilt in degrees and the deflection in mm, ISO timestamps."""
    folder = tmp_path_factory.mktemp("noise")
    time, values, _ = record(300.0, 20.0, [TILT, DEFLECTION], rng=9)
    start = datetime(2022, 4, 11, 8, 36, 24, 897000)
    _iso_log(folder / "log.csv", time, values / np.array([[DEG], [1e-3]]),
             lambda t: (start + timedelta(seconds=t)).isoformat(sep=" ", timespec="milliseconds"))
    (folder / "case.toml").write_text(CASE + '[logger]\ntilt_unit = "deg"\ndeflection_unit = "mm"\n')
    return folder


def test_cli_noise_prints_writes_json_figure_and_case(degree_log, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["noise", "--config", str(degree_log / "case.toml"), "--timeseries", str(degree_log / "log.csv"),
                 "--json", str(tmp_path / "noise.json"), "--out", str(out), "--write-case",
                 str(tmp_path / "case-noise.toml"), "--speed", "1.5"])
    text = capsys.readouterr().out
    assert code == 0
    assert "INC01 (rotation)" in text and "urad" in text and "LVDT (deflection)" in text and " mm" in text
    assert "quiet parts:" in text and "Allan deviation" in text
    data = json.loads((tmp_path / "noise.json").read_text())
    tilt = data["channels"][0]
    # 5 minutes at 20 Hz: the white std is tight, the rest loose (their own standard errors say so)
    assert abs(tilt["white_std"]["value"] / TILT.white - 1.0) < 0.05
    assert tilt["white_std"]["std_error"] > 0.0 and len(tilt["allan_deviation"]["tau_s"]) >= 8
    assert (out / "allan_deviation.png").stat().st_size > 10_000
    assert "allan_deviation.png" in (out / ".sensorplan-manifest.json").read_text()
    case = load_case(tmp_path / "case-noise.toml")
    assert case.noise.std[0] == pytest.approx(tilt["white_std"]["value"])
    assert case.noise.std[1] == pytest.approx(data["channels"][1]["white_std"]["value"])
    if "correlated_std" in (tmp_path / "case-noise.toml").read_text():  # a case writer with the [noise] time keys
        for key in ("correlated_std", "correlation_time_s", "random_walk"):
            assert getattr(case.noise, key)[0] == pytest.approx(tilt[key]["value"])
        assert case.noise.speed == 1.5


@pytest.mark.parametrize("logger, message", [
    ('tilt_unit = "rad"\ndeflection_unit = "mm"\n', "column 'INC01' read in 'rad'"),
    ('tilt_unit = "deg"\ndeflection_unit = "mm"\ntime_unit = "ms"\n', ""),  # ISO times need no unit: read
])
def test_cli_noise_unit_slip_is_one_line_and_writes_nothing(degree_log, tmp_path, capsys, logger, message):
    case = tmp_path / "case.toml"
    case.write_text(CASE + "[logger]\n" + logger)
    code = main(["noise", "--config", str(case), "--timeseries", str(degree_log / "log.csv"), "--json",
                 str(tmp_path / "noise.json"), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    if message:
        assert code == 1 and message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
        assert not (tmp_path / "noise.json").exists() and not (tmp_path / "out").exists()
    else:
        assert code == 0 and (tmp_path / "noise.json").exists()


def test_cli_noise_write_case_needs_a_speed(degree_log, tmp_path, capsys):
    code = main(["noise", "--config", str(degree_log / "case.toml"), "--timeseries", str(degree_log / "log.csv"),
                 "--json", str(tmp_path / "noise.json"), "--write-case", str(tmp_path / "c.toml")])
    err = capsys.readouterr().err
    assert code == 1 and "--speed" in err and not (tmp_path / "noise.json").exists()


def test_cli_noise_reads_a_ms_time_base_and_catches_it_declared_as_s(tmp_path, capsys):
    time, values, _ = record(240.0, 20.0, [TILT, DEFLECTION], rng=3)
    write_csv(tmp_path / "log.csv", time, [TILT, DEFLECTION], values, time_scale=1e-3)  # ms under 'time_s'
    (tmp_path / "ms.csv").write_text((tmp_path / "log.csv").read_text().replace("time_s,", "time_ms,", 1))
    case = _case(tmp_path)
    code = main(["noise", "--config", str(case), "--timeseries", str(tmp_path / "ms.csv"), "--rate", "5",
                 "--json", str(tmp_path / "ok.json"), "--quiet"])
    assert code == 0
    assert json.loads((tmp_path / "ok.json").read_text())["sample_interval_s"] == pytest.approx(0.2)
    code = main(["noise", "--config", str(case), "--timeseries", str(tmp_path / "log.csv"), "--json",
                 str(tmp_path / "slip.json")])
    err = capsys.readouterr().err
    assert code == 1 and len(err.strip().splitlines()) == 1 and "time_unit = \"ms\"" in err
    assert not (tmp_path / "slip.json").exists()

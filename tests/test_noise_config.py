"""The noise model in time in a case file: keys, checks, the one rule for new sensors, round trip."""

import dataclasses

import numpy as np
import pytest

from sensorplan._errors import ConfigError
from sensorplan.io.case_writer import case_to_toml
from sensorplan.io.config import case_from_toml, example_case
from sensorplan.model.noise import NoiseModel
from sensorplan.model.sensors import SensorLayout

TIME = "\ncorrelated_std = 9e-6\ncorrelation_time_s = 3.0\nrandom_walk = 2.5e-6\nspeed = 1.5\nsample_rate = 100.0\n"


def case_text(noise_lines=TIME):
    text = case_to_toml(example_case("openlab-like"))
    head, _, tail = text.partition("[noise]")
    rest = tail.split("\n[", 1)
    return head + "[noise]" + noise_lines + ("\n[" + rest[1] if len(rest) > 1 else "")


def test_time_keys_are_read_and_written_back():
    case = case_from_toml(case_text())
    noise = case.noise
    assert noise.in_time and noise.speed == 1.5 and noise.sample_rate == 100.0
    np.testing.assert_array_equal(noise.correlation_time_s, [3.0, 3.0])
    again = case_from_toml(case_to_toml(case))
    assert again.noise.cache_key == noise.cache_key


def test_per_sensor_lists_are_read():
    case = case_from_toml(case_text("\ncorrelated_std = [9e-6, 4e-6]\ncorrelation_time_s = [3.0, 1.0]\n"
                                    "random_walk = 0.0\nspeed = 1.0\n"))
    np.testing.assert_array_equal(case.noise.correlated_std, [9e-6, 4e-6])
    assert not np.any(case.noise.random_walk)


@pytest.mark.parametrize("lines, field", [
    ("\ncorrelated_std = 9.0\ncorrelation_time_s = 3.0\nspeed = 1.0\n", "correlated_std"),  # urad given as rad
    ("\nrandom_walk = 0.5\nspeed = 1.0\n", "random_walk"),
    ("\ncorrelated_std = 9e-6\ncorrelation_time_s = 1e6\nspeed = 1.0\n", "correlation_time_s"),
    ("\nrandom_walk = 1e-6\nspeed = 360.0\n", "speed"),  # km/h given as m/s... or a typo
    ("\nrandom_walk = 1e-6\n", "speed"),
    ("\nrandom_walk = [1e-6, 1e-6, 1e-6]\nspeed = 1.0\n", "random_walk"),
    ("\nrandom_walk = \"fast\"\nspeed = 1.0\n", "random_walk"),
    ("\nrandom_walk = 1e-6\nspeed = 1.0\nsample_rate = 1e9\n", "sample_rate"),
    ("\ncorrelated_std = 9e-6\nspeed = 1.0\n", "correlation_time_s"),
    ("\ncorrelation_length = 0.5\nrandom_walk = 1e-6\nspeed = 1.0\n", "correlation_length"),
])
def test_bad_noise_keys_name_the_field(lines, field):
    with pytest.raises(ConfigError, match=field) as info:
        case_from_toml(case_text(lines))
    assert "\n" not in str(info.value)


def test_new_sensors_take_the_time_model_of_their_kind():
    case = case_from_toml(case_text("\ncorrelated_std = [9e-6, 5e-6]\ncorrelation_time_s = [3.0, 1.0]\n"
                                    "random_walk = [2e-6, 4e-6]\nspeed = 2.0\n"))
    new = SensorLayout([3.0, 7.0, 20.0], ("rotation", "rotation", "rotation"), None, [1e-6, 2e-6, 3e-6])
    noise = case.with_sensors(new).noise
    # each parameter the median of the case's rotation sensors (two: the mean of the two values)
    np.testing.assert_allclose(noise.correlated_std, 7e-6)
    np.testing.assert_allclose(noise.correlation_time_s, 2.0)
    np.testing.assert_allclose(noise.random_walk, 3e-6)
    np.testing.assert_array_equal(noise.std, [1e-6, 2e-6, 3e-6])
    assert noise.speed == 2.0
    unknown = SensorLayout([3.0], ("rotation",), None, None)
    np.testing.assert_allclose(case.with_sensors(unknown).noise.std, np.median(case.noise.std))


def test_without_a_time_model_new_sensors_keep_the_correlation_length():
    base = example_case("openlab-like")
    case = dataclasses.replace(base, noise=NoiseModel(base.noise.std, 0.5))
    new = SensorLayout([3.0], ("rotation",), None, [1e-6])
    assert case.with_sensors(new).noise.correlation_length == 0.5


def test_a_written_case_keeps_its_logger_section():
    from sensorplan.io.config import load_logger_format
    from sensorplan.model.timeseries import LoggerFormat

    logger = LoggerFormat(temperature_columns=("T_deck",), tilt_unit="deg", time_unit="ms")
    case = case_from_toml(case_text())
    text = case_to_toml(case, logger=logger)
    import pathlib
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / "case.toml"
        path.write_text(text)
        assert load_logger_format(path) == logger
    assert "[logger]" not in case_to_toml(case, logger=LoggerFormat())

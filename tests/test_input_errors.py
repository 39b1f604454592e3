"""Bad input gets a one-line error naming the field and the fix.

The project rule: a malformed config, sensors off the bridge, NaNs, wrong
columns or unit slips give one line on stderr ("sensorplan simulate: error:
..."), exit code 1, no traceback, no silent wrong answer and no partially
written output file.  The library raises ``ConfigError`` / ``DataError``
(both ``ValueError``) and nothing else.
"""

import contextlib
import copy
import csv
import io
import json
import math
import re
import tomllib
from importlib import resources

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sensorplan
from sensorplan import (ConfigError, Crossing, Crossings, DataError, example_case, load_case, read_crossings,
                        simulate_crossings, write_crossings)
from sensorplan.cli import main
from sensorplan.io.config import _KEYS

INF = math.inf
NAN = math.nan
PREFIX = "sensorplan simulate: error:"


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def _example_text(name="openlab-like"):
    return resources.files("sensorplan.examples").joinpath(f"{name}.toml").read_text("utf-8")


def base_dict():
    """The openlab-like example as a plain dict (a fresh deep copy each time)."""
    return tomllib.loads(_example_text())


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _toml_key(key):
    return key if _BARE_KEY.fullmatch(key) else json.dumps(key, ensure_ascii=False)


def _toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot serialise {value!r} to TOML")


def dumps_toml(data):
    """A tiny TOML writer: top-level scalars first, then one [table] per dict."""
    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for name, table in data.items():
        if isinstance(table, dict):
            lines.append(f"[{_toml_key(name)}]")
            lines.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in table.items())
    return "\n".join(lines) + "\n"


def test_toml_serialiser_round_trips_the_example():
    data = base_dict()
    assert tomllib.loads(dumps_toml(data)) == data


def run_cli(argv, capsys=None):
    """Run the CLI and return (exit code, stdout, stderr).

    With ``capsys`` the streams come from pytest's capture; without it (inside
    hypothesis tests, where function-scoped fixtures are shared between
    examples) from a redirection.  An escaping exception fails the test.
    """
    argv = [str(a) for a in argv]
    out, err = io.StringIO(), io.StringIO()
    if capsys is not None:
        capsys.readouterr()
    try:
        if capsys is None:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                rc = main(argv)
        else:
            rc = main(argv)
    except BaseException as exc:  # noqa: BLE001 - anything escaping would be a traceback
        pytest.fail(f"main({argv}) raised {type(exc).__name__}: {exc} "
                    "(the CLI would show a traceback instead of a one-line error)")
    if capsys is not None:
        captured = capsys.readouterr()
        return rc, captured.out, captured.err
    return rc, out.getvalue(), err.getvalue()


def assert_one_line_error(rc, err, fields=()):
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, f"expected exactly one stderr line, got {err!r}"
    assert err.endswith("\n")
    assert lines[0].startswith(PREFIX), lines[0]
    for field in fields:
        assert field in lines[0], f"the error does not name {field!r}: {lines[0]}"
    assert rc == 1, f"exit code {rc}, expected 1 (stderr: {err!r})"


def assert_nothing_written(directory, config_name="case.toml"):
    """Only the config file exists: no output, no leftover temporary file."""
    assert sorted(p.name for p in directory.iterdir()) == [config_name]


def assert_complete_csv(out_path, case):
    """The output has the header and every load position of every crossing."""
    rows = list(csv.reader(io.StringIO(out_path.read_text("utf-8"))))
    assert rows[0] == ["crossing", "position_m", *case.sensors.names]
    assert len(rows) == 1 + case.sweep.n_loads
    crossings = read_crossings(out_path, case.sensors)
    assert len(crossings) == 1
    np.testing.assert_array_equal(crossings.crossings[0].positions, case.sweep.positions)


# --------------------------------------------------------------------------
# 1. malformed configs through the CLI and load_case
# --------------------------------------------------------------------------

def _set(section, key, value):
    def mutate(d):
        d.setdefault(section, {})[key] = value
    return mutate


def _drop(section, key):
    def mutate(d):
        del d[section][key]
    return mutate


def _rename(section, old, new):
    def mutate(d):
        d[section][new] = d[section].pop(old)
    return mutate


def _add_section(name, table):
    def mutate(d):
        d[name] = table
    return mutate


def _text(edit):
    """Mark a mutation that edits the TOML text itself (syntax errors)."""
    edit.on_text = True
    return edit


def _both(*mutations):
    def mutate(d):
        for m in mutations:
            m(d)
    return mutate


# (id, mutation of the dict or a function of the TOML text, fields the message must name)
CONFIG_CASES = [
    ("missing-spans", _drop("bridge", "spans"), ["spans", "bridge"]),
    ("negative-span", _set("bridge", "spans", [15.0, -15.0]), ["spans"]),
    ("ei-negative", _set("bridge", "ei", [-7.5e9, 1.0e10]), ["ei"]),
    ("ei-string", _set("bridge", "ei", "stiff"), ["ei"]),
    ("rotational-springs-count", _set("bridge", "rotational_springs", [2.0e9, 0.0]),
     ["rotational_springs"]),
    ("vertical-spring-zero", _set("bridge", "vertical_springs", [INF, 0.0, INF]),
     ["vertical_springs"]),
    ("typo-elemnts", _rename("bridge", "elements", "elemnts"), ["elemnts"]),
    ("unknown-section", _add_section("sensor", {"positions": [11.0]}), ["sensor"]),
    ("sensor-off-bridge", _set("sensors", "positions", [11.0, 31.0]), ["positions"]),
    ("sensor-negative-position", _set("sensors", "positions", [-1.0, 19.0]), ["positions"]),
    ("sensor-position-nan", _set("sensors", "positions", [11.0, NAN]), ["positions"]),
    ("kind-tilt", _set("sensors", "kinds", ["rotation", "tilt"]), ["kinds"]),
    ("duplicate-names", _set("sensors", "names", ["PE1", "PE1"]), ["names"]),
    ("axle-loads-length", _set("vehicle", "axle_loads", [24.0e3]), ["axle_loads"]),
    ("stop-before-start", _both(_set("loads", "start", 10.0), _set("loads", "stop", 5.0)),
     ["stop"]),
    ("step-zero", _set("loads", "step", 0.0), ["step"]),
    ("noise-two-keys", _set("sensors", "noise_std_mm_per_m", 0.005),
     ["noise_std", "noise_std_mm_per_m"]),
    ("noise-unit-slip-0.5", _set("sensors", "noise_std", 0.5), ["noise_std"]),
    ("invalid-toml", _text(lambda text: text.replace("step = 0.25", "step = = 0.25")),
     ["TOML", "line"]),
    ("invalid-toml-unclosed-list",
     _text(lambda text: text.replace("spans = [15.0, 15.0]", "spans = [15.0, 15.0")), ["TOML"]),
]

# Malformations found by the property test below; each one currently escapes
# as a traceback (ValueError/TypeError/IndexError) or is silently accepted.
MORE_CONFIG_CASES = [
    ("ei-list-of-strings", _set("bridge", "ei", ["a", "b"]), ["ei"]),
    ("ei-table", _set("bridge", "ei", {"value": 1.0e10}), ["ei"]),
    ("ei-nested-list", _set("bridge", "ei", [[7.5e9, 1.0e10]]), ["ei"]),
    ("ei-bool", _set("bridge", "ei", True), ["ei"]),
    ("elements-string", _set("bridge", "elements", "thirty"), ["elements"]),
    ("elements-list", _set("bridge", "elements", [30]), ["elements"]),
    ("elements-nan", _set("bridge", "elements", NAN), ["elements"]),
    ("names-bool", _set("sensors", "names", True), ["names"]),
    ("kinds-bool", _set("sensors", "kinds", True), ["kinds"]),
    ("names-string", _set("sensors", "names", "PE"), ["names"]),
    ("position-bool", _set("sensors", "positions", [11.0, True]), ["positions"]),
    # 5e-6 rad written in mm/m (0.005) under the SI key: a unit slip by a factor 1000.
    ("noise-unit-slip-mm-per-m", _set("sensors", "noise_std", 0.005), ["noise_std"]),
]


def _write_case(tmp_path, mutate):
    if getattr(mutate, "on_text", False):
        text = mutate(_example_text())
        assert text != _example_text()
    else:
        data = base_dict()
        mutate(data)
        text = dumps_toml(data)
    path = tmp_path / "case.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _check_config_case(tmp_path, capsys, mutate, fields):
    path = _write_case(tmp_path, mutate)
    out = tmp_path / "out.csv"
    rc, stdout, err = run_cli(["simulate", "--config", path, "--out", out], capsys)
    assert_one_line_error(rc, err, fields)
    assert stdout == ""
    assert not out.exists()
    assert_nothing_written(tmp_path)
    with pytest.raises(ConfigError) as info:
        load_case(path)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, sensorplan.SensorplanError)
    for field in fields:
        assert field in str(info.value)


@pytest.mark.parametrize("mutate, fields", [c[1:] for c in CONFIG_CASES],
                         ids=[c[0] for c in CONFIG_CASES])
def test_malformed_config_gives_one_line_error(tmp_path, capsys, mutate, fields):
    _check_config_case(tmp_path, capsys, mutate, fields)


@pytest.mark.parametrize("mutate, fields", [c[1:] for c in MORE_CONFIG_CASES],
                         ids=[c[0] for c in MORE_CONFIG_CASES])
def test_more_malformed_configs_give_one_line_error(tmp_path, capsys, mutate, fields):
    _check_config_case(tmp_path, capsys, mutate, fields)


def test_valid_config_still_runs(tmp_path, capsys):
    """The unmutated example through the same path: exit 0 and a complete CSV."""
    path = tmp_path / "case.toml"
    path.write_text(dumps_toml(base_dict()), encoding="utf-8")
    out = tmp_path / "out.csv"
    rc, stdout, err = run_cli(["simulate", "--config", path, "--out", out], capsys)
    assert (rc, err) == (0, "")
    assert_complete_csv(out, load_case(path))


def test_missing_config_file_gives_one_line_error(tmp_path, capsys):
    out = tmp_path / "out.csv"
    rc, _, err = run_cli(["simulate", "--config", tmp_path / "nope.toml", "--out", out], capsys)
    assert_one_line_error(rc, err, ["nope.toml"])
    assert not out.exists()


# --------------------------------------------------------------------------
# 2. CSV files of crossings
# --------------------------------------------------------------------------

SENSORS = example_case("openlab-like").sensors

GOOD_ROWS = """\
1,0.0,1.0e-5,-2.0e-5
1,0.25,2.0e-5,-1.0e-5
2,0.0,1.5e-5,-2.5e-5
2,0.25,2.5e-5,-1.5e-5
"""
GOOD = "crossing,position_m,PE1,PE2\n" + GOOD_ROWS

CSV_CASES = [
    ("missing-crossing", "position_m,PE1,PE2\n0.0,1e-5,2e-5\n", ["'crossing'"]),
    ("missing-position", "crossing,PE1,PE2\n1,1e-5,2e-5\n", ["'position_m'"]),
    ("unknown-sensor", "crossing,position_m,PE1,PE3\n1,0.0,1e-5,2e-5\n", ["'PE3'"]),
    ("duplicate-column", "crossing,position_m,PE1,PE1\n1,0.0,1e-5,2e-5\n", ["'PE1'", "twice"]),
    ("too-few-fields", GOOD.replace("1,0.25,2.0e-5,-1.0e-5", "1,0.25,2.0e-5"), ["row 3"]),
    ("non-numeric", GOOD.replace("2.0e-5,-1.0e-5", "2.0e-5,abc"), ["row 3", "'PE2'", "abc"]),
    ("nan", GOOD.replace("1.5e-5", "NaN"), ["row 4", "'PE1'"]),
    ("inf", GOOD.replace("1.5e-5", "inf"), ["row 4", "'PE1'"]),
    ("empty-value", GOOD.replace("2,0.25,2.5e-5", "2,0.25,"), ["row 5", "'PE1'"]),
    ("empty-label", GOOD.replace("2,0.0,", ",0.0,"), ["row 4", "'crossing'"]),
    ("decreasing-positions", GOOD.replace("2,0.25,", "2,-0.25,"), ["crossing '2'", "position_m"]),
    ("repeated-position", GOOD.replace("1,0.25,", "1,0.0,"), ["crossing '1'", "position_m"]),
    ("load-factor-zero", "crossing,position_m,PE1,PE2,load_factor\n"
     "1,0.0,1e-5,2e-5,1.0\n1,0.25,1e-5,2e-5,0.0\n", ["'load_factor'"]),
    ("load-factor-negative", "crossing,position_m,PE1,PE2,load_factor\n"
     "1,0.0,1e-5,2e-5,-1.0\n1,0.25,1e-5,2e-5,1.0\n", ["'load_factor'"]),
    ("rotation-in-mm-per-m", "crossing,position_m,PE1,PE2\n"
     "1,0.0,0.03,1e-5\n1,0.25,0.2,2e-5\n1,0.5,0.5,3e-5\n", ["'PE1'", "rad"]),
    ("empty-file", "", ["empty"]),
    ("blank-lines-only", "\n \n\n", ["empty"]),
    ("header-only", "crossing,position_m,PE1,PE2\n", ["no data rows"]),
    ("no-sensor-column", "crossing,position_m\n1,0.0\n", ["sensor column"]),
]


@pytest.mark.parametrize("text, fields", [c[1:] for c in CSV_CASES], ids=[c[0] for c in CSV_CASES])
def test_malformed_csv_raises_data_error(tmp_path, text, fields):
    path = tmp_path / "data.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DataError) as info:
        read_crossings(path, SENSORS)
    assert isinstance(info.value, ValueError)
    message = str(info.value)
    assert "\n" not in message
    for field in fields:
        assert field in message, f"{field!r} not in {message!r}"


def test_good_csv_reads(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text(GOOD, encoding="utf-8")
    crossings = read_crossings(path, SENSORS)
    assert crossings.labels == ("1", "2")
    assert crossings.sensor_names == ("PE1", "PE2")


def test_missing_csv_file_raises_data_error(tmp_path):
    with pytest.raises(DataError, match="not found"):
        read_crossings(tmp_path / "nope.csv", SENSORS)


def test_stray_quote_in_a_large_csv_raises_data_error(tmp_path):
    """An unbalanced quote makes the csv module read the rest of the file as one field;
    past 128 KiB it raises csv.Error, which must still surface as a DataError."""
    rows = [f"1,{0.25 * k!r},1e-5,2e-5" for k in range(10000)]
    rows[1] = '"1,0.25,1e-5,2e-5'
    path = tmp_path / "data.csv"
    path.write_text("crossing,position_m,PE1,PE2\n" + "\n".join(rows) + "\n", encoding="utf-8")
    assert path.stat().st_size > 131072
    with pytest.raises(DataError, match="unbalanced quote"):
        read_crossings(path, SENSORS)


def _assert_same(a, b):
    assert a.sensor_names == b.sensor_names
    assert a.labels == b.labels
    for ca, cb in zip(a, b):
        np.testing.assert_array_equal(ca.positions, cb.positions)
        np.testing.assert_array_equal(ca.values, cb.values)
        np.testing.assert_array_equal(ca.load_factor, cb.load_factor)


def test_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    pos = np.sort(rng.uniform(0.0, 32.0, 50))
    crossings = Crossings(("PE1", "PE2"), (
        Crossing("1", pos, rng.normal(0.0, 1e-5, (2, 50)), np.ones(50)),
        Crossing("run B, lane 2", pos[:20] + 0.1, rng.normal(0.0, 1e-5, (2, 20)),
                 rng.uniform(0.5, 1.5, 20)),
        Crossing("Überfahrt 3", np.arange(5) * 0.1, np.full((2, 5), 1.0 / 3.0e5), np.ones(5)),
    ))
    path = tmp_path / "out" / "data.csv"
    write_crossings(path, crossings)
    _assert_same(read_crossings(path, SENSORS), crossings)
    assert sorted(p.name for p in path.parent.iterdir()) == ["data.csv"]


def test_csv_round_trip_of_a_simulated_crossing(tmp_path):
    case = example_case("openlab-like")
    crossings = simulate_crossings(case, 2, noise=True, rng=1)
    path = tmp_path / "sim.csv"
    write_crossings(path, crossings)
    _assert_same(read_crossings(path, case.sensors), crossings)


# --------------------------------------------------------------------------
# 3. property: randomly malformed configs never escape as tracebacks
# --------------------------------------------------------------------------

_BASE = base_dict()
_OPTIONAL = {("bridge", "elements"), ("bridge", "rotational_springs"),
             ("bridge", "vertical_springs"), ("sensors", "names"), ("sensors", "kinds"),
             ("sensors", "noise_std"), ("case", "name")}
_OPTIONAL_SECTIONS = {"case", "loads"}
_KNOWN = set(_KEYS) | set().union(*_KEYS.values())

WRONG_VALUES = {
    "string": "abc",
    "mixed list": ["abc", 1.0, True],
    "nested list": [[1.0, 2.0]],
    "empty list": [],
    "table": {"x": 1.0},
    "bool": True,
    "nan": NAN,
}


def _negative(value):
    if isinstance(value, list):
        return [_negative(v) for v in value]
    return -abs(value) - 1.0


def _is_numeric(value):
    if isinstance(value, list):
        return bool(value) and all(_is_numeric(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@st.composite
def mutations(draw):
    """(description, mutated dict, field the error must name, whether it may stay valid)."""
    data = copy.deepcopy(_BASE)
    fields = [(s, k) for s in _BASE for k in _BASE[s]]
    kind = draw(st.sampled_from(["drop", "drop section", "wrong type", "wrong element",
                                 "wrong section", "unknown key"]))
    if kind == "drop":
        section, key = draw(st.sampled_from(fields))
        del data[section][key]
        return f"drop [{section}] {key}", data, key, (section, key) in _OPTIONAL
    if kind == "drop section":
        section = draw(st.sampled_from(sorted(_BASE)))
        del data[section]
        return f"drop [{section}]", data, section, section in _OPTIONAL_SECTIONS
    if kind == "wrong section":
        section = draw(st.sampled_from(sorted(_BASE)))
        label = draw(st.sampled_from(sorted(WRONG_VALUES)))
        data[section] = copy.deepcopy(WRONG_VALUES[label])
        return f"[{section}] = {label}", data, section, False
    if kind == "unknown key":
        key = draw(st.from_regex(r"[a-z][a-z_]{0,11}", fullmatch=True).filter(
            lambda k: k not in _KNOWN))
        section = draw(st.sampled_from([None, *sorted(_BASE)]))
        if section is None:
            data[key] = 1.0
        else:
            data[section][key] = 1.0
        return f"unknown key {key!r} in {section or 'top level'}", data, key, False
    section, key = draw(st.sampled_from(fields))
    original = data[section][key]
    labels = sorted(WRONG_VALUES) + (["negative"] if _is_numeric(original) else [])
    label = draw(st.sampled_from(labels))
    new = _negative(original) if label == "negative" else copy.deepcopy(WRONG_VALUES[label])
    if kind == "wrong element" and isinstance(original, list) and label != "negative":
        index = draw(st.integers(0, len(original) - 1))
        data[section][key][index] = new
        # A name is any string: str() of whatever replaced one of two names is still valid.
        valid = (section, key) == ("sensors", "names")
        return f"[{section}] {key}[{index}] = {label}", data, key, valid
    data[section][key] = new
    valid = section == "case" or ((section, key) == ("loads", "start") and label == "negative")
    return f"[{section}] {key} = {label}", data, key, valid


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(mutation=mutations())
def test_random_malformed_configs_never_escape(tmp_path_factory, mutation):
    description, data, field, may_be_valid = mutation
    directory = tmp_path_factory.mktemp("fuzz")
    path = directory / "case.toml"
    text = dumps_toml(data)
    path.write_text(text, encoding="utf-8")
    out = directory / "out.csv"
    rc, _, err = run_cli(["simulate", "--config", path, "--out", out])
    if rc == 0:
        assert may_be_valid, (f"{description}: accepted silently (exit 0) although the "
                              f"config is invalid:\n{text}")
        assert err == ""
        assert_complete_csv(out, load_case(path))
    else:
        assert rc == 1, f"{description}: exit code {rc}, stderr {err!r}"
        assert_one_line_error(rc, err, [field])
        assert not out.exists()
        assert_nothing_written(directory)


# --------------------------------------------------------------------------
# 4. property: fuzzed CSV cells give a Crossings object or a DataError
# --------------------------------------------------------------------------

_SPECIAL_CELLS = ["", " ", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e400", "-1e400",
                  "1e308", "9" * 400, "1e-320", "0", "-0.0", "0x10", "1_000", "1,5", "1.5.2",
                  "١٢", "𝟙", "µ", "\u00a0", '"', '""', "'", "\t1e-5", "1e-5 ", "\x00", "\r",
                  "\n"]
_CELL = st.one_of(
    st.sampled_from(_SPECIAL_CELLS),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-1e-4, 1e-4).map(repr),
    st.floats(0.0, 40.0).map(repr),
    st.integers(-10**40, 10**40).map(str),
    st.text(st.characters(blacklist_categories=("Cs",)), max_size=8),
)
_LABEL = st.one_of(st.sampled_from(["1", "2", "run A"]), _CELL)


@st.composite
def csv_texts(draw):
    header = ["crossing", "position_m", "PE1", "PE2"]
    if draw(st.booleans()):
        header.append("load_factor")
    rows = draw(st.lists(
        st.one_of(
            st.tuples(_LABEL, *(_CELL for _ in header[1:])).map(list),   # right width
            st.lists(_CELL, max_size=len(header) + 2),                   # any width
        ),
        max_size=8))
    if draw(st.booleans()):
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([header, *rows])
        return buf.getvalue()
    return "\n".join(",".join(r) for r in [header, *rows]) + "\n"


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(text=csv_texts())
def test_fuzzed_csv_gives_crossings_or_data_error(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("csv") / "data.csv"
    path.write_bytes(text.encode("utf-8"))
    try:
        crossings = read_crossings(path, SENSORS)
    except DataError:
        return
    except Exception as exc:  # noqa: BLE001
        pytest.fail(f"read_crossings raised {type(exc).__name__}: {exc} for\n{text!r}")
    assert isinstance(crossings, Crossings)
    for c in crossings:                       # what is accepted is clean
        assert np.all(np.isfinite(c.positions)) and np.all(np.diff(c.positions) > 0.0)
        assert np.all(np.isfinite(c.values)) and np.all(np.abs(c.values) <= 0.02)
        assert np.all(np.isfinite(c.load_factor)) and np.all(c.load_factor > 0.0)


# --------------------------------------------------------------------------
# 5. CLI usage errors
# --------------------------------------------------------------------------

def test_simulate_without_out_is_a_usage_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, stdout, err = run_cli(["simulate", "--example", "openlab-like"], capsys)
    assert rc == 1  # usage errors are one line and exit code 1, like every user error
    assert "--out" in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_unknown_example_gives_one_line_error(tmp_path, capsys):
    out = tmp_path / "out.csv"
    rc, stdout, err = run_cli(["simulate", "--example", "nope", "--out", out], capsys)
    assert_one_line_error(rc, err, ["'nope'", "openlab-like"])
    assert stdout == ""
    assert list(tmp_path.iterdir()) == []



def test_a_sensor_the_model_says_reads_nothing_is_not_a_unit_slip_or_a_sign_flip():
    # A deflection sensor on a rigid bearing reads zero in the model: up to round-off (~1e-19 m),
    # not exactly.  Its measured noise has no scale to compare with (openLAB's laser LWA_2 at a bearing).
    import warnings

    from sensorplan.inference.screening import check_case_data_scale
    from sensorplan.model.case import Case
    from sensorplan.model.simulate import simulate_crossings

    bridge = sensorplan.Bridge((15.0, 15.0))
    sensors = sensorplan.SensorLayout([7.5, 15.0, 22.5], "deflection", ["D1", "D2", "D3"], [2e-5] * 3)
    case = Case(bridge, sensorplan.Mesh.uniform(bridge, 30), 1e10, sensorplan.Vehicle.point_load(1e5), sensors,
                sweep=sensorplan.LoadSweep.from_range(0.0, 30.0, 0.5))
    assert 0.0 < np.abs(case.influence_lines().predictions[1]).max() < 1e-15  # round-off, not exactly zero
    data = simulate_crossings(case, 3, noise=True, rng=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_case_data_scale(case, data)
    # the other sensors are still checked: D1 in mm under the SI key is a unit slip
    from dataclasses import replace

    slipped = replace(data, crossings=tuple(replace(c, values=c.values * np.array([[1e3], [1.0], [1.0]]))
                                            for c in data))
    with pytest.raises(DataError, match="D1"):
        check_case_data_scale(case, slipped)

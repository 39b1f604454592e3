"""Hostile input gets a correct result or a one-line error; nothing informationless passes.

1. A generated invalid-input suite in the style of scikit-learn's parameter
   validation tests: every option of every command, found by introspecting
   the argparse parsers of ``sensorplan.cli`` (so options added later are
   covered), is crossed with invalid values suited to its type.  Each run
   must exit with 1, print exactly one line on stderr naming the option, no
   traceback, and leave no file behind.
2. Options that parse but make no sense on the case (off the bridge, longer
   than the bridge, too many candidates, --fixed in an excluded zone).
3. Hostile case files and data files: physical bounds, unit slips, names
   that would become bad file names, data without information.
4. Outputs are all-or-nothing when a write fails midway.
5. Property tests (hypothesis) for the readers and the numerical limits.
"""

import argparse
import contextlib
import csv
import io
import json
import math
import re
import tomllib
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sensorplan
from sensorplan import ConfigError, DataError, SensorplanWarning, example_case
from sensorplan.cli import _common, _kinds, build_parser, main
from sensorplan.inference.screening import check_case_data_scale
from sensorplan.io.config import case_from_toml
from sensorplan.io.csvio import parse_crossings
from sensorplan.model.noise import NoiseModel

EXAMPLE = ["--example", "openlab-like"]


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def _example_text(name="openlab-like"):
    return resources.files("sensorplan.examples").joinpath(f"{name}.toml").read_text("utf-8")


def run(argv, capsys):
    """(exit code, stdout, stderr) of the CLI run in-process; an escaping exception fails the test."""
    argv = [str(a) for a in argv]
    capsys.readouterr()
    try:
        rc = main(argv)
    except BaseException as exc:  # noqa: BLE001 - anything escaping would be a traceback
        pytest.fail(f"main({argv}) raised {type(exc).__name__}: {exc}")
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def assert_one_line_error(rc, err, command, fields=()):
    """One error line on stderr (after the progress lines of the stages that ran, if any)."""
    assert "Traceback" not in err, err
    lines = err.splitlines()
    progress = [line for line in lines[:-1] if re.match(rf"sensorplan {command}: (?!error:|warning:)", line)]
    lines = lines[len(progress):]
    assert len(lines) == 1, f"expected exactly one stderr line, got {err!r}"
    assert lines[0].startswith((f"sensorplan {command}: error:", "sensorplan: error:")), lines[0]
    for field in fields:
        assert field in lines[0], f"the error does not name {field!r}: {lines[0]}"
    assert rc == 1, f"exit code {rc}, expected 1 (stderr: {err!r})"


def files_under(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def _noisy_csv(tmp_path, crossings=2):
    path = tmp_path / "data.csv"
    assert main(["simulate", *EXAMPLE, "--crossings", str(crossings), "--noise", "--seed", "1",
                 "--out", str(path), "--quiet"]) == 0
    return path


def _valid_argv(command, parser, data, out):
    """A valid command line for ``command``: the example case and every required option."""
    argv = [command, *EXAMPLE]
    for action in parser._actions:
        if not action.required or not action.option_strings:
            continue
        option = action.option_strings[0]
        if option == "--out":
            argv += [option, out / "out.csv" if command in ("simulate", "crossings") else out]
        elif option in ("--data", "--timeseries"):
            argv += [option, data]
        elif option == "--layout":
            argv += [option, "5,25"]
        else:  # pragma: no cover - a new required option needs a valid value here
            pytest.fail(f"no valid value known for the required option {option} of {command}")
    if not any(a.option_strings and a.option_strings[0] == "--out" and a.required for a in parser._actions):
        if any("--out" in a.option_strings for a in parser._actions):
            argv += ["--out", out]
    return argv


def _invalid_values(action):
    """Invalid values for an option, from its type (and its declared range)."""
    kind = action.type
    bounds = getattr(kind, "bounds", None)
    if action.choices is not None:
        return ["nosuch", ""]
    if kind is _common.input_file:  # a folder, a missing file
        return ["", ".", "no-such-file.csv"]
    if kind is _common.output_file:  # a folder
        return ["", "."]
    if kind is _common.parse_positions:
        return ["", "nan", "inf", "1,1", "a,b", "5;25", "1e400"]
    if kind is _common.parse_zones:
        return ["3", "a:b", "16:14", "nan:1", "1:inf", ""]
    if kind is _kinds.parse_sensors:
        return ["", "nan", "inf", "a,b", "5;25", "1e400", "5:nosuch", "5,5"]
    if kind is _kinds.KINDS:
        return ["", "nosuch", "rotation,rotation", "rotation,"  "nosuch"]
    if kind is _kinds.PER_KIND:
        return ["", "nan", "-1", "0", "abc", "nosuch=1", "rotation=abc", "rotation=-1", "rotation"]
    if kind is _kinds.COUNTS:
        return ["", "a", "-1", "1.5", "1,-1"]
    if kind is _kinds.SCHEDULER:
        return ["", " ", "tcp://a b"]
    if getattr(kind, "__name__", "") == "parse_severities":
        return ["", "0", "1", "nan", "abc", "-0.1", "0.2,1.5"]
    if bounds is not None:
        low, high, low_open, high_open = bounds
        is_integer = kind.__name__ == "integer"
        values = ["nan", "inf", "1e400", "abc", "", "-1e300" if low > -1e300 else "abc"]
        values.append(str(low) if low_open else str(low - 1))
        values.append(str(high) if high_open else str(high * 10 + 1 if high != 0 else 1))
        if is_integer:
            values += ["1.5", "1e3", "99999999999999999999999999"]
        return values
    return []


def _generated_cases():
    cases = []
    for command, parser in _subparsers().items():
        for action in parser._actions:
            if not action.option_strings or action.nargs == 0:
                continue
            for value in _invalid_values(action):
                cases.append((command, action.option_strings[0], value))
    return cases


GENERATED = _generated_cases()


def test_the_generated_suite_covers_every_typed_option():
    """Every option with a value is either typed (and crossed above) or a path."""
    covered = {(c, o) for c, o, _ in GENERATED}
    for command, parser in _subparsers().items():
        for action in parser._actions:
            if not action.option_strings or action.nargs == 0:
                continue
            option = action.option_strings[0]
            if action.type is Path or option in {"--example", "--config"}:
                continue
            assert (command, option) in covered, f"{command} {option} has no validated type"
    assert len(GENERATED) > 300


@pytest.fixture(scope="module")
def data_csv(tmp_path_factory):
    return _noisy_csv(tmp_path_factory.mktemp("data"))


@pytest.mark.parametrize("command, option, value", GENERATED,
                         ids=[f"{c}{o}={v!r}" for c, o, v in GENERATED])
def test_every_option_rejects_invalid_values(tmp_path, capsys, data_csv, command, option, value):
    parser = _subparsers()[command]
    out = tmp_path / "out"
    argv = _valid_argv(command, parser, data_csv, out) + [f"{option}={value}"]
    rc, stdout, err = run(argv, capsys)
    assert_one_line_error(rc, err, command, [option])
    assert stdout == ""
    assert files_under(tmp_path) == []


def test_usage_errors_are_one_line(tmp_path, capsys):
    for argv, field in ([["no-such-command"], "no-such-command"],
                        [["recommend", *EXAMPLE, "--nosuch"], "--nosuch"],
                        [["simulate", *EXAMPLE], "--out"],
                        [["verify", *EXAMPLE, "--out", tmp_path], "--layout"],
                        [["invert", "--example"], "--example"],
                        [["recommend", *EXAMPLE, "--config", "x.toml"], "--config"]):
        rc, _, err = run(argv, capsys)
        assert_one_line_error(rc, err, argv[0], [field])
    assert files_under(tmp_path) == []


# --------------------------------------------------------------------------
# 2. options that parse but do not fit the case
# --------------------------------------------------------------------------

SEMANTIC = [
    (["recommend", "--fixed", "15", "--exclude", "14:16"], ["--fixed", "--exclude"]),
    (["recommend", "--fixed", "40"], ["--fixed", "30 m"]),
    (["recommend", "--fixed", "11,12", "--min-spacing", "2"], ["--fixed", "--min-spacing"]),
    (["recommend", "--spacing", "5e-324"], ["--spacing"]),
    (["recommend", "--spacing", "1e-7"], ["--spacing", "GiB"]),
    (["recommend", "--spacing", "31"], ["--spacing"]),
    (["recommend", "--min-spacing", "100"], ["--min-spacing"]),
    (["recommend", "--exclude", "100:200"], ["--exclude"]),
    (["recommend", "--noise-std", "0.5"], ["--noise-std", "rad"]),
    (["recommend", "--noise-std", "1e-300"], ["--noise-std"]),
    (["recommend", "--kind", "deflection", "--noise-std", "0.5"], ["--noise-std", "m"]),
    (["recommend", "--count", "100"], ["--count"]),
    (["recommend", "--count", "61", "--min-spacing", "10"], ["--count 61", "--min-spacing 10 m", "at most 4"]),
    (["recommend", "--count", "3", "--per-span-min", "3,0", "--min-spacing", "8"], ["--per-span-min", "--min-spacing"]),
    (["recommend", "--count", "3", "--per-span-max", "1,1"], ["--per-span-max", "--count"]),
    (["recommend", "--count", "2", "--budget", "2", "--cost", "rotation=1.5"], ["--budget", "--count"]),
    (["recommend", "--count", "2", "--fixed", "5,15,25", "--min-spacing", "10"], ["--fixed", "--min-spacing"]),
    (["recommend", "--count", "2", "--exclude", "0:30"], ["--exclude"]),
    (["report", "--count", "5", "--min-spacing", "10"], ["--count 5", "--min-spacing"]),
    (["recommend", "--criterion", "A", "--region", "100:200", "--count", "2"], ["--region"]),
    (["recommend", "--criterion", "detect", "--length", "1e-300", "--count", "2"], ["--length", "1 mm"]),
    (["verify", "--layout", "5,25", "--length", "1e-300", "--scenarios", "2"], ["--length", "1 mm"]),
    (["detectability", "--length", "1e-300"], ["--length", "1 mm"]),
    (["detectability", "--json", "."], ["--json", "folder"]),
    (["verify", "--layout", "5,100"], ["--layout"]),
    (["verify", "--layout", "5,25", "--noise-std", "0.01"], ["--noise-std"]),
    (["informativeness", "--positions", "-1"], ["--positions"]),
    (["detectability", "--layout", "40"], ["--layout"]),
    (["detectability", "--step", "1e-300"], ["--step"]),
    (["detectability", "--step", "100"], ["--step"]),
    (["detectability", "--length", "100"], ["--length"]),
]


@pytest.mark.parametrize("argv, fields", SEMANTIC, ids=[" ".join(a) for a, _ in SEMANTIC])
def test_options_that_do_not_fit_the_case(tmp_path, capsys, argv, fields):
    rc, stdout, err = run([argv[0], *EXAMPLE, *argv[1:], "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, argv[0], fields)
    assert files_under(tmp_path) == []


def test_invert_elements_below_the_span_count_names_the_option(tmp_path, capsys, data_csv):
    rc, _, err = run(["invert", *EXAMPLE, "--data", data_csv, "--elements", "1", "--out", tmp_path / "o"], capsys)
    assert_one_line_error(rc, err, "invert", ["--elements"])
    assert files_under(tmp_path) == []


# --------------------------------------------------------------------------
# 3. hostile case files
# --------------------------------------------------------------------------

def _replace(old, new):
    def mutate(text):
        assert old in text, old
        return text.replace(old, new)
    return mutate


HOSTILE_TOML = [
    ("span-1e300", _replace("spans = [15.0, 15.0]", "spans = [1e300, 15.0]"), ["spans", "m"]),
    ("span-in-mm", _replace("spans = [15.0, 15.0]", "spans = [15000.0, 15.0]"), ["spans"]),
    ("span-tiny", _replace("spans = [15.0, 15.0]", "spans = [1e-9, 15.0]"), ["spans"]),
    ("ei-1e300", _replace("ei = [7.5e9, 1.0e10]", "ei = [1e300, 1e300]"), ["'ei'", "N m^2"]),
    ("ei-tiny", _replace("ei = [7.5e9, 1.0e10]", "ei = [1e-3, 1e-3]"), ["'ei'"]),
    ("ei-in-kNm2", _replace("ei = [7.5e9, 1.0e10]", "ei = [7.5e6, 1.0e7]"), ["EI", "kN m^2"]),
    ("loads-1e300", _replace("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [1e300, 1e300]"), ["axle_loads"]),
    ("loads-in-kN", _replace("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [2.4e-2, 2.4e-2]"), ["axle_loads"]),
    ("loads-in-kN-but-above-1-N", _replace("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [24.0, 24.0]"),
     ["noise", "kN"]),
    ("offsets-1e300", _replace("axle_offsets = [0.0, 2.0]", "axle_offsets = [0.0, 1e300]"), ["axle_offsets"]),
    ("noise-1e-300", _replace("noise_std = 5.0e-6", "noise_std = 1e-300"), ["noise_std"]),
    ("correlation-1e20", _replace("noise_std = 5.0e-6", "noise_std = 5.0e-6\n[noise]\ncorrelation_length = 1e20"),
     ["correlation_length"]),
    ("springs-1e300", _replace("rotational_springs = [2.0e9, 0.0, 1.0e9]", "rotational_springs = [1e300, 0.0, 1e300]"),
     ["rotational_springs"]),
    ("springs-1e-300", _replace("rotational_springs = [2.0e9, 0.0, 1.0e9]",
                                "rotational_springs = [1e-300, 0.0, 1e-300]"), ["rotational_springs"]),
    ("vertical-springs-1e-300", _replace("vertical_springs = [inf, inf, inf]",
                                         "vertical_springs = [1e-300, 1e-300, 1e-300]"), ["vertical_springs"]),
    ("step-subnormal", _replace("step = 0.25", "step = 5e-324"), ["step"]),
    ("elements-memory", lambda t: _replace("step = 0.25", "step = 0.001")(_replace("elements = 30", "elements = 2000")(t)),
     ["GiB", "elements", "step"]),
    ("loads-off-the-bridge", _replace("start = 0.0\nstop = 32.0", "start = 100.0\nstop = 200.0"), ["loads"]),
    ("loads-in-cm", _replace("start = 0.0\nstop = 32.0", "start = 0.0\nstop = 3200.0"), ["loads"]),
    ("positions-in-cm", _replace("positions = [11.0, 19.0]", "positions = [1100.0, 1900.0]"), ["positions"]),
    ("name-with-slash", _replace('names = ["PE1", "PE2"]', 'names = ["../evil", "PE2"]'), ["names", "../evil"]),
    ("name-dotdot", _replace('names = ["PE1", "PE2"]', 'names = ["..", "PE2"]'), ["names"]),
    ("name-newline", _replace('names = ["PE1", "PE2"]', 'names = ["a\\nb", "PE2"]'), ["names"]),
    ("name-tab", _replace('names = ["PE1", "PE2"]', 'names = ["a\\tb", "PE2"]'), ["names"]),
    ("name-control", _replace('names = ["PE1", "PE2"]', 'names = ["a\\u0001", "PE2"]'), ["names"]),
    ("name-empty", _replace('names = ["PE1", "PE2"]', 'names = ["", "PE2"]'), ["names"]),
    ("name-duplicate", _replace('names = ["PE1", "PE2"]', 'names = ["PE1", "PE1"]'), ["names"]),
    ("name-crossing", _replace('names = ["PE1", "PE2"]', 'names = ["crossing", "PE2"]'), ["crossing", "reserved"]),
    ("name-position", _replace('names = ["PE1", "PE2"]', 'names = ["position_m", "PE2"]'), ["position_m"]),
    ("name-load-factor", _replace('names = ["PE1", "PE2"]', 'names = ["load_factor", "PE2"]'), ["load_factor"]),
    ("name-time", _replace('names = ["PE1", "PE2"]', 'names = ["time_s", "PE2"]'), ["time_s"]),
]


@pytest.mark.parametrize("mutate, fields", [c[1:] for c in HOSTILE_TOML], ids=[c[0] for c in HOSTILE_TOML])
def test_hostile_case_files_give_one_line_errors(tmp_path, capsys, mutate, fields):
    path = tmp_path / "case.toml"
    path.write_text(mutate(_example_text()), encoding="utf-8")
    rc, stdout, err = run(["simulate", "--config", path, "--out", tmp_path / "out" / "x.csv"], capsys)
    assert_one_line_error(rc, err, "simulate", fields)
    assert files_under(tmp_path) == ["case.toml"]
    with pytest.raises(ConfigError):
        case_from_toml(mutate(_example_text()))


def test_a_case_file_with_a_byte_order_mark_is_read(tmp_path, capsys):
    path = tmp_path / "case.toml"
    path.write_bytes(b"\xef\xbb\xbf" + _example_text().encode("utf-8"))
    rc, _, err = run(["simulate", "--config", path, "--out", tmp_path / "x.csv", "--quiet"], capsys)
    assert (rc, err) == (0, "")
    assert sensorplan.load_case(path).sensors.names == ("PE1", "PE2")


def test_huge_element_counts_are_refused_before_an_analysis(tmp_path, capsys):
    path = tmp_path / "case.toml"
    path.write_text(_replace("elements = 30", "elements = 5000")(_example_text()), encoding="utf-8")
    rc, _, err = run(["informativeness", "--config", path, "--out", tmp_path / "o"], capsys)
    assert_one_line_error(rc, err, "informativeness", ["5000 elements", "400"])
    assert files_under(tmp_path) == ["case.toml"]


def test_a_design_alone_is_limited_by_its_estimate_not_by_the_element_count(tmp_path, capsys):
    # 450 elements, above the analyses' 400: a design without --verify runs (its memory and CPU estimate is
    # the limit; a few seconds at 17 candidates), the same design with --verify is refused, naming the fix
    path = tmp_path / "case.toml"
    path.write_text(_replace("elements = 30", "elements = 450")(_example_text()), encoding="utf-8")
    design = ["recommend", "--config", path, "--count", "2", "--spacing", "2", "--quiet"]
    rc, _, err = run([*design, "--out", tmp_path / "o"], capsys)
    assert (rc, err) == (0, "")
    assert json.loads((tmp_path / "o" / "design.json").read_text())["n_params"] == 450
    rc, _, err = run([*design, "--verify", "--out", tmp_path / "v"], capsys)
    assert_one_line_error(rc, err, "recommend", ["450 elements", "400", "--verify"])
    assert not (tmp_path / "v").exists()


def test_a_design_beyond_its_estimate_is_refused_with_the_estimate(tmp_path, capsys):
    # 20,000 elements: the CPU estimate alone (the relaxation's m P^3 Newton steps) is far beyond the 6 h
    # limit on any machine, so the refusal does not depend on this machine's memory
    path = tmp_path / "case.toml"
    path.write_text(_replace("elements = 30", "elements = 20000")(_example_text()), encoding="utf-8")
    rc, _, err = run(["recommend", "--config", path, "--out", tmp_path / "o"], capsys)
    assert_one_line_error(rc, err, "recommend", ["20000 parameters", "h of CPU", "fewer elements"])
    assert files_under(tmp_path) == ["case.toml"]


# --------------------------------------------------------------------------
# 3b. hostile data files
# --------------------------------------------------------------------------

def _rows(path):
    rows = list(csv.reader(io.StringIO(path.read_text("utf-8"))))
    return rows[0], rows[1:]


def _rewrite(path, func, header=None):
    head, rows = _rows(path)
    text = ",".join(header or head) + "\n" + "".join(",".join(map(str, func(r))) + "\n" for r in rows)
    out = path.with_name("hostile.csv")
    out.write_text(text, encoding="utf-8")
    return out


HOSTILE_DATA = [
    ("all-zero", lambda r: [r[0], r[1], 0.0, 0.0], ["PE1", "constant"]),
    ("dead-channel", lambda r: [r[0], r[1], r[2], 1e-6], ["PE2", "constant"]),
    ("positions-in-mm", lambda r: [r[0], float(r[1]) * 1000, r[2], r[3]], ["position_m", "mm"]),
    ("vehicle-never-on-the-bridge", lambda r: [r[0], float(r[1]) + 100, r[2], r[3]], ["position_m", "bridge"]),
    ("readings-x1000", lambda r: [r[0], r[1], float(r[2]) * 1000, float(r[3]) * 1000], ["PE1"]),
    ("readings-x1e-300", lambda r: [r[0], r[1], float(r[2]) * 1e-300, float(r[3]) * 1e-300], ["PE1", "unit slip"]),
]


@pytest.mark.parametrize("command", ["invert", "diagnose"])
@pytest.mark.parametrize("func, fields", [c[1:] for c in HOSTILE_DATA], ids=[c[0] for c in HOSTILE_DATA])
def test_data_without_information_is_refused(tmp_path, capsys, command, func, fields):
    data = _rewrite(_noisy_csv(tmp_path), func)
    rc, _, err = run([command, *EXAMPLE, "--data", data, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, command, fields)
    assert files_under(tmp_path) == ["data.csv", "hostile.csv"]


@pytest.mark.parametrize("factor", ["1e300", "1e-300"])
def test_absurd_load_factors_blame_the_load_factor(tmp_path, capsys, factor):
    path = _noisy_csv(tmp_path)
    head, rows = _rows(path)
    data = _rewrite(path, lambda r: r + [factor], header=head + ["load_factor"])
    rc, _, err = run(["invert", *EXAMPLE, "--data", data, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, "invert", ["load_factor"])
    assert files_under(tmp_path) == ["data.csv", "hostile.csv"]


@pytest.mark.parametrize("sep, label", [(";", "semicolon"), ("\t", "tab")])
def test_delimited_csv_says_so(tmp_path, capsys, sep, label):
    path = _noisy_csv(tmp_path)
    path.write_text(path.read_text("utf-8").replace(",", sep), encoding="utf-8")
    rc, _, err = run(["invert", *EXAMPLE, "--data", path, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, "invert", [label])


def test_noise_free_data_cannot_be_diagnosed(tmp_path, capsys):
    path = tmp_path / "clean.csv"
    assert main(["simulate", *EXAMPLE, "--crossings", "2", "--out", str(path), "--quiet"]) == 0
    rc, _, err = run(["diagnose", *EXAMPLE, "--data", path, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, "diagnose", ["noise-free", "--noise"])
    assert files_under(tmp_path) == ["clean.csv"]


@pytest.mark.slow
def test_noise_free_data_invert_with_a_warning(tmp_path, capsys):
    """The noise estimate has a floor (1e-3 of the configured noise): the fit runs and says why it is odd."""
    path = tmp_path / "clean.csv"
    assert main(["simulate", *EXAMPLE, "--crossings", "2", "--out", str(path), "--quiet"]) == 0
    rc, stdout, err = run(["invert", *EXAMPLE, "--data", path, "--out", tmp_path / "out"], capsys)
    assert rc == 0 and "Traceback" not in err
    assert "the estimated noise is 0.001 times the configured noise_std" in err
    assert (tmp_path / "out" / "posterior.json").exists()


def test_a_sign_flipped_tiltmeter_is_warned_about():
    """The library check warns, naming the sensor and the likely cause, before anything is fitted."""
    case = example_case("openlab-like")
    clean = sensorplan.simulate_crossings(case, 2, noise=True, rng=1)
    flipped = sensorplan.Crossings(clean.sensor_names, tuple(
        sensorplan.Crossing(c.label, c.positions, c.values * np.array([[1.0], [-1.0]]), c.load_factor)
        for c in clean))
    with pytest.warns(SensorplanWarning, match="'PE2' is anti-correlated.*sign flip"):
        check_case_data_scale(case, flipped)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_case_data_scale(case, clean)  # the unflipped data raise nothing


# --------------------------------------------------------------------------
# 4. all-or-nothing outputs
# --------------------------------------------------------------------------

def test_a_failing_json_write_leaves_no_figure(tmp_path, capsys, monkeypatch):
    """Figures are staged before the JSON: a disk that fills at the JSON leaves nothing behind."""
    calls = []

    def full(files, path, payload):
        calls.append(path)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(_common, "stage_json", full)
    import sensorplan.cli.detectability as detect_cli
    monkeypatch.setattr(detect_cli, "stage_json", full)
    rc, _, err = run(["detectability", *EXAMPLE, "--step", "5", "--out", tmp_path / "out"], capsys)
    assert calls
    assert_one_line_error(rc, err, "detectability", ["No space left"])
    assert files_under(tmp_path) == []


def test_a_commit_that_fails_midway_is_undone(tmp_path, capsys, monkeypatch):
    """The second rename of the commit fails: the first file is removed again, no temporary file stays."""
    import os

    from sensorplan.io import output

    real, count = os.replace, []

    def flaky(src, dst):
        count.append(dst)
        if len(count) == 2:
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(output.os, "replace", flaky)
    rc, _, err = run(["informativeness", *EXAMPLE, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(rc, err, "informativeness", ["No space left"])
    assert files_under(tmp_path) == []


# --------------------------------------------------------------------------
# 5. property tests
# --------------------------------------------------------------------------

EXTREMES = st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e-12, 1e-3, 1.0, 30.0, 1e7, 1e14, 1e20, 1e300,
                            math.inf, -math.inf, math.nan, -1.0])
NUMERIC_FIELDS = [
    ("spans = [15.0, 15.0]", "spans = [{x}, 15.0]"),
    ("ei = [7.5e9, 1.0e10]", "ei = [{x}, 1.0e10]"),
    ("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [{x}, 24.0e3]"),
    ("axle_offsets = [0.0, 2.0]", "axle_offsets = [0.0, {x}]"),
    ("noise_std = 5.0e-6", "noise_std = {x}"),
    ("noise_std = 5.0e-6", "noise_std = 5.0e-6\n[noise]\ncorrelation_length = {x}"),
    ("rotational_springs = [2.0e9, 0.0, 1.0e9]", "rotational_springs = [{x}, 0.0, 1.0e9]"),
    ("vertical_springs = [inf, inf, inf]", "vertical_springs = [{x}, inf, inf]"),
    ("step = 0.25", "step = {x}"),
    ("stop = 32.0", "stop = {x}"),
    ("positions = [11.0, 19.0]", "positions = [{x}, 19.0]"),
]


def _toml_float(x):
    return "nan" if math.isnan(x) else ("inf" if x == math.inf else "-inf" if x == -math.inf else repr(x))


@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(range(len(NUMERIC_FIELDS))), EXTREMES), min_size=1, max_size=3))
def test_extreme_numbers_in_a_case_file_give_a_finite_case_or_a_config_error(edits):
    """Any field at any extreme: a ConfigError, or a case whose predictions are finite and plausible."""
    text = _example_text()
    for index, x in edits:
        old, new = NUMERIC_FIELDS[index]
        if old in text:
            text = text.replace(old, new.format(x=_toml_float(x)), 1)
    try:
        case = case_from_toml(text)
    except ConfigError as exc:
        assert "\n" not in str(exc).strip()
        return
    predictions = case.influence_lines().predictions
    assert np.all(np.isfinite(predictions))
    assert np.max(np.abs(predictions)) <= 1.0
    assert np.all(np.isfinite(case.noise.whiten(predictions, case.sweep.positions)))


@settings(max_examples=60)
@given(st.floats(0.0, 1e300, allow_subnormal=True),
       st.lists(st.floats(1e-9, 1e3), min_size=2, max_size=30, unique=True))
def test_whitening_stays_finite_for_any_correlation_length(correlation_length, steps):
    """Reference: whitening is a bidiagonal recursion with 1 / sqrt(1 - rho^2); rho is capped below 1."""
    positions = np.cumsum(steps)
    noise = NoiseModel([1e-6], correlation_length)
    white = noise.whiten(np.ones((1, positions.size)), positions)
    assert np.all(np.isfinite(white))
    assert math.isfinite(noise.log_det_gamma(positions))


_CELL = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.sampled_from(["", " ", "1e400", "-0", "5e-324", "1,0", "0x10", "nan", "\u00a0"]))


@settings(max_examples=80)
@given(st.lists(st.tuples(st.sampled_from(["1", "2"]), _CELL, _CELL, _CELL), min_size=1, max_size=12),
       st.sampled_from([",", ";", "\t"]))
def test_the_csv_reader_returns_finite_crossings_or_a_data_error(rows, sep):
    sensors = example_case("openlab-like").sensors
    text = sep.join(["crossing", "position_m", "PE1", "PE2"]) + "\n"
    text += "".join(sep.join(r) + "\n" for r in rows)
    try:
        crossings = parse_crossings(text, sensors)
    except DataError as exc:
        assert "\n" not in str(exc)
        return
    for c in crossings:
        assert np.all(np.isfinite(c.values)) and np.all(np.abs(c.values) <= 0.02)
        assert np.all(np.diff(c.positions) > 0)


@settings(max_examples=40)
@given(st.text(min_size=0, max_size=12))
def test_sensor_names_are_safe_file_names_or_refused(name):
    """A name either refuses with a ConfigError or is safe as a CSV column and as part of a file name."""
    try:
        layout = sensorplan.SensorLayout([5.0], names=[name])
    except ConfigError:
        return
    (accepted,) = layout.names
    assert accepted not in {".", ".."}
    assert accepted.isprintable() and accepted.strip() == accepted and accepted
    assert accepted.lower() not in {"crossing", "position_m", "load_factor", "time_s"}
    part = _common.safe_name(accepted)  # as the CLI writes it into fit_NAME.png
    assert part and all(ch.isascii() and (ch.isalnum() or ch in "._-") for ch in part)
    assert len(part) == len(accepted)
    header = "crossing,position_m," + accepted + "\n1,0.0,1e-6\n1,1.0,2e-6\n"
    assert parse_crossings(header, layout).sensor_names == (accepted,)


def test_cli_prints_library_warnings_on_one_line(tmp_path, capsys):
    """Warnings raised during a command go to stderr as one line each (no source line echoed)."""
    from sensorplan.cli import _one_line_warning

    show = _one_line_warning("invert")
    with contextlib.redirect_stderr(io.StringIO()) as err:
        show("multi\nline   message", SensorplanWarning, "x.py", 1)
    assert err.getvalue() == "sensorplan invert: warning: multi line message\n"


def test_the_example_cases_pass_their_own_bounds():
    for name in sensorplan.io.config.EXAMPLES:
        case = example_case(name)
        assert tomllib.loads(_example_text(name))["bridge"]["spans"]
        assert case.sweep.n_loads > 0


def test_out_inside_an_existing_file_names_the_file(tmp_path, capsys):
    blocker = tmp_path / "afile"
    blocker.write_text("x", encoding="utf-8")
    rc, _, err = run(["informativeness", *EXAMPLE, "--out", blocker / "sub"], capsys)
    assert_one_line_error(rc, err, "informativeness", [str(blocker), "is a file"])
    assert files_under(tmp_path) == ["afile"]


def test_crossings_speed_range_upside_down_names_both_options(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("time_s,PE1,PE2\n0,0,0\n0.1,0,0\n", encoding="utf-8")
    rc, _, err = run(["crossings", *EXAMPLE, "--timeseries", log, "--min-speed", "50", "--max-speed", "1",
                      "--out", tmp_path / "out" / "x.csv"], capsys)
    assert_one_line_error(rc, err, "crossings", ["--min-speed 50", "--max-speed 1"])
    rc, _, err = run(["crossings", *EXAMPLE, "--timeseries", log, "--speed", "1e-300",
                      "--out", tmp_path / "out" / "x.csv"], capsys)
    assert_one_line_error(rc, err, "crossings", ["--speed 1e-300", "--min-speed"])
    assert files_under(tmp_path) == ["log.csv"]


def test_a_vehicle_of_a_million_axles_is_refused_before_any_work():
    text = _replace("axle_offsets = [0.0, 2.0]", "axle_offsets = [" + ", ".join(["0.0"] * 2000) + "]")(
        _replace("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [" + ", ".join(["1.0"] * 2000) + "]")(
            _example_text()))
    with pytest.raises(ConfigError, match="2000 axles, more than 1000"):
        case_from_toml(text)


LOGGER_HOSTILE = [
    ("semicolons", "time_s;PE1;PE2\n" + "".join(f"{0.1 * k:.1f};0;0\n" for k in range(20)), "semicolon"),
    ("two-rows", "time_s,PE1,PE2\n0,0,0\n0.1,0,0\n", "at least 10 samples"),
    ("subnormal-steps", "time_s,PE1,PE2\n" + "".join(f"{k * 5e-324!r},0,0\n" for k in range(20)), "time_s"),
    ("time-1e300", "time_s,PE1,PE2\n" + "".join(f"{k * 1e300!r},0,0\n" for k in range(20)), "time_s"),
]


@pytest.mark.parametrize("text, field", [c[1:] for c in LOGGER_HOSTILE], ids=[c[0] for c in LOGGER_HOSTILE])
def test_hostile_logger_records_name_the_file_and_the_fault(tmp_path, capsys, text, field):
    log = tmp_path / "log.csv"
    log.write_text(text, encoding="utf-8")
    rc, _, err = run(["crossings", *EXAMPLE, "--timeseries", log, "--out", tmp_path / "out" / "x.csv"], capsys)
    assert_one_line_error(rc, err, "crossings", [str(log), field])
    assert files_under(tmp_path) == ["log.csv"]


def test_two_outputs_to_one_file_are_refused(tmp_path, capsys):
    """--json naming a figure's file would overwrite it silently."""
    rc, _, err = run(["recommend", "--example", "simply-supported", "--count", "2", "--spacing", "2", "--out",
                      tmp_path / "o", "--json", tmp_path / "o" / "layout.png"], capsys)
    assert_one_line_error(rc, err, "recommend", ["layout.png", "--json"])
    assert files_under(tmp_path) == []


def test_json_outputs_are_strict_json(tmp_path):
    """Rigid springs (inf) and undefined values (NaN) are written as JSON any reader takes."""
    import json

    from sensorplan.io.output import OutputFiles

    with OutputFiles() as files:
        _common.stage_json(files, tmp_path / "x.json", {"springs": [math.inf, -math.inf, 1.0], "t": math.nan})

    def reject(token):
        raise ValueError(token)

    assert json.loads((tmp_path / "x.json").read_text("utf-8"), parse_constant=reject) == {
        "springs": ["inf", "-inf", 1.0], "t": None}


def test_a_tiny_false_alarm_rate_gives_a_finite_threshold():
    """z_(1 - a) as -ndtri(a): 1 - 1e-300 is 1.0 in floating point and gave an infinite threshold (log 0)."""
    from sensorplan.detection.detectability import detectability

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = detectability(example_case("simply-supported"), false_alarm=1e-300, step=2.0)
    d = result.to_dict()
    assert np.all(np.isfinite(np.asarray(d["power"], dtype=float)))


def test_a_case_with_more_sensors_than_the_options_take_is_refused():
    text = _replace('names = ["PE1", "PE2"]', "")(_replace('kinds = ["rotation", "rotation"]', "")(
        _replace("positions = [11.0, 19.0]", "positions = [" + ", ".join(f"{0.01 * i:.2f}" for i in range(1001))
                 + "]")(_example_text())))
    with pytest.raises(ConfigError, match="1001 sensors, more than 1000"):
        case_from_toml(text)


def test_folders_given_as_files_give_one_line_errors(tmp_path, capsys):
    folder = tmp_path / "folder"
    folder.mkdir()
    for argv, field in ([["simulate", "--config", folder, "--out", tmp_path / "x.csv"], "folder"],
                        [["invert", *EXAMPLE, "--data", folder, "--out", tmp_path / "o"], "folder"],
                        [["simulate", *EXAMPLE, "--out", folder], "folder"]):
        rc, _, err = run(argv, capsys)
        assert_one_line_error(rc, err, argv[0], [field])
    assert files_under(tmp_path) == ["folder"]

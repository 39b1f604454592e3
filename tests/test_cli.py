"""Command line: every command on every embedded example, through main([...])."""

import csv
import json
import re
from importlib import resources

import numpy as np
import pytest

import sensorplan as sp
from sensorplan import EXAMPLES, example_case, read_crossings
from sensorplan.cli import main

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|\bnan\b")


def numbers(text):
    return [float(x) for x in _NUMBER.findall(text)]


@pytest.mark.parametrize("example", EXAMPLES)
def test_simulate_writes_readable_crossings(example, tmp_path, capsys):
    out = tmp_path / "sim.csv"
    assert main(["simulate", "--example", example, "--crossings", "3", "--noise", "--seed", "4",
                 "--out", str(out)]) == 0
    case = example_case(example)
    data = read_crossings(out, case.sensors)
    assert len(data) == 3 and data.sensor_names == case.sensors.names
    clean = case.influence_lines().predictions
    noise = data.crossings[0].values - clean
    assert 0.5 < np.std(noise) / np.median(case.noise.std) < 1.5
    assert capsys.readouterr().out == (f"wrote 3 noisy synthetic crossing(s) of '{example}' ({case.sweep.n_loads} load "
                                       f"positions, sensors {', '.join(case.sensors.names)}; rotation in rad, "
                                       f"deflection in m) to {out}\n")
    # without noise the file holds the exact predictions
    assert main(["simulate", "--example", example, "--out", str(out), "--quiet"]) == 0
    np.testing.assert_allclose(read_crossings(out, case.sensors).crossings[0].values, clean, rtol=1e-15)
    assert capsys.readouterr().out == ""


def test_simulate_is_reproducible_from_seed(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for path in (a, b):
        assert main(["simulate", "--example", "three-span", "--noise", "--seed", "9",
                     "--out", str(path)]) == 0
    assert a.read_text() == b.read_text()


def test_simulate_noise_needs_seed(tmp_path, capsys):
    assert main(["simulate", "--example", "openlab-like", "--noise", "--out",
                 str(tmp_path / "x.csv")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--seed" in err[0]
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("example", EXAMPLES)
def test_informativeness_writes_curves_and_figures(example, tmp_path, capsys):
    assert main(["informativeness", "--example", example, "--out", str(tmp_path)]) == 0
    case = example_case(example)
    with open(tmp_path / "informativeness.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["x_left_m", "x_right_m", *case.sensors.names]
    assert len(rows) == case.n_elements + 1
    np.testing.assert_allclose([float(r[0]) for r in rows[1:]], case.mesh.edges[:-1])
    for name in ("informativeness.png", "spectrum.png", "eigenvectors.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    for name in case.sensors.names:
        assert name in printed and "peaks at" in printed


def test_informativeness_positions_name_columns_by_position(tmp_path, capsys):
    assert main(["informativeness", "--example", "simply-supported", "--positions", "2.5,5,10",
                 "--out", str(tmp_path)]) == 0
    header = (tmp_path / "informativeness.csv").read_text().splitlines()[0]
    assert header == "x_left_m,x_right_m,2.5,5,10"
    out = capsys.readouterr().out
    assert "2.5 at    2.500 m: curve peaks at" in out


def test_informativeness_rejects_positions_off_the_bridge(tmp_path, capsys):
    assert main(["informativeness", "--example", "simply-supported", "--positions", "5,25",
                 "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "positions" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "informativeness.csv").exists()


def test_module_entry_point_help():
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "sensorplan", "simulate", "--help"],
                          capture_output=True, text=True, check=True)
    assert "example:" in done.stdout and "sensorplan simulate" in done.stdout


@pytest.mark.parametrize("example", EXAMPLES)
def test_invert_writes_json_and_figures(example, tmp_path, capsys):
    data = tmp_path / "data.csv"
    assert main(["simulate", "--example", example, "--crossings", "4", "--noise", "--seed", "2",
                 "--out", str(data), "--quiet"]) == 0
    js = tmp_path / "post.json"
    assert main(["invert", "--example", example, "--data", str(data), "--elements", "12",
                 "--json", str(js), "--out", str(tmp_path / "fig")]) == 0
    result = json.loads(js.read_text())
    # reference: the same inversion through the Python API (the CLI parses and delegates)
    for key in ("edges_m", "ei_mean", "ei_ci75", "ei_ci95", "springs", "noise_std", "tau",
                "log_evidence", "converged", "n_iter", "excluded_crossings", "hyper_posterior", "warnings",
                "damage", "damage_probability"):
        assert key in result
    assert result["hyperparameters"] == "integrated" and result["hyper_posterior"]["at_bound"] is False
    assert abs(sum(result["hyper_posterior"]["weights"]) - 1.0) < 1e-9
    case = example_case(example)
    coarse = case.with_mesh(sp.Mesh.uniform(case.bridge, 12))
    expected = json.loads(json.dumps(sp.invert(coarse, read_crossings(data, case.sensors)).to_dict()))
    assert result == expected
    assert len(result["edges_m"]) == 13 and len(result["ei_ci95"]) == 12
    assert result["converged"] is True
    assert set(result["noise_std"]) == set(case.sensors.names)
    assert (tmp_path / "fig" / "ei_posterior.png").exists()
    for name in case.sensors.names:
        assert (tmp_path / "fig" / f"fit_{name}.png").exists()
    printed = capsys.readouterr().out
    assert f"log evidence {result['log_evidence']:.3f}" in printed
    assert f"tau = {result['tau']:.4g}" in printed
    assert "posterior written to" in printed


def test_invert_warns_when_the_fit_is_not_to_be_trusted(tmp_path, capsys):
    import json

    import numpy as np

    import sensorplan as sp

    case = example_case("openlab-like")
    clean = sp.simulate_crossings(case, 3)
    rng = np.random.default_rng(5)
    noisy = sp.Crossings(clean.sensor_names, tuple(  # noise 4 times the configured 5 urad
        sp.Crossing(c.label, c.positions, c.values + 20e-6 * rng.standard_normal(c.values.shape), c.load_factor)
        for c in clean))
    data = tmp_path / "noisy.csv"
    sp.write_crossings(data, noisy)
    js = tmp_path / "post.json"
    assert main(["invert", "--example", "openlab-like", "--data", str(data), "--json", str(js),
                 "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "sensorplan invert: warning: the estimated noise is" in captured.err
    assert "sensorplan diagnose" in captured.err and "WARNING: the estimated noise" in captured.out
    assert json.loads(js.read_text())["warnings"][0].startswith("the estimated noise is")


def test_invert_rejects_unit_slip(tmp_path, capsys):
    data = tmp_path / "data.csv"
    assert main(["simulate", "--example", "openlab-like", "--out", str(data), "--quiet"]) == 0
    text = data.read_text().splitlines()
    # values in mm/m would be 1000 times larger but stay below the absolute limit here:
    rows = [text[0]] + [",".join(r.split(",")[:2] + [repr(float(v) * 100) for v in r.split(",")[2:]])
                        for r in text[1:]]
    data.write_text("\n".join(rows) + "\n")
    js = tmp_path / "post.json"
    assert main(["invert", "--example", "openlab-like", "--data", str(data), "--json", str(js),
                 "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unit slip" in err[0] and "PE1" in err[0]
    assert not js.exists()


@pytest.mark.parametrize("example", EXAMPLES)
def test_recommend_prints_table_and_writes_json_and_figures(example, tmp_path, capsys):
    js = tmp_path / "design.json"
    assert main(["recommend", "--example", example, "--count", "2", "--criterion", "D",
                 "--spacing", "1.0", "--json", str(js), "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    # reference: the same recommendation through the Python API (solver timings aside)
    case = example_case(example)
    expected = json.loads(json.dumps(sp.recommend(case, 2, "D", grid=sp.CandidateGrid(spacing=1.0)).to_dict()))
    for payload in (d, expected):
        payload["solver"] = {k: v for k, v in payload["solver"].items() if "time" not in k}
    assert d == expected
    assert d["count"] == 2 and len(d["layout_m"]) == 2 and d["layout_m"] == sorted(d["layout_m"])
    for b in d["baselines"].values():
        assert b is None or b["value"] <= d["value"] + 1e-9
    for name in ("layout.png", "layout_informativeness.png", "posterior_std.png", "criterion_vs_R.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
    printed = capsys.readouterr().out
    # the printed summary shows the computed layout, values and certificate
    assert "  positions [m]: " + ", ".join(f"{x:.2f}" for x in d["layout_m"]) in printed
    assert (f"criterion {d['value']:.6g}; relaxation bound {d['bound']:.6g}" in printed
            and f"certified efficiency >= {100 * d['efficiency']:.2f} %" in printed)
    for name, b in d["baselines"].items():
        row = next(line for line in printed.splitlines() if line.strip().startswith(name))
        assert b is None or f"{b['value']:.6g}" in row
    assert "design written to" in printed


def test_recommend_exclusion_and_fixed_options(tmp_path, capsys):
    js = tmp_path / "d.json"
    assert main(["recommend", "--example", "openlab-like", "--count", "2", "--criterion", "A",
                 "--exclude", "14:16,0:1", "--fixed", "11", "--min-spacing", "1.5", "--json", str(js),
                 "--out", str(tmp_path), "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert all(not (14 <= x <= 16) and x > 1 for x in d["layout_m"])
    assert d["fixed_m"] == [11.0]
    assert capsys.readouterr().out == ""


def test_recommend_bad_zone_is_a_usage_error(tmp_path, capsys):
    assert main(["recommend", "--example", "openlab-like", "--exclude", "14-16", "--out", str(tmp_path)]) == 1
    assert "start:stop" in capsys.readouterr().err


_RATE = re.compile(r"(\d\.\d\d) \((\d+)/(\d+); (\d\.\d\d)-(\d\.\d\d)\)")
_PM = re.compile(r"(\d+\.\d{3})(?:±(\d+\.\d{3}))?(?![\d/)])")


def _summary_rows(printed, labels):
    """The cells of the verification table's rows, one row per label: (mean[, se]) cells, rates, the limit,
    the non-converged count."""
    rows = {}
    for line in printed.splitlines():
        for label in labels:
            if line.startswith(f"  {label} ") and "±" in line:
                rows[label] = line[2 + len(label):]
    return rows


@pytest.mark.parametrize("example", EXAMPLES)
def test_verify_writes_comparison(example, tmp_path, capsys):
    js = tmp_path / "v.json"
    case = example_case(example)
    first = ",".join(f"{x:g}" for x in case.sensors.positions)
    assert main(["verify", "--example", example, "--layout", first, "--layout", "1,2",
                 "--scenarios", "2", "--seed", "3", "--json", str(js), "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    assert len(d["layouts"]) == 2 and d["layouts"][1]["layout_m"] == [1.0, 2.0]
    assert d["layouts"][0]["layout_m"] == list(case.sensors.positions)
    assert (d["seed"], d["n_crossings"], d["severity"], d["damage_length_m"]) == (3, 10, 0.25, 2.0)
    for entry in d["layouts"]:
        assert entry["n_scenarios"] == 2 + case.bridge.n_spans + 5  # local, span softenings, controls
        for key in ("detection_rate", "false_alarm_rate", "coverage95", "control_coverage95"):
            assert 0.0 <= entry[key] <= 1.0
    # the printed table shows the numbers written to the JSON: rates with their counts and Wilson intervals,
    # "no detections" for the localisation error when nothing was detected, never nan
    printed = capsys.readouterr().out
    assert "nan" not in printed
    labels = [first.replace(",", ", "), "1, 2"]
    rows = _summary_rows(printed, labels)
    for label, entry in zip(labels, d["layouts"]):
        row = rows[label]
        for match, key in zip(_RATE.findall(row), ("detection_rate", "false_alarm_rate")):
            mean, count, n, lo, hi = match
            assert float(mean) == pytest.approx(entry[key], abs=5e-3)
            assert (int(count), int(n)) == (entry[key + "_count"], entry[key + "_n"])
            np.testing.assert_allclose([float(lo), float(hi)], entry[key + "_ci95"], atol=5e-3)
        pms = [(float(m), float(se) if se else None) for m, se in _PM.findall(_RATE.sub("", row))]
        keys = ["rmse"] + ([] if entry["localisation_error_m"] is None else ["localisation_error_m"])
        keys += ["detection_limit", "coverage95", "band_width"]
        assert len(pms) == len(keys) and (entry["localisation_error_m"] is not None or "no detections" in row)
        for (mean, se), key in zip(pms, keys):
            assert mean == pytest.approx(entry[key], abs=5e-4)
            if key != "detection_limit" and se is not None:
                assert se == pytest.approx(entry[key + "_se"], abs=5e-4)
        assert row.rstrip().endswith(f"{entry['non_converged_count']}/{entry['non_converged_n']}")
    assert (tmp_path / "verification.png").exists()
    assert "Verification:" in printed


def test_verify_json_equals_the_python_result(tmp_path):
    # reference: verify_layouts with the same options (same seed, same scenarios)
    js = tmp_path / "v.json"
    assert main(["verify", "--example", "simply-supported", "--layout", "4,16", "--layout", "0,10,20",
                 "--scenarios", "1", "--verify-crossings", "3", "--seed", "3", "--json", str(js),
                 "--out", str(tmp_path), "--quiet"]) == 0
    result = sp.verify_layouts(example_case("simply-supported"), [[4.0, 16.0], [0.0, 10.0, 20.0]], n_locations=1,
                               n_crossings=3, seed=3)
    assert json.loads(js.read_text()) == json.loads(json.dumps(result.to_dict()))


@pytest.mark.slow
def test_recommend_verify_adds_verification(tmp_path, capsys):
    js = tmp_path / "d.json"
    assert main(["recommend", "--example", "simply-supported", "--count", "2", "--spacing", "2",
                 "--verify", "--scenarios", "2", "--json", str(js), "--out", str(tmp_path), "--quiet"]) == 0
    d = json.loads(js.read_text())
    verification = d["verification"]
    feasible = [(name, b) for name, b in d["baselines"].items() if b is not None]
    # the verified layouts are the recommended one and every feasible baseline, in that order
    assert [entry["name"] for entry in verification["layouts"]] == ["recommended"] + [n for n, _ in feasible]
    assert [entry["layout_m"] for entry in verification["layouts"]] == [d["layout_m"]] + [b["layout_m"]
                                                                                        for _, b in feasible]
    assert "equally_spaced" in dict(feasible)
    assert json.loads((tmp_path / "verification.json").read_text()) == verification


def test_verify_rejects_layout_off_the_bridge(tmp_path, capsys):
    assert main(["verify", "--example", "simply-supported", "--layout", "5,25", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "layout" in err[0]


@pytest.mark.slow
def test_diagnose_writes_json_and_figures(tmp_path, capsys):
    data = tmp_path / "d.csv"
    assert main(["simulate", "--example", "simply-supported", "--crossings", "3", "--noise", "--seed", "5",
                 "--out", str(data), "--quiet"]) == 0
    js = tmp_path / "diag.json"
    assert main(["diagnose", "--example", "simply-supported", "--data", str(data), "--json", str(js),
                 "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    gap = d["gap"]
    assert set(gap) >= {"rms_residual", "systematic_rms", "noise_rms", "by_sensor", "worst_positions_m"}
    assert d["causes"] == [] and d["unexplained"] is False
    assert d["statement"].startswith("none: the model is adequate")
    assert d["verdict"]["status"] == "no_change"
    # the noise of effect-free data is the configured 2 urad (three crossings: within 25 %)
    assert 0.75 * 2e-6 < gap["noise_rms"] < 1.25 * 2e-6 and gap["systematic_rms"] < gap["noise_rms"]
    # the printed summary shows the numbers written to the JSON
    captured = capsys.readouterr()
    printed = captured.out.splitlines()
    assert printed[0] == f"Verdict (no_change): {d['verdict']['summary']}"  # the one verdict first
    assert printed[1] == f"Sim-to-real gap: not significant (p = {gap['p_value']:.2g})"
    # per sensor in its own unit (µrad), never rad and m summed
    for name, s in gap["by_sensor"].items():
        assert any(line.startswith(f"  {name}: residual rms {1e6 * s['rms_residual']:.3g} µrad,") for line in printed)
    for effect in d["effects"]:
        row = next(line for line in printed if line.startswith(f"  {effect['name']} "))
        assert numbers(row)[:1] == [pytest.approx(effect["log_bayes_factor"], abs=0.05)]
    # progress on stderr: the base fit and every candidate effect
    assert "sensorplan diagnose: base fit" in captured.err
    assert f"effect {len(d['effects'])} of {len(d['effects'])}" in captured.err
    assert f"  statement: {d['statement']}" in printed
    for name in ("residual_map.png", "shrinkage.png", "ei_before_after.png"):
        assert (tmp_path / name).exists()


def test_diagnose_fits_a_dense_record_in_bins_and_reports_the_readings(tmp_path, capsys):
    # a reading every 0.05 m through the CSV format: the case file's sweep, simulate, diagnose; the truth has the
    # middle bearing settling (2 x 48 EI / L^3 with EI = 1e10 N m^2, L = 15 m) on a finer mesh
    text = (resources.files("sensorplan.examples") / "openlab-like.toml").read_text()
    model = text.replace("step = 0.25", "step = 0.05") + "\n[noise]\ncorrelation_length = 0.5\n"
    (tmp_path / "model.toml").write_text(model)
    truth = model.replace("vertical_springs = [inf, inf, inf]", "vertical_springs = [inf, 2.84e8, inf]")
    (tmp_path / "truth.toml").write_text(truth.replace("elements = 30", "elements = 90"))
    data, js = tmp_path / "d.csv", tmp_path / "d.json"
    assert main(["simulate", "--config", str(tmp_path / "truth.toml"), "--crossings", "6", "--noise", "--seed", "2",
                 "--out", str(data), "--quiet"]) == 0
    assert main(["diagnose", "--config", str(tmp_path / "model.toml"), "--data", str(data), "--json", str(js),
                 "--out", str(tmp_path)]) == 0
    d = json.loads(js.read_text())
    printed = capsys.readouterr().out
    assert d["causes"] == ["vertical_support_spring"]
    assert d["binning"]["size"] > 1 and f"fitted in bins of {d['binning']['size']} consecutive readings" in printed
    (finding,) = d["findings"]["vertical_support_spring"]
    assert finding["low"] < 2.84e8 < finding["high"]
    # the residuals are those of the readings (5 urad of noise each), not of the bins
    for s in d["shrinkage"].values():
        assert s["rms_after"] == pytest.approx(5e-6, rel=0.1)


def test_recommend_kind_follows_the_case_and_refuses_unit_mixups(tmp_path, capsys):
    cfg = tmp_path / "defl.toml"
    cfg.write_text("""
[bridge]
spans = [20.0]
ei = 1e10
elements = 10
[vehicle]
axle_offsets = [0.0]
axle_loads = [1e5]
[sensors]
positions = [10.0]
kinds = ["deflection"]
noise_std_mm = 0.05
""")
    js = tmp_path / "d.json"
    assert main(["recommend", "--config", str(cfg), "--count", "1", "--spacing", "2", "--json", str(js),
                 "--out", str(tmp_path), "--quiet"]) == 0
    assert json.loads(js.read_text())["kind"] == "deflection"
    assert main(["recommend", "--config", str(cfg), "--kind", "rotation", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--noise-std" in err[0]

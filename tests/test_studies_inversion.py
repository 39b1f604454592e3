"""Smoke runs of the inversion study scripts (their printed findings are checked)."""

import re
import runpy
import sys


def run(script, tmp_path, monkeypatch, capsys, *extra):
    monkeypatch.setattr(sys, "argv", [script, "--out", str(tmp_path), *extra])
    runpy.run_path(script, run_name="__main__")
    return capsys.readouterr().out


def test_noise_levels(tmp_path, monkeypatch, capsys):
    out = run("studies/inversion/paper_noise_levels.py", tmp_path, monkeypatch, capsys)
    assert "bands contract: yes" in out
    assert "damage sharpens: yes" in out
    assert (tmp_path / "inversion_noise_levels.png").is_file()


def test_bias_variance_quick(tmp_path, monkeypatch, capsys):
    out = run("studies/inversion/paper_bias_variance.py", tmp_path, monkeypatch, capsys, "--quick")
    assert "lambda by quasi-optimality once per R" in out
    # one verdict per R and method (quick: R = 2, 8), seeded: the paper's U-shaped RMSE over N appears
    # with tau by evidence for both R; tau by quasi-optimality once at N_ref misses it for R = 2
    verdicts = re.findall(r"R=(\d): minimum RMSE [\d.]+ % at N = (\d+); (.*)", out)
    assert verdicts == [
        ("2", "5", "NOT U-shaped: RMSE grows with N from the coarsest mesh"),  # quasi-optimality
        ("8", "21", "U-shaped"),
        ("2", "11", "U-shaped"),  # evidence
        ("8", "21", "U-shaped"),
    ]
    assert (tmp_path / "inversion_bias_variance.png").is_file()


def test_openlab_frame(tmp_path, monkeypatch, capsys):
    out = run("studies/inversion/openlab_frame.py", tmp_path, monkeypatch, capsys)
    assert out.count("span 1 identified softer than span 2") == 2  # 6 and 30 elements
    assert (tmp_path / "inversion_openlab_30el.png").is_file()


def test_calibration_integrated_quick(tmp_path, monkeypatch, capsys):
    # 40 replicates per case (deterministic seeds): the integrated bands are calibrated within a
    # wide tolerance and tau never reaches a grid end; evidence maximisation covers less.
    import json

    out = run("studies/inversion/calibration_integrated.py", tmp_path, monkeypatch, capsys, "--quick")
    assert "40 replicates per case" in out
    results = json.loads((tmp_path / "calibration_integrated.json").read_text())
    assert set(results) == {"white", "ar1", "low-signal", "time"}
    for name, case in results.items():
        integrated, evidence = case["summary"]["integrated"], case["summary"]["evidence"]
        assert integrated["n"] == evidence["n"] == 40
        assert 0.88 <= integrated["coverage95"] <= 0.995, (name, integrated)
        assert 0.62 <= integrated["coverage75"] <= 0.86, (name, integrated)
        assert integrated["at_bound"] == 0 and integrated["warned"] <= 1, (name, integrated)
        assert evidence["coverage95"] < integrated["coverage95"], (name, evidence, integrated)

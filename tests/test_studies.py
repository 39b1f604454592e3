"""Smoke runs of the study scripts (their printed findings are checked)."""

import runpy
import sys

import pytest


@pytest.mark.parametrize("script,expect", [
    ("studies/fisher/paper_single_span.py", "sensor x/L=1/4 : curve peaks at x/L = 0.338"),
    ("studies/fisher/paper_two_span.py", "sensor just right of the support"),
])
def test_fisher_studies(script, expect, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", [script, "--out", str(tmp_path)])
    runpy.run_path(script, run_name="__main__")
    assert expect in capsys.readouterr().out


@pytest.mark.slow
def test_criteria_vs_verification_study_smoke(tmp_path, monkeypatch, capsys):
    # the quick run: one bridge, every registered criterion's layout and the evenly spaced one, verified
    script = "studies/design/criteria_vs_verification.py"
    out = tmp_path / "table.txt"
    monkeypatch.setattr(sys, "argv", [script, "--quick", "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        runpy.run_path(script, run_name="__main__")
    assert exc.value.code == 0
    from sensorplan.design.criteria import CRITERIA

    rows = [line.split() for line in out.read_text().splitlines() if line.startswith("simply-supported")]
    expected = [c for c in ("D", "A", "E", "Ds", "detect") if c in CRITERIA] + ["even"]
    assert [r[1].rstrip("*") for r in rows] == expected
    assert sum(r[1].endswith("*") for r in rows) == 1  # one layout first by verification
    for r in rows:  # detection rate and limit are probabilities
        assert 0.0 <= float(r[2].split("±")[0]) <= 1.0 and 0.0 <= float(r[3]) <= 1.0

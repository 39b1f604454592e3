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

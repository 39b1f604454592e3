"""Progress on stderr: a line per stage, counts with the time left, nothing with --quiet, and the same
numbers whether progress is shown or not.  Tests never depend on the timing text itself."""

import io
import json

from sensorplan.cli import main
from sensorplan.cli._progress import Progress, duration


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_stage_lines_and_counts_with_the_time_left():
    clock, stream = Clock(), io.StringIO()
    progress = Progress("verify", clock=clock, stream=stream, interval=3.0)
    progress.stage("verifying 2 layouts", unit="scenario inversions")
    for done in range(1, 11):
        clock.now += 2.0  # 2 s per unit
        progress.count(done, 10)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "sensorplan verify: verifying 2 layouts"
    # a count at most every 3 s, each with the time left from the pace so far (2 s per unit), and the total
    assert lines[1:] == ["sensorplan verify: 2/10 scenario inversions, about 16 s left",
                         "sensorplan verify: 4/10 scenario inversions, about 12 s left",
                         "sensorplan verify: 6/10 scenario inversions, about 8 s left",
                         "sensorplan verify: 8/10 scenario inversions, about 4 s left",
                         "sensorplan verify: 10/10 scenario inversions in 20 s"]
    quiet = io.StringIO()
    silent = Progress("verify", quiet=True, clock=clock, stream=quiet)
    silent.stage("x")
    silent.count(1, 1)
    assert quiet.getvalue() == ""
    assert [duration(t) for t in (0.2, 12.4, 185.0)] == ["under 1 s", "12 s", "3 min 05 s"]


def test_verify_shows_progress_unless_quiet_and_the_numbers_do_not_change(tmp_path, capsys):
    argv = ["verify", "--example", "simply-supported", "--layout", "5,15", "--scenarios", "1", "--verify-crossings",
            "2", "--seed", "4"]
    assert main([*argv, "--json", str(tmp_path / "a.json"), "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("sensorplan verify: verifying 1 layout(s) by inversion of synthetic damage")
    total = 1 + 1 + 5  # one location, one span softening, five controls
    assert err[-1].startswith(f"sensorplan verify: {total}/{total} scenario inversions in ")
    assert main([*argv, "--json", str(tmp_path / "b.json"), "--out", str(tmp_path / "b"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    assert json.loads((tmp_path / "a.json").read_text()) == json.loads((tmp_path / "b.json").read_text())


def test_invert_and_detectability_say_what_they_compute(tmp_path, capsys):
    data = tmp_path / "d.csv"
    assert main(["simulate", "--example", "simply-supported", "--crossings", "2", "--noise", "--seed", "1",
                 "--out", str(data), "--quiet"]) == 0
    assert main(["invert", "--example", "simply-supported", "--data", str(data), "--out", str(tmp_path / "i")]) == 0
    assert capsys.readouterr().err.startswith("sensorplan invert: identifying EI on ")
    assert main(["detectability", "--example", "simply-supported", "--out", str(tmp_path / "d")]) == 0
    assert capsys.readouterr().err.startswith("sensorplan detectability: mapping the detection power of ")

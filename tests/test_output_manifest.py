"""Output folders hold one run's files: what the previous run wrote and this one did not rewrite is removed
(and said), never a file sensorplan did not write, changed since, or read as an input; a data file missing a
sensor column of the case is said on stderr."""

import json
from pathlib import Path

import pytest

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.io.csvio import write_crossings
from sensorplan.io.manifest import MANIFEST, Manifest
from sensorplan.io.output import OutputFiles


def _run(folder, names, *, keep=(), fail=False):
    with pytest.raises(RuntimeError) if fail else _nothing():
        with OutputFiles(folder=folder, keep=keep) as files:
            for name in names:
                files.write_text(folder / name, f"{name} of this run\n")
            if fail:
                raise RuntimeError("disk full")
    return files.removed


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_the_previous_runs_files_go_the_users_stay(tmp_path):
    out = tmp_path / "out"
    assert _run(out, ["a.json", "a.png", "sub/b.json"]) == ()
    assert set(Manifest.read(out).files) == {"a.json", "a.png", "sub/b.json"}
    (out / "notes.txt").write_text("mine")  # the user's own file
    (out / "a.png").write_text("edited by the user")  # changed since sensorplan wrote it
    removed = _run(out, ["c.json", "a.json"])
    assert removed == ("sub/b.json",)
    assert sorted(p.name for p in out.rglob("*") if p.is_file()) == [MANIFEST, "a.json", "a.png", "c.json",
                                                                      "notes.txt"]
    # a failed run removes nothing and keeps the manifest of the last complete one
    assert _run(out, ["d.json"], fail=True) == ()
    assert set(Manifest.read(out).files) == {"c.json", "a.json"} and (out / "c.json").exists()
    # an input of the run is never removed, even one sensorplan wrote
    assert _run(out, ["e.json"], keep=[out / "c.json"]) == ("a.json",)
    assert (out / "c.json").exists() and not (out / "a.json").exists()


def test_a_manifest_never_reaches_outside_its_folder(tmp_path):
    out, victim = tmp_path / "out", tmp_path / "victim.txt"
    victim.write_text("x")
    _run(out, ["a.json"])
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"]["../victim.txt"] = Manifest.of(tmp_path, [victim]).files["victim.txt"]
    (out / MANIFEST).write_text(json.dumps(manifest))
    _run(out, ["b.json"])
    assert victim.exists()
    (out / MANIFEST).write_text("not json")  # a broken manifest is ignored, not an error
    assert _run(out, ["c.json"]) == ()


def test_a_new_command_in_the_same_folder_removes_the_old_outputs_and_says_so(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["informativeness", "--example", "simply-supported", "--positions", "5,10", "--out", str(out),
                 "--quiet"]) == 0
    first = {p.name for p in out.iterdir()} - {MANIFEST}
    assert first == {"informativeness.csv", "informativeness.png", "spectrum.png", "eigenvectors.png"}
    assert main(["detectability", "--example", "simply-supported", "--layout", "5,10", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.strip().splitlines()
    assert printed[-1] == (f"removed 4 file(s) of the previous run in {out} that this run did not rewrite: "
                           "eigenvectors.png, informativeness.csv, informativeness.png, spectrum.png")
    assert {p.name for p in out.iterdir()} == {MANIFEST, "detectability.json", "detectability.png"}


def test_a_data_file_without_a_sensor_column_says_which_sensors_it_uses(tmp_path, capsys):
    case = sp.example_case("openlab-like")
    data = sp.simulate_crossings(case, 2, noise=True, rng=3)
    only = Path(tmp_path / "pe1.csv")
    write_crossings(only, data.sensor_subset(["PE1"]))
    assert main(["invert", "--example", "openlab-like", "--data", str(only), "--out", str(tmp_path / "inv"),
                 "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (f"sensorplan invert: warning: {only} has no column for sensor(s) PE2 of the case: using PE1, "
                      "leaving out PE2.")



def test_diagnose_says_which_sensors_a_partial_data_file_uses(tmp_path, capsys):
    case = sp.example_case("simply-supported")
    data = sp.simulate_crossings(case, 3, noise=True, rng=5)
    only = Path(tmp_path / "t1.csv")
    write_crossings(only, data.sensor_subset(["T1"]))
    assert main(["diagnose", "--example", "simply-supported", "--data", str(only), "--out", str(tmp_path / "d"),
                 "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (f"sensorplan diagnose: warning: {only} has no column for sensor(s) T2 of the case: using T1, "
                      "leaving out T2.")

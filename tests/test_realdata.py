"""The openLAB PE 2.1 load-test reader and study (studies/realdata/openlab_pe21.py).

The data (Herbers, Richter, Walker, Marx, TU Dresden, DOI 10.25532/OPARA-852,
CC BY-SA 4.0) are not part of the repository.  The checks of the plateaus
and of the fits run from the derived plateau table the repository ships
(studies/realdata/derived/openlab_pe21_plateaus.csv, CC BY-SA 4.0 with the
attribution in derived/README.md), so they run on a fresh clone.  Only the
checks of the reader itself (that it reproduces the shipped table from the
raw catman files) skip when ../shared/realdata/openlab_pe21_static_loadtest
is absent.  Reference values are the approximate plateau medians of the
"Quick look" table in that folder's SOURCE.md (written by whoever mirrored
the data, not by us), e.g. step 1: F ~74-75 kN, LWA_1 -0.96, LWA_3 3.15,
LWA_4 5.05 mm.
"""

import csv
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from realdata_table import plateaus_from_table  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "studies" / "realdata" / "openlab_pe21.py"
DATA = REPO.parent / "shared" / "realdata" / "openlab_pe21_static_loadtest"
DERIVED = REPO / "studies" / "realdata" / "derived"


def _load_study():
    spec = importlib.util.spec_from_file_location("openlab_pe21_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


study = _load_study()


@pytest.fixture(scope="module")
def plateaus():
    """The plateaus of the seven load steps, from the derived table in the repository."""
    return plateaus_from_table(study)


@pytest.fixture(scope="module")
def raw_plateaus():
    """The plateaus read from the raw catman files (absent on a fresh clone)."""
    if not DATA.is_dir():
        pytest.skip(f"raw openLAB data not available at {DATA}; the derived table is checked instead")
    return study.read_plateaus(DATA)


def test_derived_table_is_shipped_with_its_attribution():
    assert study.TABLE == DERIVED / "openlab_pe21_plateaus.csv" and study.TABLE.is_file()
    readme = (DERIVED / "README.md").read_text(encoding="utf-8")
    for credit in ("Herbers", "Richter", "Walker", "Marx", "TU Dresden", "10.25532/OPARA-852", "CC BY-SA 4.0",
                   "openlab_pe21_plateaus.csv"):
        assert credit in readme, credit


@pytest.fixture(scope="module")
def elastic(plateaus):
    return study.fit([p for p in plateaus if p.step in (1, 2)], hyper="evidence")


def test_missing_data_gives_a_clear_error(tmp_path):
    with pytest.raises(study.DataMissing, match="OPARA-852"):
        study.data_dir(tmp_path)


def test_data_folder_is_found_relative_to_the_repository():
    assert study.DATA_DIR == DATA


def test_despike_follows_the_readme_rule():
    u = np.array([60.0, 60.2, 300.0, 310.0, 60.3, 60.1, 60.0])
    out, removed = study.despike(u, window=1)
    assert removed == 2
    assert np.isnan(out[2]) and np.isnan(out[3])
    np.testing.assert_allclose(out[[0, 1, 4, 5, 6]], u[[0, 1, 4, 5, 6]])


def test_step1_matches_the_quick_look(plateaus):
    p = plateaus[0]
    # SOURCE.md quick look, step 1: F ~74-75 kN (ours is net of a 0.3 kN pre-load reading),
    # LWA_1 -0.96, LWA_2 ~0.0, LWA_3 3.15, LWA_4 5.05, LWA_5 ~0.7-0.8 mm
    assert 73.0e3 < p.force < 76.0e3
    np.testing.assert_allclose(p.deflection[[0, 2, 3]], [-0.96e-3, 3.15e-3, 5.05e-3], atol=0.1e-3)
    assert abs(p.deflection[1]) < 0.1e-3
    assert 0.6e-3 < p.deflection[4] < 0.85e-3


def test_steps_2_and_3_match_the_quick_look(plateaus):
    # SOURCE.md: step 2 ~127-129 kN, -1.65, 6.32, 10.1 mm; step 3 ~204-205 kN, -2.9, 11.9, 20.3 mm
    p2, p3 = plateaus[1], plateaus[2]
    assert 125.0e3 < p2.force < 130.0e3
    np.testing.assert_allclose(p2.deflection[[0, 2, 3]], [-1.65e-3, 6.32e-3, 10.1e-3], atol=0.15e-3)
    assert 203.0e3 < p3.force < 206.0e3
    np.testing.assert_allclose(p3.deflection[[0, 2, 3]], [-2.9e-3, 11.9e-3, 20.3e-3], atol=0.3e-3)


def test_untared_steps_are_referred_to_their_own_pre_load_state(plateaus):
    by_step = {p.step: p for p in plateaus}
    assert [p.tared for p in plateaus] == [True] * 5 + [False] * 2
    for s in (1, 2, 3, 4, 5):  # tared: the pre-load reading is ~0
        assert np.max(np.abs(by_step[s].baseline)) < 0.2e-3
    for s in (6, 7):
        # same zero as the previous file (lines 28-29 repeat the step-5 tare), back to back:
        # the pre-load reading equals the previous file's end reading
        np.testing.assert_allclose(by_step[s].baseline, by_step[s - 1].end, atol=0.2e-3)
        assert by_step[s].baseline[3] > 1.0e-3  # LWA_4 starts from the accumulated residual
    # the load-induced LWA_4 is below u_max by about that residual
    assert 45e-3 < by_step[6].deflection[3] < 50e-3
    assert 54e-3 < by_step[7].deflection[3] < 59e-3


def test_force_and_deflection_grow_and_noise_is_small(plateaus):
    force = np.array([p.force for p in plateaus])
    lwa4 = np.array([p.deflection[3] for p in plateaus])
    assert np.all(np.diff(force) > 0) and np.all(np.diff(lwa4) > 0)
    np.testing.assert_allclose(lwa4, [p.u_max for p in plateaus], rtol=0.06, atol=1.5e-3)
    noise = np.array([p.noise for p in plateaus])
    assert np.all(np.isfinite(noise)) and np.all(noise > 0) and np.all(noise < 0.5e-3)


def test_table_round_trips_through_the_study_writer(plateaus, tmp_path):
    # reading the shipped table and writing it with the study's writer reproduces it byte for byte
    path = study.write_table(plateaus, tmp_path / "t.csv")
    assert path.read_text() == study.TABLE.read_text()
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["step"]) for r in rows] == list(range(1, 8))
    assert list(rows[0]) == study.COLUMNS


def test_reader_reproduces_the_shipped_table(raw_plateaus, plateaus):
    # the raw catman files, read again, give the shipped table (to its printed digits)
    with open(study.TABLE) as fh:
        shipped = list(csv.DictReader(fh))
    for new, old in zip(study.table_rows(raw_plateaus), shipped, strict=True):
        for key, value in zip(study.COLUMNS, new):
            if key == "file":
                assert value == old[key]
            else:
                assert float(value) == pytest.approx(float(old[key]), rel=1e-3, abs=1e-7), key
    for raw, table in zip(raw_plateaus, plateaus, strict=True):
        np.testing.assert_allclose(raw.end, table.end, atol=2e-7)


def test_elastic_fit_reproduces_steps_1_and_2(elastic):
    case, result = elastic
    assert result.converged
    # Tolerance 0.75 mm (7.5 % of the 10 mm step-2 peak): the secant flexibility grows by 15 %
    # from step 1 to step 2, which one linear model must split between the two steps.
    for f in result.fits:
        np.testing.assert_allclose(f.model[:, 0], f.data[:, 0], atol=0.75e-3)
    assert study.max_residual(result) < 0.75e-3
    # span 2 (loaded): effective EI a few 1e8 N m^2, well determined
    lo, hi = result.credible_interval(0.95)[1]
    assert 3e8 < lo < result.ei_map[1] < hi < 1e9


def test_elastic_fit_finds_a_finite_bearing_stiffness_at_axis_30(elastic):
    case, result = elastic
    k = result.springs()["vertical_2"]
    # LWA_5 moves ~0.5-1 mm per 100 kN: the bearing is far from rigid, and the data pin it down
    assert 2e7 < k["low"] < k["map"] < k["high"] < 5e8
    compression = study.reaction_30(case, result) / k["map"]
    assert 0.3e-3 < compression < 1.2e-3  # per 100 kN at 24.3 m


def test_later_steps_soften(plateaus, elastic):
    steps = study.per_step([plateaus[0], plateaus[-1]], study.SPAN_MESH, start=elastic[1])
    first, last = steps[0][2], steps[-1][2]
    assert first.converged and last.converged
    assert last.ei_map[1] < 0.6 * first.ei_map[1]
    assert last.credible_interval(0.95)[1, 1] < first.credible_interval(0.95)[1, 0]


def test_study_runs_and_reports(plateaus, tmp_path, capsys, monkeypatch):
    # the whole study, fed the shipped table in place of the raw files when these are absent
    folder = DATA
    if not DATA.is_dir():
        monkeypatch.setattr(study, "read_plateaus", lambda folder=None: plateaus)
        monkeypatch.setattr(study, "data_dir", lambda folder=None: study.TABLE)
        folder = None
    study.main(tmp_path, tmp_path / "table.csv", folder)
    out = capsys.readouterr().out
    for text in ("Elastic reference", "vert_30", "softening: EI 15-30 m at step 7", "load share"):
        assert text in out
    assert (tmp_path / "table.csv").read_text() == study.TABLE.read_text()
    assert (tmp_path / "openlab_pe21_deflection_lines.png").is_file()
    assert (tmp_path / "openlab_pe21_ei_per_step.png").is_file()

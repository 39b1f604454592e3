"""Gap diagnosis on the openLAB PE 2.1 load test with LWA_5 withheld (studies/realdata/openlab_pe21_diagnosis.py).

The data (Herbers, Richter, Walker, Marx, TU Dresden, DOI 10.25532/OPARA-852,
CC BY-SA 4.0) are not part of the repository; the tests run from the plateau
table derived from them, which the repository ships
(studies/realdata/derived/openlab_pe21_plateaus.csv, CC BY-SA 4.0 with the
attribution in derived/README.md), so they run on a fresh clone.

The finding asserted is the honest one: with the support laser withheld,
steps 1-2 do not point at the bearing at x = 30 m.  The support spring is not
named, its stiffness posterior equals its prior and the gap does not shrink,
because an EI of span 2 about 5 % lower absorbs what the settlement does to LWA_1..LWA_4
except for ~0.03 mm.  With LWA_5 in the data the same refit pins the bearing
down and reproduces the reading.  The tests use a subset of the effect library
(the support spring plus the two effects that win on these data) so that they
run in about ten seconds per diagnosis (marked slow); with the full library the
support spring is not named either and dynamic_amplification still ranks
first (see the README).

On all seven steps load-dependent stiffness ranks first but leaves a significant
gap (the curvature concentrates under the load, which one EI per span cannot
follow): the diagnosis reports it as partial and the gap as unexplained, which
studies/realdata/openlab_pe21_softening.py shows to be right (the gap test is
calibrated after the correction; the remainder is real).
"""

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from sensorplan.diagnosis.gap import systematic_f_test

sys.path.insert(0, str(Path(__file__).parent))
from realdata_table import plateaus_from_table  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "studies" / "realdata" / "openlab_pe21_diagnosis.py"


def _load_study(name, script):
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, script)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


study = _load_study("openlab_pe21_diagnosis_study", SCRIPT)
softening = _load_study("openlab_pe21_softening_study", SCRIPT.with_name("openlab_pe21_softening.py"))


@pytest.fixture(scope="module")
def plateaus():
    """The plateaus of the seven load steps, from the derived table in the repository."""
    return plateaus_from_table(study.pe21)


@pytest.fixture(scope="module")
def withheld(plateaus):
    return study.run(plateaus, (1, 2), effects=study.QUICK_EFFECTS)


@pytest.fixture(scope="module")
def with_lwa5(plateaus):
    return study.run(plateaus, (1, 2), sensors=study.pe21.LASERS, effects=[study.VERTICAL])


def test_missing_data_gives_a_clear_error(tmp_path):
    with pytest.raises(study.DataMissing, match="OPARA-852"):
        study.main(tmp_path, quick=True)


def test_base_model_is_rigid_and_blind_at_30_m():
    case = study.make_case()
    assert all(math.isinf(k) for k in case.bridge.vertical_springs)
    assert case.sensors.names == ("LWA_1", "LWA_2", "LWA_3", "LWA_4")
    assert max(case.sensors.positions) < 30.0


@pytest.mark.slow
def test_withheld_laser_does_not_point_at_the_support(withheld):
    d = withheld.diagnosis
    # the gap of steps 1-2 is not significant: its mean over the steps is ~0 and the
    # step-to-step difference (15 % non-linearity) counts as scatter
    assert not d.gap.significant
    # (measured: 0.065 of the noise rms with the log-normal hyperprior, < 0.05 with the PC prior)
    assert d.gap.systematic_rms < 0.1 * d.gap.noise_rms
    # the support spring is neither named nor ranked first, and the evidence is against it
    assert study.VERTICAL not in d.causes
    assert d.effects[0].name != study.VERTICAL
    assert withheld.vertical.log_bayes_factor < 1.0
    # no support parameter learns anything: posterior = prior
    for s in withheld.supports:
        assert abs(s.moved) < 0.5
    s2 = withheld.supports[2]
    assert s2.information < 0.1
    # hence the implied settlement at 30 m is the prior's: its 95 % range spans 4 decades
    assert s2.settlement_high / s2.settlement_low > 1e3
    assert s2.settlement_low < withheld.lwa5["slope"] < s2.settlement_high
    # and the gap does not shrink
    assert withheld.vertical.rms_after > 0.98 * d.gap.rms_residual
    assert withheld.vertical.heldout_rms_after > 0.95 * withheld.base_heldout_rms


@pytest.mark.slow
def test_what_ranks_first_is_the_step_to_step_non_linearity(withheld):
    # step 2 is ~15 % more flexible per kN than step 1: an EI that falls with the load level fits
    # that best, but with two steps the evidence is not strong enough to name it
    d = withheld.diagnosis
    assert d.effects[0].name == study.LOAD_DEPENDENT
    assert d.effects[0].parameters["log_ei_per_100kN"]["map"] < 0
    assert d.effects[0].log_bayes_factor < 3 and d.causes == ()
    # held-out scores with two steps stay finite and of the order of the data (not -1e20)
    assert all(abs(e.heldout_score_gain) < 100 for e in d.effects)


@pytest.fixture(scope="module")
def seven_steps(plateaus):
    return study.run(plateaus, study.ALL_STEPS)


@pytest.fixture(scope="module")
def corrected(plateaus):
    """The seven steps refitted with load-dependent stiffness as diagnose's final refit does (the partial model)."""
    return softening.refit(study.make_case(), study.make_crossings(plateaus), (study.LOAD_DEPENDENT,))


# The numbers below were measured by studies/realdata/openlab_pe21_softening.py (its docstring holds the table):
# the gap test after the correction is calibrated (200 null replicates from the corrected model as fitted: KS p
# 0.78, share below 0.05 0.065), and data from a truth whose softening concentrates under the load (each step
# fitted with span 2 split at 21 m) leave a significant gap after the correction in 86 % of replicates, with the
# same LWA_4 shrinkage as the real data (5.08 -> 0.72 mm there, 5.07 -> 0.70 mm here).  One EI per span that falls
# with the load cannot follow that shape, so the honest diagnosis names load-dependent stiffness first and says
# the gap is only partly explained.
@pytest.mark.slow
def test_seven_steps_rank_load_dependent_stiffness_first_and_leave_the_gap_partly_explained(seven_steps, corrected):
    d = seven_steps.diagnosis
    # a static jack test: no dynamics, one sample per step (no drift, no offset per step); nothing impossible named
    assert {"dynamic_amplification", "thermal_drift", "sensor_offset"} <= set(d.not_offered)
    assert not (set(d.causes) | set(d.partial)) & set(d.not_offered)
    # load-dependent stiffness first, far ahead (measured: log BF 11.2, held-out gain 37; position_offset next, 2.0)
    first, second = d.effects[:2]
    assert first.name == study.LOAD_DEPENDENT and first.converged
    assert first.log_bayes_factor > 8 and first.log_bayes_factor - second.log_bayes_factor > 6
    assert first.heldout_score_gain > 20
    # EI falls with the load: the whole 95 % interval of the change per 100 kN is negative (measured -21 %)
    (finding,) = first.findings
    assert finding.unit == "%" and finding.high < 0
    # as the secant flexibility LWA_4 / F does without any model (derived table: x 2.14 from step 1 to 7)
    lwa4 = [p.deflection[3] / p.force for p in plateaus_from_table(study.pe21)]
    assert lwa4[-1] > 1.3 * lwa4[0]
    # but it leaves a significant gap: reported as partial, not as a cause, and the verdict says unexplained
    assert d.causes == () and d.partial == (study.LOAD_DEPENDENT,) and d.unexplained
    assert d.statement.startswith("unexplained") and d.verdict.status == "model_error"
    assert "unexplained" in d.verdict.summary and study.LOAD_DEPENDENT not in d.verdict.summary  # partial: no cause
    assert "not causes: load_dependent_stiffness reduces the gap but leaves it significant" in d.summary()
    # the partial model: the largest reading's residual shrinks by a factor of seven (5.07 -> 0.70 mm measured) ...
    rms = corrected.rms_by_sensor
    assert rms[3] < 0.2 * d.shrinkage["LWA_4"].rms_before
    assert corrected.gap.significant  # measured p = 1.1e-4 (5.2e-6 before)
    # the diagnosis itself reports what the partial model explains, as the study's refit measures it
    assert d.partial_gap is not None and d.partial_gap.significant
    assert d.partial_gap.p_value == pytest.approx(corrected.gap.p_value, rel=0.05)
    assert d.partial_shrinkage["LWA_4"].rms_after == pytest.approx(rms[3], rel=0.05)
    line = next(t for t in d.summary().splitlines() if "before -> with load_dependent_stiffness" in t)
    assert "LWA_4 5.05 mm -> 0.70" in line  # measured 5.05 -> 0.701 mm (the fit's own rms, before the held-out one)
    # ... and what remains has one sign per laser from step 3 on and grows with the load: LWA_1 and LWA_3 below
    # the model, LWA_4 above it (curvature concentrated under the load), up to 2.15 mm = 11 x the 0.2 mm laser level
    res = corrected.residuals[2:]
    assert np.all(res[:, 0] < 0) and np.all(res[:, 2] < 0) and np.all(res[:, 3] > 0)
    assert np.max(np.abs(res)) > 5 * study.NOISE_STD


def test_the_corrected_gap_test_counts_the_effect_and_the_systematic_columns(corrected):
    # 7 steps x 4 lasers = 28 readings; parameters: EI of the two spans and the change per 100 kN (3); systematic
    # columns: one per laser (4, none in the span of the model's Jacobian: LWA_2 reads nothing in the model)
    assert systematic_f_test(corrected.problem, corrected.theta)[2] == 28 - 3 - 4


@pytest.mark.slow
def test_the_gap_test_after_the_correction_is_calibrated(plateaus, corrected):
    # null data from the corrected model as fitted (0.5 m mesh) plus noise at the refit's level; the study's 200
    # replicates gave KS p 0.78; 40 here
    case = study.make_case()
    forces = np.array([p.force for p in plateaus])
    truth = softening.corrected_truth(case, forces, corrected)
    sigma = corrected.noise_scale * study.NOISE_STD
    rows = softening.simulate(case, forces, truth, sigma, 40, np.random.default_rng(5))
    assert stats.kstest(rows[:, 0], "uniform").pvalue > 0.01
    assert np.mean(rows[:, 0] < 0.05) <= 0.15


@pytest.mark.slow
def test_with_lwa5_the_same_refit_finds_the_bearing(with_lwa5):
    s2 = with_lwa5.supports[2]
    assert s2.information > 0.9
    assert 4e7 < math.exp(s2.map) < 1.6e8  # N/m; openlab_pe21.py finds 8.1e7 with invert
    # the implied settlement per 100 kN matches the LWA_5 reading (least-squares slope 0.64 mm)
    assert s2.settlement == pytest.approx(with_lwa5.lwa5["slope"], rel=0.25)
    assert s2.settlement_low < with_lwa5.lwa5["slope"] < s2.settlement_high
    assert 0.5e-3 < with_lwa5.lwa5["slope"] < 0.8e-3


@pytest.mark.slow
def test_ei_absorbs_the_settlement_in_the_kept_lasers(withheld, with_lwa5):
    bridge, ei = study.fitted_model(with_lwa5.case, with_lwa5.diagnosis)
    fp = study.fingerprint(bridge.vertical_springs[2], ei, withheld.crossings)
    assert fp["raw"][3] > 0.25e-3  # at the same EI the bearing adds ~0.3 mm at LWA_4 per 100 kN
    assert fp["rms"] < 0.05e-3  # after refitting EI only ~0.03 mm is left
    assert fp["rms"] < 0.2 * withheld.diagnosis.gap.rms_residual
    assert 0.9 < fp["ei_rigid"][1] / ei[1] < 1.0  # span 2 a few per cent softer instead


@pytest.mark.slow
def test_report_prints(withheld, capsys):
    study.print_outcome(withheld)
    out = capsys.readouterr().out
    for text in ("Verdict (", "statement:", "implied settlement at x = 30 m", "withheld LWA_5", "2 (x = 30.0)"):
        assert text in out

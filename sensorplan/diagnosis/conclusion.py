"""What a diagnosis concludes: its one-line statement and its one verdict (:class:`~sensorplan.verdict.Verdict`).

The statement says which effects explain the gap; the verdict is what an
owner reads first, with the statuses of :mod:`sensorplan.verdict`:

``insufficient_data``
    No test of the gap could be run (a single crossing too short for the
    structure test).
``model_error``
    The case's model with EI fitted leaves a significant gap, or effects
    were named as its causes, or a gap remains after them: a damage
    conclusion drawn from that model cannot be trusted.  The summary names
    the causes (or says "unexplained") and ``next_step`` what to do: write
    the corrected case for effects the case holds (springs, sensor
    positions, axle loads), correct the records for effects of the data
    (offsets, drift, gains, amplification, load positions), or check the
    installation when no effect of the library explains the gap.
``departure``
    The model explains the data once EI is fitted, but EI departs from its
    nominal value: the nominal log EI lies outside the fitted EI's
    simultaneous band somewhere (:func:`~sensorplan.verdict.band_departures`),
    or the nominal model itself leaves a significant gap that the fitted EI
    closes (an EI change of any extent, or an effect an EI change can mimic
    -- a sensor 0.6 m off its position moved EI by up to 60 % inside its
    band).  Where and by how much.  The library has no local stiffness loss
    among its effects, so a diagnosis never concludes ``local_damage``: a
    local loss shows as a departure, and the damage detector of ``invert``
    says whether it is one.
``no_change``
    The nominal model is adequate: no significant gap with or without EI
    fitted, and EI within its band.

Owns: :func:`statement`, :func:`gap_verdict`.  May import: the verdict (foundations) and numpy.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..verdict import BAND_LEVEL, Verdict, band_departures

__all__ = ["EIFit", "gap_verdict", "statement"]


def statement(causes, *, unexplained, significant):
    """The one-line statement: causes found, partly explained, unexplained or adequate.

    ``causes`` and a remaining gap go together only when the selection
    policy names partial causes (``SelectionPolicy.name_partial``).
    """
    if causes and not unexplained:
        return "causes found: " + ", ".join(causes)
    if causes:
        return ("partly explained by " + ", ".join(causes) + "; a significant gap remains (unexplained)"
                if significant else "causes found: " + ", ".join(causes)
                + "; the residual structure after the fit is significant (unexplained remainder)")
    if unexplained:
        return "unexplained: a significant gap remains that no candidate effect explains"
    return "none: the model is adequate (no significant gap)"


@dataclass(frozen=True, eq=False)
class EIFit:
    """The fitted EI a verdict reads: element ``edges`` [m], posterior mean and std of log EI, the nominal log EI."""

    edges: np.ndarray
    log_mean: np.ndarray
    log_std: np.ndarray
    log_nominal: np.ndarray


def gap_verdict(gap, nominal_gap, ei: EIFit, *, causes: Sequence[str], unexplained: bool, in_case: Mapping,
                partial: Sequence[str] = (), springs_differ: Sequence[str] = (), confounded: Sequence[str] = (),
                findings: Mapping | None = None, text: str = "") -> Verdict:
    """The :class:`~sensorplan.verdict.Verdict` of a diagnosis.

    ``gap``: of the case's model with EI fitted; ``nominal_gap``: of the
    nominal model (EI and springs as the case holds them); ``causes``: the
    named effects (``in_case``: name -> whether the case holds it);
    ``partial``: effects that reduced the gap but left it significant (not
    causes); ``springs_differ``: where the case's elastic springs differ
    from their configured values; ``confounded``: effects an EI change can
    mimic; ``findings``: cause -> its :class:`~.results.Finding` s (where
    each cause acts is said in the summary); ``text``: the statement.
    """
    findings = {} if findings is None else findings
    stretches = band_departures(ei.edges, ei.log_mean, ei.log_std, ei.log_nominal)
    change = ei.log_mean - ei.log_nominal
    evidence = {
        "statement": text, "causes": list(causes), "partial": list(partial), "unexplained": bool(unexplained),
        "gap": {"significant": bool(gap.significant), "p_value": float(gap.p_value), "testable": bool(gap.testable)},
        "nominal_gap": {"significant": bool(nominal_gap.significant), "p_value": float(nominal_gap.p_value)},
        "band": {"level": BAND_LEVEL, "simultaneous": "Bonferroni over elements", "outside": stretches},
        "max_ei_change": float(np.max(np.abs(np.expm1(change)))) if change.size else 0.0,
        "springs_differ": list(springs_differ), "confounded": list(confounded),
        "findings": {name: [f.text for f in findings.get(name, ())] for name in causes},
    }
    if not gap.testable:
        return Verdict("insufficient_data", "Insufficient data: the gap between the model and the data cannot be "
                       "tested (a single crossing too short for the structure test, or no reading left to estimate the noise "
                       "from once the model is fitted).", evidence=evidence,
                       next_step="record two crossings or more (`sensorplan recommend --target-power` for how many)")
    if gap.significant or causes or unexplained:
        return _model_error(causes, unexplained, in_case, evidence, gap.significant, findings)
    springs = ("; the case's elastic springs differ from their configured values: " + ", ".join(springs_differ)
               if springs_differ else "")
    step = ("write the identified springs into the case: `sensorplan diagnose --write-case FILE`"
            if springs_differ else None)
    if stretches or nominal_gap.significant:
        return _departure(stretches, change, ei.edges, nominal_gap.significant, len(confounded), springs, step,
                          evidence)
    return Verdict("no_change", "No change: the model is adequate (no significant gap between the nominal model and "
                   f"the data) and EI stays within its nominal band{springs}.", evidence=evidence, next_step=step)


def _model_error(causes, unexplained, in_case, evidence, significant, findings):
    """The model-error verdict: the causes (or unexplained), where they act (their first two findings), what next."""
    gap = ("a significant systematic gap between the model and the data" if significant or not causes else
           "a systematic difference between the model and the data (below the gap test's level; the effects' "
           "refits find it)")
    if causes:
        found = "explained by " + " and ".join(
            c + (f" ({'; '.join(f.where for f in findings[c][:2])})" if findings.get(c) else "") for c in causes)
        case_side = [c for c in causes if in_case.get(c, False)]
        data_side = [c for c in causes if not in_case.get(c, False)]
        steps = []
        if case_side:
            steps.append(f"write the corrected case ({', '.join(case_side)} identified) with `sensorplan diagnose "
                         "--write-case FILE` and invert with it")
        if data_side:
            steps.append(f"correct the records for {', '.join(data_side)} (properties of the data, not of the case) "
                         "before inverting")
        step = "; ".join(steps)
    else:
        found = "which no effect of the diagnosis's library explains (unexplained)"
        step = ("check each sensor's sign, position and unit, the supports (a bearing that settles or lifts off) and "
                "the recorded load positions; the effect is outside the library (shear deformation, vibration, a "
                "support in one-sided contact), so no correction is offered")
    return Verdict("model_error", f"Model error: {gap}, {found}; EI fitted with the model as it is cannot be "
                   "trusted.", evidence=evidence,
                   next_step=step)


def _departure(stretches, change, edges, nominal_failed, n_confounded, springs, step, evidence):
    """The departure verdict: where and by how much EI departs from nominal, and on what evidence."""
    if stretches:
        worst = max(stretches, key=lambda s: abs(s["z"]))
        where, loss = (worst["start"], worst["stop"]), worst["loss"]
        how = f"outside the simultaneous {100 * BAND_LEVEL:.0f} % band"
    else:
        where, loss = _largest_change(change, edges)
        how = f"within the simultaneous {100 * BAND_LEVEL:.0f} % band"
    why = (" the nominal model leaves a significant gap that the fitted EI closes;" if nominal_failed else "")
    mimic = (f" An EI change cannot be told apart here from {n_confounded} candidate effect(s) (evidence: "
             "confounded)." if nominal_failed and n_confounded else "")
    return Verdict("departure", f"EI departs from its nominal value:{why} the largest change is at {where[0]:.1f}-"
                   f"{where[1]:.1f} m ({_percent(loss)}, {how}){springs}.{mimic}", location_m=where, loss=loss,
                   evidence=evidence, next_step=step)


def _largest_change(change, edges):
    """((start, stop) [m], loss) of the stretch around the largest |log EI change| where it is at least half of it."""
    k = int(np.argmax(np.abs(change)))
    big = np.abs(change) >= 0.5 * abs(change[k])
    same = np.sign(change) == np.sign(change[k])
    lo = hi = k
    while lo > 0 and big[lo - 1] and same[lo - 1]:
        lo -= 1
    while hi + 1 < change.size and big[hi + 1] and same[hi + 1]:
        hi += 1
    return (float(edges[lo]), float(edges[hi + 1])), float(-np.expm1(change[k]))


def _percent(loss):
    return f"{100 * loss:.0f} % loss" if loss >= 0 else f"{-100 * loss:.0f} % stiffer"

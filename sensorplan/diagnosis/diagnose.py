"""Sim-to-real gap diagnosis: where model and data disagree, which effect causes it.

1. Base fit: the case's model with EI (and the case's elastic springs, as
   ``invert`` estimates them) identified, hyperparameters by evidence.
2. Where: residuals split into crossing-to-crossing scatter (noise) and the
   mean over crossings (systematic part), per sensor and load position,
   with Ljung-Box tests on the whitened residuals (:mod:`.gap`).
3. Which effect (screening): every candidate effect that can act on the
   data is refitted jointly with EI, warm-started at the base MAP with the
   base hyperparameters held (:mod:`.selection.refit`), and ranked by its
   Laplace log Bayes factor, with its held-out predictive gain (blocks of
   load positions held out in every crossing; whole crossings for static
   load steps) from rank updates of the linearised problem
   (:mod:`.selection.heldout`).  Non-converged fits are flagged and never
   selected.  When the model a fit starts from is grossly distorted (its
   noise scale above the policy's ``distorted``) and a support-spring fit
   from its MAP does not converge, it is also fitted from the nominal EI
   and springs; the better fit counts (:mod:`.selection.context`).
4. Stepwise selection (:mod:`.selection.select`): forward steps, noise
   scale re-estimated after each pick, backward test, look-ahead, swaps.
5. The selected model is refitted with its hyperparameters; its EI and
   bands are the EI after correction.  If its gap is still significant the
   picks are not named as causes (:func:`.selection.select.named_causes`):
   they are partial, the gap is unexplained and the case's model is refitted
   instead.
6. Confounding: an effect whose data signature a plausible EI change can
   mimic is reported as confounded, with the candidate sensor position that
   best separates the two (:mod:`.confounding`).
7. The statement and the one verdict (:mod:`.conclusion`), which also reads
   the gap of the nominal model (the case's EI and springs).

Owns: :func:`diagnose`.  May import: inference, model, the executors and the diagnosis's parts.
"""

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from .._executors import executor_for
from .._threads import single_threaded
from ..inference.screening import check_case_data_scale
from ..model.crossings import Crossings
from ..model.prior import GMRFPrior
from .conclusion import EIFit, gap_verdict, statement
from .confounding import confounding
from .effects import CaseSprings, effect_names, make_effect
from .entries import corrected_model, effect_entry
from .gap import residual_gap
from .joint.binning import KEEP, bin_crossings, choose_size
from .joint.fits import blocks_of, integrated_fit
from .joint.problem import JointProblem
from .results import Binning, GapDiagnosis, SensorShrinkage
from .selection.candidate import Candidate
from .selection.context import DiagnosisContext
from .selection.heldout import fold_rows, heldout, make_folds
from .selection.passes import fit_models
from .selection.policy import DEFAULT_POLICY
from .selection.refit import quick_fit
from .selection.select import named_causes, select

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["diagnose"]


@dataclass(frozen=True, eq=False)
class _Data:
    """The data as fitted (``case``, ``crossings``: whitened bins of a dense record) and as recorded (``raw_*``)."""

    case: Any
    crossings: Any
    raw_case: Any
    raw_crossings: Any
    binning: Binning | None

    def on_rows(self, problem, effects, prior, estimate_springs):
        """``problem`` on the recorded readings (itself when the data were not binned)."""
        if self.raw_crossings is problem.crossings:
            return problem
        return JointProblem(self.raw_case, self.raw_crossings, effects, prior, estimate_springs=estimate_springs)


@dataclass(frozen=True, eq=False)
class _Base:
    """The base fit: its problem, the fit with hyperparameters integrated, its quick fit and score, its gap.

    ``nominal_gap``: the gap of the nominal model (the case's EI and springs).
    """

    problem: Any
    full: Any
    candidate: Candidate
    gap: Any
    residual_map: Any
    nominal_gap: Any

    @property
    def ei(self):
        return np.exp(self.candidate.fit.theta[:self.problem.n_elements])


@single_threaded
def diagnose(case: "Case", crossings: Crossings, *, effects: "Sequence[str] | None" = None,
             prior: GMRFPrior | None = None, bf_threshold: float = 3.0, gain_threshold: float = 3.0,
             n_folds: int = 4, max_rounds: int = 3, estimate_springs: bool = True,
             progress: "Callable[[str], None] | None" = None, workers: int = 1, scheduler: str | None = None,
             scheduler_timeout: float = 10.0,
             check_scale: bool | str = True) -> GapDiagnosis:
    """Diagnose the gap between ``case`` and measured ``crossings``.

    Parameters
    ----------
    case : Case
    crossings : Crossings
    effects : sequence of str, optional
        Candidate effects (default: every registered effect,
        :func:`~sensorplan.diagnosis.effects.effect_names`); those that cannot
        act on the data are not offered (see ``not_offered``).
    prior : GMRFPrior, optional
    bf_threshold : float
        Log Bayes factor an effect needs to be selected (3 is "strong" on
        Jeffreys' scale); also the margin within which other effects are
        reported as alternatives.
    gain_threshold : float
        Total held-out log predictive gain the next effect needs (and a gain
        consistent across folds).
    n_folds, max_rounds : int
        Held-out folds; largest number of selected effects.
    estimate_springs : bool
        Estimate the case's elastic springs with EI, as ``invert`` does.
    progress : callable, optional
        Called with a line of text at each stage (base fit, effect k of n,
        selection round, final refit).
    workers : int
        Processes for the screening of the candidate effects.
    scheduler, scheduler_timeout : str, float
        Screen on a Dask cluster instead (the ``dask`` extra): a scheduler
        address or ``"local"`` (a LocalCluster of ``workers`` processes), as in
        :func:`sensorplan.verify_layouts`; the result does not depend on it.
    check_scale : bool or str
        Refuse data far larger or smaller than the model predicts (a unit
        slip); a string names the data source in the message.

    Returns
    -------
    GapDiagnosis
    """
    say = progress if progress is not None else (lambda text: None)
    if check_scale:
        check_case_data_scale(case, crossings, source=check_scale if isinstance(check_scale, str) else "data")
    prior = GMRFPrior() if prior is None else prior
    policy = replace(DEFAULT_POLICY, bf_threshold=bf_threshold, gain_threshold=gain_threshold, max_rounds=max_rounds)
    offered, not_offered = _offered(effect_names() if effects is None else effects, crossings)
    executor = partial(executor_for, workers, scheduler, timeout=scheduler_timeout, name="--scheduler")
    return _diagnose(case, crossings, prior, offered, not_offered, policy, n_folds=n_folds,
                     estimate_springs=estimate_springs, say=say, executor=executor)


def _diagnose(case, crossings, prior, offered, not_offered, policy, *, n_folds, estimate_springs, say, executor):
    """The stages of :func:`diagnose`; ``executor()`` opens where the screening and selection run.

    This process, a process pool or a Dask cluster: the results come in the
    order of the effects, the same on any of them.
    """
    data = _fitted_data(case, crossings, prior, say)
    folds = make_folds(data.crossings, n_folds)
    base, ctx = _base_fit(data, prior, offered, folds, policy=policy, estimate_springs=estimate_springs, say=say)
    with executor() as runner:
        results, selection = _screen_and_select(ctx, list(offered), base, policy=policy, folds=bool(folds), say=say,
                                                runner=runner)
    say("final refit of the selected model with its hyperparameters")
    final = _final_fit(data, base, [offered[n] for n in selection.selected], selection.current, prior,
                       estimate_springs=estimate_springs)
    causes = named_causes(selection.selected, gap_remains=final.gap.significant, policy=policy)
    partly = None  # the partial effects' refit and held-out statistics: what they explain is still reported
    if len(causes) < len(selection.selected):
        say("the selected effects leave a significant gap: no cause named; final refit of the case's model")
        partly = (final, selection.current.held)
        selection = replace(selection, selected=(), alternatives={}, current=base.candidate,
                            partial=selection.selected)
        final = _final_fit(data, base, [], base.candidate, prior, estimate_springs=estimate_springs)
    say("confounding with EI")
    others = [offered[r.name] for r in results if r.name not in selection.selected]
    confounded = confounding(data.case, data.crossings, others, prior=prior, theta_base=base.candidate.fit.theta,
                             alpha=base.full.noise_scale, tau=base.full.tau, estimate_springs=estimate_springs)
    return _diagnosis(data, base, final=final, selection=selection, results=results, confounded=confounded,
                      offered=offered, not_offered=not_offered, estimate_springs=estimate_springs, partly=partly)


def _screen_and_select(ctx, names, base, *, policy, folds, say, runner):
    """(one :class:`EffectFit` per candidate fitted alone, best first; the :class:`Selection` of the causes)."""
    screened = fit_models(ctx, {n: ([n], None) for n in names}, base.candidate.fit.log_evidence + policy.bf_threshold,
                          policy=policy, runner=runner, say=say, label="")
    results = [effect_entry(n, screened[n], base.candidate, base.ei) for n in names]
    results.sort(key=lambda r: (r.converged, -math.inf if math.isnan(r.log_bayes_factor) else r.log_bayes_factor),
                 reverse=True)
    return results, select(ctx, names, screened, base.candidate, policy=policy, folds=folds, say=say, runner=runner)


def _offered(names, crossings):
    """({name: effect} of the candidates that can act on ``crossings``, {name: why not} of the others)."""
    offered, not_offered = {}, {}
    for n in names:
        effect = make_effect(n)
        reason = effect.applicable(crossings)
        if reason is None:
            offered[n] = effect
        else:
            not_offered[n] = reason
    return offered, not_offered


def _fitted_data(case, crossings, prior, say):
    """The data as fitted: dense records in whitened bins of consecutive readings (the exact model of a bin).

    The gap before and after is reported on the readings themselves.
    """
    size = choose_size(case, crossings, prior)
    if size == 1:
        return _Data(case, crossings, case, crossings, None)
    fitted_case, fitted = bin_crossings(case, crossings, size)
    step = float(np.median([np.median(np.diff(c.raw_positions)) for c in fitted]))
    binning = Binning(size=size, width_m=round(size * step, 9), rows=int(sum(c.raw_positions.size for c in fitted)),
                      bins=int(sum(c.n_loads for c in fitted)), keep=KEEP)
    say(f"fitting bins of {size} consecutive readings ({size * step:.2f} m; they keep >= "
        f"{100 * KEEP:.0f} % of the information on EI)")
    return _Data(fitted_case, fitted, case, crossings, binning)


def _base_fit(data, prior, offered, folds, *, policy, estimate_springs, say):
    """The base fit (:class:`_Base`) and the selection's context at its hyperparameters."""
    say("base fit (EI and the case's elastic springs, hyperparameters integrated as in invert)")
    problem = JointProblem(data.case, data.crossings, [], prior, estimate_springs=estimate_springs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        full = integrated_fit(problem, prior)
    alpha, tau = full.noise_scale, full.tau
    fit = quick_fit(problem, full.theta_mode, alpha, tau, policy=policy)
    _, _, cross, load, _ = problem.rows(fit.theta)
    test_masks = fold_rows(data.crossings, folds, cross, load)
    candidate = Candidate(fit, heldout(fit, test_masks))
    rows = data.on_rows(problem, [], prior, estimate_springs)
    gap, residual_map = residual_gap(rows, fit.theta, alpha)
    nominal_gap, _ = residual_gap(rows, problem.theta0, alpha)
    predictions = [y for y, _ in problem.predict(problem.theta0, jacobian=False)]  # the nominal model
    ctx = DiagnosisContext(data.case, data.crossings, prior=prior, effects=offered, estimate_springs=estimate_springs,
                           noise_scale=alpha, tau=tau, blocks=blocks_of(problem, fit.theta), test_masks=test_masks,
                           predictions=predictions, policy=policy)
    return _Base(problem, full, candidate, gap, residual_map, nominal_gap), ctx


@dataclass(frozen=True, eq=False)
class _Final:
    """The selected model refitted with its hyperparameters, at ``theta`` (its findings, its gap, its state)."""

    problem: Any
    fit: Any
    theta: np.ndarray
    converged: bool
    gap: Any
    findings: dict
    springs: tuple
    corrected: Any


def _final_fit(data, base, effects, current, prior, *, estimate_springs):
    """The selected model (``effects``) refitted from the selection's fit ``current`` with its hyperparameters."""
    problem = JointProblem(data.case, data.crossings, effects, prior, estimate_springs=estimate_springs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        fit = integrated_fit(problem, prior, start=current.fit.theta, noise_scale=base.full.noise_scale,
                             tau=base.full.tau)
    # a tau node with an effect parameter out of the model's domain (exp overflow of an axle load) makes the
    # mixture mean invalid: then the MAP at the hyper-posterior's mode, else the selection's own MAP (the final
    # fit is then reported as not converged)
    valid = [t for t in (fit.mixture.mean, fit.theta_mode) if problem.in_domain(t)]
    theta = valid[0] if valid else current.fit.theta
    gap, _ = residual_gap(data.on_rows(problem, effects, prior, estimate_springs), theta, fit.noise_scale)
    std = np.sqrt(np.clip(np.diag(fit.mixture.covariance), 0, None))
    findings = {b.name: tuple(b.effect.describe(b, problem, theta[sl], std[sl]))
                for b, sl in zip(problem.blocks, problem.slices)}
    springs = findings.pop(CaseSprings.name, ())  # the case's own springs are no cause
    return _Final(problem, fit, theta, bool(valid) and fit.converged, gap, findings, springs,
                  corrected_model(problem, theta, std))


def _shrinkage(base, after, held):
    """sensor -> :class:`SensorShrinkage` from the base fit to the refit ``after`` (held-out stats ``held``)."""
    problem, base_held = base.problem, base.candidate.held
    kinds = dict(zip(problem.sensor_names, problem.sensors.kinds))
    return {n: SensorShrinkage(
        kind=kinds[n], rms_before=base.gap.by_sensor[n].rms_residual, rms_after=after.gap.by_sensor[n].rms_residual,
        heldout_rms_before=None if base_held is None else float(base_held.rms_by_sensor[i]),
        heldout_rms_after=None if held is None else float(held.rms_by_sensor[i]))
        for i, n in enumerate(problem.sensor_names)}


def _diagnosis(data, base, *, final, selection, results, confounded, offered, not_offered, estimate_springs,
               partly=None):
    """The :class:`GapDiagnosis` of the stages' results (``partly``: the partial effects' refit, held)."""
    selected, held = selection.selected, selection.current.held
    # no cause named: the gap of the case's model (the base fit, or its refit) is what remains
    unexplained = bool(final.gap.significant or (not selected and base.gap.significant))
    text = statement(selected, unexplained=unexplained, significant=base.gap.significant)
    # a candidate a cause holds as a special case is not a second finding: the data cannot tell them apart
    includes = {s: inside for s in selected
                if (inside := tuple(n for n in offered[s].contains if n in offered and n not in selected))}
    differs = [f.where for f in final.springs if f.differs]
    if differs:
        text += "; the case's elastic springs differ from the configured values: " + ", ".join(differs)
    problem, base_held = base.problem, base.candidate.held
    shrinkage = _shrinkage(base, final, held)
    n_base, n_el = problem.n_elements, final.problem.n_elements
    verdict = gap_verdict(base.gap, base.nominal_gap, _ei_fit(data, final), causes=selected, unexplained=unexplained,
                          in_case={n: offered[n].in_case for n in selected}, partial=selection.partial,
                          springs_differ=differs, confounded=[c.name for c in confounded], findings=final.findings,
                          text=text)
    return GapDiagnosis(
        base.gap, effects=tuple(results), causes=tuple(selected), unexplained=unexplained,
        confounded=tuple(confounded), statement=text, verdict=verdict, gap_after=final.gap,
        ei_edges=data.case.mesh.edges.copy(), ei_base=base.ei, ei_final=np.exp(final.theta[:n_el]),
        residual_map=base.residual_map, ei_base_band=tuple(np.exp(b[:n_base]) for b in base.full.band()),
        ei_final_band=tuple(np.exp(b[:n_el]) for b in final.fit.band()),
        findings=final.findings, alternatives=dict(selection.alternatives), not_offered=not_offered,
        shrinkage=shrinkage, springs=final.springs,
        springs_estimated=bool(estimate_springs and data.case.bridge.spring_names),
        noise_scale=float(final.fit.noise_scale), converged=bool(base.full.converged and final.converged),
        heldout_ratio_after=None if held is None else held.ratio,
        heldout_ratio_before=None if base_held is None else base_held.ratio, corrected_model=final.corrected,
        binning=data.binning, includes=includes, partial=tuple(selection.partial),
        partial_gap=None if partly is None else partly[0].gap,
        partial_shrinkage={} if partly is None else _shrinkage(base, *partly))


def _ei_fit(data, final):
    """The final refit's log EI (posterior mean and std of the mixture over the hyperparameters) and its nominal."""
    n_el = final.problem.n_elements
    std = np.sqrt(np.clip(np.diag(final.fit.mixture.covariance)[:n_el], 0, None))
    return EIFit(data.case.mesh.edges, final.theta[:n_el], std, final.problem.theta0[:n_el])

"""Sim-to-real gap diagnosis: where model and data disagree, which effect causes it.

1. Base fit: the case's model with EI (and the case's elastic springs, as
   ``invert`` estimates them) identified, hyperparameters by evidence.
2. Where: residuals split into crossing-to-crossing scatter (noise) and the
   mean over crossings (systematic part), per sensor and load position,
   with Ljung-Box tests on the whitened residuals.
3. Which effect (screening): every candidate effect that can act on the
   data is refitted jointly with EI, warm-started at the base MAP with the
   base hyperparameters held (:mod:`.refit`), and ranked by its Laplace log
   Bayes factor, with its held-out predictive gain (blocks of load
   positions held out in every crossing; whole crossings for static load
   steps) from rank updates of the linearised problem.  Non-converged fits
   are flagged and never selected.  When the model a fit starts from is
   grossly distorted (its noise scale above ``DISTORTED``: EI twisted to
   mimic a settled bearing) and a support-spring fit from its MAP does not
   converge, it is also fitted from the nominal EI and springs; the better
   fit counts.  After a pick the noise scale is re-estimated, so once the
   selected effects explain most of the gap this second start stops.
4. Stepwise selection (:mod:`.selection`): the effect with the largest
   Bayes factor among those with a significant held-out gain over the
   current model is added (effects within ``bf_threshold`` of it are
   reported as alternatives); the noise scale is re-estimated at the new
   model, the others are retested given the selection, and earlier picks
   that the new one makes redundant are dropped (backward test).  With two
   or more selected, a swap pass replaces a selected effect by another one
   when that raises the evidence without losing held-out score.
5. The selected model is refitted with its hyperparameters; its EI and
   bands are the EI after correction.
6. Confounding: an effect whose data signature a plausible EI change can
   mimic is reported as confounded, with the candidate sensor position that
   best separates the two.
"""

import math
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .._executors import executor_for
from .._threads import single_threaded
from ..inference.screening import check_case_data_scale
from ..model.crossings import Crossings
from ..model.prior import GMRFPrior
from .binning import KEEP, bin_crossings, choose_size
from .confounding import confounding
from .describe import describe, informed
from .effects import EFFECTS, make_effect
from .gap import residual_gap
from .joint import JointProblem
from .refit import blocks_of, fold_rows, heldout, integrated_fit, quick_fit, warm_start
from .results import EffectFit, GapDiagnosis
from .selection import fit_models, select

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["diagnose"]

# base noise scale above which the base EI is taken as distorted by the gap: the support-spring effects are then
# also fitted from the nominal EI (_Context.fit)
DISTORTED = 3.0


def _folds(crossings, n_folds=4):
    """Masks (train, test) per fold.

    With load sweeps (>= 8 positions per crossing) every fold holds out two
    contiguous blocks of load positions in every crossing, one in each half
    of the sweep (blocks b and b + n_folds of 2 n_folds), so parameters of a
    single crossing (offsets, drift, amplification, trigger shifts) are
    estimated from the rest of that crossing.  With fewer positions (static
    load steps) whole crossings are held out.
    """
    n_c = len(crossings)
    folds = []
    if all(c.n_loads >= 8 for c in crossings):
        for b in range(n_folds):
            test = []
            for c in crossings:
                mask = np.zeros(c.n_loads, bool)
                blocks = np.array_split(np.arange(c.n_loads), 2 * n_folds)
                mask[np.concatenate([blocks[b], blocks[b + n_folds]])] = True
                test.append(mask)
            folds.append(([~m for m in test], test))
        return folds
    if n_c >= 2:
        groups = np.array_split(np.arange(n_c), min(n_folds, n_c))
        for g in groups:
            train = [np.full(c.n_loads, i not in g) for i, c in enumerate(crossings)]
            test = [np.full(c.n_loads, i in g) for i, c in enumerate(crossings)]
            folds.append((train, test))
    return folds


class _Context:
    """What every refit shares: the data, the base fit's hyperparameters and blocks, the fold rows."""

    def __init__(self, case, crossings, prior, estimate_springs, alpha, tau, blocks, test_masks, predictions):
        self.case, self.crossings, self.prior = case, crossings, prior
        self.estimate_springs, self.alpha, self.tau = estimate_springs, alpha, tau
        self.blocks, self.test_masks, self.predictions = blocks, test_masks, predictions

    def fit(self, names, blocks=None, *, initial=True, max_iter=40, floor=None, budget=False):
        problem = JointProblem(self.case, self.crossings, [make_effect(n) for n in names], self.prior,
                               estimate_springs=self.estimate_springs)
        start = warm_start(problem, self.blocks if blocks is None else blocks)
        effect, sl = problem.block(names[-1])
        init = effect.initial(problem, self.predictions) if initial else None
        if init is not None:
            # a moment estimate against the nominal model (a sign flip, a unit slip): the base MAP is
            # distorted by exactly what the effect explains, so this fit starts from the nominal EI
            start = warm_start(problem, {"log_ei": problem.theta0[:problem.n_elements]} if blocks is None
                               else blocks)
            start[sl] = init
        fit = quick_fit(problem, start, self.alpha, self.tau, max_iter=max_iter, floor=floor, budget=budget)
        distorted = self.alpha > DISTORTED  # the noise scale of the model the fit starts from
        if effect.frees and initial and distorted and (fit is None or not (fit.converged or fit.abandoned)):
            # a support that settles or restrains is what the base EI twisted to mimic (EI off by orders of
            # magnitude next to a settled bearing): from there the spring's fit crawls or stops in a worse
            # optimum, so it also starts from the nominal EI and springs (other effects' blocks kept); the
            # better fit counts
            nominal = problem.theta0.copy()
            for e, s in zip(problem.effects, problem.slices):
                if not e.structural:
                    nominal[s] = start[s]
            cold = quick_fit(problem, nominal, self.alpha, self.tau, max_iter=max_iter, floor=floor, budget=budget)
            if cold is not None and (fit is None or (cold.converged, cold.log_evidence) > (fit.converged,
                                                                                             fit.log_evidence)):
                fit = cold
        return self._scored(fit)

    def resume(self, fit, *, max_iter=40, floor=None):
        """``fit`` continued from where it stopped."""
        return self._scored(quick_fit(fit.problem, fit.theta, self.alpha, self.tau, max_iter=max_iter, floor=floor))

    def _scored(self, fit):
        held = heldout(fit, self.test_masks) if fit is not None and fit.converged else None
        return fit, held


def _entry(name, fit, held, base, base_held, ei_base):
    if fit is None:
        return EffectFit(name=name, log_bayes_factor=math.nan, heldout_score_gain=None, rms_after=math.nan,
                         heldout_rms_after=None, parameters={}, ei_shift=(), max_ei_shift=math.nan,
                         converged=False)
    problem = fit.problem
    effect, sl = problem.block(name)
    std = np.sqrt(np.clip(np.diag(fit.covariance)[sl], 0, None))
    shift = np.exp(fit.theta[:problem.n_elements]) / ei_base - 1.0
    gain = None if held is None or base_held is None else float(np.sum(held.log_density - base_held.log_density))
    res = np.concatenate([r.ravel() for r in problem.residuals(fit.theta)])
    return EffectFit(
        name=name, log_bayes_factor=float(fit.log_evidence - base.log_evidence), heldout_score_gain=gain,
        rms_after=float(math.sqrt(np.mean(res**2))), heldout_rms_after=None if held is None else held.rms,
        parameters={n: {"map": float(v), "std": float(s)} for n, v, s in zip(effect.names, fit.theta[sl], std)},
        ei_shift=tuple(shift.tolist()), max_ei_shift=float(np.max(np.abs(shift))), converged=fit.converged,
        abandoned=fit.abandoned,
        findings=tuple(describe(effect, problem, fit.theta[sl], std)))


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
        Candidate effects (default: the whole library, ``EFFECTS``); those
        that cannot act on the data are not offered (see ``not_offered``).
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
    names = list(EFFECTS) if effects is None else list(effects)
    not_offered = {}
    for n in names:
        reason = make_effect(n).applicable(crossings)
        if reason is not None:
            not_offered[n] = reason
    names = [n for n in names if n not in not_offered]
    # dense records: fitted in whitened bins of consecutive readings (the exact model of a bin; binning.py);
    # the gap before and after is reported on the readings themselves
    raw_case, raw_crossings = case, crossings
    size = choose_size(case, crossings, prior)
    binning = {}
    if size > 1:
        case, crossings = bin_crossings(case, crossings, size)
        step = float(np.median([np.median(np.diff(c.raw_positions)) for c in crossings]))
        binning = {"size": size, "width_m": round(size * step, 9), "rows": int(sum(c.raw_positions.size for c in crossings)),
                   "bins": int(sum(c.n_loads for c in crossings)), "keep": KEEP}
        say(f"fitting bins of {size} consecutive readings ({size * step:.2f} m; they keep >= "
            f"{100 * KEEP:.0f} % of the information on EI)")
    folds = _folds(crossings, n_folds)
    say("base fit (EI and the case's elastic springs, hyperparameters integrated as in invert)")
    base_problem = JointProblem(case, crossings, [], prior, estimate_springs=estimate_springs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        base_full = integrated_fit(base_problem, prior)
    alpha, tau = base_full.noise_scale, base_full.tau
    base = quick_fit(base_problem, base_full.theta_mode, alpha, tau)
    _, _, cross, load, _ = base_problem.rows(base.theta)
    test_masks = fold_rows(crossings, folds, cross, load)
    base_held = heldout(base, test_masks)
    gap, residual_map = residual_gap(_on_rows(base_problem, raw_case, raw_crossings, [], prior, estimate_springs),
                                     base.theta, alpha)
    predictions = [y for y, _ in base_problem.predict(base_problem.theta0, jacobian=False)]  # nominal model
    ctx = _Context(case, crossings, prior, estimate_springs, alpha, tau, blocks_of(base_problem, base.theta),
                   test_masks, predictions)
    n_base = base_problem.n_elements
    ei_base = np.exp(base.theta[:n_base])
    # screening and selection on this process, a process pool or a Dask cluster (results in the order of
    # the effects, the same on any of them)
    with executor_for(workers, scheduler, timeout=scheduler_timeout, name="--scheduler") as runner:
        screened = fit_models(ctx, {n: ([n], None) for n in names}, base.log_evidence + bf_threshold,
                              bf_threshold=bf_threshold, runner=runner, say=say, label="")
        results = [_entry(n, screened[n][0], screened[n][1], base, base_held, ei_base) for n in names]
        results.sort(key=lambda r: (r.converged,
                                    -math.inf if math.isnan(r.log_bayes_factor) else r.log_bayes_factor), reverse=True)
        selected, alternatives, current, current_held = select(
            ctx, names, screened, base, base_held, bf_threshold=bf_threshold, gain_threshold=gain_threshold,
            max_rounds=max_rounds, folds=bool(folds), say=say, runner=runner)
    say("final refit of the selected model with its hyperparameters")
    final_problem = JointProblem(case, crossings, [make_effect(n) for n in selected], prior,
                                 estimate_springs=estimate_springs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        final = integrated_fit(final_problem, prior, start=current.theta, noise_scale=alpha, tau=tau)
    # a tau node with an effect parameter out of the model's domain (exp overflow of an axle load) makes the
    # mixture mean invalid: then the MAP at the hyper-posterior's mode, else the selection's own MAP (the final
    # fit is then reported as not converged)
    valid = [t for t in (final.mixture.mean, final.theta_mode)
             if final_problem._safe_predict(t, False) is not None]
    theta_final = valid[0] if valid else current.theta
    final_ok = bool(valid) and final.converged
    gap_after, _ = residual_gap(_on_rows(final_problem, raw_case, raw_crossings, selected, prior, estimate_springs),
                                theta_final, final.noise_scale)
    n_el = final_problem.n_elements
    sd_all = np.sqrt(np.clip(np.diag(final.mixture.covariance), 0, None))
    findings = {}
    for e, sl in zip(final_problem.effects, final_problem.slices):
        findings[e.name] = tuple(describe(e, final_problem, theta_final[sl], sd_all[sl]))
    springs = findings.pop("case_springs", ())
    corrected = _corrected_model(final_problem, theta_final, sd_all)
    say("confounding with EI")
    confounded = confounding(case, crossings, [r.name for r in results if r.name not in selected], prior,
                             base.theta, alpha, tau, estimate_springs)
    unexplained = bool(gap_after.significant)
    verdict = _verdict(selected, unexplained, gap.significant, confounded)
    # a candidate a cause holds as a special case is not a second finding: the data cannot tell them apart
    includes = {s: held for s in selected
                if (held := tuple(n for n in make_effect(s).contains if n in names and n not in selected))}
    differs = [f["where"] for f in springs if f.get("differs")]
    if differs:
        verdict += "; the case's elastic springs differ from the configured values: " + ", ".join(differs)
    kinds = dict(zip(base_problem.sensor_names, base_problem.sensors.kinds))
    shrinkage = {n: {"kind": kinds[n], "rms_before": gap.by_sensor[n].rms_residual,
                     "rms_after": gap_after.by_sensor[n].rms_residual,
                     "heldout_rms_before": None if base_held is None else float(base_held.rms_by_sensor[i]),
                     "heldout_rms_after": None if current_held is None else float(current_held.rms_by_sensor[i])}
                 for i, n in enumerate(base_problem.sensor_names)}
    return GapDiagnosis(
        gap, tuple(results), tuple(selected), unexplained, tuple(confounded), verdict, gap_after,
        case.mesh.edges.copy(), ei_base, np.exp(theta_final[:n_el]),
        {"grid_m": residual_map[0], "normalised_mean_residual": residual_map[1]},
        ei_base_band=tuple(np.exp(b[:n_base]) for b in base_full.band()),
        ei_final_band=tuple(np.exp(b[:n_el]) for b in final.band()),
        findings=findings, alternatives=alternatives, not_offered=not_offered, shrinkage=shrinkage,
        springs=springs, springs_estimated=bool(estimate_springs and case.bridge.spring_names),
        noise_scale=float(final.noise_scale), converged=bool(base_full.converged and final_ok),
        heldout_ratio_after=None if current_held is None else current_held.ratio,
        heldout_ratio_before=None if base_held is None else base_held.ratio, corrected_model=corrected,
        binning=binning, includes=includes)


def _on_rows(problem, case, crossings, selected, prior, estimate_springs):
    """``problem`` on the unbinned readings (itself when the data were not binned)."""
    if crossings is problem.crossings:
        return problem
    return JointProblem(case, crossings, [make_effect(n) for n in selected], prior, estimate_springs=estimate_springs)


def _corrected_model(problem, theta, std):
    """The model state of the final MAP (SI): springs, sensor positions, axle loads, and what a case cannot hold.

    A support-spring effect frees every support of its kind; supports the
    data did not inform (posterior = prior) keep the case's value.
    """
    state = problem.initial_state()
    for e, sl in zip(problem.effects, problem.slices):
        if e.structural:
            e.apply(state, theta[sl])
    if any(e.frees for e in problem.effects):  # uninformed supports back to pins, clamps, rigid
        rot, vert = list(state.bridge.rotational_springs), list(state.bridge.vertical_springs)
        for e, sl in zip(problem.effects, problem.slices):
            if e.frees:
                keep = ~informed(theta[sl], std[sl], e.mean, e.std)
                target = rot if "rotational" in e.frees else vert
                source = (problem.case.bridge.rotational_springs if "rotational" in e.frees
                          else problem.case.bridge.vertical_springs)
                for i in np.flatnonzero(keep):
                    target[i] = source[i]
        state.bridge = type(state.bridge)(state.bridge.spans, tuple(rot), tuple(vert))
    b = state.bridge
    return {"rotational_springs": [float(k) for k in b.rotational_springs],
            "vertical_springs": [float(k) for k in b.vertical_springs],
            "sensor_positions": [float(x) for x in state.sensor_positions],
            "axle_loads": [float(w) for w in np.asarray(problem.case.vehicle.axle_loads) * state.axle_factors],
            "not_in_case": [e.name for e in problem.effects if not e.in_case]}


def _verdict(selected, unexplained, significant, confounded):
    if selected and not unexplained:
        verdict = "causes found: " + ", ".join(selected)
    elif selected:
        verdict = ("partly explained by " + ", ".join(selected) + "; a significant gap remains (unexplained)"
                   if significant else "causes found: " + ", ".join(selected)
                   + "; the residual structure after the fit is significant (unexplained remainder)")
    elif significant:
        verdict = "unexplained: a significant gap remains that no candidate effect explains"
    else:
        verdict = "none: the model is adequate (no significant gap)"
    if confounded and not selected and significant:
        verdict += "; confounded with an EI change: " + ", ".join(c.name for c in confounded)
    return verdict

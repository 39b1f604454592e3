"""Sim-to-real gap diagnosis: where model and data disagree, which effect causes it.

1. Base fit: the case's model with EI identified (evidence-optimal).
2. Where: residuals split into crossing-to-crossing scatter (noise) and the
   mean over crossings (systematic part), per sensor and load position,
   with Ljung-Box tests on the whitened residuals.
3. Which effect: every candidate effect is refitted jointly with EI and
   ranked by its Laplace log Bayes factor, with its held-out predictive
   score (blocks of load positions held out in every crossing; whole
   crossings for static load steps) reported and required to improve; its EI shift is the bias it was causing.  Forward
   selection adds effects while the evidence improves clearly.
4. Confounding: an effect whose data signature a plausible EI change can
   mimic (its information given unknown EI is a small fraction of its
   information given known EI) is reported as confounded, with the
   candidate sensor position that best separates the two.
"""

import math
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .._threads import single_threaded
from ..inference.laplace import fit_problem
from ..inference.screening import check_case_data_scale
from ..model.crossings import Crossings
from ..model.prior import GMRFPrior
from .effects import EFFECTS, make_effect
from .gap import residual_gap
from .joint import JointProblem
from .results import Confounding, EffectFit, GapDiagnosis

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["diagnose"]

_SEPARABLE = ("support_rotational_spring", "vertical_support_spring", "position_offset", "axle_loads",
              "dynamic_amplification")


def _fit(case, crossings, effects, prior, start=None, masks=None):
    problem = JointProblem(case, crossings, [make_effect(e) for e in effects], prior, masks=masks)
    theta0 = problem.theta0
    if start is not None:
        theta_start = theta0.copy()
        theta_start[:problem.n_elements] = start["theta"][:problem.n_elements]
        for name, value in start.get("effects", {}).items():
            idx = [i for i, n in enumerate(problem.param_names) if n.startswith(name + ":")]
            if len(idx) == len(value):
                theta_start[idx] = value
        alpha, tau = start["alpha"], start["tau"]
    else:
        theta_start, alpha, tau = None, 1.0, prior.tau
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        fit = fit_problem(problem, problem.rough, problem.fixed, theta0, noise_scale=alpha, tau=tau,
                          start=theta_start, max_outer=60, tol=1e-9)
    return problem, fit


def _start(problem, fit):
    eff = {}
    for e, sl in zip(problem.effects, problem.slices):
        eff[e.name] = fit.theta[sl]
    return {"theta": fit.theta, "alpha": fit.noise_scale, "tau": fit.tau, "effects": eff}


def _folds(crossings, n_folds=4):
    """Masks (train, test) per fold.

    With load sweeps (>= 8 positions per crossing) every fold holds out two
    contiguous blocks of load positions in every crossing, one in each half
    of the sweep (blocks b and b + n_folds of 2 n_folds), so parameters of a
    single crossing (offsets, drift, amplification, trigger shifts) are
    estimated from the rest of that crossing, no fold has to extrapolate a
    drift from one end of the sweep, and the held-out score tests the shape
    of the model along the bridge.  With fewer positions (static load
    steps) whole crossings are held out.
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


def _heldout(case, crossings, effects, prior, start, folds):
    if not folds:
        return None, None
    logp, sq, count = 0.0, 0.0, 0
    for train, test in folds:
        problem, fit = _fit(case, crossings, effects, prior, start=start, masks=train)
        lp, s, n = problem.heldout(fit.theta, fit.covariance, fit.noise_scale, test)
        logp, sq, count = logp + lp, sq + s, count + n
    return logp, math.sqrt(sq / max(count, 1))


def _confounding(case, crossings, name, prior, base_start):
    """Fraction of the effect's information that survives unknown EI, and the best separating sensor."""
    problem = JointProblem(case, crossings, [make_effect(name)], prior)
    theta = problem.theta0.copy()
    theta[:problem.n_elements] = base_start["theta"][:problem.n_elements]
    lin = problem.evaluate(theta)
    if lin is None:
        return 1.0, None
    kept = _kept_fraction(lin.jtj / base_start["alpha"] ** 2, problem, base_start["tau"])
    best = None
    if kept < 0.2 and name in _SEPARABLE:
        best = _separating_sensor(case, crossings, name, prior, theta, base_start, kept)
    return kept, best


def _kept_fraction(info, problem, tau):
    n = problem.n_elements
    q = tau * problem.rough + problem.fixed
    e, f = slice(0, n), slice(n, problem.n_params)
    known = info[f, f] + q[f, f]
    marg = known - info[f, e] @ np.linalg.solve(info[e, e] + q[e, e], info[e, f])
    data_known = info[f, f]
    # directions the data would inform if EI were known (data info >= 3 x prior)
    vals, vecs = np.linalg.eigh(data_known)
    useful = vecs[:, vals >= 3.0 * np.max(np.diag(q[f, f]))]
    if useful.shape[1] == 0:
        return 1.0
    a = useful.T @ known @ useful
    b = useful.T @ marg @ useful
    ratio = np.linalg.eigvals(np.linalg.solve(a, b)).real
    return float(np.clip(ratio.min(), 0.0, 1.0))


def _separating_sensor(case, crossings, name, prior, theta, base_start, kept):
    from dataclasses import replace

    from ..model.crossings import Crossing, Crossings
    from ..model.noise import NoiseModel
    from ..model.sensors import SensorLayout

    kind = case.sensors.kinds[0]
    std = float(np.median(case.noise.std)) if case.noise is not None else 1e-6
    base_problem = JointProblem(case, crossings, [make_effect(name)], prior)
    base_info = base_problem.evaluate(theta).jtj / base_start["alpha"] ** 2
    best, best_kept = None, kept
    for x in np.linspace(0.0, case.bridge.length, 41):
        sensors = SensorLayout([x], kind, ["candidate"], [std])
        cand_case = replace(case, sensors=sensors, noise=NoiseModel([std], case.noise.correlation_length
                                                                    if case.noise is not None else 0.0))
        dummy = Crossings(("candidate",), tuple(Crossing(c.label, c.positions, np.zeros((1, c.n_loads)),
                                                         c.load_factor) for c in crossings))
        p = JointProblem(cand_case, dummy, [make_effect(name)], prior)
        lin = p.evaluate(theta)
        if lin is None:
            continue
        k = _kept_fraction(base_info + lin.jtj / base_start["alpha"] ** 2, base_problem, base_start["tau"])
        if k > best_kept + 1e-6:
            best, best_kept = float(x), k
    return best


@single_threaded
def diagnose(case: "Case", crossings: Crossings, *, effects: "Sequence[str] | None" = None,
             prior: GMRFPrior | None = None, bf_threshold: float = 3.0, n_folds: int = 4,
             progress: "Callable[[int, int], None] | None" = None, check_scale: bool | str = True) -> GapDiagnosis:
    """Diagnose the gap between ``case`` and measured ``crossings``.

    Parameters
    ----------
    case : Case
    crossings : Crossings
    effects : sequence of str, optional
        Candidate effects (default: the whole library, ``EFFECTS``).
    prior : GMRFPrior, optional
    bf_threshold : float
        Log Bayes factor an effect needs to be selected as a cause (3 is
        "strong" on Jeffreys' scale).
    n_folds : int
        Folds of the held-out score.
    progress : callable, optional
        Called with (done, total) after each candidate effect.
    check_scale : bool or str
        Refuse data far larger or smaller than the model predicts (a unit
        slip); a string names the data source in the message.

    Returns
    -------
    GapDiagnosis
    """
    if check_scale:
        check_case_data_scale(case, crossings, source=check_scale if isinstance(check_scale, str) else "data")
    prior = GMRFPrior() if prior is None else prior
    names = list(EFFECTS) if effects is None else list(effects)
    for n in names:
        make_effect(n)
    folds = _folds(crossings, n_folds)
    base_problem, base = _fit(case, crossings, [], prior)
    base_start = _start(base_problem, base)
    gap, residual_map = residual_gap(base_problem, base.theta, base.noise_scale)
    base_heldout, base_heldout_rms = _heldout(case, crossings, [], prior, base_start, folds)
    ei_base = np.exp(base.theta[:base_problem.n_elements])
    results, fits = [], {}
    for k, name in enumerate(names):
        problem, fit = _fit(case, crossings, [name], prior, start=base_start)
        fits[name] = (problem, fit)
        score, hrms = _heldout(case, crossings, [name], prior, _start(problem, fit), folds)
        ei = np.exp(fit.theta[:problem.n_elements])
        shift = ei / ei_base - 1.0
        sl = problem.slices[0]
        std = np.sqrt(np.clip(np.diag(fit.covariance)[sl], 0, None))
        results.append(EffectFit(
            name=name,
            log_bayes_factor=float(fit.log_evidence - base.log_evidence),
            heldout_score_gain=None if score is None else float(score - base_heldout),
            rms_after=float(math.sqrt(np.mean(np.concatenate([r.ravel() for r in problem.residuals(fit.theta)]) ** 2))),
            heldout_rms_after=hrms,
            parameters={n: {"map": float(v), "std": float(s)} for n, v, s in
                        zip(problem.effects[0].names, fit.theta[sl], std)},
            ei_shift=tuple(shift.tolist()),
            max_ei_shift=float(np.max(np.abs(shift))),
        ))
        if progress is not None:
            progress(k + 1, len(names))
    results.sort(key=lambda r: r.log_bayes_factor, reverse=True)
    # forward selection
    selected: list[str] = []
    current, current_problem = base, base_problem
    remaining = [r.name for r in results]
    current_start = base_start
    current_heldout = base_heldout
    while remaining:
        best: tuple | None = None
        for name in remaining:
            if not selected:
                problem, fit = fits[name]
            else:
                problem, fit = _fit(case, crossings, selected + [name], prior, start=current_start)
            bf = fit.log_evidence - current.log_evidence
            if best is None or bf > best[1]:
                best = (name, bf, problem, fit)
        if best is None:
            break
        name, bf, problem, fit = best
        if bf < bf_threshold:
            break
        if folds:
            score, _ = _heldout(case, crossings, selected + [name], prior, _start(problem, fit), folds)
            if score is None or score <= current_heldout:
                break
            current_heldout = score
        selected.append(name)
        remaining.remove(name)
        current, current_problem, current_start = fit, problem, _start(problem, fit)
    gap_after, _ = residual_gap(current_problem, current.theta, current.noise_scale)
    confounded = []
    for r in results:
        if r.name in selected:
            continue
        kept, where = _confounding(case, crossings, r.name, prior, base_start)
        if kept < 0.2:
            confounded.append(Confounding(r.name, kept, where))
    unexplained = bool(gap_after.significant)
    if selected and not unexplained:
        verdict = "causes found: " + ", ".join(selected)
    elif selected:
        verdict = ("partly explained by " + ", ".join(selected) + "; a significant gap remains (unexplained)"
                   if gap.significant else "causes found: " + ", ".join(selected)
                   + "; the residual structure after the fit is significant (unexplained remainder)")
    elif gap.significant:
        verdict = "unexplained: a significant gap remains that no candidate effect explains"
    else:
        verdict = "none: the model is adequate (no significant gap)"
    if confounded and not selected:
        verdict += "; confounded with an EI change: " + ", ".join(c.name for c in confounded)
    return GapDiagnosis(gap, tuple(results), tuple(selected), unexplained, tuple(confounded), verdict, gap_after,
                        case.mesh.edges.copy(), ei_base, np.exp(current.theta[:current_problem.n_elements]),
                        {"grid_m": residual_map[0], "normalised_mean_residual": residual_map[1]})

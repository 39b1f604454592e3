"""Stepwise selection of the effects that explain the gap (forward steps, backward pruning, swaps).

Every comparison is between nested or same-size models fitted at the same
hyperparameters: a log Bayes factor (Laplace) and the held-out predictive
gain over the folds (:func:`.refit.gain_is_significant`).

* Forward: the effect with the largest Bayes factor among those with a
  Bayes factor >= ``bf_threshold`` and a significant held-out gain over the
  current model is added; effects within ``bf_threshold`` of it are its
  alternatives.  A later pick (the second or third) with two or more
  alternatives is not made: when three different effects explain what the
  earlier picks left about equally, none of them is an identified cause
  (the remainder stays in the gap after the fit).
* Noise scale: after each forward step the noise scale is re-estimated at
  the new model's MAP (MacKay's evidence fixed point: whitened residual sum
  of squares over the data count less the effective number of fitted
  parameters, iterated to the fixed point) and the current model refitted
  there.  The base fit's noise scale absorbs the whole gap; the
  Bayes factor of a second effect given the first would otherwise be judged
  against a noise inflated by what the first already explains (and a small
  second effect would be missed).
* In this process the candidates of a step are fitted in the order of
  what they explained alone, and the later ones give up once they cannot
  come within ``bf_threshold`` of an earlier one's evidence; should those
  leaders fail the tests, the ones given up below them are continued (in
  the screening too: a settled bearing given up below a dynamic
  amplification that failed the held-out test, whose pair was the answer).
* Backward: after a forward step every earlier pick is tested against the
  model without it; a pick whose Bayes factor given the others is below
  ``bf_threshold``, or whose held-out gain given them is not significant,
  is dropped (an early pick that only absorbed part of a later one, a gain
  that mimicked a settlement, gives way).  A model already visited ends the
  search (no cycles).
* Look-ahead: when no candidate passes both tests but one with a Bayes
  factor >= ``bf_threshold`` cuts the held-out rms by a fifth or more, it
  is taken tentatively and the next step fitted given it; the pair is kept
  only if it passes both tests against the model before (a pick that pays
  off only once a second missing effect is in, :func:`_look_ahead`).  The
  same when a candidate passes but one that fails the held-out test has a
  Bayes factor ``bf_threshold`` beyond it; the pair must then also beat
  the passing candidate by ``bf_threshold``.
* Swap: with two or more selected, a selected effect is replaced by
  another one that alone explains part of the gap (screening Bayes factor
  >= ``bf_threshold``) when that raises the evidence without losing
  held-out score; a swapped model gets ``FIRST_PASS`` steps from the
  current fit to converge, and gives up once the pace of its last steps
  cannot get it there within them (``quick_fit``'s budget).  A model
  already fitted in the step that made a pick and unable to reach the
  pick's evidence there is not tried again (:func:`.revisions.swap`).

Two passes per set of candidate fits (:func:`fit_models`): every candidate
gets ``FIRST_PASS`` Levenberg-Marquardt iterations; those not converged are
continued only while they may still reach the level a decision needs (the
best candidate's evidence less ``bf_threshold``, and the current model's
plus ``bf_threshold``).  A candidate that misses what the data show fits
slowly (large residuals, curved valleys) and cannot be chosen: it is left
*abandoned* (not converged, flagged) instead of costing 40 iterations.  In a
selection step (after the first pick) only a candidate that reaches the
current model's evidence plus ``bf_threshold`` can matter, so there a fit
gives up during its first pass as soon as it cannot reach that.  The
backward and swap tests give up in the same way once their model cannot
reach the evidence that would change the selection.

Owns: the selection.  May import: the diagnosis's refits and the foundations.
"""

import math
from dataclasses import replace

import numpy as np

from .._executors import map_ordered
from .refit import blocks_of, heldout, quick_fit
from .revisions import better, prune, swap

__all__ = []

AMBIGUOUS = 2  # a later pick with this many alternatives within bf_threshold is not made
FIRST_PASS = 15  # iterations every candidate gets; most converge within them (2-12 on the validation datasets)
SECOND_PASS = 40  # further iterations of the candidates that may still matter after the first pass (fit_models)
THIRD_PASS = 60  # further iterations of a leading candidate still crawling after the second pass (fit_models)
RESCALE_MAX_ITER = 40  # the refit at a re-estimated noise scale (see _rescale)
LOOK_AHEAD_RATIO = 0.8  # a pick that cuts the held-out rms this much may pay off with the next one (_look_ahead)


def _light(out):
    if out[0] is not None:  # the influence-line cache is not needed any more (and not worth sending back)
        out[0].problem.drop_caches()
    return out


def _first_pass(item):
    ctx, names, blocks, floor = item
    return _light(ctx.fit(names, blocks, max_iter=FIRST_PASS, floor=floor))


def _continued(item):
    ctx, fit, floor, max_iter = item
    return _light(ctx.resume(fit, max_iter=max_iter, floor=floor))


def fit_models(ctx, models, level, *, bf_threshold, runner, say, label, strict=False, eligible=None):
    """{name: (fit, held-out)} of ``models`` ({name: (effect names, warm-start blocks or None)}), two passes.

    ``level``: the log evidence a candidate needs to be chosen.  ``runner``:
    an executor or None (this process).  ``strict``: only a candidate that
    reaches ``level`` matters (a selection step, where an alternative must be
    eligible itself), so a fit gives up as soon as its ceiling is below it;
    otherwise (screening, whose table reports every effect) the first pass
    runs its full budget.  ``eligible(name, fit, held)``: whether a fitted
    candidate passes the step's tests; in this process (no ``runner``) the
    candidates are then fitted in the order given and each later one gives
    up once it cannot come within ``bf_threshold`` of an earlier one's
    evidence (neither pick nor alternative then): on a flipped sensor the
    pick reaches 2800 log units above the others, which crawled through
    their whole first pass (2.5 of 16 s).  Should the leaders fail the
    step's tests, those given up below them are continued (:func:`_revive`).
    """
    names = list(models)
    prefix = f"{label}: " if label else ""
    early = level if strict else None
    floors = {}
    if strict and runner is None and eligible is not None:
        first, best = [], -math.inf
        for k, n in enumerate(names):
            floors[n] = max(early, best - bf_threshold)
            first.append(_first_pass((ctx, *models[n], floors[n])))
            say(f"{prefix}effect {k + 1} of {len(names)}: {n}")
            fit = first[-1][0]
            if fit is not None and math.isfinite(fit.log_evidence):
                best = max(best, fit.log_evidence)
    else:
        first = map_ordered(runner, _first_pass, [(ctx, *models[n], early) for n in names], chunksize=1,
                            progress=lambda k, n: say(f"{prefix}effect {k} of {n}: {names[k - 1]}"))
    out = dict(zip(names, first))
    _continue_slow(ctx, out, level, bf_threshold=bf_threshold, runner=runner, say=say, prefix=prefix)
    if floors:
        _revive(ctx, out, floors, early, eligible, bf_threshold=bf_threshold, say=say, prefix=prefix)
    return out


def _revive(ctx, out, floors, level, eligible, *, bf_threshold, say, prefix):
    """Continue the candidates given up below a leader that then failed the step's tests (updates ``out``).

    A candidate needs only come within ``bf_threshold`` of the best one that
    passes the tests (and reach ``level``); one given up against a higher
    floor that could still reach this gets a first pass's budget more.
    """
    best = max((f.log_evidence for n, (f, h) in out.items() if eligible(n, f, h)), default=-math.inf)
    need = max(level, best - bf_threshold)
    back = [n for n, (f, _) in out.items()
            if f is not None and f.abandoned and floors[n] > need and f.ceiling >= need]
    for k, n in enumerate(back):
        say(f"{prefix}continued below a failed leader {k + 1} of {len(back)}: {n}")
        out[n] = _continued((ctx, out[n][0], need, FIRST_PASS))


def _continue_slow(ctx, out, level, *, bf_threshold, runner, say, prefix):
    """Second (and third) passes of the candidates not converged that may still matter (updates ``out``)."""
    names = list(out)
    reached = [f.log_evidence for f, _ in out.values() if f is not None and math.isfinite(f.log_evidence)]
    if not reached:
        return
    floor = max(max(reached) - bf_threshold, level)
    slow = [n for n in names if out[n][0] is not None and not out[n][0].converged]
    todo = [n for n in slow if out[n][0].ceiling >= floor]
    for n in slow:
        if n not in todo:
            out[n] = (replace(out[n][0], abandoned=True), None)
    if todo:
        again = map_ordered(runner, _continued, [(ctx, out[n][0], floor, SECOND_PASS) for n in todo], chunksize=1,
                            progress=lambda k, n: say(f"{prefix}continued {k} of {n}: {todo[k - 1]}"))
        out.update(zip(todo, again))
        # the leader still crawling: a strongly nonlinear effect on precise data (six sensor positions at
        # 0.2 micro-radians of noise: log BF 334 at 55 iterations, converged at 62) gets one more pass, as it
        # alone can decide the step
        done = [f.log_evidence for f, _ in out.values() if f is not None and f.converged]
        best = max(todo, key=lambda n: -math.inf if out[n][0] is None else out[n][0].log_evidence)
        fit = out[best][0]
        if (fit is not None and not fit.converged and not fit.abandoned and math.isfinite(fit.log_evidence)
                and fit.log_evidence >= max(done, default=-math.inf) + bf_threshold):
            say(f"{prefix}continued further: {best}")
            out[best] = _continued((ctx, fit, floor, THIRD_PASS))


def _reached(fit):
    """The log evidence ``fit`` reached (-inf without one)."""
    return -math.inf if fit is None or not math.isfinite(fit.log_evidence) else fit.log_evidence


def _passes(fit, held, current, current_held, level, gain_threshold, folds):
    """Whether the converged ``fit`` beats ``current`` by ``level`` in evidence with a significant held-out gain."""
    if fit is None or not fit.converged:
        return False
    bf, significant = better(fit, held, current, current_held, gain_threshold, folds)
    return bf >= level and significant


def _rescale(ctx, current, *, max_iter=5, rtol=0.01):
    """Noise scale re-estimated at ``current``'s MAP; ``current`` refitted there (ctx.alpha updated).

    MacKay's fixed point is iterated (refit, re-estimate) until the scale
    moves by less than ``rtol``: one step from a fit made at the inflated
    scale of the model before the pick stops short (a two-span restraint
    next to thermal drift: 1.19 after one step, 0.99 at the fixed point,
    and the restraint's log Bayes factor 2.8 -> above the threshold).
    """
    held = None
    for _ in range(max_iter):
        lin = current.problem.evaluate(current.theta)
        if lin is None or lin.jtj is None:
            break
        # alpha^2 = |r|^2 / (N - gamma), gamma = tr(H^-1 J^T J) / alpha^2 the effective number of parameters
        # the data determine (the ML |r|^2 / N would be biased low by them)
        gamma = float(np.trace(np.linalg.solve(current.hessian, lin.jtj))) / current.noise_scale**2
        dof = current.problem.n_data - gamma
        if dof <= 1.0:
            break
        alpha = math.sqrt(max(lin.rr / dof, 1e-300))
        if not alpha < ctx.alpha:  # only shrinks: the base noise scale bounds it from above
            break
        fit = quick_fit(current.problem, current.theta, alpha, ctx.tau, max_iter=RESCALE_MAX_ITER)
        if fit is None or not math.isfinite(fit.ceiling):
            break
        step = 1.0 - alpha / ctx.alpha
        ctx.alpha = alpha
        if not fit.converged:
            # A model that leaves part of the gap unexplained can crawl at the smaller scale: EI twists to
            # absorb what is missing (single-span sign flip, the restraint not yet modelled: 130-230 steps).
            # Kept at that scale with the evidence it could still reach (its ceiling), so the next pick
            # must beat an optimistic bound of it; the old scale would hide the missing effect (its log
            # Bayes factor -0.6 at 18.6 against 167 at 1.54)
            return replace(fit, log_evidence=fit.ceiling), heldout(fit, ctx.test_masks)
        current, held = fit, heldout(fit, ctx.test_masks)
        if step < rtol:
            break
    return current, held


def select(ctx, names, screened, base, base_held, *, bf_threshold, gain_threshold, max_rounds, folds, say,
           runner=None):
    """Selected effect names, their alternatives, and the fit and held-out score of the selected model."""
    selected: list[str] = []
    alternatives: dict[str, tuple] = {}
    current, current_held = base, base_held
    candidates = screened
    visited = {frozenset()}
    lost = set()  # models fitted in a step that could not reach its pick's evidence (no swap test for them)
    for step in range(2 * max_rounds):
        if len(selected) >= max_rounds:
            break
        remaining = [n for n in names if n not in selected]

        def passes(name, fit, held):
            return (frozenset(selected + [name]) not in visited
                    and _passes(fit, held, current, current_held, bf_threshold, gain_threshold, folds))

        if step > 0:
            blocks = blocks_of(current.problem, current.theta)
            # the candidates that explained most alone first (an eligible one lets the others give up early)
            order = sorted(remaining, key=lambda n: -_reached(screened[n][0]))
            candidates = fit_models(ctx, {n: (selected + [n], blocks) for n in order},
                                    current.log_evidence + bf_threshold, bf_threshold=bf_threshold, runner=runner,
                                    say=say, label=f"selection step {step + 1} given {', '.join(selected)}",
                                    strict=True, eligible=passes)
        else:  # the screening gave up below its leader too
            _revive(ctx, candidates, dict.fromkeys(remaining, math.inf), current.log_evidence + bf_threshold,
                    passes, bf_threshold=bf_threshold, say=say, prefix="screening: ")
        eligible = [(candidates[n][0].log_evidence - current.log_evidence, n) for n in remaining
                    if passes(n, *candidates[n])]
        first = None
        if len(selected) + 2 <= max_rounds and folds:
            # also when a candidate passes: one that explains far more but fails the held-out test may be
            # the first of two missing effects (see _look_ahead)
            above = max(eligible)[0] if eligible else None
            ahead = _look_ahead(ctx, remaining, selected, candidates, current, current_held, visited, bf_threshold,
                                gain_threshold, runner, say, above=above)
            if ahead[2] is not None:
                eligible, candidates, first = ahead
                selected.append(first)
                alternatives[first] = ()
        if not eligible:
            break
        eligible.sort(reverse=True)
        best_bf, best = eligible[0]
        close = tuple(n for bf, n in eligible[1:] if bf >= best_bf - bf_threshold)
        if selected and len(close) >= AMBIGUOUS:
            # three or more different effects explain what is left about equally: the remainder has no
            # identifiable cause (it stays in the gap after the fit), none of them is named
            say(f"no further cause: {best}, {', '.join(close)} explain the remainder about equally")
            if first is not None:  # the tentative pick goes with it
                selected.remove(first)
                alternatives.pop(first)
            break
        alternatives[best] = close
        winner = candidates[best][0].log_evidence
        lost |= {frozenset(selected + [n]) for n, (fit, _) in candidates.items() if n != best and fit is not None
                 and (fit.converged or fit.abandoned) and fit.ceiling < winner}
        selected.append(best)
        visited.add(frozenset(selected))
        current, current_held = candidates[best]
        rescaled, held = _rescale(ctx, current)
        if held is not None:
            current, current_held = rescaled, held
        current, current_held = prune(ctx, selected, alternatives, current, current_held, visited,
                                      bf_threshold, gain_threshold, folds, say)
    if len(selected) >= 2:
        # swap candidates: effects that alone explain part of the gap (screening log BF >= bf_threshold); one
        # that explains nothing alone cannot replace a pick that does (and the test costs a refit each)
        # (an abandoned fit's evidence is what it had reached: enough to count it)
        strong = [n for n in names if screened[n][0] is not None
                  and (screened[n][0].converged or screened[n][0].abandoned)
                  and screened[n][0].log_evidence - base.log_evidence >= bf_threshold]
        current, current_held = swap(ctx, strong, selected, alternatives, current, current_held, say,
                                     max_iter=FIRST_PASS, lost=lost)
    return selected, alternatives, current, current_held


def _look_ahead(ctx, remaining, selected, candidates, current, current_held, visited, bf_threshold, gain_threshold,
                runner, say, above=None):
    """(eligible, candidates, first): a pick that only pays off together with the next one.

    When no candidate passes both tests but one has a Bayes factor above
    ``bf_threshold`` and cuts the held-out rms by a fifth or more while its
    held-out log density falls, a second effect the data also need may be
    missing: the first one's fit then twists EI to mimic it and predicts a
    held-out block badly (a flipped sensor next to a settled end bearing:
    log BF 2531, held-out rms ratio 6.8 -> 3.5, held-out gain -1812 from one
    block; the pair: log BF 1559 over the base and a significant held-out
    gain).  The best such candidate is taken tentatively and the next step is
    fitted given it; its effects are judged against ``current`` (both
    tests), so the pair must beat the model without either pick, and the
    backward test afterwards drops the first one if the second alone does
    as well.  ``first`` is None when nothing qualifies.

    ``above``: the Bayes factor of the best candidate that passes both
    tests, if any.  A candidate that fails the held-out test with a Bayes
    factor ``bf_threshold`` beyond it is then tried the same way, and the
    pair must beat that candidate by ``bf_threshold`` too (thermal drift next
    to a settled end bearing: drift log BF 562, held-out rms 0.65 of the
    base's but a held-out gain of -8380, the noise scale of its folds shrunk
    by what it explains while the settlement is still missing; load-position
    offsets passed both tests at log BF 187, and the selection went through
    them, 50 refits, before dropping them again).
    """
    level = bf_threshold if above is None else above + bf_threshold
    tentative = []
    for name in remaining:
        fit, held = candidates[name]
        if (fit is None or not fit.converged or held is None or current_held is None
                or frozenset(selected + [name]) in visited):
            continue
        bf = fit.log_evidence - current.log_evidence
        if bf >= level and held.ratio <= LOOK_AHEAD_RATIO * current_held.ratio:
            tentative.append((bf, name))
    if not tentative:
        return [], candidates, None
    _, first = max(tentative)
    fit, _ = candidates[first]
    blocks = blocks_of(fit.problem, fit.theta)
    rest = sorted((n for n in remaining if n != first), key=lambda n: -_reached(candidates[n][0]))

    def passes(name, pair, held):
        return _passes(pair, held, current, current_held, level, gain_threshold, True)

    pairs = fit_models(ctx, {n: (selected + [first, n], blocks) for n in rest}, current.log_evidence + level,
                       bf_threshold=bf_threshold, runner=runner, say=say,
                       label=f"look-ahead given {', '.join(selected + [first])}", strict=True, eligible=passes)
    eligible = [(pairs[n][0].log_evidence - current.log_evidence, n) for n in rest if passes(n, *pairs[n])]
    if not eligible:
        return [], candidates, None
    visited.add(frozenset(selected + [first]))
    return eligible, pairs, first

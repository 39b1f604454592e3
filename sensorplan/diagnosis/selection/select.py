"""Stepwise selection of the effects that explain the gap: the decision in one place.

Every comparison is between nested or same-size models fitted at the same
hyperparameters: a log Bayes factor (Laplace) and the held-out predictive
gain over the folds (:func:`.heldout.gain_is_significant`); a candidate
*passes* against a model when it beats it by a level in evidence with a
significant held-out gain (:func:`passes`).

* Forward: the effect with the largest Bayes factor among those that pass
  against the current model at ``bf_threshold`` is added; effects within
  ``bf_threshold`` of it are its alternatives.  A later pick (the second
  or third) with ``ambiguous`` alternatives or more is not made: when three
  different effects explain what the earlier picks left about equally,
  none of them is an identified cause (the remainder stays in the gap).
* Noise scale: after each forward step the noise scale is re-estimated at
  the new model's MAP and the model refitted there
  (:meth:`~.candidate.SelectionContext.rescaled`).  The base fit's noise
  scale absorbs the whole gap; the Bayes factor of a second effect given
  the first would otherwise be judged against a noise inflated by what the
  first already explains.
* Candidates are fitted in passes (:mod:`.passes`), in the order of what
  they explained alone, and later ones give up once they cannot come
  within ``bf_threshold`` of an earlier one's evidence.
* Backward (:func:`.revisions.prune`): after a forward step every earlier
  pick is tested against the model without it and dropped if redundant.
  A model already visited ends the search (no cycles).
* Look-ahead (:func:`look_ahead`): a candidate that fails the
  held-out test but cuts the held-out rms to ``look_ahead_ratio`` may be
  the first of two missing effects; it is taken tentatively with the next
  one, and the pair is kept only if it passes against the model before.
* Swap (:func:`.revisions.swap`): with two or more selected, a selected
  effect is replaced by another one that alone explains part of the gap
  when that raises the evidence without losing held-out score.
* Named (:func:`named_causes`): the picks are causes only if the model
  with them leaves no significant gap (``policy.name_partial``); otherwise
  the gap is unexplained and the picks are partial.

Owns: :func:`select`, :func:`named_causes`, :class:`Selection`.  May import: the selection's parts and the joint model's warm starts.
"""

from dataclasses import dataclass

from ..joint.fits import blocks_of
from .candidate import Candidate
from .passes import fit_models, revive
from .policy import SelectionPolicy
from .revisions import prune, swap
from .state import SelectionState, passes

__all__ = ["Selection", "named_causes", "select"]


@dataclass(frozen=True, eq=False)
class Selection:
    """The selected effects in order of selection, each pick's alternatives, the selected model's fit and score.

    ``partial``: picks not named as causes (:func:`named_causes`): they
    reduce the gap but leave it significant.
    """

    selected: tuple
    alternatives: dict
    current: Candidate
    partial: tuple = ()


def select(ctx, names, screened, base, *, policy: SelectionPolicy, folds, say, runner=None):
    """The effects that explain the gap among ``names`` (screened alone: ``screened``), against ``base``.

    ``folds``: whether held-out scores exist (without them every gain
    counts as significant).  Returns a :class:`Selection`.
    """
    state = SelectionState(ctx=ctx, selected=(), alternatives={}, current=base, visited=frozenset({frozenset()}),
                           lost=frozenset(), screened=dict(screened))
    for step in range(2 * policy.max_rounds):
        if len(state.selected) >= policy.max_rounds:
            break
        state, go_on = _forward_step(state, step, names, policy=policy, folds=folds, say=say, runner=runner)
        if not go_on:
            break
    if len(state.selected) >= 2:
        # swap candidates: effects that alone explain part of the gap (an abandoned screening fit's evidence is
        # what it had reached: enough to count it); one that explains nothing alone cannot replace a pick that does
        strong = [n for n in names if state.screened[n].fit is not None
                  and (state.screened[n].fit.converged or state.screened[n].fit.abandoned)
                  and state.screened[n].fit.log_evidence - base.fit.log_evidence >= policy.bf_threshold]
        state = swap(state, strong, policy=policy, say=say)
    return Selection(state.selected, state.alternatives, state.current)


def named_causes(picks, *, gap_remains, policy: SelectionPolicy):
    """The picks named as causes: all of them, or none when the model with them still leaves a significant gap.

    ``gap_remains``: the gap test of the selected model refitted with its
    hyperparameters fails.  Effects that take part of a gap without removing
    it are no identified cause (the reason is ``policy.name_partial``'s).
    """
    return tuple(picks) if not gap_remains or policy.name_partial else ()


def _candidates(state, step, remaining, eligible, *, policy, say, runner):
    """(the step's candidates by name, the state with the screening's given-up fits continued at step 0)."""
    current = state.current.fit
    level = current.log_evidence + policy.bf_threshold
    if step == 0:  # the screening gave up below its leader too
        screened = revive(state.ctx, state.screened, dict.fromkeys(remaining, float("inf")), level, eligible,
                          policy=policy, say=say, prefix="screening: ")
        return screened, state.replaced(screened=screened)
    blocks = blocks_of(current.problem, current.theta)
    # the candidates that explained most alone first (an eligible one lets the others give up early)
    order = sorted(remaining, key=lambda n: -state.screened[n].reached)
    candidates = fit_models(state.ctx, {n: (list(state.selected) + [n], blocks) for n in order}, level, policy=policy,
                            runner=runner, say=say, label=f"selection step {step + 1} given {', '.join(state.selected)}",
                            strict=True, eligible=eligible)
    return candidates, state


def _forward_step(state, step, names, *, policy, folds, say, runner):
    """The state after forward step ``step`` (a pick, the noise rescale, the backward test), and whether to go on."""
    remaining = [n for n in names if n not in state.selected]

    def eligible(name, candidate):
        return (frozenset(state.selected + (name,)) not in state.visited
                and passes(candidate, state.current, policy.bf_threshold, policy=policy, folds=folds))

    candidates, state = _candidates(state, step, remaining, eligible, policy=policy, say=say, runner=runner)
    base_evidence = state.current.fit.log_evidence
    ranked = [(candidates[n].fit.log_evidence - base_evidence, n) for n in remaining if eligible(n, candidates[n])]
    first = None
    if len(state.selected) + 2 <= policy.max_rounds and folds:
        # also when a candidate passes: one that explains far more but fails the held-out test may be the first
        # of two missing effects
        above = max(ranked)[0] if ranked else None
        ahead = look_ahead(state, remaining, candidates, policy=policy, say=say, runner=runner, above=above)
        if ahead is not None:
            ranked, candidates, first, state = ahead
    if not ranked:
        return state, False
    ranked.sort(reverse=True)
    best_bf, best = ranked[0]
    close = tuple(n for bf, n in ranked[1:] if bf >= best_bf - policy.bf_threshold)
    if state.selected and len(close) >= policy.ambiguous:
        # three or more different effects explain what is left about equally: the remainder has no
        # identifiable cause (it stays in the gap after the fit), none of them is named
        say(f"no further cause: {best}, {', '.join(close)} explain the remainder about equally")
        if first is not None:  # the tentative pick goes with it
            state = state.without(first)
        return state, False
    return _pick(state, best, close, candidates, policy=policy, folds=folds, say=say), True


def _pick(state, best, close, candidates, *, policy, folds, say):
    """The state with ``best`` selected (alternatives ``close``), the noise rescaled, redundant picks pruned."""
    winner = candidates[best].fit.log_evidence
    # models fitted in this step that could not reach the pick's evidence: no swap test for them later
    lost = {frozenset(state.selected + (n,)) for n, c in candidates.items() if n != best and c.fit is not None
            and (c.fit.converged or c.fit.abandoned) and c.fit.ceiling < winner}
    selected = state.selected + (best,)
    state = state.replaced(selected=selected, alternatives={**state.alternatives, best: close},
                           visited=state.visited | {frozenset(selected)}, lost=state.lost | lost,
                           current=candidates[best])
    ctx, rescaled = state.ctx.rescaled(state.current)
    state = state.replaced(ctx=ctx, current=state.current if rescaled is None else rescaled)
    return prune(state, policy=policy, folds=folds, say=say)


def look_ahead(state, remaining, candidates, *, policy, say, runner, above=None):
    """(ranked pairs, pairs by name, the tentative first pick, the state with it selected), or None.

    When no candidate passes both tests but one beats the current model by
    ``bf_threshold`` in evidence and cuts the held-out rms to
    ``look_ahead_ratio`` while its held-out log density falls, a second
    effect the data also need may be missing: the first one's fit then
    twists EI to mimic it and predicts a held-out block badly.  The best
    such candidate is taken tentatively and the next step fitted given it;
    the pairs are judged against the current model (both tests), so a pair
    must beat the model without either pick, and the backward test drops
    the first one if the second alone does as well.

    ``above``: the Bayes factor of the best candidate that passes both
    tests, if any; a candidate that fails the held-out test with a Bayes
    factor ``bf_threshold`` beyond it is then tried the same way, and the
    pair must beat that candidate by ``bf_threshold`` too.
    """
    current = state.current
    level = policy.bf_threshold if above is None else above + policy.bf_threshold
    first = _tentative(state, remaining, candidates, level, policy=policy)
    if first is None:
        return None
    fit = candidates[first].fit
    blocks = blocks_of(fit.problem, fit.theta)
    rest = sorted((n for n in remaining if n != first), key=lambda n: -candidates[n].reached)

    def eligible(name, pair):
        return passes(pair, current, level, policy=policy, folds=True)

    given = list(state.selected) + [first]
    pairs = fit_models(state.ctx, {n: (given + [n], blocks) for n in rest}, current.fit.log_evidence + level,
                       policy=policy, runner=runner, say=say, label=f"look-ahead given {', '.join(given)}",
                       strict=True, eligible=eligible)
    ranked = [(pairs[n].fit.log_evidence - current.fit.log_evidence, n) for n in rest if eligible(n, pairs[n])]
    if not ranked:
        return None
    state = state.replaced(selected=state.selected + (first,), alternatives={**state.alternatives, first: ()},
                           visited=state.visited | {frozenset(given)})
    return ranked, pairs, first, state


def _tentative(state, remaining, candidates, level, *, policy):
    """The candidate with the largest Bayes factor >= ``level`` that cuts the held-out rms enough, or None."""
    current = state.current
    tentative = []
    for name in remaining:
        c = candidates[name]
        if (c.fit is None or not c.fit.converged or c.held is None or current.held is None
                or frozenset(state.selected + (name,)) in state.visited):
            continue
        bf = c.fit.log_evidence - current.fit.log_evidence
        if bf >= level and c.held.ratio <= policy.look_ahead_ratio * current.held.ratio:
            tentative.append((bf, name))
    return max(tentative)[1] if tentative else None

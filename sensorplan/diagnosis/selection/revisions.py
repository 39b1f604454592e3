"""Revisions of a selection after a pick: earlier picks dropped (backward test) or exchanged (swap).

Owns: :func:`prune`, :func:`swap`.  May import: the selection's state and the joint model's warm starts.
"""

import numpy as np

from ..joint.fits import blocks_of
from .state import significant_gain

__all__ = ["prune", "swap"]


def prune(state, *, policy, folds, say):
    """The state with earlier picks that the latest one makes redundant dropped, weakest first.

    Every earlier pick is tested against the model without it; a pick
    whose Bayes factor given the others is below ``bf_threshold``, or whose
    held-out gain given them is not significant, is redundant (an early pick
    that only absorbed part of a later one gives way).
    """
    while len(state.selected) >= 2:
        current = state.current
        weakest = None
        for name in state.selected[:-1]:
            others = [n for n in state.selected if n != name]
            say(f"backward test: {name} given {', '.join(others)}")
            blocks = blocks_of(current.fit.problem, current.fit.theta)
            # given up once it cannot come within bf_threshold of the current model (the pick then stays)
            without = state.ctx.fit(others, blocks, initial=False, floor=current.fit.log_evidence - policy.bf_threshold)
            if without.fit is None or not without.fit.converged:
                continue
            bf = current.fit.log_evidence - without.fit.log_evidence
            redundant = bf < policy.bf_threshold or not significant_gain(current, without, policy=policy, folds=folds)
            if redundant and (weakest is None or bf < weakest[0]):
                weakest = (bf, name, without)
        if weakest is None:
            break
        _, name, without = weakest
        state = state.without(name)
        state = state.replaced(visited=state.visited | {frozenset(state.selected)}, current=without)
    return state


def swap(state, names, *, policy, say):
    """The state with picks that absorbed part of a later one exchanged (evidence up, held-out score not down).

    A selected effect is replaced by one of ``names`` (effects that alone
    explain part of the gap) when that raises the evidence without losing
    held-out score.  A swapped model gets ``first_pass`` steps from the
    current fit and gives up once the pace of its last steps cannot get it
    there; models in ``state.lost`` are not tried (fitted in the step that
    made a pick, they could not reach its evidence).
    """
    for name in state.selected:  # the picks as they were when the pass began
        others = [n for n in state.selected if n != name]
        for other in [n for n in names if n not in state.selected and frozenset(others + [n]) not in state.lost]:
            say(f"swap test: {other} for {name}")
            current = state.current
            # given up once it cannot beat the current model, or when it has not converged in its steps from the
            # current fit: a swap that removes what the data need crawls with a high ceiling through every step
            trial = state.ctx.fit(others + [other], blocks_of(current.fit.problem, current.fit.theta),
                                  max_iter=policy.first_pass, floor=current.fit.log_evidence, budget=True)
            if _wins(trial, current):
                alternatives = dict(state.alternatives)
                alternatives[other] = tuple(a for a in alternatives.pop(name, ()) if a != other)
                selected = tuple(other if n == name else n for n in state.selected)
                state = state.replaced(selected=selected, alternatives=alternatives, current=trial)
                break
    return state


def _wins(trial, current):
    """Whether the converged ``trial`` has more evidence than ``current`` and no less held-out score."""
    wins = trial.fit is not None and trial.fit.converged and trial.fit.log_evidence > current.fit.log_evidence
    if wins and trial.held is not None and current.held is not None:
        wins = float(np.sum(trial.held.log_density)) >= float(np.sum(current.held.log_density))
    return wins

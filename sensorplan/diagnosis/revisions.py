"""Backward pruning and swap tests of the stepwise selection (:mod:`.selection`, whose docstring describes them).

Owns: the revisions of a selection.  May import: the diagnosis's refits and the foundations.
"""

import numpy as np

from .refit import blocks_of, gain_is_significant

__all__ = []


def better(fit, held, current, current_held, threshold, folds):
    """(Bayes factor, significant held-out gain) of ``fit`` over ``current``."""
    bf = fit.log_evidence - current.log_evidence
    significant = gain_is_significant(held, current_held, threshold)[0] if folds else True
    return bf, significant


def prune(ctx, selected, alternatives, current, current_held, visited, bf_threshold, gain_threshold, folds, say):
    """Drop earlier picks that the latest one makes redundant (weakest first); updates ``selected``."""
    while len(selected) >= 2:
        weakest = None
        for name in selected[:-1]:
            others = [n for n in selected if n != name]
            say(f"backward test: {name} given {', '.join(others)}")
            blocks = blocks_of(current.problem, current.theta)
            # given up once it cannot come within bf_threshold of the current model (the pick then stays)
            fit, held = ctx.fit(others, blocks, initial=False, floor=current.log_evidence - bf_threshold)
            if fit is None or not fit.converged:
                continue
            bf, significant = better(current, current_held, fit, held, gain_threshold, folds)
            redundant = bf < bf_threshold or not significant
            if redundant and (weakest is None or bf < weakest[0]):
                weakest = (bf, name, fit, held)
        if weakest is None:
            break
        _, name, fit, held = weakest
        selected.remove(name)
        alternatives.pop(name, None)
        visited.add(frozenset(selected))
        current, current_held = fit, held
    return current, current_held


def swap(ctx, names, selected, alternatives, current, current_held, say, *, max_iter, lost=frozenset()):
    """An early pick that absorbed part of a later one gives way (evidence up, held-out score not down).

    A swapped model gets ``max_iter`` steps from the current fit.  Models in
    ``lost`` are not tried: they were fitted in the step that made a pick,
    at that step's hyperparameters, and could not reach the pick's evidence
    (converged below it, or given up with a ceiling below it) -- replacing
    the last pick by a candidate it beat (half the swap tests with two
    picks, 16-36 refit steps each on a dense three-span record).
    """
    for name in list(selected):
        others = [n for n in selected if n != name]
        for other in [n for n in names if n not in selected and frozenset(others + [n]) not in lost]:
            say(f"swap test: {other} for {name}")
            # given up once it cannot beat the current model, or when it has not converged in max_iter steps
            # from the current fit: a swap that removes what the data need (a flipped sensor) crawls with a high
            # ceiling through every step it gets (four such tests took 19 of 34 s on one dataset)
            fit, held = ctx.fit(others + [other], blocks_of(current.problem, current.theta),
                                max_iter=max_iter, floor=current.log_evidence, budget=True)
            wins = fit is not None and fit.converged and fit.log_evidence > current.log_evidence
            if wins and held is not None and current_held is not None:
                wins = float(np.sum(held.log_density)) >= float(np.sum(current_held.log_density))
            if wins:
                alternatives[other] = tuple(a for a in alternatives.pop(name, ()) if a != other)
                selected[selected.index(name)] = other
                current, current_held = fit, held
                break
    return current, current_held

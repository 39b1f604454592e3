"""The state a selection carries from step to step, and the test a candidate passes.

Owns: :class:`SelectionState`, :func:`passes`.  May import: the selection's candidates and held-out scores.
"""

from dataclasses import dataclass, replace

from .candidate import Candidate
from .heldout import gain_is_significant

__all__ = ["SelectionState", "passes"]


@dataclass(frozen=True, eq=False)
class SelectionState:
    """Where a selection stands: each step returns a new one.

    ``ctx``: the :class:`~.candidate.SelectionContext` at the current noise
    scale; ``selected``: the picks in order; ``alternatives``: each pick's
    alternatives (in the order the picks were made); ``current``: the
    selected model's :class:`~.candidate.Candidate`; ``visited``: the models
    (frozensets of names) selected at some point (no cycles); ``lost``:
    models fitted in the step that made a pick that could not reach its
    evidence (no swap test for them); ``screened``: each effect fitted alone.
    """

    ctx: object
    selected: tuple
    alternatives: dict
    current: Candidate
    visited: frozenset
    lost: frozenset
    screened: dict

    def replaced(self, **changes):
        """A copy with ``changes``."""
        return replace(self, **changes)

    def without(self, name):
        """A copy with the pick ``name`` and its alternatives removed (the current model stays)."""
        alternatives = dict(self.alternatives)
        alternatives.pop(name, None)
        return replace(self, selected=tuple(n for n in self.selected if n != name), alternatives=alternatives)


def passes(candidate, current, level, *, policy, folds):
    """Whether the converged ``candidate`` beats ``current`` by ``level`` in evidence with a significant held-out gain.

    Without folds (``folds`` False) every gain counts as significant.
    """
    if candidate.fit is None or not candidate.fit.converged:
        return False
    bf = candidate.fit.log_evidence - current.fit.log_evidence
    return bf >= level and significant_gain(candidate, current, policy=policy, folds=folds)


def significant_gain(new, current, *, policy, folds):
    """Whether ``new``'s held-out score beats ``current``'s significantly (always, without folds)."""
    return gain_is_significant(new.held, current.held, policy.gain_threshold)[0] if folds else True

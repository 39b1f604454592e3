"""What the selection compares and what it asks of the diagnosis: :class:`Candidate`, :class:`SelectionContext`.

Owns: the selection's candidate type and context protocol.  May import: the selection's refits and held-out scores.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

from .heldout import Heldout
from .refit import QuickFit

__all__ = ["Candidate", "SelectionContext"]


@dataclass(frozen=True, eq=False)
class Candidate:
    """A model fitted for the selection: its quick fit and held-out score.

    ``fit``: None when the model had no valid start; ``held``: None when the
    fit is not converged (or without folds).
    """

    fit: QuickFit | None
    held: Heldout | None = None

    @property
    def reached(self) -> float:
        """The log evidence the fit reached (-inf without one)."""
        fit = self.fit
        return -math.inf if fit is None or not math.isfinite(fit.log_evidence) else fit.log_evidence

    @property
    def converged(self) -> bool:
        return self.fit is not None and self.fit.converged

    def given_up(self) -> "Candidate":
        """This candidate marked abandoned (it cannot reach the level a decision needs), unscored."""
        assert self.fit is not None
        return Candidate(replace(self.fit, abandoned=True), None)

    def light(self) -> "Candidate":
        """This candidate with its problem's caches dropped (not needed any more, not worth sending back)."""
        if self.fit is not None:
            self.fit.problem.clear_cache()
        return self


class SelectionContext(Protocol):
    """What the selection needs from the diagnosis (the tests implement it with tables of models).

    A model is a list of effect names; its fit starts from ``blocks`` (the
    parameters of a smaller model's fit by block name, None: the base fit's)
    and is made at the context's hyperparameters (``noise_scale`` and the
    base fit's tau).

    * :meth:`fit`: the model ``names`` fitted, its last effect the new one
      (``initial``: its start from a moment estimate, when the effect has
      one); the fit gives up below ``floor`` (and, with ``budget``, when it
      cannot converge within ``max_iter`` steps at its pace); scored on the
      folds when converged.
    * :meth:`resume`: a candidate's fit continued for ``max_iter`` steps.
    * :meth:`rescaled`: the noise scale re-estimated at ``candidate``'s MAP
      (the evidence's fixed point, only ever smaller); returns the context
      at that scale and the candidate refitted there, or None to keep
      ``candidate`` as it is.  The context itself is not changed.
    """

    noise_scale: float

    def fit(self, names: Sequence[str], blocks: Mapping | None = None, *, initial: bool = True, max_iter: int = 40,
            floor: float | None = None, budget: bool = False) -> Candidate: ...

    def resume(self, candidate: Candidate, *, max_iter: int = 40, floor: float | None = None) -> Candidate: ...

    def rescaled(self, candidate: Candidate) -> "tuple[SelectionContext, Candidate | None]": ...

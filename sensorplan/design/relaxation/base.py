"""The result of a relaxation, the two solver protocols, and the repair of solver round-off.

Owns: Relaxation, RelaxationSolver, FastMethod, repair_weights.  May import: errors.
"""

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

__all__ = ["Relaxation", "RelaxationSolver", "FastMethod", "repair_weights"]


@dataclass(frozen=True, eq=False)
class Relaxation:
    """Solution of the relaxed problem.

    Attributes
    ----------
    weights : ndarray (C,)
    utility : float
        Utility at ``weights`` (a feasible relaxed point).
    bound : float
        Certified bound on the relaxed optimum (utility >= ... <= bound).
    method : str
    stats : dict
        Solver name, status, iterations, time.
    """

    weights: np.ndarray
    utility: float
    bound: float
    method: str
    stats: dict = field(default_factory=dict)

    @property
    def relative_gap(self):
        return (self.bound - self.utility) / max(1.0, abs(self.bound))

    def to_dict(self):
        """JSON-ready: weights, utility, bound, relative gap, method and the solver's statistics."""
        return {"weights": [float(v) for v in self.weights], "utility": float(self.utility),
                "bound": float(self.bound), "relative_gap": float(self.relative_gap), "method": self.method,
                "stats": dict(self.stats)}


class RelaxationSolver(Protocol):
    """A relaxation solver, registered under a name (``solve_relaxation(problem, name)``).

    Contract: return a :class:`Relaxation` whose weights are feasible for the
    relaxed problem of ``problem`` (box, sum w = R, side rows; see
    :func:`repair_weights`) and whose ``bound`` is certified by the
    criterion's own certificate (:meth:`Criterion.bound` or
    :meth:`Criterion.cvxpy_bound`), independently of the solver's accuracy
    claims; raise :class:`~sensorplan.SolverError` when it cannot solve it.
    ``start_layout`` (candidate indices) is a good integer layout the solver
    may start from.
    """

    def __call__(self, problem, *, start_layout=None) -> Relaxation: ...


class FastMethod(Protocol):
    """The fast relaxation of a kind of criterion, registered under the name a criterion's
    ``relaxation`` attribute gives (the ``"fast"`` solver dispatches on it).

    Contract as :class:`RelaxationSolver`, with the relative certified gap
    ``tol`` to reach and at most ``max_rounds`` rounds of its outer loop.
    """

    def __call__(self, problem, *, tol, start_layout=None, max_rounds=50) -> Relaxation: ...


def repair_weights(problem, w):
    """Project solver round-off: clip to [0, 1] and rescale to the exact count."""
    w = np.clip(w, 0.0, 1.0)
    total = w.sum()
    if total > 0:
        w = w * (problem.count / total)
        w = np.clip(w, 0.0, 1.0)
    return w

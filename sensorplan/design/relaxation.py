"""Convex relaxation of the placement problem: the result type and the solver registry.

Every solver returns a :class:`Relaxation` whose ``bound`` is a certified
bound on the relaxed utility (hence on every integer layout), computed by
the criterion's own certificate (:meth:`Criterion.bound`) independently of
the solver's accuracy claims.  Solvers, one per module:

* ``"cvxpy"`` (:mod:`.relax_cvxpy`): the generic cvxpy formulation solved by
  Clarabel, the reference;
* ``"fast"``: column generation with a primal-dual interior-point method for
  smooth criteria (:mod:`.relax_ipm`), an eigen-subspace cutting-plane
  method for criteria that declare ``relaxation = "eigen-subspace"``
  (:mod:`.relax_eigen`, E), or the epigraph interior point of the
  worst-case detectability (:mod:`.relax_detect`, detect).

Owns: the Relaxation type, repair of solver round-off, solver dispatch.
May import: model, errors.
"""

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._errors import ConfigError, SolverError

__all__ = ["Relaxation", "solve_relaxation", "RELAXATION_SOLVERS", "register_relaxation_solver"]

RELAXATION_SOLVERS: dict[str, Callable] = {}


def register_relaxation_solver(name):
    """Register ``function(problem, *, start_layout=None) -> Relaxation`` under ``name``."""
    def decorator(function):
        RELAXATION_SOLVERS[name] = function
        return function
    return decorator


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


def _repair(problem, w):
    """Project solver round-off: clip to [0, 1] and rescale to the exact count."""
    w = np.clip(w, 0.0, 1.0)
    total = w.sum()
    if total > 0:
        w = w * (problem.count / total)
        w = np.clip(w, 0.0, 1.0)
    return w


def solve_relaxation(problem, solver="auto", *, start_layout=None):
    """Solve the relaxation of ``problem`` with a registered solver.

    ``"auto"`` is the fast path: it agrees with cvxpy + Clarabel to the
    certified gap and was faster for D, A and E at both sizes of
    studies/benchmarks/bench_design.py.
    """
    from . import relax_cvxpy, relax_eigen, relax_ipm  # noqa: F401  (register the solvers)

    name = "fast" if solver == "auto" else solver
    if name not in RELAXATION_SOLVERS:
        raise ConfigError(f"The 'solver' parameter must be 'auto' or one of {', '.join(sorted(RELAXATION_SOLVERS))}. "
                          f"Got {solver!r} instead.")
    if solver != "auto":
        return RELAXATION_SOLVERS[name](problem, start_layout=start_layout)
    try:
        return RELAXATION_SOLVERS[name](problem, start_layout=start_layout)
    except SolverError as exc:
        # the fast path needs a strictly feasible point; when the constraints are tight (every candidate
        # chosen, a count that just fits the spacing) the relaxed set has none and Clarabel solves it
        try:
            relaxation = RELAXATION_SOLVERS["cvxpy"](problem, start_layout=start_layout)
        except SolverError:
            raise exc from None
        relaxation.stats["fallback"] = f"fast path failed ({exc}); solved by cvxpy"
        return relaxation


@register_relaxation_solver("fast")
def solve_relaxation_fast(problem, *, start_layout=None, tol=1e-7, max_rounds=50):
    """The fast path of the criterion: interior point (smooth), eigen-subspace (E) or epigraph (detect)."""
    from .relax_detect import solve_detect_epigraph
    from .relax_eigen import solve_eigen_subspace
    from .relax_ipm import solve_column_generation

    methods = {"eigen-subspace": solve_eigen_subspace, "detect-epigraph": solve_detect_epigraph}
    method = methods.get(problem.criterion.relaxation, solve_column_generation)
    return method(problem, tol=tol, start_layout=start_layout, max_rounds=max_rounds)

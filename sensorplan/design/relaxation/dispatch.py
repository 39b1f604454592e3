"""Solve a relaxation with a registered solver; the ``"fast"`` solver dispatches on the criterion.

This module loads every built-in member of the family (importing them
registers them): ``"cvxpy"`` (:mod:`.cvxpy_reference`, the reference) and
the fast methods :mod:`.smooth` (``"interior-point"``: D, Ds, A and any
smooth criterion), :mod:`.eigen_subspace` (E) and :mod:`.detect_epigraph`
(detect).

Owns: solve_relaxation and the "fast" solver.  May import: errors, design.relaxation.
"""

from dataclasses import replace

from ..._errors import ConfigError, SolverError
from . import cvxpy_reference, detect_epigraph, eigen_subspace, smooth  # noqa: F401  (register the members)
from .registry import FAST_METHODS, RELAXATION_SOLVERS, register_relaxation_solver

__all__ = ["solve_relaxation", "solve_relaxation_fast", "CVXPY_FALLBACK_ENTRIES"]

# largest C x P^2 for which "auto" falls back to cvxpy + Clarabel (its dense conic data grow with it: the
# D relaxation at C = 200, P = 60 took 89 s and C = 800, P = 400 aborted on allocation)
CVXPY_FALLBACK_ENTRIES = 5_000_000


def solve_relaxation(problem, solver="auto", *, start_layout=None):
    """Solve the relaxation of ``problem`` with a registered solver.

    ``"auto"`` is the fast path, falling back to cvxpy + Clarabel when the
    fast path fails (studies/benchmarks/bench_design.py compares the two).
    """
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
        # chosen, a count that just fits the spacing) the relaxed set has none and Clarabel solves it --
        # on problems small enough for its dense conic data (beyond, it would run out of memory)
        entries = problem.n_candidates * problem.n_params**2
        if entries > CVXPY_FALLBACK_ENTRIES:
            raise SolverError(f"{' '.join(str(exc).split())} (the cvxpy fallback is not tried: "
                              f"{problem.n_candidates} candidates x {problem.n_params}^2 parameters is beyond "
                              f"its memory; use fewer candidates or elements)") from None
        try:
            relaxation = RELAXATION_SOLVERS["cvxpy"](problem, start_layout=start_layout)
        except SolverError:
            raise exc from None
        return replace(relaxation, stats={**relaxation.stats,
                                          "fallback": f"fast path failed ({exc}); solved by cvxpy"})


@register_relaxation_solver("fast")
def solve_relaxation_fast(problem, *, start_layout=None, tol=None, max_rounds=50):
    """The fast method registered under the criterion's ``relaxation`` name (interior point if none is), to the
    relative gap ``tol`` (default: the criterion's ``relaxation_tol``)."""
    method = FAST_METHODS.get(problem.criterion.relaxation, FAST_METHODS["interior-point"])
    tol = problem.criterion.relaxation_tol if tol is None else tol
    return method(problem, tol=tol, start_layout=start_layout, max_rounds=max_rounds)

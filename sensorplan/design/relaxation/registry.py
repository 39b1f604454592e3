"""The registries of relaxation solvers and of the fast methods the ``"fast"`` solver dispatches to.

Members register with :func:`register_relaxation_solver` (selected by
``solve_relaxation(problem, name)``) or :func:`register_fast_method`
(selected by the criterion's ``relaxation`` attribute).  The built-in
members are loaded by :mod:`sensorplan.design.relaxation` (the package).

Owns: RELAXATION_SOLVERS, FAST_METHODS and their decorators.  May import: design.relaxation.base.
"""

from .base import FastMethod, RelaxationSolver

__all__ = ["RELAXATION_SOLVERS", "FAST_METHODS", "register_relaxation_solver", "register_fast_method"]

RELAXATION_SOLVERS: dict[str, RelaxationSolver] = {}
FAST_METHODS: dict[str, FastMethod] = {}


def register_relaxation_solver(name):
    """Register ``function(problem, *, start_layout=None) -> Relaxation`` under ``name``."""
    def decorator(function):
        RELAXATION_SOLVERS[name] = function
        return function
    return decorator


def register_fast_method(name):
    """Register ``function(problem, *, tol, start_layout=None, max_rounds=50) -> Relaxation`` as the fast
    relaxation of the criteria whose ``relaxation`` attribute is ``name``."""
    def decorator(function):
        FAST_METHODS[name] = function
        return function
    return decorator

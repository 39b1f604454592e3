"""Convex relaxation of the placement problem: the result type, the solver registry and its members.

Every solver returns a :class:`~.base.Relaxation` whose ``bound`` is a
certified bound on the relaxed utility (hence on every integer layout),
computed by the criterion's own certificate (:meth:`Criterion.bound`)
independently of the solver's accuracy claims.  Solvers:

* ``"cvxpy"`` (:mod:`.cvxpy_reference`): the generic cvxpy formulation
  solved by Clarabel, the reference;
* ``"fast"`` (:mod:`.dispatch`): the fast method registered under the
  criterion's ``relaxation`` name: column generation (:mod:`.column_generation`)
  around a primal-dual interior point for smooth criteria (:mod:`.smooth`),
  an eigen-subspace cutting-plane method whose small SDPs have their own
  interior point (:mod:`.eigen_subspace`, :mod:`.lmi`; E), or the epigraph
  barrier method of the worst-case detectability (:mod:`.detect_epigraph`;
  detect).  :mod:`.interior_point` holds what the interior points share.

:mod:`.base` holds the result type and the two solver protocols,
:mod:`.registry` the registries the members register through; importing
this package loads every built-in member.

Owns: the relaxation solvers.  May import: errors, design.criteria, design.problem.
"""

from .base import FastMethod, Relaxation, RelaxationSolver, repair_weights
from .dispatch import solve_relaxation
from .registry import FAST_METHODS, RELAXATION_SOLVERS, register_fast_method, register_relaxation_solver

__all__ = ["Relaxation", "RelaxationSolver", "FastMethod", "repair_weights", "solve_relaxation",
           "RELAXATION_SOLVERS", "FAST_METHODS", "register_relaxation_solver", "register_fast_method"]

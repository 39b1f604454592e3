"""Optimal-design criteria on the posterior precision Q(w) = Q_0 + sum_i w_i I_i.

Every criterion is one class behind one protocol (:class:`~.base.Criterion`):
its value, the utility that is maximised (``value`` or ``-value``), the
gradient matrix G with d utility / d w_i = <G, I_i>, the Hessian in the
weights of a working set, upper bounds on the utility of adding one
candidate (for pruned greedy and exchange), the certified bound of a relaxed
point, the cvxpy objective, and the efficiency of a value against a bound.
:func:`~.registry.register_criterion` makes a new criterion available to
:func:`~sensorplan.design.recommend.recommend`, greedy, exchange, both
relaxation solvers and the command line.

One module per family (Q is the posterior precision in log-EI parameters,
optionally with spring log-stiffnesses appended):

* :mod:`.determinant`: D = log det Q, and Ds = log det of the Schur
  complement of the spring block (the springs marginalised);
* :mod:`.covariance`: A = trace(C Q^-1 C^T), C = identity, rows selecting
  the elements of a region of interest, or given linear functionals;
* :mod:`.eigenvalue`: E = lambda_min(Q);
* :mod:`.detect`: the worst case over damage centres of the detectability d^2.

:mod:`.base` holds the protocol, :mod:`.registry` the registry the members
register through, :mod:`.linalg` the dense kernels they share.  This
package is the loader: importing it registers every built-in criterion, in
the order D, Ds, A, E, detect.

Owns: the criteria and their registry.  May import: errors, detection.
"""

from .base import Criterion
from .registry import CRITERIA, criterion_class, make_criterion, register_criterion

# the members register on import, in this order (the order of CRITERIA, of --criterion's choices)
from .determinant import DCriterion, DsCriterion  # isort: skip
from .covariance import ACriterion  # isort: skip
from .eigenvalue import ECriterion  # isort: skip
from .detect import DetectCriterion  # isort: skip

__all__ = ["Criterion", "DCriterion", "DsCriterion", "ACriterion", "ECriterion", "DetectCriterion", "CRITERIA",
           "register_criterion", "make_criterion", "criterion_class"]

"""The whitened-problem engine: one base for every Bayesian least-squares problem of the package.

:mod:`.problem` holds :class:`WhitenedProblem`, the base of the EI problem
of the inversion, the diagnosis's joint problem and the detector's null
model: the whitened data of a case's crossings, their groups, the one cache
and the normal equations; :mod:`.normal` the accumulation of r.r, J^T J and
J^T r (:class:`NormalEquations`, :class:`Linearisation`); :mod:`.steps` the
Levenberg-Marquardt MAP (:func:`solve_map`), the secant curvature, the
Laplace evidence and the ridge Gauss-Newton iteration of the detector's null
fit (:func:`ridge_gauss_newton`).  The hyperparameter methods built on these steps are
:mod:`..laplace` (point estimates) and :mod:`..hyperposterior` (integration).

Owns: whitened data, normal equations, MAP steps, Laplace evidence.
May import: model and the foundations.
"""

from .normal import Linearisation, NormalEquations
from .problem import (DEFAULT_STD, CrossingGroup, LinearisedProblem, Stacked, StackedProblem, WhitenedProblem,
                      crossing_groups, data_sensors, rows_of)
from .steps import LOG_NOISE_FLOOR, STALL_STEPS, SecantCurvature, log_evidence, ridge_gauss_newton, solve_map

__all__ = ["Linearisation", "NormalEquations", "LinearisedProblem", "CrossingGroup", "WhitenedProblem",
           "crossing_groups", "data_sensors", "DEFAULT_STD", "LOG_NOISE_FLOOR", "STALL_STEPS", "SecantCurvature",
           "log_evidence", "solve_map", "Stacked", "StackedProblem", "ridge_gauss_newton", "rows_of"]

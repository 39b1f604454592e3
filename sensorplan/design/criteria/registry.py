"""The registry of design criteria: every criterion class under its name.

Members register with :func:`register_criterion`; the built-in members are
loaded by :mod:`sensorplan.design.criteria` (the package), which is what
callers import to see the whole family.

Owns: CRITERIA, register_criterion, criterion_class, make_criterion.
May import: errors, design.criteria.base.
"""

from ..._errors import ConfigError
from .base import Criterion

__all__ = ["CRITERIA", "register_criterion", "criterion_class", "make_criterion"]

CRITERIA: dict[str, type[Criterion]] = {}


def register_criterion(cls):
    """Class decorator: make ``cls`` (a :class:`Criterion` subclass) available under ``cls.name``."""
    CRITERIA[cls.name] = cls
    return cls


def criterion_class(name):
    """The registered criterion class called ``name`` (ConfigError if there is none)."""
    if name not in CRITERIA:
        raise ConfigError(f"The 'criterion' parameter must be one of {', '.join(CRITERIA)}. Got {name!r} instead.")
    return CRITERIA[name]


def make_criterion(name, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
    """Build a registered criterion.

    Parameters
    ----------
    name : str
        A key of ``CRITERIA`` ("D", "A", "E", "Ds" or a registered one).
    n_params : int
        Dimension of Q.
    n_elements : int
        Number of log-EI parameters (the leading ones); needed for Ds and
        for targeted A.
    edges : ndarray
        Element edges [m] (for ``region``).
    region : (float, float), optional
        A-criterion restricted to the elements overlapping [a, b] m.
    functionals : ndarray (m, n_elements), optional
        A-criterion on linear functionals of log EI (e.g. zone means).
    """
    return criterion_class(name).from_options(n_params, n_elements=n_elements, edges=edges, region=region,
                                              functionals=functionals)

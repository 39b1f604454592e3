"""The shared vocabulary of the effects' engineering statements: a finding, informed parameters, units.

An effect's :meth:`~.base.Effect.describe` turns its parameter block (MAP
and standard deviation) into findings such as "vertical spring at support 2
(x = 20.0 m): 5.0e8 N/m, 95 % interval 3.1e8-8.0e8 N/m"; only parameters
the data moved away from their prior (or pinned down well beyond it) are
stated (:func:`informed`).

Owns: :func:`finding`, :func:`informed`.  May import: the diagnosis's results.
"""

import numpy as np

from ..results import Finding

__all__ = ["Z95", "finding", "informed"]

Z95 = 1.959963984540054  # standard normal quantile of 0.975: the half-width of a 95 % interval in std


def finding(where, value, low, high, unit, fmt=".3g"):
    """One :class:`~sensorplan.diagnosis.results.Finding` (the values are in ``unit``)."""
    return Finding(where=where, value=float(value), low=float(low), high=float(high), unit=unit,
                   text=f"{where}: {value:{fmt}} {unit}, 95 % interval {low:{fmt}} to {high:{fmt}} {unit}")


def informed(mean, std, prior_mean, prior_std):
    """Parameters the data informed: moved by > 2 posterior std from the prior mean, and std < 0.7 prior std."""
    return (np.abs(mean - prior_mean) > 2.0 * std) & (std < 0.7 * prior_std)

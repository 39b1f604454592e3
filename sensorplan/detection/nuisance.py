"""What an undamaged bridge may do: the nuisance of damage detection, as columns on log EI.

* ``levels``: one common factor on each span's EI (one column per span);
* ``smooth``: log EI(x) = log EI_nominal(x) + a + b x + c x^2 within each span
  (three columns per span; x relative to the span centre, in span lengths,
  for conditioning: the projection does not depend on that choice).

Each column holds the element averages of 1, x, x^2 over the elements of its
span (exact for the element-wise constant EI of the forward model).  The
log stiffnesses of the elastic springs are the other nuisance parameters;
they come with the forward model's Jacobian.
"""

import numpy as np

from .._errors import ConfigError

__all__ = ["NUISANCES", "nuisance_matrix"]

NUISANCES = ("smooth", "levels")


def nuisance_matrix(bridge, mesh, nuisance="smooth"):
    """Matrix P (n_elements, n_columns): d log EI_e / d (nuisance coefficients)."""
    if nuisance not in NUISANCES:
        raise ConfigError(f"The 'nuisance' parameter must be one of {', '.join(NUISANCES)}. Got {nuisance!r} instead.")
    supports = np.asarray(bridge.support_positions, dtype=float)
    span = bridge.span_of(mesh.midpoints)
    order = 1 if nuisance == "levels" else 3
    out = np.zeros((mesh.n_elements, bridge.n_spans * order))
    for s in range(bridge.n_spans):
        inside = span == s
        a, b = supports[s], supports[s + 1]
        x0 = (mesh.edges[:-1][inside] - 0.5 * (a + b)) / (b - a)
        x1 = (mesh.edges[1:][inside] - 0.5 * (a + b)) / (b - a)
        moments = [np.ones_like(x0), 0.5 * (x0 + x1), (x0 * x0 + x0 * x1 + x1 * x1) / 3.0]
        for k in range(order):
            out[inside, s * order + k] = moments[k]
    return out

"""The normal equations of a whitened least-squares problem: r.r, J^T J and J^T r.

A problem's whitened residual r = W (y - F(theta)) and Jacobian J = -dr/dtheta
are never stacked: each block of rows (a crossing, or a group of crossings
that share their whitened Jacobian) adds its share to the three sums.  Both
the EI inversion and the diagnosis's joint problem accumulate through
:class:`NormalEquations`, so the sums are formed one way everywhere.

Owns: :class:`Linearisation`, :class:`NormalEquations`.  May import: numpy.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Linearisation", "NormalEquations"]


@dataclass(frozen=True)
class Linearisation:
    """Whitened misfit r.r and the normal-equation terms J^T J, J^T r (r = y - F; None without the Jacobian)."""

    rr: float
    jtj: np.ndarray
    jtr: np.ndarray


class NormalEquations:
    """Accumulates r.r, J^T J and J^T r block by block (rows of the whitened problem).

    Parameters
    ----------
    n_params : int
        Columns of the full Jacobian.
    jacobian : bool
        Form J^T J and J^T r (else only r.r).

    A block that acts on some parameters only passes their indices as
    ``columns``; its Jacobian then holds those columns only.  Blocks with
    the same whitened Jacobian (crossings at the same positions and load
    factors) add its Gram matrix once, times their ``count``.
    """

    def __init__(self, n_params, *, jacobian=True):
        self.rr = 0.0
        self.jtj = np.zeros((n_params, n_params)) if jacobian else None
        self.jtr = np.zeros(n_params) if jacobian else None

    @property
    def jacobian(self):
        """Whether J^T J and J^T r are formed."""
        return self.jtr is not None

    def add_residual(self, residual, white_jacobian=None, *, columns=None):
        """Add r.r of a block's whitened ``residual`` (flat) and, with its ``white_jacobian`` (rows, columns), J^T r."""
        self.rr += float(residual @ residual)
        if self.jtr is not None and white_jacobian is not None:
            if columns is None:
                self.jtr += white_jacobian.T @ residual
            else:
                self.jtr[columns] += white_jacobian.T @ residual

    def add_gram(self, gram, *, columns=None, count=1):
        """Add ``count`` times a block's Gram matrix J_b^T J_b (on ``columns`` if given) to J^T J."""
        if self.jtj is None:
            return
        if columns is None:
            self.jtj += count * gram
        else:
            self.jtj[np.ix_(columns, columns)] += gram if count == 1 else count * gram

    def linearisation(self):
        """The sums as a :class:`Linearisation`."""
        return Linearisation(self.rr, self.jtj, self.jtr)

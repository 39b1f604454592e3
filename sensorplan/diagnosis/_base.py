"""Base of the candidate effects: the model state and the effect protocol.

Owns: the Effect protocol.  May import: the foundations.
"""

from dataclasses import dataclass

import numpy as np

__all__ = []

_H = 1e-4  # position step of the central differences [m]


@dataclass
class State:
    bridge: object
    sensor_positions: np.ndarray
    positions: list
    axle_factors: np.ndarray
    ei_log_scale: np.ndarray  # log EI factor per crossing (load-dependent stiffness)


class Effect:
    """Base class: a named block of parameters with a Gaussian prior."""

    name = ""
    structural = False  # changes the forward model (else only the outputs)
    in_case = False  # a property of the case (springs, sensor positions, axle loads), written by --write-case
    frees: tuple = ()  # spring kinds whose stiffness the effect sets (the case's springs of that kind step aside)
    log_prior_constant = 0.0  # log prior of the effect's discrete choices (added to the evidence)
    additive = False  # an output term added to the reading (applied after the multiplicative outputs)
    moves_loads = False  # moves the load positions (the lines then need a continuous entry onto the bridge)
    needs_axle_lines = False  # the Jacobian needs each axle's response alone (JointProblem.axle_lines)
    # library effects this one holds as a special case: once it is in the model the data cannot tell them apart
    contains: tuple = ()

    def applicable(self, crossings):
        """Reason the effect cannot act on these data (None: it can)."""
        return

    def initial(self, ctx, predictions):
        """Start values from the base model's ``predictions`` per crossing (None: the prior mean)."""
        return

    def configure(self, ctx):
        """Set ``names``, ``mean``, ``std`` for the context; return self."""
        raise NotImplementedError

    @property
    def n_params(self):
        return len(self.names)

    def apply(self, state, phi):
        """Modify ``state`` in place (structural effects)."""

    def columns(self, ctx, c):
        """Indices of the parameters that can act on crossing ``c`` (None: all of them).

        The Jacobian blocks of crossing ``c`` hold these columns only: a
        parameter of one crossing (an offset, a shift) is zero in the others.
        """
        return

    def structural_jacobian(self, ctx, state, phi, c, y):
        """dy/dphi for crossing ``c`` (S, K, n) of a structural effect, n over ``columns(ctx, c)``."""
        raise NotImplementedError

    def output(self, ctx, state, phi, c, y):
        """Return (y', dy'/dphi (S, K, n) over ``columns(ctx, c)``, multiplier (scalar, applied to earlier
        Jacobians))."""
        return y, None, 1.0



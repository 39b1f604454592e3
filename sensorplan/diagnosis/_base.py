"""Base of the candidate effects: the model state and the effect protocol.

Owns: the Effect protocol.  May import: the foundations.
"""

from dataclasses import dataclass

import numpy as np

__all__ = []

_H = 1e-4  # position step of the central differences [m]


class PerSensor:
    """Columns dy/dphi of which each acts on one sensor's readings only: ``values`` (S, K or 1, k).

    Sensor ``i``'s readings depend on its own ``k`` columns ``i k .. i k + k
    - 1`` of the block (over ``columns(ctx, c)``) and on no others: an effect
    returns this instead of the block (S, K, S k) that is zero off those
    columns (offsets, drift, gains, sensor positions), and only the ``k``
    columns of each sensor are written (six sensors and 1739 readings per
    crossing: a sixth of the writes).
    """

    def __init__(self, values):
        self.values = values

    def write(self, target, add):
        """Write (or add) into ``target`` (S, K, S k), sensor by sensor into its own columns (the others stay)."""
        k = self.values.shape[2]
        for i, values in enumerate(self.values):
            own = target[i, :, i * k:(i + 1) * k]
            if add:
                own += values
            else:
                own[...] = values


class Outer:
    """Columns dy/dphi that are a product of a sensor factor and a reading factor: ``sensors[:, None, :] *
    loads[None, :, :]`` with ``sensors`` (S, n) and ``loads`` (K, n) (a spring's sensor and load reactions).

    Written as that product straight into the Jacobian's columns (no
    temporary block and no copy of it).
    """

    def __init__(self, sensors, loads):
        self.sensors, self.loads = sensors, loads

    def write(self, target, add):
        """Write (or add) the product into ``target`` (S, K, n), sensor by sensor.

        One (K, n) product per sensor: the Jacobian's buffers hold each
        reading's sensors and columns together (the bin map's layout), and a
        single broadcast product into that view ran an inner loop of n
        columns per reading and sensor (1.8 times slower).
        """
        for i, factor in enumerate(self.sensors):
            if add:
                target[i] += self.loads * factor
            else:
                np.multiply(self.loads, factor, out=target[i])


class Columns:
    """Columns dy/dphi given one by one: ``parts``, each (S, K), written into consecutive columns (no block formed)."""

    def __init__(self, parts):
        self.parts = parts

    def write(self, target, add):
        """Write (or add) the parts into ``target`` (S, K, n), column by column."""
        for j, part in enumerate(self.parts):
            if add:
                target[:, :, j] += part
            else:
                target[:, :, j] = part


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
        """dy/dphi for crossing ``c`` (S, K, n) of a structural effect, n over ``columns(ctx, c)`` (or a :class:`PerSensor`,
        :class:`Outer`, :class:`Columns`)."""
        raise NotImplementedError

    def output(self, ctx, state, phi, c, y):
        """Return (y', dy'/dphi (S, K, n) over ``columns(ctx, c)`` or a :class:`PerSensor`, multiplier (scalar or
        per sensor, applied to earlier Jacobians))."""
        return y, None, 1.0



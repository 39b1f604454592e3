"""Blocks of Jacobian columns an effect returns without forming them, and how they are written.

An effect's dy/dphi of one crossing is an array (S, K, n) or one of these
blocks, which write only what is not zero: :class:`PerSensor` (each sensor's
own columns), :class:`Outer` (a sensor factor times a reading factor: a
spring's sensor and load reactions), :class:`Columns` (columns given one by
one).  :func:`put` writes either into the joint model's Jacobian.

Owns: the column blocks.  May import: numpy.
"""

import numpy as np

__all__ = ["Columns", "Outer", "PerSensor", "put"]


class PerSensor:
    """Columns dy/dphi of which each acts on one sensor's readings only: ``values`` (S, K or 1, k).

    Sensor ``i``'s readings depend on its own ``k`` columns ``i k .. i k + k
    - 1`` of the block and on no others: an effect returns this instead of
    the block (S, K, S k) that is zero off those columns (offsets, drift,
    gains, sensor positions), and only the ``k`` columns of each sensor are
    written.
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
        reading's sensors and columns together (the bin map's layout), where
        a single broadcast product would run an inner loop of n columns per
        reading and sensor.
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


def put(extra, place, block, add=False):
    """Write (or with ``add`` add) an effect's ``block`` into the columns ``place`` (a slice) of ``extra`` (S, K, m).

    An array is written as it is; a :class:`PerSensor`, :class:`Outer` or
    :class:`Columns` block writes itself (only the columns it acts on,
    without forming the block).
    """
    target = extra[:, :, place]
    if isinstance(block, np.ndarray):
        if add:
            target += block
        else:
            target[...] = block
    else:
        block.write(target, add)

"""The joint model's predictions and Jacobian columns at one parameter vector, crossing by crossing.

Every crossing's predictions and the effects' columns are written at the
readings straight into the array its bin map acts on (readings first: one
sparse product per map, without copies); the log-EI block is formed on the
fitted rows directly (:func:`.lines.log_ei_blocks`) or kept as two factors
(:mod:`.factored`).  The structural effects' columns are written first, then
each output effect maps the readings and scales the columns before it (its
multiplier) and adds its own.

Owns: the assembly of an evaluation.  May import: numpy and the joint model's parts.
"""

import numpy as np

from .columns import Outer, put
from .factored import log_ei_factors
from .lines import log_ei_blocks

__all__ = ["assemble"]


def assemble(problem, theta, jacobian, factored):
    """Per crossing (y, Jacobian on its columns, None), or with ``factored`` (y, effects' columns, log-EI factor).

    ``factored`` (every crossing binned): the log-EI block stays a
    :class:`~.factored.LogEIFactor` and the Jacobian holds the effects'
    columns only (``problem.columns[c][n_elements:]``).
    """
    state = problem.state_at(theta)
    problem.prefetch(state, jacobian)
    every = [problem.lines(state, c) for c in range(problem.n_crossings)]
    # the log-EI block of every crossing, mapped onto the bins together (crossings at the same positions
    # share it; gains, amplifications and the map act on it linearly, in any order)
    log_ei = None
    if jacobian:
        items = [(lines, problem.load_factor(c), problem.binned[c]) for c, lines in enumerate(every)]
        log_ei = (log_ei_factors if factored else log_ei_blocks)(items, problem.cache)
    buffers, views = _buffers(problem, jacobian)
    scaled_blocks, on_bins = [], []
    for c, lines in enumerate(every):
        scaled, outer = _write_crossing(problem, theta, state, c, lines, views[c], None if log_ei is None else log_ei[c])
        scaled_blocks.append(scaled)
        on_bins.append(outer)
    mapped = _map_rows(problem, buffers, views)
    return [_fitted(problem, c, rows, scaled, outer, factored)
            for c, (rows, scaled, outer) in enumerate(zip(mapped, scaled_blocks, on_bins))]


def _write_crossing(problem, theta, state, c, lines, view, block):
    """Write crossing ``c``'s predictions and effects' columns at its readings into ``view``.

    Returns ((log-EI block, its scale by the outputs) or None without a
    Jacobian, the :class:`~.columns.Outer` columns of a binned crossing to
    be written on the bins after the map: (place, columns)).
    """
    y = lines.predictions * problem.load_factor(c)[None, :]
    places = problem.places[c]
    extra = None  # the effects' columns at the readings
    on_bins = []
    scale = 1.0  # the outputs' factors on the response, by which the log-EI block is scaled
    if block is not None:
        extra = view[:, :, 1:]  # zeros
        for b, sl in zip(problem.blocks, problem.slices):
            cols = b.effect.jacobian(b, problem, state, theta[sl], c, y)
            if cols is None:
                continue
            if isinstance(cols, Outer) and problem.binned[c] is not None and problem.binned[c].shared:
                # a sensor factor times a reading factor: the bin map acts on the reading factor alone
                # (spring columns: bins x springs instead of readings x sensors x springs)
                on_bins.append((places[b.name], cols))
            else:
                put(extra, places[b.name], cols)
    for b, sl in problem.outputs:
        y, out_block, mult = b.effect.output(b, problem, state, theta[sl], c, y)
        if extra is not None:
            if np.ndim(mult) or mult != 1.0:  # offsets and drift multiply nothing
                mult = np.reshape(mult, (-1, 1, 1)) if np.ndim(mult) else mult
                extra *= mult
                scale = scale * mult
            put(extra, places[b.name], out_block, add=True)
    view[:, :, 0] = y
    return (None if block is None else (block, scale)), on_bins


def _fitted(problem, c, rows, scaled, on_bins, factored):
    """(y, Jacobian, factor) of crossing ``c`` on its fitted rows from its mapped ``rows`` (y, effects' columns)."""
    y = rows[:, :, 0]
    if scaled is None:
        return y, None, None
    block, scale = scaled
    for place, cols in on_bins:  # times the outputs' factors, as the columns at the readings are
        sensors, loads = problem.binned[c].outer_to_bins(cols.sensors, cols.loads)
        Outer(sensors * np.reshape(scale, (-1, 1)), loads).write(rows[:, :, 1:][:, :, place], False)
    if factored:
        block.scale = block.scale * np.ravel(scale)
        return y, rows[:, :, 1:], block
    n_el = problem.n_elements
    jac = np.empty(block.shape[:2] + (problem.columns[c].size,))
    np.multiply(block, scale, out=jac[:, :, :n_el])
    jac[:, :, n_el:] = rows[:, :, 1:]
    return y, jac, None


def _buffers(problem, jacobian):
    """Arrays (readings, S, columns) of each bin map's crossings side by side, and each crossing's view.

    A crossing's view is (S, readings, 1 + its effects' columns with
    ``jacobian``): predictions first; all zeros.  Crossings fitted row by
    row get an array of their own.
    """
    widths = [1 + (problem.columns[c].size - problem.n_elements if jacobian else 0)
              for c in range(problem.n_crossings)]
    buffers, views = [], [None] * problem.n_crossings
    for members in problem.map_groups:
        n_readings = problem.model_positions[members[0]].size
        buffer = np.zeros((n_readings, problem.n_sensors, sum(widths[c] for c in members)))
        start = 0
        for c in members:
            views[c] = buffer[:, :, start:start + widths[c]].transpose(1, 0, 2)
            start += widths[c]
        buffers.append(buffer)
    for c in range(problem.n_crossings):
        if views[c] is None:
            views[c] = np.zeros((problem.n_sensors, problem.model_positions[c].size, widths[c]))
    return buffers, views


def _map_rows(problem, buffers, views):
    """The crossings' ``views`` on the fitted rows: the bins of each buffer in one product (:func:`_buffers`)."""
    out = list(views)
    for members, buffer in zip(problem.map_groups, buffers):
        rows = problem.binned[members[0]].to_bins_first(buffer)  # (bins, S, columns)
        start = 0
        for c in members:
            width = views[c].shape[2]
            out[c] = rows[:, :, start:start + width].transpose(1, 0, 2)
            start += width
    return out

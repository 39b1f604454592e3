"""Feasibility of the placement constraints, checked before any solver runs.

How many new sensors fit is a packing question on a line: with a minimum
spacing s between any two sensors (and at most ``span_max[j]`` in span j),
taking candidates left to right whenever they keep the spacing to the last
one taken and their span has room gives the largest possible layout (the
exchange argument of interval scheduling: the leftmost feasible sensor
leaves the most room to its right, and it uses a span no later sensor of
any other layout uses).  That packing is also a feasible layout, which the
search uses as a start.

Errors name the parameters as ``'count'``, ``'min_spacing'``, ... so that
an edge (the CLI) can put its own option names in their place.

Owns: the packing, the count/spacing/span/budget feasibility messages.
May import: errors.
"""

import numpy as np

from .._errors import ConfigError

__all__ = ["check_feasible", "packing"]


def packing(positions, spans, min_spacing, span_max=None, order=None):
    """Indices of the largest layout that keeps ``min_spacing`` [m] and the ``span_max`` counts.

    Candidates are taken left to right (ties in ``order``, default by index); with
    ``min_spacing`` 0 two candidates at one position (two kinds) may both be taken.
    """
    positions = np.asarray(positions, dtype=float)
    spans = np.asarray(spans, dtype=int)
    keys = np.arange(positions.size) if order is None else np.asarray(order)
    taken, last = [], -np.inf
    room = None if span_max is None else np.array(span_max, dtype=int)
    for i in np.lexsort((keys, positions)):
        if min_spacing > 0 and positions[i] - last < min_spacing - 1e-9:
            continue
        if room is not None and room[spans[i]] <= 0:
            continue
        taken.append(int(i))
        last = positions[i]
        if room is not None:
            room[spans[i]] -= 1
    return np.array(taken, dtype=int)


def _constraint_text(min_spacing, span_max, fixed):
    parts = []
    if min_spacing > 0:
        parts.append(f"'min_spacing' {min_spacing:g} m")
    if span_max is not None:
        parts.append(f"'span_max' {','.join(str(int(v)) for v in span_max)}")
    if fixed:
        parts.append(f"{fixed} 'fixed' sensor(s)")
    return " and ".join(parts)


def check_feasible(positions, spans, count, *, min_spacing=0.0, span_min=None, span_max=None, n_fixed=0,
                   costs=None, budget=None):
    """Raise a ConfigError naming the parameters when no layout of ``count`` sensors meets the constraints.

    ``positions``/``spans`` are the candidates left after the exclusion zones and
    the existing sensors; ``n_fixed`` only words the message.
    """
    positions = np.asarray(positions, dtype=float)
    spans = np.asarray(spans, dtype=int)
    c = positions.size
    if count > c:
        raise ConfigError(f"'count' {count} is more than the {c} candidate position(s) left (grid 'spacing', "
                          f"'exclude' zones{', fixed sensors' if n_fixed else ''}); lower 'count' or use a finer "
                          "'spacing'.")
    constrained = _constraint_text(min_spacing, span_max, n_fixed if min_spacing > 0 else 0)
    fit = packing(positions, spans, min_spacing, span_max).size
    if count > fit:
        relax = " or ".join(f"'{n}'" for n, on in (("min_spacing", min_spacing > 0), ("span_max", span_max is not None))
                            if on)
        raise ConfigError(f"'count' {count} with {constrained}: at most {fit} sensor(s) fit; lower 'count'"
                          + (f" or {relax}." if relax else "."))
    if span_min is not None:
        for j, need in enumerate(np.asarray(span_min, dtype=int)):
            inside = spans == j
            cap = None if span_max is None else np.where(np.arange(len(span_min)) == j, span_max, 0)
            room = packing(positions[inside], spans[inside], min_spacing, cap).size
            if need > room:
                where = f" with 'min_spacing' {min_spacing:g} m" if min_spacing > 0 else ""
                raise ConfigError(f"'span_min' asks for {need} sensor(s) in span {j + 1}, but at most {room} fit "
                                  f"there{where}; lower 'span_min'" + (" or 'min_spacing'." if where else "."))
    if budget is not None and costs is not None:
        cheapest = float(np.sort(np.asarray(costs, dtype=float))[:count].sum())
        if cheapest > budget * (1.0 + 1e-12) + 1e-12:
            raise ConfigError(f"'budget' {budget:g} is below the cost of the {count} cheapest candidate sensors "
                              f"({cheapest:g}); raise 'budget' or lower 'count'.")

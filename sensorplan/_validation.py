"""Validation helpers used at the public boundary.

Messages follow one template: "The 'name' parameter of Owner must be ...
Got ... instead." so that the command line can show them as they are.
"""

import math

import numpy as np

from ._errors import ConfigError

__all__ = []

# shortest damaged zone [m] the scenario and detectability models take: below it a zone is not a
# physical loss on a bridge, and c +- length/2 stops being resolvable in floating point (1e-300 m -> 0 m)
MIN_ZONE_LENGTH = 1e-3


def _fail(name, owner, requirement, value, hint=""):
    message = f"The '{name}' parameter of {owner} must be {requirement}. Got {value!r} instead."
    if hint:
        message += " " + hint
    raise ConfigError(message)


def as_float(value, name, owner, *, low=None, high=None, low_open=False, allow_inf=False):
    """Return ``value`` as a float after checking its range."""
    if isinstance(value, bool):
        _fail(name, owner, "a number", value)
    try:
        out = float(value)
    except (TypeError, ValueError):
        _fail(name, owner, "a number", value)
    if math.isnan(out) or (math.isinf(out) and not allow_inf):
        _fail(name, owner, "a finite number", value)
    if low is not None and (out < low or (low_open and out == low)):
        bound = f"> {low}" if low_open else f">= {low}"
        _fail(name, owner, f"a number {bound}", value)
    if high is not None and out > high:
        _fail(name, owner, f"a number <= {high}", value)
    return out


def as_float_tuple(values, name, owner, *, length=None, **kwargs):
    """Return a tuple of floats, broadcasting a scalar when ``length`` is given."""
    if isinstance(values, (str, dict)):
        _fail(name, owner, "a number or a list of numbers", values)
    if np.isscalar(values) or isinstance(values, (int, float)):
        if length is None:
            values = [values]
        else:
            values = [values] * length
    try:
        items = list(values)
    except TypeError:
        _fail(name, owner, "a number or a list of numbers", values)
    if length is not None and len(items) != length:
        _fail(name, owner, f"a number or a list of {length} numbers", values)
    if not items:
        _fail(name, owner, "a non-empty list of numbers", values)
    return tuple(as_float(v, name, owner, **kwargs) for v in items)


def as_float_array(values, name, owner, *, ndim=1, allow_empty=False):
    """Return a finite float array of the given dimension (read-only copy)."""
    if isinstance(values, (bool, np.bool_, str, dict)) or (
            isinstance(values, (list, tuple)) and any(isinstance(v, (bool, np.bool_, str)) for v in values)):
        _fail(name, owner, f"a {ndim}-d array of numbers", values)
    try:
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError):
        _fail(name, owner, f"a {ndim}-d array of numbers", values)
    if arr.ndim == 0 and ndim == 1:
        arr = arr.reshape(1)
    if arr.ndim != ndim:
        _fail(name, owner, f"a {ndim}-d array of numbers", f"array of shape {arr.shape}")
    if arr.size == 0 and not allow_empty:
        _fail(name, owner, "a non-empty array", values)
    if not np.all(np.isfinite(arr)):
        _fail(name, owner, "finite (no NaN or inf)", "an array with non-finite entries")
    arr.setflags(write=False)
    return arr

"""Axles rolling onto an elastic end bearing over a short ramp (when an effect moves the loads).

Over an elastic end bearing a point load jumps from zero to the bearing's
response as it steps on; with the load positions as parameters a fit would
then sit on that jump (line searches fail, Levenberg-Marquardt crawls).  The
response of an axle at u (its position on the bridge) is scaled by g(u), a
smooth step s^2 (3 - 2 s) from 0 at ``entry``/2 outside the end to 1 at
``entry``/2 inside (a tyre's contact patch rolling on); outside the bridge
the response is the one at the end.  Centred on the end, the ramp crosses
the jump where a point load does (a ramp wholly outside would move the jump
out by half its width, for shifts and axle loads to absorb).  Rigid ends
carry no jump and no ramp.

Owns: the ramp.  May import: numpy.
"""

import numpy as np

__all__ = ["entry_ramp"]


def _smooth_step(s):
    """s^2 (3 - 2 s) on [0, 1], 0 below and 1 above: C1."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _smooth_step_slope(s):
    """d/ds of :func:`_smooth_step` (0 outside the open interval)."""
    return np.where((s > 0.0) & (s < 1.0), 6.0 * s * (1.0 - s), 0.0)


def entry_ramp(u, length, entry, elastic):
    """(g, dg/du) at axle positions ``u`` (A, N); None when no axle is within a ramp.

    ``elastic``: whether the (left, right) end bearings are elastic.
    """
    half = 0.5 * entry
    near = np.zeros(u.shape, bool)
    if elastic[0]:
        near |= np.abs(u) < half
    if elastic[1]:
        near |= np.abs(u - length) < half
    if not near.any():
        return None
    if elastic[0]:
        s = (u + half) / entry
        left, left_slope = _smooth_step(s), _smooth_step_slope(s) / entry
    else:
        left, left_slope = np.where(u >= 0.0, 1.0, 0.0), np.zeros(u.shape)
    if elastic[1]:
        s = (length - u + half) / entry
        right, right_slope = _smooth_step(s), -_smooth_step_slope(s) / entry
    else:
        right, right_slope = np.where(u <= length, 1.0, 0.0), np.zeros(u.shape)
    return left * right, left_slope * right + left * right_slope

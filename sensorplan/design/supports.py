"""Sensors and supports: the support margin of the candidate grid, and what a sensor on a support reads.

A support constrains the beam: a rigid vertical support does not move, so
a deflection sensor on it reads nothing; a clamped (rotationally rigid)
support does not rotate, so a tiltmeter on it reads nothing; a pin leaves
the rotation free (a tiltmeter on a pinned support still reads the
rotation of the beam there); an elastic spring moves with the load, so a
sensor on it reads the spring's deformation, which depends on the spring's
stiffness as much as on EI.

Owns: the support margin filter and the notes on sensors that sit on a support.
May import: errors.
"""

import math

import numpy as np

from .._errors import ConfigError

__all__ = ["ON_SUPPORT", "keep_off_supports", "support_notes"]

ON_SUPPORT = 0.05  # m: a sensor this close to a support sits on it (the bearing's own size)


def keep_off_supports(positions, supports, margin):
    """The candidate ``positions`` [m] at least ``margin`` [m] from every support position.

    A margin of 0 keeps every position; a ConfigError names 'support_margin'
    when it removes them all.
    """
    positions = np.asarray(positions, dtype=float)
    try:
        margin = float(margin)
    except (TypeError, ValueError):
        margin = math.nan
    if not (math.isfinite(margin) and margin >= 0.0):
        raise ConfigError(f"The 'support_margin' parameter must be a non-negative distance in m. Got {margin!r} "
                          "instead.")
    if margin == 0.0:
        return positions
    dist = np.abs(positions[:, None] - np.asarray(supports, dtype=float)[None, :]).min(axis=1)
    keep = dist >= margin - 1e-9
    if not keep.any():
        raise ConfigError(f"The 'support_margin' of {margin:g} m removes every candidate position; lower "
                          "'support_margin'.")
    return positions[keep]


def _reading(kind, support):
    """What a sensor of ``kind`` on ``support`` reads, as the end of a sentence."""
    if kind == "deflection":
        k = support.vertical_stiffness
        if math.isinf(k):
            return ("a deflection sensor there reads nothing (the rigid support does not move); move it off the "
                    "support (a support margin keeps sensors off the supports)")
        return (f"a deflection sensor there reads the compression of the elastic bearing ({k:.3g} N/m), which "
                "depends on the bearing's stiffness as much as on EI")
    k = support.rotational_stiffness
    if math.isinf(k):
        return ("a tiltmeter there reads nothing (the clamped support does not rotate); move it off the support "
                "(a support margin keeps sensors off the supports)")
    if k == 0.0:
        return ("a tiltmeter there still reads the rotation of the beam over the pinned support (the pin leaves "
                "it free); mount it on the beam, not on the bearing")
    return (f"a tiltmeter there reads the rotation the rotational spring ({k:.3g} N·m/rad) allows, which depends "
            "on the spring's stiffness as much as on EI")


def support_notes(bridge, positions, kinds):
    """One sentence for each sensor within ``ON_SUPPORT`` of a support of ``bridge``: where, and what it reads."""
    notes = []
    supports = bridge.supports
    for x, kind in zip(positions, kinds):
        near = min(supports, key=lambda s: abs(s.position - x))
        if abs(near.position - x) <= ON_SUPPORT:
            notes.append(f"sensor at {x:.2f} m sits on the support at {near.position:.2f} m: "
                         + _reading(kind, near))
    return tuple(notes)

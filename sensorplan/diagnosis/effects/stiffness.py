"""Load-dependent stiffness: EI that changes with the load level of a crossing (cracking concrete softens).

Owns: :class:`LoadDependentStiffness`, :func:`load_levels`.  May import: the effect protocol, numpy.
"""

import math

import numpy as np

from .base import EffectBlock, StructuralEffect
from .findings import Z95, finding, informed

__all__ = ["LOAD_REFERENCE", "LoadDependentStiffness", "load_levels"]

LOAD_REFERENCE = 100.0e3  # N: load-dependent stiffness is stated per 100 kN of load level


def load_levels(crossings, vehicle):
    """Load level of every crossing: the largest load factor times the vehicle's total load [N]."""
    total = float(np.sum(vehicle.axle_loads))
    return np.array([float(np.max(np.abs(c.load_factor))) * total for c in crossings])


class LoadDependentStiffness(StructuralEffect):
    """EI that depends on the load level of the crossing or step.

    log EI of crossing c = log EI + beta (P_c - mean P) / 100 kN, with P_c
    the crossing's load level; beta is the log EI change per 100 kN.  Its
    block's ``detail``: (P_c - mean P) / 100 kN per crossing.
    """

    name = "load_dependent_stiffness"

    def applicable(self, crossings):
        levels = np.array([float(np.max(np.abs(c.load_factor))) for c in crossings])
        if levels.size < 2 or np.ptp(levels) < 0.05 * np.max(levels):
            return "every crossing has the same load level"
        return None

    def configure(self, ctx):
        levels = load_levels(ctx.crossings, ctx.case.vehicle)
        return EffectBlock(self, ("log_ei_per_100kN",), np.zeros(1), np.full(1, 0.3),
                           detail=(levels - levels.mean()) / LOAD_REFERENCE)

    def apply(self, block, state, phi):
        state.ei_log_scale = state.ei_log_scale + phi[0] * block.detail

    def jacobian(self, block, ctx, state, phi, c, y):
        dy = ctx.lines(state, c).log_ei_total * ctx.load_factor(c)[None, :]
        return (dy * block.detail[c])[:, :, None]

    def describe(self, block, ctx, mean, std):
        if not informed(mean, std, block.mean, block.std)[0]:
            return []
        ref = LOAD_REFERENCE / 1e3
        return [finding(f"EI change per {ref:.0f} kN of load level", 100 * math.expm1(mean[0]),
                        100 * math.expm1(mean[0] - Z95 * std[0]), 100 * math.expm1(mean[0] + Z95 * std[0]), "%", ".1f")]

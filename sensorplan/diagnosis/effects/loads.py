"""Effects on the loads: the recorded load positions shifted (and scaled), the axle loads off nominal.

Owns: :class:`PositionOffset`, :class:`AxleLoads`.  May import: the effect protocol, the column blocks, numpy.
"""

import math

import numpy as np

from ..joint.columns import Columns
from .base import EffectBlock, StructuralEffect
from .findings import Z95, finding, informed

__all__ = ["AxleLoads", "PositionOffset"]


class PositionOffset(StructuralEffect):
    """A shift of the recorded load position per crossing, plus a common scale (speed) error."""

    name = "position_offset"
    moves_loads = True

    def configure(self, ctx):
        n = ctx.n_crossings
        return EffectBlock(self, tuple(f"shift_{label}" for label in ctx.labels) + ("scale",), np.zeros(n + 1),
                           np.concatenate([np.full(n, 0.5), [0.02]]))

    def apply(self, block, state, phi):
        state.positions = [x + phi[c] + phi[-1] * x for c, x in enumerate(state.positions)]

    def columns(self, block, ctx, c):
        return np.array([c, block.n_params - 1])

    def jacobian(self, block, ctx, state, phi, c, y):
        # exact: the slope of the piecewise-cubic lines in the load position
        dydx = ctx.line_slopes(state, c) * ctx.load_factor(c)[None, :]
        recorded = ctx.model_positions[c]
        return Columns([dydx, dydx * recorded[None, :]])

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        out = []
        shifts = np.arange(ctx.n_crossings)
        if ok[shifts].any():
            k = int(np.argmax(np.abs(mean[shifts]) * ok[shifts]))
            out.append(finding(f"load position shift, largest in crossing {ctx.labels[k]} "
                               f"({int(ok[shifts].sum())} of {shifts.size} crossings affected)", mean[k],
                               mean[k] - Z95 * std[k], mean[k] + Z95 * std[k], "m", ".2f"))
        if ok[-1]:
            out.append(finding("position scale (speed) error", 100 * mean[-1], 100 * (mean[-1] - Z95 * std[-1]),
                               100 * (mean[-1] + Z95 * std[-1]), "%", ".2f"))
        return out


class AxleLoads(StructuralEffect):
    """A factor on every axle load (total load and axle shares)."""

    name = "axle_loads"
    in_case = True
    needs_axle_lines = True

    def configure(self, ctx):
        n = ctx.case.vehicle.n_axles
        return EffectBlock(self, tuple(f"log_axle_{a}" for a in range(n)), np.zeros(n), np.full(n, 0.2))

    def apply(self, block, state, phi):
        state.axle_factors = state.axle_factors * np.exp(phi)

    def jacobian(self, block, ctx, state, phi, c, y):
        return Columns([ctx.axle_lines(state, c, a) * ctx.load_factor(c)[None, :] for a in range(block.n_params)])

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        return [finding(f"load of axle {a + 1}", 100 * math.expm1(mean[a]), 100 * math.expm1(mean[a] - Z95 * std[a]),
                        100 * math.expm1(mean[a] + Z95 * std[a]), "% vs nominal", ".1f")
                for a in range(block.n_params) if ok[a]]

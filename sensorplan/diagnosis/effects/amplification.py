"""Dynamic amplification: the whole response scaled by (1 + a) per crossing.

Owns: :class:`DynamicAmplification`.  May import: the effect protocol, numpy.
"""

import numpy as np

from .base import EffectBlock, OutputEffect
from .findings import Z95, finding, informed

__all__ = ["DynamicAmplification"]


class DynamicAmplification(OutputEffect):
    """A dynamic amplification factor (1 + a) of the whole response, per crossing."""

    name = "dynamic_amplification"

    def applicable(self, crossings):
        if all(c.n_loads < 8 for c in crossings):
            return "every crossing is a static load step (no vehicle in motion)"
        return None

    def configure(self, ctx):
        n = ctx.n_crossings
        return EffectBlock(self, tuple(f"amplification_{label}" for label in ctx.labels), np.zeros(n),
                           np.full(n, 0.1))

    def columns(self, block, ctx, c):
        return np.array([c])

    def output(self, block, ctx, state, phi, c, y):
        return y * (1.0 + phi[c]), y[:, :, None].copy(), 1.0 + phi[c]

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        if not ok.any():
            return []
        k = int(np.argmax(np.abs(mean) * ok))
        return [finding(f"response amplification, largest in crossing {ctx.labels[k]} "
                        f"({int(ok.sum())} of {ok.size} crossings affected)", 100 * mean[k],
                        100 * (mean[k] - Z95 * std[k]), 100 * (mean[k] + Z95 * std[k]), "%", ".1f")]

"""Offsets of the readings: a constant per sensor and crossing, or an offset plus a linear drift along it.

Owns: :class:`SensorOffset`, :class:`ThermalDrift`.  May import: the effect protocol, the column blocks, numpy.
"""

import numpy as np

from ..joint.columns import PerSensor
from .base import EffectBlock, OutputEffect
from ..units import UNITS
from .findings import Z95, finding, informed

__all__ = ["SensorOffset", "ThermalDrift"]


def _largest_per_sensor(block, ctx, mean, std, step, what):
    """Per sensor, the finding of its largest informed parameter (every ``step``-th of its block) over the crossings."""
    ok = informed(mean, std, block.mean, block.std)
    out = []
    for i, sname in enumerate(ctx.sensor_names):
        scale, unit = UNITS[ctx.sensors.kinds[i]]
        idx = np.array([c * ctx.n_sensors * step + i * step + (step - 1) for c in range(ctx.n_crossings)])
        if not ok[idx].any():
            continue
        k = idx[int(np.argmax(np.abs(mean[idx])))]
        c = int(np.where(idx == k)[0][0])
        out.append(finding(f"{what} of {sname}, largest in crossing {ctx.labels[c]} "
                           f"({int(ok[idx].sum())} of {idx.size} crossings affected)", scale * mean[k],
                           scale * (mean[k] - Z95 * std[k]), scale * (mean[k] + Z95 * std[k]), unit))
    return out


class SensorOffset(OutputEffect):
    """A constant offset of every sensor in every crossing (zero drift, re-levelling)."""

    name = "sensor_offset"
    per_sensor = True
    additive = True

    def applicable(self, crossings):
        if all(c.n_loads < 2 for c in crossings):
            return "with one sample per crossing an offset per crossing is the reading itself"
        return None

    def configure(self, ctx):
        names = tuple(f"offset_{name}_{label}" for label in ctx.labels for name in ctx.sensor_names)
        return EffectBlock(self, names, np.zeros(ctx.n_sensors * ctx.n_crossings),
                           np.tile(ctx.offset_scale, ctx.n_crossings))

    def columns(self, block, ctx, c):
        return np.arange(c * ctx.n_sensors, (c + 1) * ctx.n_sensors)

    def output(self, block, ctx, state, phi, c, y):
        s = ctx.n_sensors
        b = phi[c * s:(c + 1) * s]
        return y + b[:, None], PerSensor(np.ones((s, 1, 1))), 1.0

    def describe(self, block, ctx, mean, std):
        return _largest_per_sensor(block, ctx, mean, std, 1, "offset")


class ThermalDrift(OutputEffect):
    """Offset plus a linear drift along the crossing, per sensor and crossing."""

    name = "thermal_drift"
    per_sensor = True
    additive = True
    contains = ("sensor_offset",)  # its offset per sensor and crossing is the sensor offset

    def applicable(self, crossings):
        if all(c.n_loads < 3 for c in crossings):
            return "a drift along a crossing needs several samples per crossing"
        return None

    def configure(self, ctx):
        names = tuple(f"{kind}_{name}_{label}" for label in ctx.labels for name in ctx.sensor_names
                      for kind in ("drift0", "drift1"))
        return EffectBlock(self, names, np.zeros(2 * ctx.n_sensors * ctx.n_crossings),
                           np.tile(np.repeat(ctx.offset_scale, 2), ctx.n_crossings))

    def columns(self, block, ctx, c):
        return np.arange(2 * c * ctx.n_sensors, 2 * (c + 1) * ctx.n_sensors)

    def output(self, block, ctx, state, phi, c, y):
        s = ctx.n_sensors
        x = ctx.model_positions[c]
        t = (x - 0.5 * (x[0] + x[-1])) / max(x[-1] - x[0], 1e-9)
        out = y.copy()
        for i in range(s):
            k0 = 2 * (c * s + i)
            out[i] += phi[k0] + phi[k0 + 1] * t
        per_sensor = np.broadcast_to(np.stack([np.ones_like(t), t], axis=-1), (s,) + t.shape + (2,))
        return out, PerSensor(per_sensor), 1.0

    def describe(self, block, ctx, mean, std):
        return _largest_per_sensor(block, ctx, mean, std, 2, "drift along the crossing")

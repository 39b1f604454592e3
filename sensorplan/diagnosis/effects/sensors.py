"""Effects at the sensors: a recorded position off the true one, a gain (a sign and a factor).

Owns: :class:`SensorPosition`, :class:`SensorGain`.  May import: the model's forward solve, the effect protocol,
the column blocks, the cache.
"""

import math

import numpy as np

from ..._cache import Cache, value_key
from ...model.forward import influence_lines
from ..joint.columns import PerSensor
from .base import EffectBlock, OutputEffect, StructuralEffect
from .findings import Z95, finding, informed

__all__ = ["FLIP_PROBABILITY", "SensorGain", "SensorPosition"]

POSITION_STEP = 1e-4  # m: step of the central differences of the lines in the sensor position
FLIP_PROBABILITY = 0.01  # prior probability that a sensor is mounted the wrong way round

# the data gains of each set of crossings and the model they were computed for: one nominal solve per
# diagnosis, not one per model that holds a gain
_GAINS = Cache(maxsize=4)


class SensorPosition(StructuralEffect):
    """The true position of every sensor differs from the recorded one."""

    name = "sensor_position"
    per_sensor = True
    in_case = True

    def configure(self, ctx):
        n = ctx.n_sensors
        return EffectBlock(self, tuple(f"shift_{name}" for name in ctx.sensor_names), np.zeros(n), np.full(n, 0.3))

    def apply(self, block, state, phi):
        state.sensor_positions = np.clip(state.sensor_positions + phi, 0.0, state.bridge.length)

    def jacobian(self, block, ctx, state, phi, c, y):
        """A central difference of the exact lines (step ``POSITION_STEP``, clipped to the bridge)."""
        r, length, h = state.sensor_positions, state.bridge.length, POSITION_STEP
        up = ctx.lines(state, c, sensor_positions=np.clip(r + h, 0, length)).predictions
        down = ctx.lines(state, c, sensor_positions=np.clip(r - h, 0, length)).predictions
        step = np.clip(r + h, 0, length) - np.clip(r - h, 0, length)
        dydr = (up - down) / step[:, None] * ctx.load_factor(c)[None, :]
        return PerSensor(dydr[:, :, None])

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        return [finding(f"position of {sname} (recorded x = {ctx.sensors.positions[i]:.2f} m)", mean[i],
                        mean[i] - Z95 * std[i], mean[i] + Z95 * std[i], "m shift", ".2f")
                for i, sname in enumerate(ctx.sensor_names) if ok[i]]


class SensorGain(OutputEffect):
    """A gain on every sensor: a sign (-1: mounted the wrong way round) times a positive factor (10^k: a unit slip).

    The sign is discrete: it is set once per dataset from the least-squares
    gain of the data on the nominal model (negative: flipped), each flip at a
    prior probability of ``FLIP_PROBABILITY`` (its log enters the evidence as
    the block's ``log_prior_constant``; the block's ``detail`` is the sign
    per sensor).  The factor is log-normal, log gain ~ N(0, 1).  On the log
    scale a gain common to all sensors and the EI scale are linearly
    confounded (a straight valley that Gauss-Newton crosses in one step); a
    linear gain would make the valley curved (g / EI constant), along which
    Levenberg-Marquardt crawls.
    """

    name = "sensor_gain"
    per_sensor = True

    def configure(self, ctx):
        sign = np.where(data_gains(ctx) < 0.0, -1.0, 1.0)
        flips = int(np.sum(sign < 0))
        constant = flips * math.log(FLIP_PROBABILITY) + (ctx.n_sensors - flips) * math.log1p(-FLIP_PROBABILITY)
        return EffectBlock(self, tuple(f"log_gain_{name}" for name in ctx.sensor_names), np.zeros(ctx.n_sensors),
                           np.ones(ctx.n_sensors), log_prior_constant=constant, detail=sign)

    def initial(self, block, ctx, predictions):
        # the magnitude of the least-squares gain against the nominal model
        return np.clip(np.log(np.maximum(np.abs(data_gains(ctx)), 1e-3)), -3.0, 3.0)

    def output(self, block, ctx, state, phi, c, y):
        gain = block.detail * np.exp(phi)
        out = y * gain[:, None]
        return out, PerSensor(out[:, :, None]), gain

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        out = []
        for i, sname in enumerate(ctx.sensor_names):
            sign = block.detail[i]
            if ok[i] or sign < 0:
                note = " (mounted the wrong way round)" if sign < 0 else ""
                ends = sign * np.exp([mean[i] - Z95 * std[i], mean[i] + Z95 * std[i]])
                out.append(finding(f"gain of {sname}{note}", sign * math.exp(mean[i]), ends.min(), ends.max(), "",
                                   ".3f"))
        return out


def data_gains(ctx):
    """Least-squares gain of each sensor's data on the nominal model's predictions (all crossings; read-only)."""
    case = ctx.case
    key = value_key(case.bridge, case.mesh.edges, np.asarray(case.ei), ctx.sensors.positions, ctx.sensors.kinds,
                    case.vehicle, ctx.model_positions, [ctx.load_factor(c) for c in range(ctx.n_crossings)],
                    [getattr(c, "map_key", None) for c in ctx.crossings], [c.values for c in ctx.crossings])
    return _GAINS.get((), lambda: _solved_gains(ctx), key=key)


def _solved_gains(ctx):
    case = ctx.case
    lines = influence_lines(case.bridge, case.mesh, case.ei, ctx.sensors, case.vehicle,
                            np.concatenate(ctx.model_positions))
    pred = lines.predictions * np.concatenate([ctx.load_factor(c) for c in range(ctx.n_crossings)])[None, :]
    ends = np.cumsum([x.size for x in ctx.model_positions])[:-1]
    pred = np.concatenate([ctx.to_bins(c, p) for c, p in enumerate(np.split(pred, ends, axis=1))], axis=1)
    data = np.concatenate([c.values for c in ctx.crossings], axis=1)
    norm = np.sum(pred * pred, axis=1)
    # a sensor the model says reads nothing (a deflection at a rigid bearing, zero up to round-off) has gain 0
    reads = norm > 1e-24 * norm.max()
    gains = np.where(reads, np.sum(data * pred, axis=1) / np.where(reads, norm, 1.0), 0.0)
    gains.flags.writeable = False
    return gains

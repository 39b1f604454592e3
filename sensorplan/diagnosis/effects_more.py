"""More candidate effects: the case's own elastic springs, sensor gain or sign, load-dependent stiffness.

Owns: those effects.  May import: the foundations.
"""

import math
import weakref

import numpy as np

from ..model.forward import influence_lines
from ._base import Effect, PerSensor

__all__ = []

LOAD_REFERENCE = 100.0e3  # N: load-dependent stiffness is stated per 100 kN of load level
FLIP_PROBABILITY = 0.01  # prior probability that a sensor is mounted the wrong way round


class CaseSprings(Effect):
    """The elastic springs of the case, estimated as ``invert`` does (a nuisance of the base model).

    Springs of the kinds in ``freed`` are left to the effect that frees them.
    """

    name = "case_springs"
    structural = True
    in_case = True

    def __init__(self, freed=()):
        self.freed = set(freed)

    def configure(self, ctx):
        bridge = ctx.case.bridge
        pairs = [(i, kind) for i, kind in bridge.spring_parameters if kind not in self.freed]
        self.springs = pairs
        self.names = [f"log_k_{kind}_{i}" for i, kind in pairs]
        self.mean = np.array([np.log(bridge.rotational_springs[i] if kind == "rotational" else bridge.vertical_springs[i])
                              for i, kind in pairs])
        self.std = np.full(len(pairs), ctx.prior.spring_std)
        return self

    def apply(self, state, phi):
        b = state.bridge
        rot, vert = list(b.rotational_springs), list(b.vertical_springs)
        for (i, kind), v in zip(self.springs, np.exp(phi)):
            (rot if kind == "rotational" else vert)[i] = float(v)
        state.bridge = type(b)(b.spans, tuple(rot), tuple(vert))

    def structural_jacobian(self, ctx, state, phi, c, y):
        lines = ctx.lines(state, c)
        names = list(state.bridge.spring_names)
        return lines.spring_log_columns(ctx.load_factor(c), [names.index(f"{kind}_{i}") for i, kind in self.springs])


class SensorGain(Effect):
    """A gain on every sensor: a sign (-1: mounted the wrong way round) times a positive factor (10^k: a unit slip).

    The sign is discrete: it is set once per dataset from the least-squares
    gain of the data on the nominal model (negative: flipped), each flip at a
    prior probability of ``FLIP_PROBABILITY`` (its log enters the evidence as
    ``log_prior_constant``).  The factor is log-normal, log gain ~ N(0, 1).
    On the log scale a gain common to all sensors and the EI scale are
    linearly confounded (a straight valley that Gauss-Newton crosses in one
    step); a linear gain made the valley curved (g / EI constant) and
    Levenberg-Marquardt crawled along it (40 iterations without converging
    on a flipped sensor of the two-span bridge with a settled bearing).
    """

    name = "sensor_gain"

    def configure(self, ctx):
        self.names = [f"log_gain_{name}" for name in ctx.sensor_names]
        self.sign = np.where(_data_gains(ctx) < 0.0, -1.0, 1.0)
        self.mean = np.zeros(ctx.n_sensors)
        self.std = np.ones(ctx.n_sensors)
        flips = int(np.sum(self.sign < 0))
        self.log_prior_constant = flips * math.log(FLIP_PROBABILITY) + (ctx.n_sensors - flips) * math.log1p(
            -FLIP_PROBABILITY)
        return self

    def initial(self, ctx, predictions):
        # the magnitude of the least-squares gain against the nominal model
        return np.clip(np.log(np.maximum(np.abs(_data_gains(ctx)), 1e-3)), -3.0, 3.0)

    def output(self, ctx, state, phi, c, y):
        gain = self.sign * np.exp(phi)
        out = y * gain[:, None]
        return out, PerSensor(out[:, :, None]), gain


# the data gains of each set of crossings (with the case they were computed for): one nominal solve per
# diagnosis instead of two per model holding a gain (~0.1 s each on three spans and twelve crossings)
_GAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _data_gains(ctx):
    """Least-squares gain of each sensor's data on the nominal model's predictions (all crossings)."""
    kept = _GAINS.get(ctx.crossings)
    if kept is not None and kept[0] is ctx.case:
        return kept[1]
    gains = _solved_gains(ctx)
    gains.flags.writeable = False
    _GAINS[ctx.crossings] = (ctx.case, gains)
    return gains


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
    return np.where(reads, np.sum(data * pred, axis=1) / np.where(reads, norm, 1.0), 0.0)


def load_levels(crossings, vehicle):
    """Load level of every crossing: the largest load factor times the vehicle's total load [N]."""
    total = float(np.sum(vehicle.axle_loads))
    return np.array([float(np.max(np.abs(c.load_factor))) * total for c in crossings])


class LoadDependentStiffness(Effect):
    """EI that depends on the load level of the crossing or step (cracking concrete softens under load).

    log EI of crossing c = log EI + beta (P_c - mean P) / 100 kN, with P_c
    the crossing's load level; beta is the log EI change per 100 kN.
    """

    name = "load_dependent_stiffness"
    structural = True

    def applicable(self, crossings):
        levels = np.array([float(np.max(np.abs(c.load_factor))) for c in crossings])
        if levels.size < 2 or np.ptp(levels) < 0.05 * np.max(levels):
            return "every crossing has the same load level"
        return None

    def configure(self, ctx):
        levels = load_levels(ctx.crossings, ctx.case.vehicle)
        self.level = (levels - levels.mean()) / LOAD_REFERENCE
        self.names = ["log_ei_per_100kN"]
        self.mean = np.zeros(1)
        self.std = np.full(1, 0.3)
        return self

    def apply(self, state, phi):
        state.ei_log_scale = state.ei_log_scale + phi[0] * self.level

    def structural_jacobian(self, ctx, state, phi, c, y):
        dy = ctx.lines(state, c).log_ei_total * ctx.load_factor(c)[None, :]
        return (dy * self.level[c])[:, :, None]

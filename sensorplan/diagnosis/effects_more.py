"""More candidate effects: the case's own elastic springs, sensor gain or sign, load-dependent stiffness.

Owns: those effects.  May import: the foundations.
"""

import numpy as np

from ._base import Effect

__all__ = []

LOAD_REFERENCE = 100.0e3  # N: load-dependent stiffness is stated per 100 kN of load level


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
        jac = lines.spring_log_jacobian * ctx.load_factor(c)[None, :, None]
        cols = [names.index(f"{kind}_{i}") for i, kind in self.springs]
        return jac[:, :, cols]


class SensorGain(Effect):
    """A gain on every sensor: 1 is right, -1 a sensor mounted the wrong way round, 10^k a unit slip."""

    name = "sensor_gain"

    def configure(self, ctx):
        self.names = [f"gain_{name}" for name in ctx.sensor_names]
        self.mean = np.ones(ctx.n_sensors)
        self.std = np.ones(ctx.n_sensors)  # a sign flip (-1) is two prior std away
        return self

    def initial(self, ctx, predictions):
        # least-squares gain of the data on the base model's predictions: a flipped sensor starts at -1
        num = sum(np.sum(c.values * y, axis=1) for c, y in zip(ctx.crossings, predictions))
        den = sum(np.sum(y * y, axis=1) for y in predictions)
        return np.clip(num / np.maximum(den, 1e-300), -3.0, 3.0)

    def output(self, ctx, state, phi, c, y):
        jac = np.zeros(y.shape + (self.n_params,))
        for i in range(ctx.n_sensors):
            jac[i, :, i] = y[i]
        return y * phi[:, None], jac, phi


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
        lines = ctx.lines(state, c)
        dy = lines.jacobian("log_ei").sum(axis=2) * ctx.load_factor(c)[None, :]
        return (dy * self.level[c])[:, :, None]

"""Candidate unmodelled effects: parametric extensions of the forward model.

Each effect owns a block of parameters phi with an independent Gaussian
prior (mean, std), changes the model state (bridge springs, sensor or load
positions, axle loads) or the outputs (offsets, drift, amplification), and
returns the exact derivative of the predictions with respect to its
parameters (sensor-position derivatives by a central difference of the
exact influence lines, step 1e-4 m; load-position derivatives exact, from
the piecewise-cubic lines of ``JointProblem.line_slopes``).

State passed around (one per parameter vector):
  bridge, sensor_positions (S,), positions (list per crossing),
  axle_factors (A,), and the evaluation context.
"""

import math

import numpy as np

from ._base import _H, Columns, Effect, Outer, PerSensor, State
from .effects_more import CaseSprings, LoadDependentStiffness, SensorGain

__all__ = ["EFFECTS", "CaseSprings", "State", "make_effect"]


def _span_reference(ctx, support):
    bridge = ctx.case.bridge
    xs = bridge.support_positions
    spans = np.array(bridge.spans)
    if support == 0:
        length = spans[0]
    elif support == len(xs) - 1:
        length = spans[-1]
    else:
        length = 0.5 * (spans[support - 1] + spans[support])
    ei = float(np.median(ctx.case.ei))
    return ei, float(length)


def _fixity_prior(ctx, stiffness, reference, low, high, std=2.5):
    """Prior mean and std of log k from the fixity f = k / (k + reference), clipped to [low, high].

    log k is flat in the data near f = 0 or 1 (a pin, a clamp, a rigid
    support), so the prior starts where the data can act on it.
    """
    mean = []
    for i, k in enumerate(stiffness):
        ref = reference(*_span_reference(ctx, i))
        f = float(np.clip(k / (k + ref) if np.isfinite(k) else 1.0, low, high))
        mean.append(math.log(ref * f / (1.0 - f)))
    return np.array(mean), np.full(len(mean), std)


class SupportRotationalSpring(Effect):
    """A rotational spring at every support (pins gain a restraint, clamps lose some)."""

    name = "support_rotational_spring"
    structural = True
    in_case = True
    frees = ("rotational",)

    def configure(self, ctx):
        # fixity f = k / (k + 4 EI / L): a pin is taken as f = 0.05, a clamp as 0.95
        self.names = [f"log_k_rot_{i}" for i in range(ctx.case.bridge.support_positions.size)]
        self.mean, self.std = _fixity_prior(ctx, ctx.case.bridge.rotational_springs,
                                            lambda ei, length: 4.0 * ei / length, 0.05, 0.95)
        return self

    def apply(self, state, phi):
        b = state.bridge
        state.bridge = type(b)(b.spans, tuple(np.exp(phi)), b.vertical_springs)

    def structural_jacobian(self, ctx, state, phi, c, y):
        return _spring_columns(ctx, state, c, "rotational")


class VerticalSupportSpring(Effect):
    """A vertical spring at every support (rigid supports may settle)."""

    name = "vertical_support_spring"
    structural = True
    in_case = True
    frees = ("vertical",)

    def configure(self, ctx):
        # f = k / (k + 48 EI / L^3), support against mid-span stiffness: rigid is taken as f = 0.98
        self.names = [f"log_k_vert_{i}" for i in range(ctx.case.bridge.support_positions.size)]
        self.mean, self.std = _fixity_prior(ctx, ctx.case.bridge.vertical_springs,
                                            lambda ei, length: 48.0 * ei / length**3, 0.02, 0.98)
        return self

    def apply(self, state, phi):
        b = state.bridge
        state.bridge = type(b)(b.spans, b.rotational_springs, tuple(np.exp(phi)))

    def structural_jacobian(self, ctx, state, phi, c, y):
        return _spring_columns(ctx, state, c, "vertical")


def _spring_columns(ctx, state, c, kind):
    """dy/dlog k of the ``kind`` springs at every support (S, N, supports); zero where a support is rigid."""
    lines = ctx.lines(state, c)
    n = state.bridge.support_positions.size
    pairs = [(col, int(name.partition("_")[2])) for col, name in enumerate(state.bridge.spring_names)
             if name.partition("_")[0] == kind]
    if not pairs:
        return np.zeros(y_shape(lines) + (n,))
    cols, supports = zip(*pairs)
    jac = lines.spring_log_columns(ctx.load_factor(c), cols)
    if list(supports) == list(range(n)):
        return jac
    sensors, loads = (np.zeros((len(part), n)) for part in (jac.sensors, jac.loads))
    sensors[:, list(supports)], loads[:, list(supports)] = jac.sensors, jac.loads
    return Outer(sensors, loads)


def y_shape(lines):
    return lines.predictions.shape


class SensorOffset(Effect):
    """A constant offset of every sensor in every crossing (zero drift, re-levelling)."""

    name = "sensor_offset"
    additive = True

    def applicable(self, crossings):
        if all(c.n_loads < 2 for c in crossings):
            return "with one sample per crossing an offset per crossing is the reading itself"
        return None

    def configure(self, ctx):
        s, n_c = ctx.n_sensors, ctx.n_crossings
        self.names = [f"offset_{name}_{label}" for label in ctx.labels for name in ctx.sensor_names]
        self.mean = np.zeros(s * n_c)
        self.std = np.tile(ctx.offset_scale, n_c)
        return self

    def columns(self, ctx, c):
        return np.arange(c * ctx.n_sensors, (c + 1) * ctx.n_sensors)

    def output(self, ctx, state, phi, c, y):
        s = ctx.n_sensors
        b = phi[c * s:(c + 1) * s]
        return y + b[:, None], PerSensor(np.ones((s, 1, 1))), 1.0


class ThermalDrift(Effect):
    """Offset plus a linear drift along the crossing, per sensor and crossing."""

    name = "thermal_drift"
    additive = True
    contains = ("sensor_offset",)  # its offset per sensor and crossing is the sensor offset

    def applicable(self, crossings):
        if all(c.n_loads < 3 for c in crossings):
            return "a drift along a crossing needs several samples per crossing"
        return None

    def configure(self, ctx):
        s, n_c = ctx.n_sensors, ctx.n_crossings
        self.names = [f"{kind}_{name}_{label}" for label in ctx.labels for name in ctx.sensor_names
                      for kind in ("drift0", "drift1")]
        self.mean = np.zeros(2 * s * n_c)
        self.std = np.tile(np.repeat(ctx.offset_scale, 2), n_c)
        return self

    def columns(self, ctx, c):
        return np.arange(2 * c * ctx.n_sensors, 2 * (c + 1) * ctx.n_sensors)

    def output(self, ctx, state, phi, c, y):
        s = ctx.n_sensors
        x = ctx.model_positions[c]
        t = (x - 0.5 * (x[0] + x[-1])) / max(x[-1] - x[0], 1e-9)
        out = y.copy()
        for i in range(s):
            k0 = 2 * (c * s + i)
            out[i] += phi[k0] + phi[k0 + 1] * t
        per_sensor = np.broadcast_to(np.stack([np.ones_like(t), t], axis=-1), (s,) + t.shape + (2,))
        return out, PerSensor(per_sensor), 1.0


class PositionOffset(Effect):
    """A shift of the recorded load position per crossing, plus a common scale (speed) error."""

    name = "position_offset"
    structural = True
    moves_loads = True

    def configure(self, ctx):
        self.names = [f"shift_{label}" for label in ctx.labels] + ["scale"]
        self.mean = np.zeros(ctx.n_crossings + 1)
        self.std = np.concatenate([np.full(ctx.n_crossings, 0.5), [0.02]])
        return self

    def apply(self, state, phi):
        state.positions = [x + phi[c] + phi[-1] * x for c, x in enumerate(state.positions)]

    def columns(self, ctx, c):
        return np.array([c, self.n_params - 1])

    def structural_jacobian(self, ctx, state, phi, c, y):
        # exact: the slope of the piecewise-cubic lines in the load position (JointProblem.line_slopes)
        dydx = ctx.line_slopes(state, c) * ctx.load_factor(c)[None, :]
        recorded = ctx.model_positions[c]
        return Columns([dydx, dydx * recorded[None, :]])


class AxleLoads(Effect):
    """A factor on every axle load (total load and axle shares)."""

    name = "axle_loads"
    structural = True
    in_case = True
    needs_axle_lines = True

    def configure(self, ctx):
        n = ctx.case.vehicle.n_axles
        self.names = [f"log_axle_{a}" for a in range(n)]
        self.mean = np.zeros(n)
        self.std = np.full(n, 0.2)
        return self

    def apply(self, state, phi):
        state.axle_factors = state.axle_factors * np.exp(phi)

    def structural_jacobian(self, ctx, state, phi, c, y):
        return Columns([ctx.axle_lines(state, c, a) * ctx.load_factor(c)[None, :] for a in range(self.n_params)])


class SensorPosition(Effect):
    """The true position of every sensor differs from the recorded one."""

    name = "sensor_position"
    structural = True
    in_case = True

    def configure(self, ctx):
        self.names = [f"shift_{name}" for name in ctx.sensor_names]
        self.mean = np.zeros(ctx.n_sensors)
        self.std = np.full(ctx.n_sensors, 0.3)
        return self

    def apply(self, state, phi):
        state.sensor_positions = np.clip(state.sensor_positions + phi, 0.0, state.bridge.length)

    def structural_jacobian(self, ctx, state, phi, c, y):
        r = state.sensor_positions
        up = ctx.lines(state, c, sensor_positions=np.clip(r + _H, 0, state.bridge.length)).predictions
        down = ctx.lines(state, c, sensor_positions=np.clip(r - _H, 0, state.bridge.length)).predictions
        step = np.clip(r + _H, 0, state.bridge.length) - np.clip(r - _H, 0, state.bridge.length)
        dydr = (up - down) / step[:, None] * ctx.load_factor(c)[None, :]
        return PerSensor(dydr[:, :, None])


class DynamicAmplification(Effect):
    """A dynamic amplification factor (1 + a) of the whole response, per crossing."""

    name = "dynamic_amplification"

    def applicable(self, crossings):
        if all(c.n_loads < 8 for c in crossings):
            return "every crossing is a static load step (no vehicle in motion)"
        return None

    def configure(self, ctx):
        self.names = [f"amplification_{label}" for label in ctx.labels]
        self.mean = np.zeros(ctx.n_crossings)
        self.std = np.full(ctx.n_crossings, 0.1)
        return self

    def columns(self, ctx, c):
        return np.array([c])

    def output(self, ctx, state, phi, c, y):
        return y * (1.0 + phi[c]), y[:, :, None].copy(), 1.0 + phi[c]


EFFECTS = {cls.name: cls for cls in (SupportRotationalSpring, VerticalSupportSpring, SensorOffset, ThermalDrift,
                                      PositionOffset, AxleLoads, SensorPosition, DynamicAmplification,
                                      SensorGain, LoadDependentStiffness)}


def make_effect(name):
    try:
        return EFFECTS[name]()
    except KeyError:
        from .._errors import ConfigError

        raise ConfigError(f"Unknown effect {name!r}; choose from {', '.join(EFFECTS)}.") from None

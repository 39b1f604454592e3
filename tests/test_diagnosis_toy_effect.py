"""Adding an effect is one class: a toy effect defined here, registered from outside the package.

The toy is a constant tilt of each tiltmeter, the same in every crossing (a
sensor mounted out of level) -- one parameter per sensor, where the
library's ``sensor_offset`` has one per sensor and crossing.  The data are
simulated with such a tilt on one sensor; the diagnosis must screen the
toy with the library, select it as the cause and state it in engineering
terms, through ``diagnose`` and without any change to the package
(docs/api.md, "Adding an effect").
"""

from dataclasses import replace

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.diagnosis.effects import EFFECTS, EffectBlock, OutputEffect, register_effect, unregister_effect
from sensorplan.diagnosis.effects.findings import Z95, finding, informed

TILT = 20e-6  # rad: the second tiltmeter's tilt in the data


class SensorTilt(OutputEffect):
    """A constant offset of each sensor, the same in every crossing (a tiltmeter mounted out of level)."""

    name = "sensor_tilt"
    additive = True  # added to the reading, after any effect that scales the response
    per_sensor = True  # its parameters belong to the data's sensors

    def configure(self, ctx):
        n = ctx.n_sensors
        return EffectBlock(self, tuple(f"tilt_{s}" for s in ctx.sensor_names), np.zeros(n),
                           np.asarray(ctx.offset_scale, dtype=float))

    def output(self, block, ctx, state, phi, c, y):
        # y' = y + tilt per sensor: dy'_i/dtilt_j = 1 if i == j; it scales no earlier column (multiplier 1)
        return y + phi[:, None], np.broadcast_to(np.eye(y.shape[0])[:, None, :], y.shape + (y.shape[0],)), 1.0

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        return [finding(f"tilt of {s}", 1e6 * mean[i], 1e6 * (mean[i] - Z95 * std[i]), 1e6 * (mean[i] + Z95 * std[i]),
                        "µrad") for i, s in enumerate(ctx.sensor_names) if ok[i]]


@pytest.fixture
def toy():
    register_effect(SensorTilt)
    yield SensorTilt
    unregister_effect(SensorTilt.name)


def _tilted_data():
    case = sp.example_case("openlab-like")
    case = replace(case.with_mesh(sp.Mesh.uniform(case.bridge, 8)), sweep=sp.LoadSweep.from_range(0.0, 32.0, 1.0))
    data = sp.simulate_crossings(case, 4, noise=True, rng=6)
    tilt = np.array([[0.0], [TILT]])
    return case, sp.Crossings(data.sensor_names, tuple(replace(c, values=c.values + tilt) for c in data.crossings))


def test_a_toy_effect_registered_from_outside_is_screened_selected_and_described(toy):
    assert list(EFFECTS)[-1] == "sensor_tilt"
    case, data = _tilted_data()
    d = sp.diagnose(case, data)
    # screened with the library (every registered effect is a default candidate)
    assert "sensor_tilt" in [e.name for e in d.effects] and "sensor_offset" in [e.name for e in d.effects]
    # selected: one parameter per sensor explains the gap with more evidence than one per sensor and crossing
    assert d.causes == ("sensor_tilt",) and not d.unexplained
    entry = {e.name: e for e in d.effects}["sensor_tilt"]
    assert entry.log_bayes_factor > 3 and entry.converged
    # described: the tilt of the second tiltmeter, its 95 % interval holding the simulated one
    (found,) = d.findings["sensor_tilt"]
    assert found.where == f"tilt of {case.sensors.names[1]}" and found.unit == "µrad"
    assert found.low < 1e6 * TILT < found.high
    assert found.text in d.summary() and "cause 1: sensor_tilt" in d.summary()
    assert d.to_dict()["findings"]["sensor_tilt"][0]["where"] == found.where
    # a property of the data, not of the case
    assert d.corrected_model.not_in_case == ("sensor_tilt",)


def test_registering_keeps_names_unique_and_unregistering_restores_the_library(toy):
    from sensorplan.diagnosis.effects.springs import VerticalSupportSpring

    class Impostor(SensorTilt):
        name = "vertical_support_spring"

    with pytest.raises(sp.ConfigError, match="registered already"):
        register_effect(Impostor)
    assert EFFECTS["vertical_support_spring"] is VerticalSupportSpring
    with pytest.raises(sp.ConfigError, match="subclass"):
        register_effect(int)
    unregister_effect("sensor_tilt")
    assert "sensor_tilt" not in EFFECTS

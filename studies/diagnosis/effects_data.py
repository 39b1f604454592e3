"""Synthetic crossings with one unmodelled effect, generated independently of the effect library.

Each generator builds the data with the public forward model (a finer,
differently aligned truth mesh, noise from the case's noise model) and
applies the effect directly: a changed bridge, shifted sensors, shifted
load positions, changed axle loads, or additive / multiplicative terms.

Three effects are outside the library (:data:`OUT_OF_LIBRARY`): a free
vibration along the crossing, and two the package's beam cannot express,
simulated with the study's own finite-element beam (:mod:`beam_fe`) and
added as the difference they make to its readings:

* ``shear_deformation``: the deck's shear flexibility (a Timoshenko beam,
  phi = 12 EI / (kGA L^2) of 0.05-0.2 over the first span);
* ``bearing_liftoff``: one bearing of a continuous bridge a one-sided
  contact with a gap of 2-10 % of the largest deflection above it without
  it: it carries no reaction under a light or distant load, nor in tension.
"""

from dataclasses import replace

import numpy as np

import sensorplan as sp
from sensorplan.model.crossings import Crossing, Crossings
from sensorplan.verification.verify import truth_mesh

from beam_fe import liftoff_readings, shear_lines

EFFECT_NAMES = ("support_rotational_spring", "vertical_support_spring", "sensor_offset", "thermal_drift",
                "position_offset", "axle_loads", "sensor_position", "dynamic_amplification", "sensor_gain",
                "load_dependent_stiffness")
OUT_OF_LIBRARY = ("vibration", "shear_deformation", "bearing_liftoff")


def _fine(case):
    return case.with_mesh(truth_mesh(case))


def generate(case, effect, rng, n_crossings=6, *, ei=None, return_noise_rms=False, noise_free=False):
    """Crossings of ``case`` with ``effect`` present (None: effect-free; :data:`OUT_OF_LIBRARY`: out of library).

    ``effect`` may also be a tuple of effects, applied together (each as it is
    applied alone, in the order given).

    With ``return_noise_rms=True`` return ``(crossings, noise_rms)``, where
    ``noise_rms`` is the rms of the noise actually added to the data (all
    crossings, sensors and load positions): the floor a correct model's
    residuals can reach.  With ``noise_free=True`` the same draws without the
    noise (the effects' realisations are drawn before it).
    """
    rng = np.random.default_rng(rng)
    fine = _fine(case)
    ei_fine = fine.ei if ei is None else ei(fine.mesh.midpoints)
    pos = case.sweep.positions
    peak = np.abs(fine.influence_lines(ei_fine).predictions).max(axis=1)
    std = case.noise.std
    bridge, sensors, vehicle = fine.bridge, fine.sensors, fine.vehicle
    shifts = np.zeros(n_crossings)
    add = np.zeros((n_crossings, sensors.n_sensors, pos.size))
    mult = np.ones(n_crossings)
    gain = np.ones(sensors.n_sensors)
    load_factor = np.ones(n_crossings)
    ei_factor = np.ones(n_crossings)
    beam = {}  # the out-of-library effects of the study's own beam: name -> their parameters
    for name in (effect,) if effect is None or isinstance(effect, str) else tuple(effect):
        if name == "support_rotational_spring":
            rot = list(bridge.rotational_springs)
            i = int(rng.integers(0, len(rot)))
            ei0 = float(np.median(case.ei))
            span = bridge.spans[min(i, len(bridge.spans) - 1)]
            rot[i] = (3.0 if rot[i] == 0 else 0.3) * ei0 / span * (1 if rot[i] == 0 else rot[i] * span / ei0)
            bridge = sp.Bridge(bridge.spans, tuple(rot), bridge.vertical_springs)
        elif name == "vertical_support_spring":
            vert = list(bridge.vertical_springs)
            i = int(rng.integers(0, len(vert)))
            ei0 = float(np.median(case.ei))
            span = bridge.spans[min(i, len(bridge.spans) - 1)]
            vert[i] = 2.0 * 48 * ei0 / span**3  # settles noticeably
            bridge = sp.Bridge(bridge.spans, bridge.rotational_springs, tuple(vert))
        elif name == "sensor_offset":
            add += (rng.choice([-1, 1], (n_crossings, sensors.n_sensors)) * rng.uniform(6, 12, (n_crossings, sensors.n_sensors))
                    * std[None, :])[:, :, None]
        elif name == "thermal_drift":
            t = (pos - pos.mean()) / (pos[-1] - pos[0])
            slope = rng.choice([-1, 1], (n_crossings, sensors.n_sensors)) * rng.uniform(10, 20, (n_crossings, sensors.n_sensors))
            add += slope[:, :, None] * std[None, :, None] * t[None, None, :]
        elif name == "position_offset":
            shifts = rng.choice([-1, 1], n_crossings) * rng.uniform(0.4, 0.8, n_crossings)
        elif name == "axle_loads":
            loads = np.array(vehicle.axle_loads) * rng.uniform(1.15, 1.3, vehicle.n_axles)
            vehicle = sp.Vehicle(vehicle.axle_offsets, tuple(loads))
        elif name == "sensor_position":
            moved = sensors.positions + rng.choice([-1, 1], sensors.n_sensors) * rng.uniform(0.4, 0.7, sensors.n_sensors)
            sensors = sp.SensorLayout(np.clip(moved, 0.0, bridge.length), sensors.kinds, sensors.names, sensors.noise_std)
        elif name == "dynamic_amplification":
            mult = 1.0 + rng.uniform(0.05, 0.15, n_crossings)
        elif name == "sensor_gain":  # one sensor mounted the wrong way round
            gain[int(rng.integers(0, sensors.n_sensors))] = -1.0
        elif name == "load_dependent_stiffness":  # heavier crossings see a softer (cracked) bridge
            load_factor = np.linspace(0.6, 1.4, n_crossings)
            total = float(np.sum(vehicle.axle_loads))
            ei_factor = np.exp(-rng.uniform(0.15, 0.3) * (load_factor - load_factor.mean()) * total / 100e3)
        elif name == "vibration":  # out of the library: a free vibration along the crossing
            phase = rng.uniform(0, 2 * np.pi, n_crossings)
            wave = np.sin(2 * np.pi * pos[None, :] / 2.3 + phase[:, None])
            add += 0.08 * peak[None, :, None] * wave[:, None, :]
        elif name == "shear_deformation":
            span = bridge.spans[0]
            beam[name] = {"kga": 12.0 * float(np.median(case.ei)) / (rng.uniform(0.05, 0.2) * span**2)}
        elif name == "bearing_liftoff":
            if bridge.n_spans < 2:
                raise ValueError("bearing_liftoff needs a continuous bridge (two spans or more)")
            beam[name] = {"support": int(rng.integers(0, bridge.n_spans + 1)), "fraction": rng.uniform(0.02, 0.1)}
        elif name is not None:
            raise ValueError(name)
    truth = replace(fine, bridge=bridge, sensors=sensors, vehicle=vehicle)
    added = {}  # the beam effects of the crossings that share a load shift and an EI factor, computed once
    for c in range(n_crossings):
        key = (float(shifts[c]), float(ei_factor[c]))
        if key not in added:
            added[key] = _beam_effects(truth, ei_fine * ei_factor[c], pos + shifts[c], beam)
        add[c] += added[key] * load_factor[c]
    noise = case.noise.sample(pos, rng, n_crossings)
    if noise_free:
        noise = np.zeros_like(noise)
    crossings = []
    for c in range(n_crossings):
        clean = truth.influence_lines(ei_fine * ei_factor[c], positions=pos + shifts[c]).predictions
        clean = clean * load_factor[c]
        values = gain[:, None] * (mult[c] * clean + add[c]) + noise[c]
        crossings.append(Crossing(str(c + 1), pos, values, np.full(pos.size, load_factor[c])))
    out = Crossings(case.sensors.names, tuple(crossings))
    if return_noise_rms:
        return out, float(np.sqrt(np.mean(noise**2)))
    return out


def _beam_effects(truth, ei, positions, beam):
    """The readings the out-of-library ``beam`` effects add to ``truth``'s, (S, m) (0 without them)."""
    out = np.zeros((truth.sensors.n_sensors, positions.size))
    if not beam:
        return out
    mesh = truth.mesh
    args = (truth.bridge, lambda x: ei[mesh.element_of(x)], truth.sensors, truth.vehicle, positions)
    if "shear_deformation" in beam:
        timoshenko, bernoulli = shear_lines(*args, kga=beam["shear_deformation"]["kga"], ei_edges=mesh.edges)
        out += timoshenko - bernoulli
    if "bearing_liftoff" in beam:
        p = beam["bearing_liftoff"]
        lifted, bearing = liftoff_readings(*args, support=p["support"], gap_fraction=p["fraction"],
                                           ei_edges=mesh.edges)
        out += lifted - bearing
    return out

"""Physical bounds of a case read from a file: what a bridge, a vehicle and a sensor can be.

The value objects accept any positive number; a case file is checked
against the ranges below, so that a unit slip (EI in kN m^2, axle loads in
kN or t, a length in mm) or a typo (1e300) gets a one-line error naming
the field instead of an overflow deep in the algebra.

=========================  =====================================
span length                0.5 to 2000 m, at most 50 spans
flexural rigidity EI       1e3 to 1e14 N m^2
rotational spring          0 (pin), inf (clamp) or 1 to 1e16 N m/rad
vertical spring            inf (rigid) or 1e2 to 1e16 N/m
axle load                  1 N to 1e7 N; axle offsets at most 100 m
noise correlation length   at most 1e4 m
correlated noise std       as a white noise std of the sensor's kind
correlation time           at most one day
random walk                at most 1e-3 rad or 1e-2 m per sqrt(s)
crossing speed             0.05 to 100 m/s
logger sample rate         0.01 Hz to 1 MHz
load sweep                 within 10 bridge lengths of the bridge,
                           at least one position with an axle on it
predicted readings         at most 0.02 rad / 1 m (as the CSV reader)
=========================  =====================================

Owns: the bounds and the checks.  May import: model, errors.
"""

import math

import numpy as np

from .._errors import ConfigError

__all__ = ["BOUNDS", "check_bridge", "check_vehicle", "check_noise", "check_case", "check_signal"]

BOUNDS = {
    "span": (0.5, 2000.0),
    "n_spans": 50,
    "ei": (1e3, 1e14),
    "rotational_spring": (1.0, 1e16),
    "vertical_spring": (1e2, 1e16),
    "axle_load": (1.0, 1e7),
    "axle_offset": 100.0,
    "correlation_length": 1e4,
    "correlation_time_s": 86400.0,
    "random_walk": {"rotation": 1e-3, "deflection": 1e-2},
    "speed": (0.05, 100.0),
    "sample_rate": (1e-2, 1e6),
    "correlated_std": {"rotation": 1e-3, "deflection": 5e-3},
}
READING_LIMITS = {"rotation": (0.02, "rad"), "deflection": (1.0, "m")}


def _outside(value, low, high):
    return not (low <= value <= high)


def check_bridge(bridge):
    low, high = BOUNDS["span"]
    if bridge.n_spans > BOUNDS["n_spans"]:
        raise ConfigError(f"'spans' lists {bridge.n_spans} spans; at most {BOUNDS['n_spans']} are supported.")
    for span in bridge.spans:
        if _outside(span, low, high):
            raise ConfigError(f"'spans' has a span of {span:g} m; spans must be {low:g} to {high:g} m "
                              "(lengths are in m: 15 m, not 15000 mm).")
    for key, values in (("rotational_springs", bridge.rotational_springs),
                        ("vertical_springs", bridge.vertical_springs)):
        low, high = BOUNDS[key[:-1]]
        for k in values:
            if k in (0.0, math.inf):
                continue
            if _outside(k, low, high):
                unit = "N m/rad" if key.startswith("rot") else "N/m"
                ends = "0 (pin) or inf (clamp)" if key.startswith("rot") else "inf (rigid)"
                raise ConfigError(f"'{key}' has a stiffness of {k:g} {unit}; an elastic spring must be {low:g} "
                                  f"to {high:g} {unit}, or {ends}.")


def check_ei(ei):
    low, high = BOUNDS["ei"]
    bad = [float(v) for v in np.ravel(ei) if _outside(v, low, high)]
    if bad:
        raise ConfigError(f"'ei' is {bad[0]:g} N m^2; the flexural rigidity of a bridge is {low:g} to {high:g} "
                          "N m^2 (EI is in N m^2: 1 kN m^2 = 1e3 N m^2).")


def check_vehicle(vehicle):
    low, high = BOUNDS["axle_load"]
    for load in vehicle.axle_loads:
        if _outside(load, low, high):
            raise ConfigError(f"'axle_loads' has a load of {load:g} N; an axle load is {low:g} to {high:g} N "
                              "(loads are in N: 24 kN = 24e3 N).")
    if vehicle.length > BOUNDS["axle_offset"]:
        raise ConfigError(f"'axle_offsets' reaches {vehicle.length:g} m; a vehicle is at most "
                          f"{BOUNDS['axle_offset']:g} m long (offsets are in m).")


def check_noise(noise, kinds=None):
    """The noise model's correlation and time parameters within what an instrument and a vehicle can have."""
    if noise is None:
        return
    if noise.correlation_length > BOUNDS["correlation_length"]:
        raise ConfigError(f"'correlation_length' is {noise.correlation_length:g} m; at most "
                          f"{BOUNDS['correlation_length']:g} m is supported (use 0 for independent noise).")
    if np.any(noise.correlation_time_s > BOUNDS["correlation_time_s"]):
        raise ConfigError(f"'correlation_time_s' is {np.max(noise.correlation_time_s):g} s; at most one day "
                          f"({BOUNDS['correlation_time_s']:g} s): slower changes are the random walk.")
    low, high = BOUNDS["speed"]
    if noise.speed is not None and _outside(noise.speed, low, high):
        raise ConfigError(f"'speed' is {noise.speed:g} m/s; a crossing speed is {low:g} to {high:g} m/s "
                          "(in m/s: 36 km/h = 10 m/s).")
    low, high = BOUNDS["sample_rate"]
    if noise.sample_rate is not None and _outside(noise.sample_rate, low, high):
        raise ConfigError(f"'sample_rate' is {noise.sample_rate:g} Hz; a logger samples at {low:g} Hz to "
                          f"{high:g} Hz (in Hz: 100 Hz, not 0.01 s).")
    unit = {"rotation": "rad", "deflection": "m"}
    for key in ("correlated_std", "random_walk"):
        for kind, value in zip(kinds or ("rotation",) * noise.n_sensors, getattr(noise, key)):
            if value > BOUNDS[key][kind]:
                raise ConfigError(f"'{key}' is {value:g} {unit[kind]}{'/sqrt(s)' if key == 'random_walk' else ''} "
                                  f"for a {kind} sensor, far above any instrument: give it in {unit[kind]}"
                                  f"{' per sqrt(s)' if key == 'random_walk' else ''} (1 urad = 1e-6 rad).")


def check_sweep(case):
    """The load positions: near the bridge and with an axle on it at least once."""
    length, pos = case.bridge.length, case.sweep.positions
    reach = 10.0 * (length + case.vehicle.length)
    if pos[0] < -reach or pos[-1] > reach:
        raise ConfigError(f"the load positions run from {pos[0]:g} to {pos[-1]:g} m, far from the {length:g} m "
                          "bridge; give start and stop in m.")
    axles = case.vehicle.axle_positions(pos)
    if not np.any((axles >= 0.0) & (axles <= length)):
        raise ConfigError(f"the load positions {pos[0]:g} to {pos[-1]:g} m never put an axle on the bridge "
                          f"(0 to {length:g} m); give start and stop in m.")


def check_case(case):
    """Readings the case predicts: plausible for a bridge in service (blames EI), and above the noise."""
    lines = case.influence_lines()
    check_readings(case, lines)
    return lines


def check_readings(case, lines):
    peaks = np.max(np.abs(lines.predictions), axis=1)
    for name, kind, peak in zip(case.sensors.names, case.sensors.kinds, peaks):
        limit, unit = READING_LIMITS[kind]
        if not np.isfinite(peak) or peak > limit:
            raise ConfigError(
                f"the case predicts readings of {peak:g} {unit} at sensor {name}, beyond any bridge in service "
                f"({limit:g} {unit}): is EI in kN m^2 instead of N m^2, or are the axle loads too large "
                "(in N, not in kg or 1e3 N)?")


def check_signal(case, lines):
    """Refuse a case whose sensors would read nothing but noise (axle loads in kN, noise in another unit)."""
    if case.noise is None:
        return
    snr = np.sqrt(np.sum(lines.predictions**2, axis=1)) / case.noise.std
    if np.all(snr < 0.1):
        raise ConfigError(
            f"every sensor's predicted readings are below its noise (signal-to-noise {float(np.max(snr)):.2g} "
            "over a whole crossing): the data could not say anything about EI; are the axle loads in kN "
            "instead of N, or the noise_std in the wrong unit?")

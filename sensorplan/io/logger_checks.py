"""Plausibility of a logger record's stated units and time base: catch a slip before it becomes data.

Two slips pass every format check and silently give wrong numbers:

* **A time column in milliseconds read as seconds** (or the reverse).  The
  rule: sensorplan reads a logger record to see crossings (seconds long) and
  the noise's structure (correlation times of seconds), so a record needs at
  least one sample a second; a numeric time column whose median interval is
  1 s or more is refused as probably in ms (a 100 Hz logger's 10 ms written
  as "10" reads as 10 s steps), and one in ms whose median interval is below
  0.1 ms (over 10 kHz, far above any tiltmeter or deflection logger) as
  probably in s.  Timestamps (ISO 8601) carry their own unit and are not
  checked.
* **A channel in another unit than stated** (degrees read as rad, mm read as
  m).  Two physical bounds, on the converted (SI) values: the peak-to-peak
  range of a record (a bridge's tilt under traffic and temperature stays
  well below 0.02 rad = 1.1 deg, its deflection below 1 m) and the
  sample-to-sample noise (robust std of the first differences over sqrt(2):
  a bridge tiltmeter's per-sample noise is at most ~1e-4 rad, a deflection
  sensor's well below a millimetre; the limits are 2e-4 rad and 2e-3 m).
  The Munich INC01 record in degrees read as rad has 1.2e-3 "rad" of noise
  per sample and bursts of 0.28 "rad" and fails both.  A channel that is
  smooth *and* small in the wrong unit (e.g. 0.005 deg of signal with
  micro-degree noise) is indistinguishable from a plausible one in rad; no
  check on the record alone can catch it.

Owns: these two checks.  May import: errors, model.
"""

import math

import numpy as np

from .._errors import DataError

__all__ = ["check_time_base", "check_channel", "sample_noise"]

MAX_INTERVAL_S = 1.0  # at least one sample a second
MIN_INTERVAL_MS = 1e-4  # at most 10 kHz
RANGE_LIMIT = {"rotation": 0.02, "deflection": 1.0}  # rad, m: peak-to-peak of a record
NOISE_LIMIT = {"rotation": 2e-4, "deflection": 2e-3}  # rad, m: per-sample noise
_LIKELY = {"rad": "deg", "m": "mm"}  # the unit a slip most likely meant


def check_time_base(time, name, unit, path):
    """Refuse a numeric time column whose median interval says its unit is not ``unit`` ("s" or "ms")."""
    step = np.diff(np.asarray(time, dtype=float))
    if step.size == 0 or not np.all(np.isfinite(step)):
        return
    interval = float(np.median(step))
    if unit == "s" and MAX_INTERVAL_S <= interval <= 1e3 * 60.0:
        raise DataError(f"{path}: column '{name}' has a median sample interval of {interval:g} s (below one sample "
                        "a second, too coarse to see a crossing or the noise); if the times are in milliseconds, "
                        "name the column time_ms or set [logger] time_unit = \"ms\".")
    if unit == "ms" and 0.0 < interval < MIN_INTERVAL_MS:
        raise DataError(f"{path}: column '{name}' read in ms has a median sample interval of {1e3 * interval:g} ms "
                        f"({1.0 / interval:.3g} Hz, above any bridge logger); if the times are in seconds, name the "
                        "column time_s and set [logger] time_unit = \"s\".")


def sample_noise(values):
    """Robust per-sample noise std of a record: 1.4826 MAD of the first differences / sqrt(2).

    Vehicles, steps and bursts occupy few differences and barely move the
    median; for white noise of std s it returns s.
    """
    diff = np.diff(np.asarray(values, dtype=float))
    if diff.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(diff - np.median(diff))) / math.sqrt(2.0))


def check_channel(values, name, kind, fmt, path):
    """Refuse a channel (SI values) whose range or per-sample noise is implausible in its stated unit."""
    unit, key = fmt.unit(kind)
    si = "rad" if kind == "rotation" else "m"
    sensor = "tiltmeter" if kind == "rotation" else "deflection sensor"
    fix = f"set [logger] {key} to the unit the logger writes" + (
        f" (\"{_LIKELY[unit]}\"?)" if unit in _LIKELY else "")
    span = float(np.ptp(values))
    if span > RANGE_LIMIT[kind]:
        raise DataError(f"{path}: column '{name}' varies by {span:g} {si} read in {unit!r}, implausible for a "
                        f"{kind} sensor; {fix}.")
    noise = sample_noise(values)
    if noise > NOISE_LIMIT[kind]:
        raise DataError(f"{path}: column '{name}' read in {unit!r} has a sample-to-sample noise of {noise:.3g} {si}, "
                        f"implausible for a {sensor} (at most {NOISE_LIMIT[kind]:g} {si}); {fix}.")

"""Independent simulator of a tiltmeter/deflection logger record (shares no code with sensorplan).

A channel's reading is

    y(t) = vehicle signal + white + Ornstein-Uhlenbeck + random walk + bursts,

with the statistics measured on the real Munich UniBw inclinometer INC01
(../shared/realdata/munich_unibw_testbridge_sample, 100 Hz, quiet windows, see
issue #36): about 21 urad white per sample, a correlated part of about 9 urad
with a correlation time near 3 s, minute-scale wander of +-20-50 urad, and
rare bursts (spikes) up to 0.28 deg.  ``MUNICH_LIKE`` holds those values.

The OU part is simulated by its exact discretisation (Gillespie 1996,
Phys. Rev. E 54, 2084: u_{k+1} = u_k e^{-dt/tau} + sigma sqrt(1 - e^{-2dt/tau}) n_k),
the walk by Gaussian increments of variance q^2 dt.  Vehicle signals are the
influence lines of an independent finite-element solve (tests/fe_reference.py)
on a fine grid of load positions, interpolated linearly at the axle positions
x = speed * (t - entry_time) - offset, summed over axles.
"""

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fe_reference import fe_response  # noqa: E402

# Measured on INC01 (issue #36): rad and s.
MUNICH_LIKE = dict(white=21e-6, correlated=9e-6, tau=3.0, walk=2.5e-6, burst_rate=1.0 / 3600.0,
                   burst_amp=4.9e-3)


@dataclass
class Channel:
    name: str
    position: float
    kind: str = "rotation"
    white: float = MUNICH_LIKE["white"]
    correlated: float = MUNICH_LIKE["correlated"]
    tau: float = MUNICH_LIKE["tau"]
    walk: float = MUNICH_LIKE["walk"]  # per sqrt(s)
    burst_rate: float = 0.0  # per s
    burst_amp: float = MUNICH_LIKE["burst_amp"]


@dataclass
class Bridge:
    spans: list
    ei: float
    rot_springs: list = field(default_factory=list)
    vert_springs: list = field(default_factory=list)
    ei_edges: list | None = None  # piecewise-constant EI (damage); None: uniform
    ei_values: list | None = None

    def springs(self):
        n = len(self.spans) + 1
        rot = self.rot_springs or [0.0] * n
        vert = self.vert_springs or [math.inf] * n
        return rot, vert


def noise(n, dt, channel, rng):
    """White + OU + random walk + bursts, ``n`` samples every ``dt`` s."""
    out = rng.standard_normal(n) * channel.white
    if channel.correlated > 0.0:
        a = math.exp(-dt / channel.tau)
        b = channel.correlated * math.sqrt(1.0 - a * a)
        u = np.empty(n)
        u[0] = rng.standard_normal() * channel.correlated
        steps = rng.standard_normal(n) * b
        for k in range(1, n):
            u[k] = a * u[k - 1] + steps[k]
        out += u
    if channel.walk > 0.0:
        out += np.cumsum(rng.standard_normal(n) * channel.walk * math.sqrt(dt))
    if channel.burst_rate > 0.0:
        count = rng.poisson(channel.burst_rate * n * dt)
        for start in rng.integers(0, n, size=count):
            width = int(rng.integers(2, max(3, int(0.5 / dt))))
            amp = channel.burst_amp * rng.uniform(0.05, 1.0) * rng.choice([-1.0, 1.0])
            out[start:start + width] += amp * np.exp(-np.arange(min(width, n - start)) * dt / 0.1)
    return out


def influence_lines(bridge, channels, xs):
    """Unit-load influence lines (n_channels, xs.size) by the independent FE solve."""
    rot, vert = bridge.springs()
    length = float(sum(bridge.spans))
    edges = bridge.ei_edges if bridge.ei_edges is not None else [0.0, length]
    values = bridge.ei_values if bridge.ei_values is not None else [bridge.ei]
    sensors = [(c.position, c.kind) for c in channels]
    lines = np.zeros((len(channels), xs.size))
    for k, x in enumerate(xs):
        if 0.0 <= x <= length:
            lines[:, k] = fe_response(bridge.spans, np.asarray(edges, float), np.asarray(values, float),
                                      rot, vert, [(float(x), 1.0)], sensors)
    return lines


@dataclass
class Crossing:
    entry_time: float  # front axle at x = 0 [s]
    speed: float  # m/s
    load_factor: float = 1.0


def record(duration, rate, channels, *, bridge=None, axle_offsets=(0.0,), axle_loads=(1.0,), crossings=(),
           rng, line_step=0.05):
    """A logger record: time [s] (n,), values (n_channels, n) [rad or m], vehicle signal (n_channels, n)."""
    rng = np.random.default_rng(rng)
    dt = 1.0 / rate
    n = int(round(duration * rate))
    time = np.arange(n) * dt
    signal = np.zeros((len(channels), n))
    if crossings:
        length = float(sum(bridge.spans))
        xs = np.arange(0.0, length + line_step / 2, line_step)
        xs[-1] = min(xs[-1], length)
        lines = influence_lines(bridge, channels, xs)
        for c in crossings:
            for offset, load in zip(axle_offsets, axle_loads):
                x = c.speed * (time - c.entry_time) - offset
                on = (x >= 0.0) & (x <= length)
                for i in range(len(channels)):
                    signal[i, on] += load * c.load_factor * np.interp(x[on], xs, lines[i])
    values = np.stack([noise(n, dt, ch, rng) for ch in channels]) + signal
    return time, values, signal


def write_csv(path, time, channels, values, *, time_scale=1.0, value_scale=1.0):
    """``time_s,<names>`` (time divided by ``time_scale``, values by ``value_scale``)."""
    with open(path, "w") as fh:
        fh.write(",".join(["time_s"] + [c.name for c in channels]) + "\n")
        for k in range(time.size):
            fh.write(",".join([repr(float(time[k] / time_scale))]
                              + [repr(float(v / value_scale)) for v in values[:, k]]) + "\n")

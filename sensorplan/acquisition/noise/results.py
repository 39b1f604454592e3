"""Results of estimating a logger's noise: per channel the four parameters, their uncertainty, the Allan deviation."""

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Estimate", "AllanDeviation", "ChannelEstimate", "NoiseEstimate"]

PARAMETERS = ("white_std", "correlated_std", "correlation_time_s", "random_walk")
# A model Allan deviation this far from the data's where the data are precise is a misfit worth a note (fits of the
# simulator's records stay within 0.15: tests/test_noise_estimate.py).
MISFIT = 0.2
PRECISE_PAIRS = 50  # independent pairs for a data Allan deviation within about 10 %


@dataclass(frozen=True)
class Estimate:
    """A positive parameter's maximum-likelihood value and its uncertainty.

    ``std_error`` is the delta-method standard error from the observed
    information in log-parameter; ``at_bound`` says the likelihood pushed the
    value to the edge of the range searched (the record does not resolve it:
    read the value as an upper bound when at the lower edge).
    """

    value: float
    std_error: float
    log_std_error: float
    at_bound: bool = False

    def interval(self, level=0.95):
        """Interval exp(log value -+ z se) (positive, as the parameter); (nan, nan) without an error."""
        from scipy.stats import norm

        if not math.isfinite(self.log_std_error):
            return (math.nan, math.nan)
        z = float(norm.ppf(0.5 + level / 2.0))
        return (self.value * math.exp(-z * self.log_std_error), self.value * math.exp(z * self.log_std_error))

    def to_dict(self):
        low, high = self.interval()
        return {"value": self.value, "std_error": self.std_error, "ci95": [low, high], "at_bound": self.at_bound}


@dataclass(frozen=True, eq=False)
class AllanDeviation:
    """Overlapping Allan deviation of the quiet data and of the fitted model at octave-spaced averaging times."""

    tau_s: np.ndarray
    data: np.ndarray
    model: np.ndarray
    n_terms: np.ndarray

    def to_dict(self):
        return {"tau_s": self.tau_s.tolist(), "data": self.data.tolist(), "model": self.model.tolist(),
                "n_terms": self.n_terms.tolist()}

    def misfit(self):
        """(largest |model / data - 1|, its tau [s]) over the averaging times where the data's Allan deviation is
        precise (about ``PRECISE_PAIRS`` independent pairs of means or more: n_terms / 2m); (0, nan) without any."""
        if not self.tau_s.size:
            return 0.0, math.nan
        m = self.tau_s / self.tau_s[0]
        precise = (self.n_terms / (2.0 * m) >= PRECISE_PAIRS) & np.isfinite(self.data)
        if not np.any(precise):
            return 0.0, math.nan
        ratio = np.abs(self.model[precise] / self.data[precise] - 1.0)
        k = int(np.argmax(ratio))
        return float(ratio[k]), float(self.tau_s[precise][k])

    def floor(self, low=1.0, high=30.0, *, model=False):
        """Smallest Allan deviation of the data (of the model) for averaging times in [low, high] s (nan if none):
        what averaging over that range cannot remove."""
        values = self.model if model else self.data
        inside = (self.tau_s >= low) & (self.tau_s <= high) & np.isfinite(values)
        return float(np.min(values[inside])) if inside.any() else math.nan


@dataclass(frozen=True, eq=False)
class ChannelEstimate:
    """The noise of one channel estimated from the quiet parts of a record (SI: rad or m, s)."""

    name: str
    kind: str
    white_std: Estimate
    correlated_std: Estimate
    correlation_time_s: Estimate
    random_walk: Estimate
    allan: AllanDeviation
    log_likelihood: float
    converged: bool
    cpu_s: float

    @property
    def unit(self):
        return "rad" if self.kind == "rotation" else "m"

    def to_dict(self):
        out = {"name": self.name, "kind": self.kind, "unit": self.unit}
        out.update({p: getattr(self, p).to_dict() for p in PARAMETERS})
        out.update({"allan_deviation": self.allan.to_dict(), "log_likelihood": self.log_likelihood,
                    "converged": self.converged, "cpu_s": self.cpu_s})
        return out


@dataclass(frozen=True, eq=False)
class NoiseEstimate:
    """Noise estimated per channel of a logger record.

    Attributes
    ----------
    channels : tuple of ChannelEstimate
    quiet_fraction : float
        Share of the record's samples in the quiet segments used.
    segments_s : tuple of (float, float)
        Start and end times [s] of the quiet segments.
    sample_interval : float
        The record's sample interval [s].
    duration : float
        The record's length [s].
    bursts, active : int
        Samples left out as bursts and as vehicle activity.
    """

    channels: tuple
    quiet_fraction: float
    segments_s: tuple
    sample_interval: float
    duration: float
    bursts: int
    active: int

    @property
    def names(self):
        return tuple(c.name for c in self.channels)

    def channel(self, name):
        return self.channels[self.names.index(name)]

    def noise_model(self, *, speed):
        """The :class:`~sensorplan.model.noise.NoiseModel` of the channels, in their order, at ``speed`` [m/s]."""
        from ...model.noise import NoiseModel

        def values(name):
            return [getattr(c, name).value for c in self.channels]

        return NoiseModel(values("white_std"), correlated_std=values("correlated_std"),
                          correlation_time_s=values("correlation_time_s"), random_walk=values("random_walk"),
                          speed=speed)

    def to_dict(self):
        return {"channels": [c.to_dict() for c in self.channels], "quiet_fraction": self.quiet_fraction,
                "segments_s": [list(s) for s in self.segments_s], "sample_interval_s": self.sample_interval,
                "duration_s": self.duration, "burst_samples": self.bursts, "active_samples": self.active}

    def summary(self):
        """Per channel the four parameters with their standard errors, in urad (tilt) or mm (deflection)."""
        lines = [f"quiet parts: {100 * self.quiet_fraction:.1f} % of {self.duration:.0f} s in "
                 f"{len(self.segments_s)} segment(s) ({self.bursts} burst and {self.active} vehicle/activity "
                 f"samples left out), sample interval {1e3 * self.sample_interval:.3g} ms"]
        for c in self.channels:
            scale, unit = (1e6, "urad") if c.kind == "rotation" else (1e3, "mm")
            lines.append(f"{c.name} ({c.kind}):")
            for label, est, factor, u in (("white std", c.white_std, scale, unit),
                                          ("correlated std", c.correlated_std, scale, unit),
                                          ("correlation time", c.correlation_time_s, 1.0, "s"),
                                          ("random walk", c.random_walk, scale, f"{unit}/sqrt(s)")):
                note = "  (at the edge of the range: not resolved)" if est.at_bound else ""
                lines.append(f"  {label:<17} {factor * est.value:10.4g} +- {factor * est.std_error:<8.2g} {u}{note}")
            lines.append("  Allan deviation [" + unit + "]:   tau [s]     data    model")
            for tau, d, m in zip(c.allan.tau_s, c.allan.data, c.allan.model):
                lines.append(f"  {'':<30}{tau:8.3g} {scale * d:8.3g} {scale * m:8.3g}")
            lines.append(f"  Allan floor between 1 and 30 s: data {scale * c.allan.floor():.3g}, model "
                         f"{scale * c.allan.floor(model=True):.3g} {unit}")
            worst, at = c.allan.misfit()
            if worst > MISFIT:
                why = ("fast structure white + OU + walk lacks (vibration?); fitting at a rate below it (--rate) folds "
                       "it into the white part" if at < 1.0 else
                       "slow structure the model lacks, or too few quiet minutes to tell correlated noise from wander")
                lines.append(f"  note: the model misses the data's Allan deviation by {100 * worst:.0f} % "
                             f"at {at:.3g} s: {why}")
        return "\n".join(lines)

"""Results of turning a logger record into crossings."""

from dataclasses import KW_ONLY, dataclass, field
from functools import cached_property

import numpy as np

__all__ = ["CrossingEvent", "ExtractedCrossings", "REASONS"]

REASONS = ("not significant", "overlapping vehicles", "implausible speed", "poor fit", "cut by the record's edge",
           "channels disagree", "noise model does not fit")


def _eng(value, kind):
    """A reading in engineering units: micro-radians for tilt, mm for deflection."""
    return f"{value * 1e6:.3g} urad" if kind == "rotation" else f"{value * 1e3:.3g} mm"


@dataclass(frozen=True, eq=False)
class CrossingEvent:
    """One detected event.

    Attributes
    ----------
    label : str
        ``e1``, ``e2``, ... in time order; accepted events keep it as crossing label.
    t_start, t_end : float
        Start and end of the detected activity [s].
    entry_time : float
        Time the reference axle enters the bridge (x = 0) [s] (nan if not fitted).
    speed, speed_ci95 : float
        Constant speed and the half-width of its 95 % confidence interval [m/s].
    fit_rms : float
        Root mean square of the whitened fit residual while the vehicle is on
        the bridge (1 = the noise model).
    glr : float
        The test statistic: the generalised likelihood ratio 2 log Lambda of
        "vehicle + wander + noise" against "wander + noise", maximised over
        the entry time and speed grid and the load factor (compare with the
        record's threshold).
    events_per_day : float
        How often chance (the noise model alone) reaches this statistic, per day of record.
    load_factor : float
        Fitted vehicle weight in units of the case's vehicle.
    entry_ci95 : float
        Half-width of the entry time's 95 % interval [s].
    accepted : bool
    reason : str
        Empty when accepted, else one of :data:`REASONS`.
    temperatures : dict
        Mean of each temperature channel over the event [deg C].
    fit_time, fit_values : ndarray
        The fitted window [s] and fitted readings incl. offsets (n_channels, n) [rad or m], for figures.
    """

    label: str
    _: KW_ONLY
    t_start: float
    t_end: float
    entry_time: float
    speed: float
    speed_ci95: float
    fit_rms: float
    accepted: bool
    reason: str = ""
    glr: float = np.nan
    events_per_day: float = np.nan
    load_factor: float = np.nan
    entry_ci95: float = np.nan
    temperatures: dict = field(default_factory=dict)
    fit_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fit_values: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def to_dict(self):
        def num(x):
            return None if not np.isfinite(x) else float(x)

        return {"label": self.label, "t_start_s": float(self.t_start), "t_end_s": float(self.t_end),
                "entry_time_s": num(self.entry_time), "speed_m_s": num(self.speed),
                "speed_ci95": num(self.speed_ci95), "entry_ci95_s": num(self.entry_ci95),
                "glr": num(self.glr), "chance_events_per_day": num(self.events_per_day),
                "load_factor": num(self.load_factor), "fit_rms": num(self.fit_rms), "accepted": bool(self.accepted),
                "reason": self.reason or None,
                "temperatures_c": {k: float(v) for k, v in self.temperatures.items()}}


@dataclass(frozen=True, eq=False)
class ExtractedCrossings:
    """Events found in a logger record and the crossings built from the accepted ones.

    Attributes
    ----------
    names, kinds : tuple of str
        The logged channels and their sensor kinds.
    noise_std : ndarray (n_channels,)
        White-noise std of each channel [rad or m].
    events : tuple of CrossingEvent
        The candidate events: every significant one, and the others down to
        the level chance reaches about once an hour (at least the strongest).
    crossings : Crossings or None
        Readings of the accepted events against reference-axle position,
        offsets and drift removed; None when no event was accepted.
    duration : float
        Length of the record [s].
    speed_source : str
        "fitted", "given" or "axle detector".
    threshold : float
        The GLR an event must exceed (for ``false_events_per_day``).
    false_events_per_day : float
        The stated false-event rate.
    noise : NoiseModel or None
        The noise model in time of the channels (one entry per channel).
    noise_source : str
        "case" or "record (robust variogram)".
    strongest_glr, strongest_time : float
        The record's largest statistic and the entry time it belongs to [s].
    burst_seconds : float
        Record time masked as bursts, summed over the channels [s].
    calibration : dict
        How the threshold was set (:meth:`~.calibration.Calibration.to_dict`).
    """

    names: tuple
    kinds: tuple
    _: KW_ONLY
    noise_std: np.ndarray
    events: tuple
    crossings: object
    duration: float
    speed_source: str = "fitted"
    threshold: float = np.nan
    false_events_per_day: float = 1.0
    noise: object = None
    noise_source: str = "case"
    strongest_glr: float = np.nan
    strongest_time: float = np.nan
    burst_seconds: float = 0.0
    calibration: dict = field(default_factory=dict)

    @cached_property
    def accepted(self):
        return tuple(e for e in self.events if e.accepted)

    @cached_property
    def rejected(self):
        return tuple(e for e in self.events if not e.accepted)

    def summary(self):
        noise = ", ".join(f"{n} {_eng(s, k)}" for n, s, k in zip(self.names, self.noise_std, self.kinds))
        lines = [f"crossings: {len(self.events)} event(s) in {self.duration:.0f} s of record, "
                 f"{len(self.accepted)} accepted (speed {self.speed_source}); white noise {noise} "
                 f"(noise model from the {self.noise_source})",
                 f"  an event is a vehicle when its GLR exceeds {self.threshold:.1f} "
                 f"({self.false_events_per_day:g} false event(s) per day of record)",
                 f"  {'event':<6} {'start [s]':>10} {'end [s]':>9} {'speed [m/s]':>12} {'±95 %':>7} "
                 f"{'GLR':>7} {'fit rms':>8}  verdict"]
        for e in self.events:
            speed = "n/a" if not np.isfinite(e.speed) else f"{e.speed:.3f}"
            ci = "n/a" if not np.isfinite(e.speed_ci95) else f"{e.speed_ci95:.3f}"
            rms = "n/a" if not np.isfinite(e.fit_rms) else f"{e.fit_rms:.2f}"
            verdict = "accepted" if e.accepted else f"rejected: {e.reason}"
            lines.append(f"  {e.label:<6} {e.t_start:>10.1f} {e.t_end:>9.1f} {speed:>12} {ci:>7} {e.glr:>7.1f} "
                         f"{rms:>8}  {verdict}")
        lines.append("  fit rms is the whitened residual's (1 = the noise model).")
        return "\n".join(lines)

    def verdict(self):
        """One line: why no crossing was accepted (or how many were)."""
        if self.accepted:
            return f"{len(self.accepted)} of {len(self.events)} event(s) accepted as vehicles"
        significant = [e for e in self.events if e.reason != "not significant"]
        rate = f"{self.false_events_per_day:g} false event(s) per day"
        level = f"threshold GLR {self.threshold:.1f} for {rate}"
        if significant:
            counts: dict = {}
            for e in significant:
                counts[e.reason] = counts.get(e.reason, 0) + 1
            why = ", ".join(f"{n} {r}" for r, n in sorted(counts.items(), key=lambda kv: -kv[1]))
            return (f"no crossing accepted: {len(significant)} candidate(s) above the {level} fit no single "
                    f"vehicle ({why}; noise model from the {self.noise_source})")
        return (f"no crossing accepted: nothing in the record is a vehicle (strongest candidate "
                f"at {self.strongest_time:.1f} s: GLR {self.strongest_glr:.1f} below the {level}; "
                f"noise model from the {self.noise_source})")

    def to_dict(self):
        return {"channels": list(self.names),
                "noise_std": {n: float(s) for n, s in zip(self.names, self.noise_std)},
                "noise_model": {} if self.noise is None else {n: _channel_noise(self.noise, i)
                                                               for i, n in enumerate(self.names)},
                "noise_source": self.noise_source, "burst_seconds": float(self.burst_seconds),
                "duration_s": float(self.duration), "speed_source": self.speed_source,
                "threshold_glr": float(self.threshold), "false_events_per_day": float(self.false_events_per_day),
                "strongest_glr": float(self.strongest_glr), "strongest_entry_s": float(self.strongest_time),
                "calibration": self.calibration,
                "n_accepted": len(self.accepted), "events": [e.to_dict() for e in self.events]}


def _channel_noise(noise, i):
    """The noise parameters of channel ``i`` of a NoiseModel, as the crossings JSON names them."""
    return {"white_std": float(noise.std[i]), "correlated_std": float(noise.correlated_std[i]),
            "correlation_time_s": float(noise.correlation_time_s[i]), "random_walk": float(noise.random_walk[i])}

"""Results of turning a logger record into crossings."""

from dataclasses import KW_ONLY, dataclass, field
from functools import cached_property

import numpy as np

__all__ = ["CrossingEvent", "ExtractedCrossings", "REASONS"]

REASONS = ("too short", "overlapping vehicles", "implausible speed", "poor fit")


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
        Root mean square fit residual in noise standard deviations (1 = noise level).
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
    temperatures: dict = field(default_factory=dict)
    fit_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fit_values: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def to_dict(self):
        def num(x):
            return None if not np.isfinite(x) else float(x)

        return {"label": self.label, "t_start_s": float(self.t_start), "t_end_s": float(self.t_end),
                "entry_time_s": num(self.entry_time), "speed_m_s": num(self.speed),
                "speed_ci95": num(self.speed_ci95), "fit_rms": num(self.fit_rms), "accepted": bool(self.accepted),
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
        Noise floor of each channel [rad or m].
    events : tuple of CrossingEvent
    crossings : Crossings or None
        Readings of the accepted events against reference-axle position,
        offsets and drift removed; None when no event was accepted.
    duration : float
        Length of the record [s].
    speed_source : str
        "fitted", "given" or "axle detector".
    """

    names: tuple
    kinds: tuple
    _: KW_ONLY
    noise_std: np.ndarray
    events: tuple
    crossings: object
    duration: float
    speed_source: str = "fitted"

    @cached_property
    def accepted(self):
        return tuple(e for e in self.events if e.accepted)

    @cached_property
    def rejected(self):
        return tuple(e for e in self.events if not e.accepted)

    def summary(self):
        noise = ", ".join(f"{n} {_eng(s, k)}" for n, s, k in zip(self.names, self.noise_std, self.kinds))
        lines = [f"crossings: {len(self.events)} event(s) in {self.duration:.0f} s of record, "
                 f"{len(self.accepted)} accepted (speed {self.speed_source}); noise floor {noise}",
                 f"  {'event':<6} {'start [s]':>10} {'end [s]':>9} {'speed [m/s]':>12} {'±95 %':>7} "
                 f"{'fit rms':>8}  verdict"]
        for e in self.events:
            speed = "n/a" if not np.isfinite(e.speed) else f"{e.speed:.3f}"
            ci = "n/a" if not np.isfinite(e.speed_ci95) else f"{e.speed_ci95:.3f}"
            rms = "n/a" if not np.isfinite(e.fit_rms) else f"{e.fit_rms:.2f}"
            verdict = "accepted" if e.accepted else f"rejected: {e.reason}"
            lines.append(f"  {e.label:<6} {e.t_start:>10.1f} {e.t_end:>9.1f} {speed:>12} {ci:>7} {rms:>8}  {verdict}")
        lines.append("  fit rms is in noise standard deviations (1 = the noise floor).")
        return "\n".join(lines)

    def to_dict(self):
        return {"channels": list(self.names),
                "noise_std": {n: float(s) for n, s in zip(self.names, self.noise_std)},
                "duration_s": float(self.duration), "speed_source": self.speed_source,
                "n_accepted": len(self.accepted), "events": [e.to_dict() for e in self.events]}

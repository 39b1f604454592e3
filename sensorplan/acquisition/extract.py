"""From a continuous logger record to crossings: test, refine, judge, convert.

An event is accepted only when the case's vehicle explains it significantly
better than wander + noise (:mod:`.glr`, threshold for a stated false-event
rate, default one per day of record) and its fit leaves noise.  The noise
model in time comes from the case ([noise] ``correlated_std``,
``correlation_time_s``, ``random_walk``, with ``[sensors] noise_std`` the white
part); a case without it gets a robust estimate from the record itself
(:func:`~.screen.estimate_noise`), and the result says which was used.

An accepted crossing is written as readings against the reference axle's
position, minus the record's level: a straight line in time between the
medians of the quiet record (the fitted vehicle removed) within ``quiet_gap``
seconds before the entry and after the exit.  That line is not fitted with
the influence line and decides nothing; it only makes an empty bridge read
zero.  The wander within the crossing stays for the noise model of
inference.
"""

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError
from .._validation import as_float
from ..model.crossings import Crossing, Crossings
from .fit import Template
from .glr import Policy, case_noise, assess_record
from .results import CrossingEvent, ExtractedCrossings

if TYPE_CHECKING:
    from ..model.case import Case
    from ..model.timeseries import TimeSeries

__all__ = ["extract_crossings"]


def _check_options(case, series, speed, axle_times, speed_range, max_rms, false_events_per_day):
    unknown = [n for n in series.names if n not in case.sensors.names]
    if unknown:
        raise ConfigError(f"The logger channel {unknown[0]!r} is not a sensor of the case "
                          f"({', '.join(case.sensors.names)}).")
    lo = as_float(speed_range[0], "min_speed", "extract_crossings", low=0.0, low_open=True)
    hi = as_float(speed_range[1], "max_speed", "extract_crossings", low=lo, low_open=True)
    if speed is not None:
        as_float(speed, "speed", "extract_crossings", low=0.0, low_open=True)
        if axle_times is not None:
            raise ConfigError("Give either the speed or the axle-detector times, not both.")
    as_float(max_rms, "max_rms", "extract_crossings", low=1.0)
    as_float(false_events_per_day, "false_events_per_day", "extract_crossings", low=0.0, low_open=True)
    return lo, hi


def extract_crossings(case: "Case", series: "TimeSeries", *, speed: float | None = None,
                      axle_times=None, axle_speeds=None, speed_range=(0.3, 40.0), quiet_gap: float = 3.0,
                      max_rms: float = 2.0, false_events_per_day: float = 1.0, noise=None) -> ExtractedCrossings:
    """Find the vehicles in ``series`` and convert them to readings against load position.

    Parameters
    ----------
    case : Case
        Its vehicle and forward model give the influence lines tested for;
        its noise model in time, when it has one, the noise.
    series : TimeSeries
    speed : float, optional
        Known constant speed of every crossing [m/s]; only entry times are fitted.
    axle_times : array_like, optional
        Axle-detector times [s] at which a front axle passes x = 0; a vehicle
        on the bridge at one of them takes it as its entry time.
    axle_speeds : array_like, optional
        Not used by the test (the speed is fitted); accepted for the CLI's
        detector files.
    speed_range : (float, float)
        Speeds searched [m/s]; an event at the range's edge is rejected ("implausible speed").
    quiet_gap : float
        Quiet time before and after a vehicle from which its level is taken [s].
    max_rms : float
        Largest accepted whitened residual rms (1 = the noise model).
    false_events_per_day : float
        The stated false-event rate: the threshold lets chance through this
        often per day of record.
    noise : NoiseModel, optional
        The noise in time of each channel (one entry per channel of ``series``, no speed needed);
        default the case's, else estimated from the record.

    Returns
    -------
    ExtractedCrossings
    """
    options = dict(speed=speed, axle_times=axle_times, speed_range=speed_range, quiet_gap=quiet_gap,
                   max_rms=max_rms, false_events_per_day=false_events_per_day, noise=noise)
    result = _extract(case, series, **options)
    return _sign_hint(case, series, options, result)


def _sign_hint(case, series, options, result):
    """When most significant events fail, name a channel whose reversed sign makes most of them fit.

    A tiltmeter mounted the wrong way round (or logged with the wrong sign) makes every event fit
    poorly; the record is tested again with each channel reversed, and if that accepts at least
    half of its events (and more than as recorded), the rejected events say so.
    """
    n_events, n_ok = len(result.events), len(result.accepted)
    if n_events == 0 or n_ok >= 0.5 * n_events or len(series.names) < 2:
        return result
    best, name = n_ok, ""
    for c, channel in enumerate(series.names):
        values = series.values.copy()
        values[c] = -values[c]
        trial = _extract(case, dataclasses.replace(series, values=values), **options)
        if len(trial.accepted) > best and len(trial.accepted) >= 0.5 * len(trial.events):
            best, name = len(trial.accepted), channel
    if not name:
        return result
    reason = (f"{name} reads with the wrong sign (mounted the wrong way round, or its sign in the logger): "
              f"with it reversed {best} of the events fit")
    events = tuple(e if e.accepted else dataclasses.replace(e, reason=reason) for e in result.events)
    return dataclasses.replace(result, events=events)


def _extract(case, series, *, speed, axle_times, speed_range, quiet_gap, max_rms, false_events_per_day, noise):
    lo, hi = _check_options(case, series, speed, axle_times, speed_range, max_rms, false_events_per_day)
    template = Template.from_case(case, series.names)
    kinds = tuple(case.sensors.kinds[case.sensors.names.index(n)] for n in series.names)
    noise = noise if noise is not None else case_noise(case, series.names)
    policy = Policy(false_events_per_day=float(false_events_per_day), max_rms=float(max_rms))
    test = assess_record(template, series.time, series.values, noise=noise, speed_range=(lo, hi), fixed_speed=speed,
                       axle_times=axle_times, policy=policy)
    t = series.time
    events: list[CrossingEvent] = []
    crossings: list[Crossing] = []
    for c in test.candidates:
        label = f"e{len(events) + 1}"
        accepted = c.significant and not c.reason
        exit_time = c.entry_time + template.length / c.speed
        on = (t >= c.entry_time) & (t <= exit_time)
        temps = {k: float(np.mean(v[on])) if on.any() else float("nan") for k, v in series.temperatures.items()}
        events.append(CrossingEvent(label, t_start=c.entry_time, t_end=exit_time, entry_time=c.entry_time,
                                    speed=c.speed, speed_ci95=c.speed_ci95, fit_rms=c.fit_rms, accepted=accepted,
                                    reason=c.reason, temperatures=temps, fit_time=t[c.window],
                                    fit_values=c.signal + _level(series, c, quiet_gap, exit_time)[1],
                                    glr=c.glr, events_per_day=c.events_per_day, load_factor=c.load_factor,
                                    entry_ci95=c.entry_ci95))
        if accepted:
            crossings.append(_crossing(series, c, label, template.length, quiet_gap, exit_time))
    source = "given" if speed is not None else ("axle detector" if axle_times is not None else "fitted")
    dt = float(np.median(np.diff(t)))
    return ExtractedCrossings(series.names, kinds, noise_std=np.array(test.noise.std),
                              events=tuple(events),
                              crossings=Crossings(series.names, tuple(crossings)) if crossings else None,
                              duration=float(t[-1] - t[0]), speed_source=source,
                              threshold=test.calibration.threshold**2,
                              false_events_per_day=float(false_events_per_day), noise=test.noise,
                              noise_source=test.noise_source, strongest_glr=max(test.strongest, 0.0)**2,
                              strongest_time=test.strongest_time, burst_seconds=float(test.burst_mask.sum() * dt),
                              calibration=test.calibration.to_dict())


def _level(series, candidate, quiet_gap, exit_time):
    """The record's level on the candidate's window: a line between the quiet medians before and after."""
    t = series.time[candidate.window]
    rest = series.values[:, candidate.window] - candidate.signal
    before = (t >= candidate.entry_time - quiet_gap) & (t < candidate.entry_time)
    after = (t > exit_time) & (t <= exit_time + quiet_gap)
    lo = np.median(rest[:, before], axis=1) if before.any() else np.median(rest, axis=1)
    hi = np.median(rest[:, after], axis=1) if after.any() else lo
    frac = np.clip((t - candidate.entry_time) / max(exit_time - candidate.entry_time, 1e-12), 0.0, 1.0)
    return t, lo[:, None] + (hi - lo)[:, None] * frac[None, :]


def _crossing(series, candidate, label, length, quiet_gap, exit_time):
    """The accepted candidate as readings against the reference axle's position, the level removed."""
    t, level = _level(series, candidate, quiet_gap, exit_time)
    z = candidate.speed * (t - candidate.entry_time)
    keep = (z >= 0.0) & (z <= length)
    values = (series.values[:, candidate.window] - level)[:, keep]
    return Crossing(label, z[keep], values, np.ones(int(keep.sum())), times=t[keep])

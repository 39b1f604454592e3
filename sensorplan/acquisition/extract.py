"""From a continuous logger record to crossings: detect, fit, judge, convert."""

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError
from .._validation import as_float
from ..model.crossings import Crossing, Crossings
from .events import find_events, noise_floor
from .fit import Template, fit_vehicles
from .results import CrossingEvent, ExtractedCrossings

if TYPE_CHECKING:
    from ..model.case import Case
    from ..model.timeseries import TimeSeries

__all__ = ["extract_crossings"]

_MIN_SAMPLES = 10
# A second vehicle is tested when the fit rms exceeds _OVERLAP_GATE noise std, and found when it removes
# more than a third of the squared residual and lowers chi^2 by more than _OVERLAP_CHI2 (a likelihood-ratio
# statistic with 2 extra parameters; chi2(2) exceeds 30 with probability 3e-7).
_OVERLAP_GATE = 1.15
_OVERLAP_CHI2 = 30.0


def _check_options(case, series, speed, axle_times, speed_range, max_rms):
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
    return lo, hi


def extract_crossings(case: "Case", series: "TimeSeries", *, speed: float | None = None,
                      axle_times=None, axle_speeds=None, speed_range=(0.3, 40.0), quiet_gap: float = 3.0,
                      smooth: float = 0.5, threshold: float = 6.0, max_rms: float = 2.0) -> ExtractedCrossings:
    """Find the crossings in ``series`` and convert them to readings against load position.

    Parameters
    ----------
    case : Case
        Its vehicle and forward model give the influence lines that are fitted.
    series : TimeSeries
    speed : float, optional
        Known constant speed of every crossing [m/s]; only entry times are fitted.
    axle_times : array_like, optional
        Axle-detector times [s] at which a front axle passes x = 0; an event
        takes the latest time before its activity, and the speed is fitted
        unless ``axle_speeds`` [m/s] gives it.
    speed_range : (float, float)
        Plausible speeds [m/s]; fits outside are rejected ("implausible speed").
    quiet_gap : float
        Minimum quiet time between two events [s].
    smooth, threshold : float
        Detection smoothing [s] and threshold [noise standard deviations].
    max_rms : float
        Largest accepted fit rms in noise standard deviations; above it an
        event is rejected as "overlapping vehicles" when a two-vehicle fit
        explains it, else as "poor fit".

    Returns
    -------
    ExtractedCrossings
    """
    options = dict(speed=speed, axle_times=axle_times, axle_speeds=axle_speeds, speed_range=speed_range,
                   quiet_gap=quiet_gap, smooth=smooth, threshold=threshold, max_rms=max_rms)
    result = _extract(case, series, **options)
    return _sign_hint(case, series, options, result)


def _sign_hint(case, series, options, result):
    """When most events fail, name a channel whose reversed sign makes most of them fit.

    A tiltmeter mounted the wrong way round (or logged with the wrong sign) makes every event fit
    poorly and look like overlapping vehicles; the record is extracted again with each channel
    reversed, and if that accepts at least half of its events (and more than as recorded), the
    rejected events say so instead of blaming the traffic.
    """
    n_events, n_ok = len(result.events), len(result.accepted)
    if n_events == 0 or n_ok >= 0.5 * n_events or len(series.names) == 0:
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
    events = tuple(e if e.accepted or e.reason == "too short" else dataclasses.replace(e, reason=reason)
                   for e in result.events)
    return dataclasses.replace(result, events=events)


def _extract(case, series, *, speed, axle_times, axle_speeds, speed_range, quiet_gap, smooth, threshold, max_rms):
    lo, hi = _check_options(case, series, speed, axle_times, speed_range, max_rms)
    template = Template.from_case(case, series.names)
    kinds = tuple(case.sensors.kinds[case.sensors.names.index(n)] for n in series.names)
    noise = noise_floor(series.values)
    noise = np.where(noise > 0.0, noise, np.maximum(np.abs(series.values).max(axis=1), 1e-12) * 1e-6)
    t = series.time
    segments, _ = find_events(t, series.values, noise, smooth=smooth, quiet_gap=quiet_gap, threshold=threshold)
    events: list[CrossingEvent] = []
    crossings: list[Crossing] = []
    i = 0
    while i < len(segments):
        left = 0 if i == 0 else (segments[i - 1][1] + segments[i][0]) // 2
        a, b = segments[i]
        label = f"e{len(events) + 1}"
        temps = {k: float(np.mean(v[a:b])) for k, v in series.temperatures.items()}
        active = (float(t[a]), float(t[b - 1]))
        if b - a < _MIN_SAMPLES or active[1] - active[0] < 0.5 * template.length / hi:
            events.append(CrossingEvent(label, t_start=active[0], t_end=active[1], entry_time=np.nan, speed=np.nan,
                                        speed_ci95=np.nan, fit_rms=np.nan, accepted=False, reason="too short",
                                        temperatures=temps))
            i += 1
            continue
        given_speed, given_entry = _given(speed, axle_times, axle_speeds, active[0])
        event = _fit_event(template, series, noise, segments, i, left=left, quiet_gap=quiet_gap,
                           speed_range=(lo, hi), fixed_speed=given_speed, fixed_entry=given_entry)
        fit, window, active = event.fit, event.window, event.active
        b = segments[event.last][1]
        i = event.last + 1
        temps = {k: float(np.mean(v[a:b])) for k, v in series.temperatures.items()}
        v, t0 = float(fit.speeds[0]), float(fit.entry_times[0])
        reason = _judge(fit, template, t[window], series.values[:, window], noise, active=active,
                        speed_range=(lo, hi), max_rms=max_rms, quiet_gap=quiet_gap,
                        constrained=given_speed is not None or given_entry is not None)
        span = (t0, t0 + template.length / v) if not reason else active  # accepted: the time on the bridge
        events.append(CrossingEvent(label, t_start=span[0], t_end=span[1], entry_time=t0, speed=v,
                                    speed_ci95=float(fit.speed_ci95[0]), fit_rms=fit.rms, accepted=not reason,
                                    reason=reason, temperatures=temps, fit_time=t[window], fit_values=fit.model))
        if not reason:
            z = v * (t[window] - t0)
            keep = (z >= 0.0) & (z <= template.length)
            values = (series.values[:, window] - fit.offsets)[:, keep]
            crossings.append(Crossing(label, z[keep], values, np.ones(int(keep.sum()))))
    source = "given" if speed is not None else ("axle detector" if axle_times is not None else "fitted")
    return ExtractedCrossings(series.names, kinds, noise_std=noise, events=tuple(events),
                              crossings=Crossings(series.names, tuple(crossings)) if crossings else None,
                              duration=float(t[-1] - t[0]), speed_source=source)


def _given(speed, axle_times, axle_speeds, start):
    """(speed, entry time) known for an event whose activity starts at ``start`` (None where not known).

    With an axle detector the event takes its latest time before ``start``, and that vehicle's speed
    when the detector gives speeds.
    """
    if axle_times is not None:
        before = np.flatnonzero(np.asarray(axle_times) <= start)
        if before.size:
            return (None if axle_speeds is None else float(axle_speeds[before[-1]])), float(axle_times[before[-1]])
    return speed, None


@dataclass(frozen=True, eq=False)
class _EventFit:
    """The fit of one event: the vehicle fit, its window of the record, the activity and its last segment."""

    fit: object
    window: slice
    active: tuple
    last: int


def _fit_event(template, series, noise, segments, i, *, left, quiet_gap, speed_range, fixed_speed, fixed_entry):
    """Fit the event starting at segment ``i``, taking in the following segments its vehicle is still on."""
    t = series.time
    a = segments[i][0]
    while True:  # one vehicle's activity may fall apart into runs (a tiltmeter reads zero in between)
        right = t.size if i == len(segments) - 1 else (segments[i][1] + segments[i + 1][0]) // 2
        active = (float(t[a]), float(t[segments[i][1] - 1]))
        margin = max(quiet_gap, 0.5 * (active[1] - active[0]))
        window = slice(max(left, int(np.searchsorted(t, active[0] - margin))),
                       min(right, int(np.searchsorted(t, active[1] + margin))))
        fit = fit_vehicles(template, t[window], series.values[:, window], noise, active=active,
                           speed_range=speed_range, fixed_speed=fixed_speed, fixed_entry=fixed_entry)
        off = fit.entry_times[0] + template.length / fit.speeds[0]
        if i + 1 < len(segments) and t[segments[i + 1][0]] < off + quiet_gap:
            i += 1
            continue
        return _EventFit(fit, window, active, i)


def _judge(fit, template, time, values, noise, *, active, speed_range, max_rms, quiet_gap, constrained):
    """Why the fit of one event (its window's ``time`` and ``values``) is rejected ("" when it is accepted)."""
    v, t0 = float(fit.speeds[0]), float(fit.entry_times[0])
    if not constrained and not (speed_range[0] <= v <= speed_range[1]):
        return "implausible speed"
    on, off = t0, t0 + template.length / v
    slack = max(quiet_gap, 0.1 * (off - on))
    outside = active[0] < on - slack or active[1] > off + slack
    if fit.rms <= _OVERLAP_GATE and not outside:
        return ""
    if not constrained:
        two = fit_vehicles(template, time, values, noise, active=active, speed_range=speed_range, n_vehicles=2)
        n = values.size
        gain = (fit.rms ** 2 - two.rms ** 2) * n / max(two.rms, 1.0) ** 2  # chi^2 drop, in units of the noise
        plausible = bool(np.all((two.speeds >= speed_range[0]) & (two.speeds <= speed_range[1])))
        if plausible and two.rms <= 0.8 * fit.rms and gain > _OVERLAP_CHI2:
            return "overlapping vehicles"
    if outside:
        return "overlapping vehicles"
    return "poor fit" if fit.rms > max_rms else ""


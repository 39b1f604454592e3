"""The vehicle test on a whole record: is this a vehicle, or wander + noise?

Hypotheses, per candidate event, under one noise model in time per channel
(white + Ornstein-Uhlenbeck + random walk, :mod:`.whitening`):

* H0: the channels read wander + noise only;
* H1: they read ``a * IL_c(v (t - t0))`` + wander + noise, the case's vehicle
  entering at ``t0`` with constant speed ``v`` and an unknown load factor
  ``a >= 0`` common to all channels (the case gives the axle spacing and the
  axles' relative loads; a vehicle's weight in traffic is not known).

No offset or drift line is fitted with the influence line: the wander is
part of the noise model on both sides, the record is whitened by its Kalman
filter and the walk's starting level is marginalised.  The generalised
likelihood ratio is z_+^2 with z the whitened matched filter (:mod:`.scan`),
maximised over entry samples and a geometric speed grid (3 % steps);
because of that search its null distribution is not chi-square, and the
threshold comes from :mod:`.calibration` for the stated false-event rate
(default one per day of record).  The test statistic reported is the grid
maximum, the one calibrated; entry time and speed are then refined
continuously (Nelder-Mead on the same whitened statistic) and their 95 %
intervals come from the Fisher information of (a, t0, v) in the whitened
domain.  Bursts are masked before the test (:mod:`.screen`); a significant
event is still rejected when the whitened residual of its fit is not noise
(rms above ``max_rms``: a burst or an unmodelled disturbance), when a second
vehicle is significant in that residual at the same threshold (overlapping
vehicles), when the channels disagree on its load factor (a sign or a gain
is wrong), when it is cut by the record's start or end, or when the
speed sits on the edge of the searched range.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import DataError
from .calibration import calibrate
from .scan import candidates, scan, speed_grid, whitened_templates
from .screen import estimate_noise, screen_bursts
from .whitening import whitener

__all__ = ["Policy", "Candidate", "RecordTest", "assess_record", "case_noise"]

# Channels disagree on the load factor when sum_c (r_c.m_c)^2/|m_c|^2 - (sum r.m)^2/sum|m|^2 exceeds this
# (chi-square with n_channels - 1 degrees of freedom under one vehicle; 24 is p = 1e-6 for one).
DISAGREEMENT = 24.0
PRE_ENTRY = 2.0  # s an axle-detector time may precede the scan's entry and still belong to the candidate


@dataclass(frozen=True)
class Policy:
    """The test's tuning, one reason each.

    false_events_per_day : the stated false-event rate the threshold is calibrated for.
    report_per_day : candidates below the threshold are listed down to the level chance reaches
        this often (24: about once an hour), so a rejected event says how close it came.
    max_rms : a significant event whose whitened residual rms exceeds this is not a clean vehicle.
    min_rms : below this the noise model overstates the noise there (rms 1 +- 1/sqrt(2n) when it is
        right), so its test cannot be trusted: rejected as "noise model does not fit".
    share : a second vehicle, or the channels' disagreement on the load, counts when it carries this
        share of the event's GLR (below it, at high signal-to-noise, it is the template's mismatch).
    n_null, seed : null samples simulated for the calibration, and their seed.
    """

    false_events_per_day: float = 1.0
    report_per_day: float = 24.0
    max_rms: float = 2.0
    min_rms: float = 0.7
    share: float = 0.1
    n_null: int = 2**19
    seed: int = 0


@dataclass(frozen=True, eq=False, kw_only=True)
class Candidate:
    """One candidate event: its test statistic and the refined vehicle.

    z : the calibrated scan statistic (the GLR is z**2); events_per_day : how often chance
    reaches it; significant : z above the threshold; entry_time [s], speed [m/s] and their
    95 % half-widths; load_factor : a (1 = the case's vehicle); fit_rms : whitened residual rms
    (1 = noise); window : the record's samples of the fit; signal : the fitted vehicle
    readings on them (n_channels, n) [rad or m]; reason : why a significant event is rejected.
    """

    z: float
    events_per_day: float
    significant: bool
    entry_time: float
    speed: float
    entry_ci95: float
    speed_ci95: float
    load_factor: float
    fit_rms: float
    window: slice
    signal: np.ndarray
    reason: str = ""

    @property
    def glr(self):
        return max(self.z, 0.0) ** 2


@dataclass(frozen=True, eq=False, kw_only=True)
class RecordTest:
    """The vehicle test of one record: its candidates, threshold, noise model and burst mask."""

    candidates: tuple
    calibration: object
    noise: object  # NoiseModel, one entry per channel
    noise_source: str
    burst_mask: np.ndarray
    strongest: float
    strongest_time: float
    speeds: np.ndarray


def case_noise(case, names):
    """The case's noise model in time for the channels ``names``, or None when it has none."""
    noise = case.noise
    if noise is None or not noise.in_time:
        return None
    return noise.subset([case.sensors.names.index(n) for n in names])


def _sample_interval(time):
    step = np.diff(time)
    dt = float(np.median(step))
    bad = np.flatnonzero(np.abs(step - dt) > 0.25 * dt)
    if bad.size:
        k = int(bad[0])
        raise DataError(f"The logger record is not evenly sampled: {step[k]:g} s between {time[k]:g} s and "
                        f"{time[k + 1]:g} s against {dt:g} s elsewhere; split the record at the gap.")
    return dt


def assess_record(template, time, values, *, noise=None, speed_range, fixed_speed=None, axle_times=None,
                policy=Policy()):
    """The :class:`RecordTest` of a record ``values`` (n_channels, n) at ``time`` [s].

    ``noise`` is a :class:`~sensorplan.model.noise.NoiseModel` with one entry per channel, or None
    to estimate it from the record (:func:`~.screen.estimate_noise`).
    ``fixed_speed`` [m/s] restricts the search to that speed; ``axle_times``
    [s] (an axle detector's front-axle times at x = 0) fix the entry of a
    candidate whose vehicle is on the bridge at one of them.
    """
    time = np.asarray(time, dtype=float)
    dt = _sample_interval(time)
    mask, clean = screen_bursts(values, dt)
    source = "case"
    if noise is None:
        noise, source = estimate_noise(clean, mask, dt), "record (robust variogram)"
    whiteners = [whitener(noise, dt, i) for i in range(noise.n_sensors)]
    pairs = [w.record(y) for w, y in zip(whiteners, clean)]
    r, ones = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
    speeds = speed_grid(speed_range, fixed_speed)
    templates = whitened_templates(template, whiteners, dt, speeds, max_samples=r.shape[1])
    cal = calibrate(templates, dt, false_events_per_day=policy.false_events_per_day, n_samples=policy.n_null,
                    seed=policy.seed)
    found = scan(r, templates, ones=ones)
    report = min(cal.level(policy.report_per_day), cal.threshold)
    picks = candidates(found, templates.durations, report) or candidates(found, templates.durations, -np.inf,
                                                                         limit=1)
    context = _Context(template, whiteners, time, r, ones, templates, cal, speed_range, fixed_speed, policy,
                       None if axle_times is None else np.sort(np.asarray(axle_times, dtype=float)))
    out = tuple(sorted((_candidate(context, k, speeds[found.speed_index[k]], float(found.z[k])) for k in picks),
                       key=lambda c: c.entry_time))
    top = int(np.argmax(found.z))
    return RecordTest(candidates=out, calibration=cal, noise=noise, noise_source=source, burst_mask=mask,
                      strongest=float(found.z[top]), strongest_time=float(time[top]), speeds=speeds)


@dataclass(frozen=True, eq=False)
class _Context:
    template: object
    whiteners: list
    time: np.ndarray
    r: np.ndarray
    ones: np.ndarray
    templates: object
    calibration: object
    speed_range: tuple
    fixed_speed: float | None
    policy: Policy
    axle_times: np.ndarray | None = None


def _candidate(ctx, k, v0, z):
    """The :class:`Candidate` of the scan maximum at entry sample ``k`` and grid speed ``v0``."""
    from .refine import refine

    entry = None
    if ctx.axle_times is not None:  # the detector's time while this vehicle is on the bridge, if any
        t_k = float(ctx.time[k])
        near = ctx.axle_times[(ctx.axle_times >= t_k - PRE_ENTRY) & (ctx.axle_times <= t_k + ctx.template.length / v0)]
        entry = float(near[np.argmin(np.abs(near - t_k))]) if near.size else None
    fit = refine(ctx, k, v0, entry=entry)
    significant = z > ctx.calibration.threshold
    reason = ""
    if significant:
        reason = _judge(ctx, fit, z)
    return Candidate(z=z, events_per_day=float(ctx.calibration.events_per_day(z)), significant=significant,
                     entry_time=fit.entry_time, speed=fit.speed, entry_ci95=fit.entry_ci95, speed_ci95=fit.speed_ci95,
                     load_factor=fit.load_factor, fit_rms=fit.rms, window=fit.window, signal=fit.signal,
                     reason=reason if significant else "not significant")


def _judge(ctx, fit, z):
    """Why a significant event is not a clean vehicle ("" when it is)."""
    if ctx.fixed_speed is None:
        lo, hi = ctx.speed_range
        if fit.speed <= lo * 1.0001 or fit.speed >= hi * 0.9999:
            return "implausible speed"
    if fit.entry_time + ctx.template.length / fit.speed > ctx.time[-1] or fit.entry_time < ctx.time[0]:
        return "cut by the record's edge"
    glr = max(z, 0.0) ** 2
    second = _second_vehicle(ctx, fit)
    if second > ctx.calibration.threshold and second**2 > ctx.policy.share * glr:
        return "overlapping vehicles"
    if _disagreement(ctx, fit) > max(DISAGREEMENT, ctx.policy.share * glr):
        return "channels disagree"
    if fit.rms < ctx.policy.min_rms:
        return "noise model does not fit"
    if fit.rms > ctx.policy.max_rms:
        return "poor fit"
    return ""


def _second_vehicle(ctx, fit):
    """The largest z of a second vehicle in the fit's whitened residual, on the bridge with the first."""
    t = ctx.time[fit.window]
    exit_time = fit.entry_time + ctx.template.length / fit.speed
    # only the residual while the first vehicle is on the bridge: a neighbouring vehicle is not an overlap
    residual = np.where((t >= fit.entry_time) & (t <= exit_time), ctx.r[:, fit.window] - fit.whitened, 0.0)
    second = scan(residual, ctx.templates)
    ends = t + ctx.template.length / ctx.templates.speeds[second.speed_index]
    together = (t < exit_time) & (ends > fit.entry_time)
    return float(np.max(second.z[together])) if together.any() else -np.inf


def _disagreement(ctx, fit):
    """Chi-square of per-channel load factors against the common one (a wrong sign or gain shows here)."""
    if fit.load_factor <= 0.0:
        return 0.0
    r = ctx.r[:, fit.window]
    m = fit.whitened / fit.load_factor
    rm, mm = np.sum(r * m, axis=1), np.sum(m * m, axis=1)
    live = mm > 0.0
    return float(np.sum(rm[live] ** 2 / mm[live]) - np.sum(rm) ** 2 / np.sum(mm))

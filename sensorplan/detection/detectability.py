"""Detectability maps: the best any detector can do against noise and nuisance.

For each zone centre c the damaged and undamaged noise-free readings are
compared through the exact forward model (:mod:`.signatures`); after
whitening and projecting out the nuisance, the norm d of the difference over
``n_crossings`` independent crossings is the signal-to-noise ratio of the
optimal (matched-filter, nuisance-invariant) one-sided test.  At false alarm
rate alpha its power is Phi(d - z_(1 - alpha)).

The minimum detectable loss is the smallest loss s with power >= 0.9, i.e.
d(s) >= z_(1 - alpha) + z_0.9 = T.  A loss raises the zone's compliance by
r = s / (1 - s), and to first order d(s) = d_1 r with d_1 the projected unit
signature, so s_lin = r / (1 + r) with r = T / d_1.  That is exact for
statically determinate bridges (readings linear in the compliance), but on
indeterminate ones the moments move away from a softened zone and the exact
d falls below d_1 r: by 2-3 % at s = 0.1, up to 12 % at s = 0.3 and more
for larger losses on the embedded examples, enough to turn power 0.9 into
0.8.  So the linear estimate only starts a root search in log r on the exact
d (bracketed, Illinois regula falsi, one zone change per centre and step,
usually 3-5 steps); the result is the upper end of the final bracket, where
the exact power is >= 0.9.  It is None where even a 99 % loss is not
detected.  The search assumes that d grows with the loss up to the first
crossing of T (true on every example checked; the exact d can dip for
losses above 90 % next to an elastic support spring).
"""

import math

import numpy as np
from scipy.special import ndtr, ndtri

from .._errors import ConfigError
from .._threads import single_threaded
from .._validation import MIN_ZONE_LENGTH, as_float_array
from ..model.sensors import SENSOR_KINDS, SensorLayout
from .results import POWER_TARGET, DetectabilityMap
from .signatures import NUISANCES, SignatureModel, centre_grid

__all__ = ["detectability", "check_detection_options", "MAX_CENTRES"]

MAX_CENTRES = 10_000
_OWNER = "detectability"
_NOT_DETECTABLE = 0.99


def _number(value, name, requirement, ok):
    bad = isinstance(value, (bool, str)) or value is None
    if not bad:
        try:
            out = float(value)
        except (TypeError, ValueError):
            bad = True
        else:
            bad = not (math.isfinite(out) and ok(out))
    if bad:
        raise ConfigError(f"The '{name}' parameter of {_OWNER} must be {requirement}. Got {value!r} instead.")
    return out


def check_detection_options(case, *, severity, length, false_alarm, n_crossings, nuisance, step):
    """The options of a detectability computation on ``case``, checked and converted.

    Returns (severity, length [m], false_alarm, n_crossings as int, step [m]);
    a ConfigError names the parameter out of range (the messages of
    :func:`detectability`, which the detect design criterion shares).
    """
    total = case.bridge.length
    severity = _number(severity, "severity", "a loss fraction in (0, 1)", lambda v: 0.0 < v < 1.0)
    length = _number(length, "length", f"a zone length in [{MIN_ZONE_LENGTH:g}, {total:g}) m (1 mm to the bridge "
                     "length)", lambda v: MIN_ZONE_LENGTH <= v < total)
    false_alarm = _number(false_alarm, "false_alarm", "a probability in (0, 0.5)", lambda v: 0.0 < v < 0.5)
    step = _number(step, "step", "a positive spacing of the zone centres in m", lambda v: v > 0.0)
    count = math.floor((total - length) / step + 1e-9) + 1
    if count > MAX_CENTRES:
        raise ConfigError(f"The 'step' parameter of {_OWNER} gives {count} zone centres, more than "
                          f"{MAX_CENTRES}. Got {step!r} instead; use a larger step.")
    crossings = _number(n_crossings, "n_crossings", "a positive integer",
                        lambda v: v >= 1 and v == int(v))
    if nuisance not in NUISANCES:
        raise ConfigError(f"The 'nuisance' parameter of {_OWNER} must be one of "
                          f"{', '.join(map(repr, NUISANCES))}. Got {nuisance!r} instead.")
    return severity, length, false_alarm, int(crossings), step


def _sensors_and_noise(case, layout, kind):
    """The case's sensors and noise, or new ``kind`` sensors at ``layout`` with the case's noise level."""
    if layout is None:
        if kind is not None:
            raise ConfigError(f"The 'kind' parameter of {_OWNER} applies to the sensors of 'layout' "
                              f"(the case's sensors keep their kinds). Got {kind!r} without a layout.")
        if case.noise is None:
            raise ConfigError("The case has no noise level; set noise_std in [sensors] of the case file.")
        return case.sensors, case.noise
    positions = as_float_array(layout, "layout", _OWNER)
    case.bridge.check_on_bridge(positions, "layout", _OWNER)
    kind = case.default_kind if kind is None else kind
    if kind not in SENSOR_KINDS:
        raise ConfigError(f"The 'kind' parameter of {_OWNER} must be one of "
                          f"{', '.join(map(repr, SENSOR_KINDS))}. Got {kind!r} instead.")
    if case.noise is None or kind not in case.sensors.kinds:
        raise ConfigError(f"The 'layout' sensors of {_OWNER} take the noise std of the case's {kind} sensors, "
                          f"and the case has no {kind} sensor with a noise level. Choose another 'kind'.")
    std = case.noise_std_for(kind)
    sensors = SensorLayout(positions, (kind,) * positions.size, None, (std,) * positions.size)
    return sensors, case.noise_for(sensors)


@single_threaded
def detectability(case, *, layout=None, kind=None, severity=0.25, length=2.0, false_alarm=0.05,
                  n_crossings=1, nuisance="smooth", step=0.5):
    """Detectability map of a local EI loss scanned along the bridge.

    Parameters
    ----------
    case : Case
        Bridge, nominal EI, vehicle, load sweep, sensors and noise (AR(1) included).
    layout : sequence of float, optional
        Positions [m] of new sensors of ``kind`` instead of the case's
        sensors; each gets the median noise std of the case's sensors of
        that kind and the case's noise correlation length.
    kind : {"rotation", "deflection"}, optional
        Kind of the ``layout`` sensors (default :attr:`Case.default_kind`).
    severity : float
        Fraction of EI lost over the zone, in (0, 1), for :attr:`~DetectabilityMap.d`
        and :attr:`~DetectabilityMap.power` (the minimum detectable loss does
        not depend on it).
    length : float
        Length of the damaged zone [m], in (0, L); the zone is not snapped
        to the case's elements.
    false_alarm : float
        False alarm rate alpha of the one-sided test, in (0, 0.5).
    n_crossings : int
        Independent identical crossings; d grows with their square root.
    nuisance : {"smooth", "levels"}
        What the detector must not mistake for damage, besides the elastic
        support springs: a quadratic log-EI trend per span (``"smooth"``)
        or one EI factor per span (``"levels"``).
    step : float
        Spacing of the zone centres [m], from length/2 to L - length/2 (at most 10000 centres).

    Returns
    -------
    DetectabilityMap

    Examples
    --------
    >>> from sensorplan import example_case
    >>> result = detectability(example_case("simply-supported"), step=2.0)
    >>> print(result.summary().splitlines()[0])
    Detectability of a 25 % EI loss over 2 m (1 crossing(s), false alarm rate 5 %, nuisance: smooth)
    >>> result.centres_m.tolist()[:3]
    [1.0, 3.0, 5.0]
    >>> print(f"{max(result.min_detectable_loss):.2f}")  # near the supports
    0.44
    """
    severity, length, false_alarm, n_crossings, step = check_detection_options(
        case, severity=severity, length=length, false_alarm=false_alarm, n_crossings=n_crossings,
        nuisance=nuisance, step=step)
    sensors, noise = _sensors_and_noise(case, layout, kind)
    centres = centre_grid(case.bridge.length, length, step)
    model = SignatureModel(case, sensors, noise, nuisance, length)
    d, d_unit, power, exact, linear = _limits(model, centres, severity, n_crossings, false_alarm)
    return DetectabilityMap(
        centres_m=centres, d=d, power=power, min_detectable_loss=_optional(exact),
        false_alarm_rate=false_alarm, n_crossings=n_crossings, severity=severity, length_m=length,
        nuisance=nuisance, sensors_m=sensors.positions, supports_m=case.bridge.support_positions,
        sensor_kinds=tuple(sensors.kinds), d_unit=d_unit, nuisance_names=model.nuisance_names,
        min_detectable_loss_linear=_optional(linear))


def _limits(model, centres, severity, n_crossings, false_alarm):
    """(d, d_unit, power, exact and first-order minimum detectable losses) per centre (module docstring).

    d and power are those of the loss ``severity``, d_unit that of the
    projected unit signature; the arrays are made read-only (the result
    holds them).
    """
    root = math.sqrt(n_crossings)
    d = root * model.projected_norms(model.damage(centres, severity))
    d_unit = root * model.projected_norms(model.unit(centres))
    z_alarm = -float(ndtri(false_alarm))  # exact for tiny rates (1 - 1e-300 == 1.0 in floating point)
    power = ndtr(d - z_alarm)
    target = z_alarm + float(ndtri(POWER_TARGET))
    with np.errstate(divide="ignore", invalid="ignore"):
        linear = target / d_unit
        linear = linear / (1.0 + linear)
    exact = _min_detectable_losses(lambda c, s: root * model.projected_norms(model.damage(c, s)),
                                   centres, d_unit, target)
    for arr in (centres, d, d_unit, power):
        arr.setflags(write=False)
    return d, d_unit, power, exact, linear


def _optional(losses):
    return tuple(float(s) if np.isfinite(s) and s < _NOT_DETECTABLE else None for s in losses)


def _min_detectable_losses(d_of, centres, d_unit, target, *, tol=1e-3, max_steps=50):
    """Smallest loss with d >= target per centre (NaN if none up to 99 %), by exact evaluations.

    ``d_of(centres, losses)`` returns the exact d.  The search runs in
    x = log r, r = s / (1 - s), on f = log(d / target) - tol / 2, starting at
    the first-order estimate, by secant steps kept inside the bracket
    (bisection otherwise).  The lower end starts as a point 3 below the
    first-order estimate, where f follows the first-order model; the upper
    end as the 99 % loss.  It stops when |f| <= tol / 2, i.e. when d is
    within [target, target e^tol], so the power is 0.9 to within 5e-4 and
    never below it.
    """
    x_max = math.log(_NOT_DETECTABLE / (1.0 - _NOT_DETECTABLE))
    out = np.full(centres.size, np.nan)
    idx = np.nonzero(d_unit > 0.0)[0]
    x_lin = np.log(target / d_unit[idx])
    lo = np.minimum(x_lin, x_max) - 3.0
    f_lo = lo - x_lin - tol / 2  # first-order model, far below the estimate
    hi, f_hi = np.full(idx.size, x_max), np.full(idx.size, np.nan)
    prev_x, prev_f = lo.copy(), f_lo.copy()
    trial = np.minimum(x_lin + tol / 2, x_max)  # where the first-order model puts f = 0
    for _ in range(max_steps):
        if idx.size == 0:
            break
        rho = np.exp(trial)
        f = np.log(np.maximum(d_of(centres[idx], rho / (1.0 + rho)), 1e-300) / target) - tol / 2
        up = f > 0.0
        hi, f_hi = np.where(up, trial, hi), np.where(up, f, f_hi)
        lo, f_lo = np.where(up, lo, trial), np.where(up, f_lo, f)
        found = np.abs(f) <= tol / 2
        out[idx[found]] = rho[found] / (1.0 + rho[found])
        narrow = ~found & (hi - lo < 1e-9) & ~np.isnan(f_hi)  # the upper end has power >= 0.9
        out[idx[narrow]] = np.exp(hi[narrow]) / (1.0 + np.exp(hi[narrow]))
        done = found | narrow | (~up & (trial >= x_max))
        with np.errstate(divide="ignore", invalid="ignore"):
            step = trial - f * (trial - prev_x) / (f - prev_f)
        inside = np.isfinite(step) & (step > lo) & (step < hi)
        fallback = np.where(np.isnan(f_hi), hi, 0.5 * (lo + hi))  # try the 99 % loss, or bisect
        prev_x, prev_f = trial, f
        trial = np.where(inside, step, fallback)
        keep = ~done
        idx, lo, f_lo, hi, f_hi, prev_x, prev_f, trial = (
            a[keep] for a in (idx, lo, f_lo, hi, f_hi, prev_x, prev_f, trial))
    bracketed = ~np.isnan(f_hi)  # not converged in max_steps: the upper end has power >= 0.9
    rho = np.exp(hi[bracketed])
    out[idx[bracketed]] = rho / (1.0 + rho)
    return out

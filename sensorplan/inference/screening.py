"""Screening of repeated crossings: flag a crossing that does not match the others."""

import numpy as np

from .._cache import value_key

__all__ = ["screen_crossings", "check_case_data_scale", "check_not_noise_free"]


def screen_crossings(crossings, *, min_correlation=0.5, rms_factor=2.5):
    """Split crossings into kept and excluded ones.

    Every crossing (divided by its load factor) is interpolated onto the
    positions common to all crossings and compared with the median crossing.
    A crossing is excluded when its correlation with the median is below
    ``min_correlation``, or (with three or more crossings) when its rms
    deviation from the median exceeds ``rms_factor`` times the median rms
    deviation of all crossings.

    Returns
    -------
    kept : Crossings
    excluded : tuple of str
        Labels of the excluded crossings.
    reasons : tuple of str
    """
    if len(crossings) < 2:
        return crossings, (), ()
    lo = max(float(c.positions[0]) for c in crossings)
    hi = min(float(c.positions[-1]) for c in crossings)
    if hi <= lo:
        return crossings, (), ()
    grid = np.linspace(lo, hi, 200)
    curves = np.stack([
        np.stack([np.interp(grid, c.positions, v / c.load_factor) for v in c.values]).ravel()
        for c in crossings])
    median = np.median(curves, axis=0)
    centred = curves - curves.mean(axis=1, keepdims=True)
    med_c = median - median.mean()
    denom = np.linalg.norm(centred, axis=1) * np.linalg.norm(med_c)
    corr = np.where(denom > 0, centred @ med_c / np.where(denom > 0, denom, 1.0), 1.0)
    rms = np.sqrt(np.mean((curves - median) ** 2, axis=1))
    typical = np.median(rms)
    excluded, reasons = [], []
    for c, rho, dev in zip(crossings, corr, rms):
        if rho < min_correlation:
            excluded.append(c.label)
            reasons.append(f"correlation {rho:.2f} with the median crossing is below {min_correlation}")
        elif len(crossings) >= 3 and typical > 0 and dev > rms_factor * typical:
            excluded.append(c.label)
            reasons.append(f"rms deviation from the median crossing is {dev / typical:.1f} times the typical")
    if len(excluded) == len(crossings):
        return crossings, (), ()
    return crossings.select([c.label for c in crossings if c.label not in excluded]), tuple(excluded), tuple(reasons)


def check_data_scale(crossings, predictions, names, *, factor=30.0, source="data"):
    """Raise DataError when a sensor's data are far larger or smaller than the model predicts.

    ``predictions`` maps sensor name to predicted readings at nominal EI.
    A ratio beyond ``factor`` either way looks like a unit slip (mm/m or
    micro-radians given as rad, mm given as m) in the data or in the case
    (EI in kN m^2 or axle loads in kN make the predictions 1000 times off).
    """
    from .._errors import DataError

    # a sensor the model says reads nothing (a deflection at a rigid bearing: zero up to round-off, some
    # 1e-19 m against readings of mm elsewhere) has no scale to compare with
    largest = max((_rms(np.asarray(predictions[n])) for n in names), default=0.0)
    for i, name in enumerate(names):
        data_rms = _rms(np.concatenate([c.values[i] / c.load_factor for c in crossings]))
        model_rms = _rms(np.asarray(predictions[name]))
        if model_rms <= 1e-12 * largest or data_rms == 0.0:
            continue
        ratio = data_rms / model_rms
        if ratio > factor or ratio < 1.0 / factor:
            case_side = ("axle loads in kN instead of N, or EI too large" if ratio > factor
                         else "EI in kN m^2 instead of N m^2, or axle loads too large")
            raise DataError(
                f"{source}: column '{name}' is {ratio:.3g} times the model's prediction at nominal EI; "
                "this looks like a unit slip (values must be rad for rotation, m for deflection; or, in the "
                f"case, {case_side}).")


def _rms(values):
    """Root mean square without underflow (readings of 1e-300 square to 0)."""
    top = float(np.max(np.abs(values))) if values.size else 0.0
    return 0.0 if top == 0.0 else top * float(np.sqrt(np.mean((values / top) ** 2)))


def check_case_data_scale(case, crossings, *, source="data"):
    """Refuse data that carry no information about the case, before anything is fitted.

    In order: positions that never put an axle on the bridge (or look like
    cm or mm), a dead (constant) channel, a unit slip (:func:`check_data_scale`);
    a sensor whose readings are anti-correlated with the model (a tiltmeter
    mounted the other way round) is warned about.
    """
    from .._errors import DataError

    _check_positions(case, crossings, source)
    sensors = case.sensors.subset([case.sensors.names.index(n) for n in crossings.sensor_names])
    predicted = {}  # the nominal predictions at each distinct set of positions
    for c in crossings:
        key = value_key(c.positions)
        if key not in predicted:
            predicted[key] = case.influence_lines(sensors=sensors, positions=c.positions).predictions
    for i, name in enumerate(crossings.sensor_names):
        # A channel is dead when its readings stay constant where the model predicts them to change.
        values = np.concatenate([c.values[i] for c in crossings])
        model = np.concatenate([predicted[value_key(c.positions)][i] * c.load_factor for c in crossings])
        if (values.size >= 3 and np.ptp(values) <= 1e-12 * np.max(np.abs(values))
                and np.ptp(model) > 1e-6 * np.max(np.abs(model))):
            raise DataError(f"{source}: column '{name}' is constant ({values[0]:g} in every row) where the model "
                            "predicts it to change: a dead or disconnected channel carries no information; remove "
                            "the column.")
    nominal = predicted[value_key(crossings.crossings[0].positions)]
    check_data_scale(crossings, dict(zip(crossings.sensor_names, nominal)), crossings.sensor_names,
                     source=source)
    _check_signs(crossings, predicted, source)


def _check_positions(case, crossings, source):
    from .._errors import DataError

    length, reach = case.bridge.length, case.vehicle.length
    top = max(float(c.positions[-1]) for c in crossings)
    if top > 10.0 * (length + reach) + 1.0:
        raise DataError(f"{source}: column 'position_m' reaches {top:g} on a {length:g} m bridge; positions in "
                        "cm or mm? Convert position_m to m.")
    for c in crossings:
        axles = case.vehicle.axle_positions(c.positions)
        if not np.any((axles >= 0.0) & (axles <= length)):
            raise DataError(
                f"{source}: crossing '{c.label}' never puts an axle on the bridge (position_m from "
                f"{c.positions[0]:g} to {c.positions[-1]:g} m; the bridge runs from 0 to {length:g} m and the "
                f"front axle leads the rear by {reach:g} m); check the unit and the origin of position_m.")


def _check_signs(crossings, predicted, source):
    import warnings

    from .._errors import SensorplanWarning

    models = [np.concatenate([predicted[value_key(c.positions)][i] for c in crossings])
              for i in range(len(crossings.sensor_names))]
    largest = max(float(np.std(m)) for m in models)
    for i, name in enumerate(crossings.sensor_names):
        data = np.concatenate([c.values[i] / c.load_factor for c in crossings])
        model = models[i]
        if np.std(data) == 0.0 or np.std(model) <= 1e-12 * largest:  # a sensor the model says reads nothing
            continue
        rho = float(np.corrcoef(data, model)[0, 1])
        if rho < -0.5:
            warnings.warn(
                f"{source}: column '{name}' is anti-correlated with the model's prediction at nominal EI "
                f"(correlation {rho:.2f}): the sensor is probably mounted the other way round (sign flip), or its "
                "position or kind is wrong; if it is mounted reversed, multiply the column by -1. The fit below "
                "will not be trusted.", SensorplanWarning, stacklevel=3)


def check_not_noise_free(case, crossings, *, source="data", what="diagnose"):
    """Refuse data that equal the nominal prediction to within 1e-3 of the noise (no gap to explain)."""
    from .._errors import DataError

    if case.noise is None:
        return
    sensors = case.sensors.subset([case.sensors.names.index(n) for n in crossings.sensor_names])
    std = case.noise.subset([case.sensors.names.index(n) for n in crossings.sensor_names]).std
    worst = 0.0
    for c in crossings:
        model = case.influence_lines(sensors=sensors, positions=c.positions).predictions * c.load_factor
        worst = max(worst, float(np.max(np.sqrt(np.mean((c.values - model) ** 2, axis=1)) / std)))
    if worst < 1e-3:
        raise DataError(f"{source}: the readings differ from the model's prediction at nominal EI by {worst:.1g} noise "
                        f"std (rms): noise-free data (as `simulate` writes without --noise) leave nothing to "
                        f"{what}; simulate with --noise --seed S or give measured data.")

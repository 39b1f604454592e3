"""Screening of repeated crossings: flag a crossing that does not match the others."""

import numpy as np

__all__ = ["screen_crossings", "check_case_data_scale"]


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
    micro-radians given as rad, mm given as m).
    """
    from .._errors import DataError

    for i, name in enumerate(names):
        data_rms = np.sqrt(np.mean(np.concatenate([c.values[i] / c.load_factor for c in crossings]) ** 2))
        model_rms = np.sqrt(np.mean(np.asarray(predictions[name]) ** 2))
        if model_rms == 0.0 or data_rms == 0.0:
            continue
        ratio = data_rms / model_rms
        if ratio > factor or ratio < 1.0 / factor:
            raise DataError(
                f"{source}: column '{name}' is {ratio:.3g} times the model's prediction at nominal EI; "
                "this looks like a unit slip (values must be rad for rotation, m for deflection).")


def check_case_data_scale(case, crossings, *, source="data"):
    """:func:`check_data_scale` of ``crossings`` against ``case`` at nominal EI."""
    sensors = case.sensors.subset([case.sensors.names.index(n) for n in crossings.sensor_names])
    nominal = case.influence_lines(sensors=sensors, positions=crossings.crossings[0].positions)
    check_data_scale(crossings, dict(zip(crossings.sensor_names, nominal.predictions)), crossings.sensor_names,
                     source=source)

"""Logger exports (``time_s,<sensor...>[,<temperature...>]``) and axle-detector times.

Sensor columns are converted from the units of the case's ``[logger]``
section to SI on entry.  Every error names the file, the row or the column
and says how to fix it.
"""

import csv
import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._errors import DataError
from ..model.timeseries import LoggerFormat, TimeSeries
from .csvio import check_delimiter, read_text

if TYPE_CHECKING:
    from ..model.sensors import SensorLayout

__all__ = ["read_timeseries", "read_axle_times"]


def _rows(path):
    path = Path(path)
    reader = csv.reader(io.StringIO(read_text(path)))
    try:
        rows = [r for r in reader if r and any(cell.strip() for cell in r)]
    except csv.Error as exc:
        raise DataError(f"{path}: line {reader.line_num}: malformed CSV ({exc}).") from None
    if len(rows) < 2:
        raise DataError(f"{path}: expected a header and data rows.")
    header = [h.strip() for h in rows[0]]
    check_delimiter(header, path, "time_s,<sensors>")
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(f"{path}: column '{dup}' appears twice.")
    return path, header, rows[1:]


def _table(path, header, rows):
    out = np.empty((len(rows), len(header)))
    for k, row in enumerate(rows):
        if len(row) != len(header):
            raise DataError(f"{path}: row {k + 2} has {len(row)} fields, the header has {len(header)}.")
        for j, cell in enumerate(row):
            try:
                value = float(cell)
            except ValueError:
                raise DataError(f"{path}: row {k + 2}, column '{header[j]}': {cell.strip()!r} is not a "
                                "number.") from None
            if math.isnan(value) or math.isinf(value):
                raise DataError(f"{path}: row {k + 2}, column '{header[j]}' is {cell.strip() or 'empty'}; "
                                "remove the row or fill in the value.")
            out[k, j] = value
    return out


def read_timeseries(path: "str | os.PathLike[str]", sensors: "SensorLayout",
                    fmt: LoggerFormat | None = None) -> TimeSeries:
    """Read a logger export.

    Parameters
    ----------
    path : str or Path
        CSV with a ``time_s`` column, one column per sensor of the case
        (any subset, at least one) and the temperature columns of ``fmt``.
    sensors : SensorLayout
        The case's sensors (names and kinds).
    fmt : LoggerFormat, optional
        Units and temperature columns (default: SI, no temperatures).
    """
    fmt = LoggerFormat() if fmt is None else fmt
    path, header, rows = _rows(path)
    if "time_s" not in header:
        raise DataError(f"{path}: missing column 'time_s'; the header must be 'time_s' followed by one "
                        "column per sensor name.")
    others = [h for h in header if h != "time_s" and h not in fmt.temperature_columns]
    unknown = [h for h in others if h not in sensors.names]
    if unknown:
        raise DataError(f"{path}: column '{unknown[0]}' is neither a sensor of the case ({', '.join(sensors.names)}) "
                        "nor a temperature column; add it to [logger] temperature_columns or remove it.")
    for name in fmt.temperature_columns:
        if name not in header:
            raise DataError(f"{path}: the temperature column '{name}' named in [logger] is missing.")
    if not others:
        raise DataError(f"{path}: no sensor column; add one column per sensor name ({', '.join(sensors.names)}).")
    table = _table(path, header, rows)
    col = {h: j for j, h in enumerate(header)}
    kinds = [sensors.kinds[sensors.names.index(h)] for h in others]
    values = np.array([table[:, col[h]] * fmt.factor(k) for h, k in zip(others, kinds)])
    temps = {h: table[:, col[h]] for h in fmt.temperature_columns}
    try:
        series = TimeSeries(table[:, col["time_s"]], tuple(others), values, temps)
    except DataError as exc:
        raise DataError(f"{path}: {exc}") from None
    for name, kind, row in zip(series.names, kinds, series.values):
        limit = 0.02 if kind == "rotation" else 1.0
        if np.ptp(row) > limit:
            raise DataError(f"{path}: column '{name}' varies by {np.ptp(row):g} {'rad' if kind == 'rotation' else 'm'}, "
                            f"implausible for a {kind} sensor; set the logger's unit in [logger] "
                            f"({'tilt_unit' if kind == 'rotation' else 'deflection_unit'}).")
    return series


def read_axle_times(path: "str | os.PathLike[str]"):
    """Axle-detector times: ``time_s`` (front axle at x = 0) and optionally ``speed_m_s`` per vehicle.

    Returns
    -------
    times : ndarray (n_vehicles,)
        Entry times [s], increasing.
    speeds : ndarray (n_vehicles,) or None
        Speeds [m/s] when the file has them.
    """
    path, header, rows = _rows(path)
    if "time_s" not in header:
        raise DataError(f"{path}: missing column 'time_s' (the time the front axle passes x = 0).")
    extra = [h for h in header if h not in ("time_s", "speed_m_s")]
    if extra:
        raise DataError(f"{path}: unexpected column '{extra[0]}'; expected 'time_s' and optionally 'speed_m_s'.")
    table = _table(path, header, rows)
    times = table[:, header.index("time_s")]
    if np.any(np.diff(times) <= 0.0):
        raise DataError(f"{path}: time_s must be strictly increasing; sort the rows by time.")
    speeds = None
    if "speed_m_s" in header:
        speeds = table[:, header.index("speed_m_s")]
        if np.any(speeds <= 0.0):
            raise DataError(f"{path}: column 'speed_m_s' must be positive (m/s).")
    return times, speeds

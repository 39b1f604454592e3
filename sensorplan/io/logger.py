"""Logger exports (``time_s,<sensor...>[,<temperature...>]``) and axle-detector times.

Sensor columns are converted from the units of the case's ``[logger]``
section to SI on entry; the time column is in s or ms (``time_ms``, or
``[logger] time_unit``) or holds ISO 8601 timestamps, read as seconds from
the first one.  Plausibility checks (:mod:`.logger_checks`) catch a unit or
time base stated wrongly.  Every error names the file, the row or the column
and says how to fix it.
"""

import csv
import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

from datetime import datetime, timedelta

import numpy as np

from .._errors import DataError
from ..model.timeseries import TIME_UNITS, LoggerFormat, TimeSeries
from .csvio import check_delimiter, read_text
from .logger_checks import check_channel, check_time_base

if TYPE_CHECKING:
    from ..model.sensors import SensorLayout

__all__ = ["read_timeseries", "read_axle_times"]

# the time column's names and the unit each implies ("time": ISO timestamps, or numbers in [logger] time_unit)
TIME_COLUMNS = {"time_s": "s", "time_ms": "ms", "time": None}


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


def _number(path, k, name, cell):
    try:
        value = float(cell)
    except ValueError:
        raise DataError(f"{path}: row {k + 2}, column '{name}': {cell.strip()!r} is not a number.") from None
    if math.isnan(value) or math.isinf(value):
        raise DataError(f"{path}: row {k + 2}, column '{name}' is {cell.strip() or 'empty'}; "
                        "remove the row or fill in the value.")
    return value


def _table(path, header, rows, *, skip=None):
    """The numbers of ``rows`` (n_rows, n_columns); the column ``skip`` (e.g. timestamps) is left at 0."""
    out = np.zeros((len(rows), len(header)))
    for k, row in enumerate(rows):
        if len(row) != len(header):
            raise DataError(f"{path}: row {k + 2} has {len(row)} fields, the header has {len(header)}.")
        for j, cell in enumerate(row):
            if j != skip:
                out[k, j] = _number(path, k, header[j], cell)
    return out


def _time_column(path, header, fmt):
    """The name of the time column and its factor to s (None: ISO timestamps are decided by the cells)."""
    # 'time' only without time_s / time_ms (a sensor may be called "time")
    found = [h for h in ("time_s", "time_ms") if h in header] or [h for h in ("time",) if h in header]
    if not found:
        raise DataError(f"{path}: missing column 'time_s' (or 'time_ms', or 'time' with timestamps); the header "
                        "must be 'time_s' followed by one column per sensor name.")
    if len(found) > 1:
        raise DataError(f"{path}: time columns {', '.join(repr(h) for h in found)}; keep one time column.")
    name = found[0]
    if name == "time_ms" and fmt.time_unit == "s":
        raise DataError(f"{path}: the time column is 'time_ms' but [logger] time_unit is \"s\"; rename the "
                        "column time_s or set time_unit = \"ms\".")
    unit = fmt.time_unit or TIME_COLUMNS[name]
    return name, None if unit is None else TIME_UNITS[unit]


def _timestamps(path, name, cells):
    """ISO 8601 timestamps -> seconds from the first one (aware ones through UTC; naive ones as written)."""
    stamps = []
    for k, cell in enumerate(cells):
        try:
            stamps.append(datetime.fromisoformat(cell.strip()))
        except ValueError:
            raise DataError(f"{path}: row {k + 2}, column '{name}': {cell.strip()!r} is neither a number nor an "
                            "ISO 8601 timestamp (e.g. 2022-03-07 16:35:15.600 or 2022-03-07T16:35:15.6+01:00)."
                            ) from None
    aware = [s.tzinfo is not None for s in stamps]
    if any(aware) and not all(aware):
        k = aware.index(not aware[0])
        raise DataError(f"{path}: row {k + 2}, column '{name}' mixes timestamps with and without a time zone; "
                        "give every timestamp with its offset, or none.")
    first = stamps[0]
    seconds = np.array([(s - first) / timedelta(microseconds=1) for s in stamps]) * 1e-6
    return seconds, first.isoformat()


def _read_time(path, name, factor, rows, col):
    """Time [s] of the rows and the ISO start ('' for a numeric column)."""
    cells = [row[col] if col < len(row) else "" for row in rows]
    try:
        float(cells[0])
    except ValueError:
        if any(ch.isdigit() for ch in cells[0]) and "-" in cells[0]:
            return _timestamps(path, name, cells)
    else:
        if factor is None:
            raise DataError(f"{path}: column '{name}' holds numbers without a unit; name it time_s or time_ms, or "
                            "set [logger] time_unit.")
    factor = 1.0 if factor is None else factor  # the first cell is no number: _number names it
    return np.array([_number(path, k, name, c) for k, c in enumerate(cells)]) * factor, ""


def read_timeseries(path: "str | os.PathLike[str]", sensors: "SensorLayout",
                    fmt: LoggerFormat | None = None) -> TimeSeries:
    """Read a logger export.

    Parameters
    ----------
    path : str or Path
        CSV with a time column (``time_s``, or ``time_ms``; numbers in the
        unit of ``[logger] time_unit``, or ISO 8601 timestamps), one column
        per sensor of the case (any subset, at least one) and the
        temperature columns of ``fmt``.
    sensors : SensorLayout
        The case's sensors (names and kinds).
    fmt : LoggerFormat, optional
        Units and temperature columns (default: SI, no temperatures).
    """
    fmt = LoggerFormat() if fmt is None else fmt
    path, header, rows = _rows(path)
    time_name, time_factor = _time_column(path, header, fmt)
    others = [h for h in header if h != time_name and h not in fmt.temperature_columns]
    unknown = [h for h in others if h not in sensors.names]
    if unknown:
        raise DataError(f"{path}: column '{unknown[0]}' is neither a sensor of the case ({', '.join(sensors.names)}) "
                        "nor a temperature column; add it to [logger] temperature_columns or remove it.")
    for name in fmt.temperature_columns:
        if name not in header:
            raise DataError(f"{path}: the temperature column '{name}' named in [logger] is missing.")
    if not others:
        raise DataError(f"{path}: no sensor column; add one column per sensor name ({', '.join(sensors.names)}).")
    col = {h: j for j, h in enumerate(header)}
    table = _table(path, header, rows, skip=col[time_name])
    time, start = _read_time(path, time_name, time_factor, rows, col[time_name])
    if not start:
        check_time_base(time, time_name, fmt.time_unit or TIME_COLUMNS[time_name], path)
    kinds = [sensors.kinds[sensors.names.index(h)] for h in others]
    values = np.array([table[:, col[h]] * fmt.factor(k) for h, k in zip(others, kinds)])
    temps = {h: table[:, col[h]] for h in fmt.temperature_columns}
    try:
        series = TimeSeries(time, tuple(others), values, temps, start=start)
    except DataError as exc:
        raise DataError(f"{path}: {exc}".replace("time_s", time_name)) from None
    for name, kind, row in zip(series.names, kinds, series.values):
        check_channel(row, name, kind, fmt, path)
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
